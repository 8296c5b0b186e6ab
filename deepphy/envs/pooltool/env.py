"""Pooltool: single-player nine-ball on the real `pooltool-billiards` package.

Each shot the cue is aimed automatically at the centre of the lowest-numbered ball on
the table (a full-ball hit, as `pooltool.ai.aim.at_ball`, no cut); the agent chooses only
the cue speed and where the tip strikes the cue ball. The physics and the nine-ball rules
are pooltool's own (`pt.simulate` with an explicit engine, pooltool's NINEBALL ruleset);
the rack, the ball-in-hand placement and the rendering are ours.

Decisions (documented in docs/environments.md):
- Actions: `Speed: Low|Medium|High` = cue speed 2 / 5 / 8 m/s, and `Strikespot:` one of
  nine spots on the cue ball as the shooter sees it. Edge spots sit half a ball radius
  from the centre on an axis, corner spots at +-0.35 on both axes (radius 0.495, the
  same distance from the centre), in pooltool's units of the ball radius:
      top-left (+0.35, +0.35)   top-centre (0, +0.5)    top-right (-0.35, +0.35)
      middle-left (+0.5, 0)     middle-centre (0, 0)    middle-right (-0.5, 0)
      bottom-left (+0.35,-0.35) bottom-centre (0, -0.5) bottom-right (-0.35, -0.35)
  as (a, b); pooltool's a = +1 is the LEFT edge of the ball, b = +1 the top. Top = follow,
  bottom = draw, left / right = side spin. 3 x 9 = 27 actions.
- Racks: pooltool's nine-ball diamond (1 at the apex on the foot spot, 9 in the middle,
  2-8 in the other places, each ball jittered inside (1 + 1e-3) R as `get_rack` does) and
  pooltool's break position of the cue ball (0.85 w, 0.23 l). We draw the permutation and
  the jitter from `seeded_rng("pooltool", "rack", k)`, name the balls ourselves and insert
  them in a fixed order (cue, 1..9): pooltool's `get_rack` has no seed and takes ball ids
  from a Python set, and dict order changes collision order, so its racks differ between
  processes.
- Physics engine: `PhysicsEngine(resolver=default_resolver())`, passed explicitly, so a
  user's ~/.config/pooltool/physics/resolver.yaml cannot change the physics.
- Rules: pooltool's nine-ball (legal break: a pot or 4 balls to a cushion; afterwards the
  lowest ball must be hit first and then a ball must be potted or a ball must reach a
  cushion; the cue ball must stay on the table). One player: the turn never passes.
  Success = the 9-ball potted on a legal shot (on the break too).
- Ball in hand: after any foul the cue ball is placed on the head spot (w/2, l/4), where
  pooltool's ruleset puts it; if a ball lies there, on the nearest free point of a fixed
  grid (2 mm steps, ties broken by position), see `_free_spot`.
- A 9-ball potted on a foul is respotted on the foot spot (w/2, 3l/4) or the nearest free
  point (standard nine-ball rule; pooltool only respots it when it was the last ball).
- Attempts: one game per task (max_attempts 1), at most 15 shots (max_steps 15).
- Rules: `rules=reference` (the default) reproduces the reference implementation's set-up,
  so numbers compare with the paper's: one rack (drawn once, `seeded_rng("pooltool", "rack",
  "reference")`) copied for all 100 games; no separate break (the cue ball starts on the
  head spot and shot 1 aims at the 1-ball like any other); no fouls: any shot that pots the
  9-ball wins; a potted cue ball goes back on the head spot (or the nearest free point);
  potted balls stay down. The paper itself blames the single rack for a deterministic
  model scoring 100%: `rules=nineball` (an opt-in departure from the paper) plays 100
  different racks under pooltool's nine-ball rules as described above.
- Observation: by default what the paper's prompt gives, the table seen from above and
  nothing else (no text, no earlier shots); `state_text=true` adds the ball positions in
  metres, the shot count, the target circled with the cue's line to it, and the earlier
  shots of the game.
- Numba: pooltool compiles its kernels on the first shot (~25-30 s of CPU). We point
  NUMBA_CACHE_DIR at `<cache root>/numba` (the per-machine cache, deepphy.cache) before
  numba is imported, so every process and worker on a machine shares one cache, and the
  first step of each process simulates a warm-up break under a file lock (`warm_up`), so
  concurrent workers on a cold machine compile once, not once each.

This module imports pooltool lazily: the action space must be importable (and rebuilt
from JSON by the MOCK model) without pulling in panda3d and numba.
"""

from __future__ import annotations

import re
from typing import Any, ClassVar, Literal

import numpy as np

