"""Cut the Rope's shortcut baselines (deepphy/envs/shortcuts.py): policies that read nothing
but the action space (what can be used now) and exploit how levels are made, not physics.

- `first-id`: act on the element labelled 1 (P1, else A1, B1, C1) and declare success():
  wins every level whose answer is "cut rope 1" (levels numbered in the order of their
  solution);
- `all-at-once`: cut every rope in one swipe and declare success(): wins every level whose
  answer is to let the candy drop;
- `random-pauses`: the random agent that also waits and swipes: each decision a pause of
  0.1-3 s (half the time) or one of the element actions (each rope alone, two or all ropes
  at once, a pop, a tap of 1, 3 or 5 puffs), uniformly; success() once nothing is left.
  The reference random agent (`mock`) never waits and cuts one rope at a time, so a level
  can sit in its blind spot; this one has none.
Deterministic: `random-pauses` draws from the context's generator (seeded by the request's
position), the others draw nothing. Light module (no pymunk).
"""

from __future__ import annotations

from deepphy.envs.cuttherope.space import CutAction, CutSpace
from deepphy.envs.shortcuts import ShortcutContext, ShortcutPolicy

PAUSE_SHARE = 0.5  # random-pauses: the chance of a pause at a decision
PAUSES = tuple(round(0.1 * k, 1) for k in range(1, 31))  # 0.1 .. 3.0 s, the pauses random-pauses draws from
SUCCESS = "success()"


def _space(ctx: ShortcutContext) -> CutSpace:
    space = ctx.action_space
    assert isinstance(space, CutSpace)
    return space


def first_id(ctx: ShortcutContext) -> str:
    """The first decision acts on the element labelled 1 of the first kind the level has;
    then success()."""
    space = _space(ctx)
    if ctx.earlier:
        return SUCCESS
    if 1 in space.pins:
        return space.format(CutAction(name="cut_pin", ids=(1,)))
    if 1 in space.active_pins:
        return space.format(CutAction(name="cut_active_pin", ids=(1,)))
    if 1 in space.bubbles:
        return space.format(CutAction(name="pop_bubble", ids=(1,)))
    if space.num_cushions:
        return space.format(CutAction(name="tap_air_cushion", ids=(1,), times=1))
    return SUCCESS


def all_at_once(ctx: ShortcutContext) -> str:
    """The first decision cuts every rope of a pin in one swipe (a level without pins: every
    active pin's); then success()."""
    space = _space(ctx)
    if ctx.earlier:
        return SUCCESS
    if space.pins:
        return space.format(CutAction(name="cut_pin", ids=tuple(space.pins)))
    if space.active_pins:
        return space.format(CutAction(name="cut_active_pin", ids=tuple(space.active_pins)))
    return SUCCESS


def random_pauses(ctx: ShortcutContext) -> str:
    """Half the time a pause of 0.1-3 s, else uniform among the element actions (each rope,
    two or all ropes at once, pops, taps of 1, 3, 5); success() when no element is left."""
    space = _space(ctx)
    actions = space.element_actions()
    for name, ids in (("cut_pin", space.pins), ("cut_active_pin", space.active_pins)):
        if len(ids) > 2:  # the swipe through every rope (pairs are among the element actions)
            actions.append(CutAction(name=name, ids=tuple(ids)))
    if not actions:
        return SUCCESS
    if ctx.rng.random() < PAUSE_SHARE:
        return space.format(CutAction(name="sleep", seconds=PAUSES[int(ctx.rng.integers(len(PAUSES)))]))
    return space.format(actions[int(ctx.rng.integers(len(actions)))])


SHORTCUTS = {
    "first-id": ShortcutPolicy(first_id, "acts on the element labelled 1 (P1, else A1, B1, C1), then success()"),
    "all-at-once": ShortcutPolicy(all_at_once, "cuts every rope in one swipe at t = 0, then success()"),
    "random-pauses": ShortcutPolicy(random_pauses, "random, but also waits 0.1-3 s half the time and cuts two or "
                                                   "all ropes at once; success() when nothing is left", draws=True),
}
