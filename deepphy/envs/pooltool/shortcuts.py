"""Pooltool's shortcut baseline (deepphy/envs/shortcuts.py)."""

from __future__ import annotations

from deepphy.envs.pooltool.space import PoolShot, PoolSpace
from deepphy.envs.shortcuts import ShortcutContext, ShortcutPolicy


def brute_force(ctx: ShortcutContext) -> str:
    """The paper's brute force: full power, centre of the cue ball, at the lowest ball (the
    aim is automatic): every shot the same."""
    space = ctx.action_space
    assert isinstance(space, PoolSpace)
    return space.format(PoolShot(speed="High", spot="middle-centre"))


SHORTCUTS = {
    "brute-force": ShortcutPolicy(brute_force, "every shot at full speed through the centre of the cue ball"),
}