from deepphy.envs.base import FILM_FPS, Action, EnvOptions, Environment, Frame, Observation, StepResult, Task
from deepphy.envs.images import Image
from deepphy.envs.pooltool import SPEC
from deepphy.envs.pooltool.render import _traces, render_table
from deepphy.envs.pooltool.sim import (
    FOOT_SPOT,
    HEAD_SPOT,
    MAX_EVENTS,
    _engine,
    _free_spot,
    _on_table,
    _place,
    _pt,
    aim_at,
    build_system,
    warm_up,
)
from deepphy.envs.pooltool.space import MAX_SHOTS, NUM_RACKS, PoolShot, PoolSpace

# -- the environment ------------------------------------------------------------------


class PooltoolOptions(EnvOptions):
    rules: Literal["nineball", "reference"] = "reference"  # see the module's docstring

    PAPER: ClassVar[dict[str, Any]] = {"rules": "reference"}  # the reference implementation's set-up


class PooltoolEnv(Environment):
    spec = SPEC
    Options = PooltoolOptions

    def __init__(self, options=None) -> None:
        super().__init__(options)
        self._system: Any = None
        self._game: Any = None
        self._task: Task | None = None
        self._shots = 0
        self._note = ""

    @classmethod
    def warm_up(cls, options, tasks) -> None:
        warm_up()

    @classmethod
    def tasks(cls, options) -> list[Task]:
        return [Task(env=SPEC.name, id=f"rack_{k:03d}",
                     params={"rack": k, "rules": options.rules, "state_text": options.state_text})
                for k in range(NUM_RACKS)]

    @staticmethod
    def rack_index(task: Task) -> int:
        if "rack" in task.params:
            return int(task.params["rack"])
        m = re.fullmatch(r"(?:rack_)?(\d+)", task.id)
        if not m:
            raise ValueError(f"not a pooltool task id: {task.id!r}")
        return int(m.group(1))

    # -- the contract ---------------------------------------------------------------

    def reset(self, task: Task) -> Observation:
        pt = _pt()
        self._task = task
        self._shots = 0
        if self.reference:
            self._system = build_system("reference", cue=HEAD_SPOT)
            self._game = None
            self._note = "First shot: the cue ball starts on the head spot."
        else:
            self._system = build_system(self.rack_index(task))
            self._game = pt.get_ruleset(pt.GameType.NINEBALL)(players=[pt.Player("agent")])
            self._note = "Break shot: the cue ball starts behind the head string."
        return self._observation()

    @property
    def reference(self) -> bool:
        return self.options.rules == "reference"  # type: ignore[attr-defined]

    def step(self, action: Action) -> StepResult:
        return self._shoot(action, film=False)[0]

    def film(self, action: Action) -> tuple[StepResult, list[Frame]]:
        return self._shoot(action, film=True)

    def _shoot(self, action: Action, film: bool) -> tuple[StepResult, list[Frame]]:
        assert isinstance(action, PoolShot) and self._system is not None
        pt = _pt()
        warm_up()
        system, game = self._system, self._game
        target = _on_table(system)[0]
        a, b = action.offsets
        system.reset_history()
        system.strike(V0=action.velocity, phi=aim_at(system, target), theta=0.0, a=a, b=b)
        pt.simulate(system, engine=_engine(), inplace=True, max_events=MAX_EVENTS)
        pictures = _film(system) if film else []
        self._shots += 1
        events = system.events
        potted = [e.agents[0].id for e in pt.events.filter_type(events, pt.EventType.BALL_POCKET)]
        first_hit = _first_hit(system)
        moved = {bid for bid, ball in system.balls.items() if _moved(ball)}
        traces = _traces(system, moved)
        truncated = len(events) >= MAX_EVENTS

        notes: list[str] = []
        if self.reference:  # no fouls: any pot of the 9 wins; a potted cue ball is respotted
            legal, reason = None, None
            success = "9" in potted
            if "cue" in potted and not success:
                notes.append(self._respot_cue("the cue ball is placed"))
        else:
            game.process_and_advance(system)
            info_obj = game.shot_info
            legal, game_over, reason = bool(info_obj.legal), bool(info_obj.game_over), info_obj.reason
            success = game_over and "9" in potted and legal
            if not legal and not game_over:
                if "9" in potted:
                    if system.balls["9"].state.s == 4:  # pooltool respots it only when it was the last ball
                        _place(system, "9", _free_spot(system, self._at(FOOT_SPOT), "9"))
                    notes.append("the 9-ball was potted on a foul, so it is respotted on the foot spot")
                notes.append(self._respot_cue("ball in hand: the cue ball is placed"))

        outcome = self._describe_shot(action, target, first_hit, potted, legal, reason, notes, truncated)
        frame = render_table(system, traces=traces)
        key = Image.from_array(
            f"shot_{self._shots}",
            f"the table after shot {self._shots}, with the paths the balls took (cue ball in white)",
            frame,
        )
        done = success or self._shots >= MAX_SHOTS
        info = {
            "shots": self._shots,
            "target": target,
            "first_hit": first_hit,
            "potted": potted,
            "legal": legal,
            "foul": None if legal in (True, None) else reason,
            "balls_left": _on_table(system),
            "events": len(events),
        }
        if not done:
            self._note = " ".join(n[0].upper() + n[1:] + "." for n in notes)
        if done and not success:
            legally = "" if self.reference else " legally"
            outcome += f" The game is over: the 9-ball was not potted{legally} within {MAX_SHOTS} shots."
        return StepResult(
            terminated=success,
            truncated=done and not success,  # the shots ran out
            success=success,
            observation=None if done else self._observation(),
            feedback=outcome,
            key_frames=[key],
            info=info,
        ), pictures

    def _at(self, spot: tuple[float, float]) -> tuple[float, float]:
        return spot[0] * self._system.table.w, spot[1] * self._system.table.l

    def _respot_cue(self, words: str) -> str:
        spot = self._at(HEAD_SPOT)
        where = _free_spot(self._system, spot, "cue")
        _place(self._system, "cue", where)
        return f"{words} on the head spot" if where == spot else f"{words} next to the head spot (it was occupied)"

    # -- text -----------------------------------------------------------------------

    def _describe_shot(self, action, target, first_hit, potted, legal, reason, notes, truncated) -> str:
        parts = [f"Shot {self._shots} ({action.speed}, {action.spot}) aimed at the {target}-ball"]
        parts.append(f"first hit: {'the ' + first_hit + '-ball' if first_hit else 'nothing'}")
        numbered = [p for p in potted if p != "cue"]
        parts.append("potted: " + (", ".join(numbered) if numbered else "none"))
        if "cue" in potted:
            parts.append("the cue ball was potted (scratch)")
        if legal is None:  # reference rules: no fouls
            if "9" in numbered:
                parts.append("the 9-ball is down: game won")
        elif legal:
            parts.append("legal shot")
            if "9" in numbered:
                parts.append("the 9-ball is down: game won")
        else:
            parts.append(f"FOUL: {reason.rstrip('!.')}")
        parts += notes
        if truncated:
            parts.append(f"(simulation stopped after {MAX_EVENTS} events)")
        return "; ".join(parts) + "."

    def _observation(self) -> Observation:
        system = self._system
        balls = _on_table(system)
        target = balls[0]
        if not self.options.state_text:  # the paper's: the table, nothing drawn on it, no text
            return Observation(images=[Image.from_array("table", "The table seen from directly above.",
                                                        render_table(system))], action_space=PoolSpace())
        img = render_table(system, target=target)
        cue = system.balls["cue"].state.rvw[0]
        lines = [
            f"Shot {self._shots + 1} of at most {MAX_SHOTS}.",
        ]
        if self._note:
            lines.append(self._note)
        lines.append(f"Balls on the table: {', '.join(balls)}. Target (lowest-numbered) ball: {target}.")
        lines.append(
            "Positions in metres, measured in the image: X from the left end of the playing "
            "surface to the right (0 to {:.2f}), Y from the top edge down (0 to {:.2f}):".format(
                system.table.l, system.table.w
            )
        )
        lines.append(f"  cue ball: X={cue[1]:.2f}, Y={cue[0]:.2f}")
        for bid in balls:
            p = system.balls[bid].state.rvw[0]
            lines.append(f"  {bid}-ball: X={p[1]:.2f}, Y={p[0]:.2f}")
        return Observation(
            images=[
                Image.from_array(
                    "table",
                    "Top-down view of the table. The dashed line shows where the cue will send the "
                    f"cue ball (at the {target}-ball, circled in magenta).",
                    img,
                )
            ],
            text="\n".join(lines),
            action_space=PoolSpace(),
        )


def _film(system) -> list[Frame]:
    """The shot just simulated, FILM_FPS pictures per second: pooltool's own interpolation
    of the ball states between events (`continuize`), on a copy of the table."""
    copy = _pt().continuize(system, dt=1 / FILM_FPS)
    balls = list(copy.balls.values())
    pictures = []
    for k, state in enumerate(balls[0].history_cts.states):
        for ball in balls:
            ball.state = ball.history_cts.states[k]
        pictures.append(Frame(render_table(copy), f"t = {state.t:.2f} s"))
    return pictures


def _first_hit(system) -> str | None:
    from pooltool.ruleset.utils import get_id_of_first_ball_hit  # loaded by sim._pt(), numba's cache configured

    return get_id_of_first_ball_hit(system, cue="cue")


def _moved(ball) -> bool:
    hist = ball.history
    if len(hist.states) < 2:
        return False
    return not np.allclose(hist.states[0].rvw[0], hist.states[-1].rvw[0]) or hist.states[-1].s == 4
