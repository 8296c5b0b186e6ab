"""I-PHYRE on the real `iphyre` package: remove gray blocks at chosen times so every red
ball falls out of the bottom of the scene.

The simulation is iphyre's own: we build `iphyre.simulator.IPHYRE`, reset it and advance
it with the same loop as its `simulate()` (one click fires per 1/60 s step, in time
order, a click is the centre of an eliminable block), pausing only to take key frames.
Rendering is ours, with OpenCV from the live pymunk state, so no display is needed.

Decisions (documented in the README):
- A plan is a JSON array of {"time": seconds, "index": block}. The empty array is a
  valid plan (do nothing): `spring_flick` is solved that way.
- `time` must satisfy 0 <= time < 15. iphyre silently ignores a click at exactly t = 0
  and never fires one at t >= 15; we fire a click at t = 0 at the first step instead,
  because that is what "remove it at the start" means to a reader, and reject t >= 15.
  For every plan with times in (0, 15) the outcome equals iphyre's `simulate()`.
- Indices follow iphyre's action space order (`PARAS[game]["eli"]`), shown on the image.
- pymunk 6.x: iphyre mutates pymunk's live views, which pymunk 7 no longer allows.
"""

from __future__ import annotations

import functools
import json
import math
import os
from typing import Any, Literal, Sequence

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict

from deepphy.envs.base import (
    Action,
    ActionSpace,
    Environment,
    InvalidAction,
    Observation,
    Planning,
    StepResult,
    Task,
)
from deepphy.envs.images import Image, draw_label, stack_frames
from deepphy.envs.parsing import first_json_array

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")  # iphyre imports pygame, which greets on stdout

MAX_TIME = 15.0  # seconds simulated per attempt (iphyre's max_time)
FPS = 60
GROUPS = ("basic", "noisy", "compositional", "multi_ball")  # iphyre's FOLD_LIST, 10 games each
MAX_CLICKS = 12  # more clicks than blocks is never useful; bounds the plan a model may send


class Click(BaseModel):
    model_config = ConfigDict(frozen=True)

    time: float
    index: int


class IPhyrePlan(Action):
    clicks: tuple[Click, ...]


class IPhyreSpace(ActionSpace):
    """Plans over `num_blocks` eliminable blocks, each removal at a time in [0, 15)."""

    kind: Literal["iphyre_plan"] = "iphyre_plan"
    num_blocks: int

    def parse(self, text: str) -> IPhyrePlan:
        raw = first_json_array(text)
        if raw is None:
            raise InvalidAction('no JSON array of {"time", "index"} objects found')
        clicks = []
        for item in raw:
            if not isinstance(item, dict):
                raise InvalidAction(f"plan entries must be objects with time and index, got {item!r}")
            keys = {str(k).strip().lower(): v for k, v in item.items()}
            if set(keys) != {"time", "index"}:
                raise InvalidAction(f"each entry needs exactly the keys time and index, got {sorted(keys)}")
            t, i = keys["time"], keys["index"]
            if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
                raise InvalidAction(f"time must be a number of seconds, got {t!r}")
            if isinstance(i, bool) or not (isinstance(i, int) or (isinstance(i, float) and i.is_integer())):
                raise InvalidAction(f"index must be an integer, got {i!r}")
            if not 0.0 <= t < MAX_TIME:
                raise InvalidAction(f"time {t} is outside [0, {MAX_TIME:g})")
            if not 0 <= int(i) < self.num_blocks:
                raise InvalidAction(f"index {int(i)} is not a gray block (0..{self.num_blocks - 1})")
            clicks.append(Click(time=round(float(t), 4), index=int(i)))
        if len(clicks) > MAX_CLICKS:
            raise InvalidAction(f"at most {MAX_CLICKS} removals per plan, got {len(clicks)}")
        return IPhyrePlan(clicks=tuple(sorted(clicks, key=lambda c: (c.time, c.index))))

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> IPhyrePlan:
        # MOCK as in the I-PHYRE baselines: remove 1-3 distinct blocks at uniform times.
        n = int(rng.integers(1, min(3, self.num_blocks) + 1))
        blocks = rng.choice(self.num_blocks, size=n, replace=False)
        times = np.round(rng.uniform(0.0, MAX_TIME, size=n), 1)
        times = np.minimum(times, MAX_TIME - 0.1)
        clicks = [Click(time=float(t), index=int(b)) for t, b in zip(times, blocks)]
        return IPhyrePlan(clicks=tuple(sorted(clicks, key=lambda c: (c.time, c.index))))

    def format(self, action: Action) -> str:
        assert isinstance(action, IPhyrePlan)
        return json.dumps([{"time": c.time, "index": c.index} for c in action.clicks])


# Colours (RGB) of the rendering; the prompt's legend names them.
WHITE, BLACK, GRAY, BLUE, RED = (255, 255, 255), (0, 0, 0), (150, 150, 150), (40, 90, 220), (220, 30, 30)
LINK = (0, 160, 0)  # joints and springs
BLOCK_RADIUS = 10  # iphyre's segment radius


class IPhyreEnv(Environment):
    name = "iphyre"
    title = "I-PHYRE"
    planning = Planning.IN_ADVANCE
    max_attempts = 10
    max_steps = 1

    def __init__(self, options=None) -> None:
        super().__init__(options)
        self._sim: Any = None
        self._task: Task | None = None
        # Every attempt starts from the same scene: render and encode it once per task.
        self._initial: dict[str, Observation] = {}

    @classmethod
    def tasks(cls, options) -> list[Task]:
        from iphyre.games import GAMES

        return [Task(env=cls.name, id=g, group=GROUPS[i // 10]) for i, g in enumerate(GAMES)]

    # -- the contract ---------------------------------------------------------------

    def reset(self, task: Task) -> Observation:
        self._task = task
        self._centres = _block_centres(task.id)
        if task.id in self._initial:
            return self._initial[task.id]  # step() builds its own fresh simulator
        self._sim = _fresh_sim(task.id)
        scene = self.render()
        annotated = self.render(labels=True)
        self._initial[task.id] = Observation(
            images=[
                Image.from_array("scene", "The scene at t = 0 s.", scene),
                Image.from_array("annotated", "The same scene with each gray block's index.", annotated),
            ],
            text=self._describe(),
            action_space=IPhyreSpace(num_blocks=len(self._centres)),
        )
        return self._initial[task.id]

    def step(self, action: Action) -> StepResult:
        assert isinstance(action, IPhyrePlan) and self._sim is not None
        clicks = [(self._centres[c.index], c.time) for c in action.clicks]
        success, removed, end_time, frames = self._simulate(clicks)
        end_time = round(end_time, 4)
        if success:
            feedback = f"all red balls left the scene at t = {end_time:.2f} s"
        else:
            feedback = f"not every red ball fell out of the scene within {MAX_TIME:g} s"
        feedback += f"; {removed} of {len(clicks)} removal(s) took effect"
        strip = stack_frames([f for _, f in frames], [f"t={t:.1f}s" for t, _ in frames])
        return StepResult(
            done=True,
            success=success,
            feedback=feedback,
            key_frames=[Image.from_array("outcome", "frames of what happened (left to right)", strip)],
            info={"end_time": end_time, "removed": removed},
        )

    # -- simulation -----------------------------------------------------------------

    def _simulate(self, clicks: list[tuple[tuple[float, float], float]]):
        """iphyre's `simulate()` loop, with t = 0 firing at the first step, and key frames.

        Returns (success, effective removals, end time, [(t, frame)]).
        """
        # A fresh simulator per attempt: a reset pymunk space keeps internal state, and
        # outcomes must not depend on which attempts an instance ran before.
        sim = self._sim = _fresh_sim(self._task.id)
        clicks = sorted(clicks, key=lambda c: c[1])
        step = removed = 0
        time_count = 0.0
        snapshots = [MAX_TIME / 4, MAX_TIME / 2, 3 * MAX_TIME / 4]
        frames: list[tuple[float, np.ndarray]] = []
        while time_count < sim.max_time:
            if step < len(clicks):
                pos, t = clicks[step]
                if time_count >= t:
                    if sim.eliminate(list(pos)) != -1:
                        removed += 1
                    step += 1
            sim.space.step(sim.timestep)
            time_count += sim.timestep
            if snapshots and time_count >= snapshots[0]:
                frames.append((time_count, self.render()))
                snapshots.pop(0)
            if sim.examine_success():
                frames.append((time_count, self.render()))
                return True, removed, time_count, frames
        frames.append((time_count, self.render()))
        return False, removed, time_count, frames

    # -- rendering ------------------------------------------------------------------

    def render(self, labels: bool = False) -> np.ndarray:
        """The live scene as RGB, 600x600, y down as in iphyre."""
        import pymunk

        sim = self._sim
        img = np.full((sim.HEIGHT, sim.WIDTH, 3), 255, np.uint8)
        bodies = list(sim.space.bodies)
        for c in sim.space.constraints:
            a, b = c.a.position, c.b.position
            cv2.line(img, _pt(a), _pt(b), LINK, 3, cv2.LINE_AA)
        for i, body in enumerate(bodies):
            shape = next(iter(body.shapes))
            if isinstance(shape, pymunk.Circle):
                cv2.circle(img, _pt(body.position), int(round(shape.radius)), RED, -1, cv2.LINE_AA)
                continue
            a = body.local_to_world(shape.a)
            b = body.local_to_world(shape.b)
            colour = GRAY if sim.eli[i] else (BLUE if sim.dynamic[i] else BLACK)
            cv2.line(img, _pt(a), _pt(b), colour, 2 * BLOCK_RADIUS, cv2.LINE_AA)
        if labels:
            for index, centre in enumerate(self._centres):
                draw_label(img, str(index), centre, scale=0.6)
        return img

    def _describe(self) -> str:
        lines = [f"Gray blocks you may remove ({len(self._centres)}), by index and centre (x, y) in pixels:"]
        lines += [f"  {i}: ({x:.0f}, {y:.0f})" for i, (x, y) in enumerate(self._centres)]
        lines.append(f"The scene is {self._sim.WIDTH}x{self._sim.HEIGHT} px, y grows downward.")
        return "\n".join(lines)


def _fresh_sim(game: str):
    from iphyre.simulator import IPHYRE

    sim = IPHYRE(game)
    sim.reset()
    return sim


@functools.lru_cache(maxsize=None)
def _block_centres(game: str) -> tuple[tuple[float, float], ...]:
    """Centres of the eliminable blocks, in iphyre's action-space order (plan index k)."""
    sim = _fresh_sim(game)
    # get_action_space(): [[0, 0]] (no action), the block centres, then [0, 0] padding.
    return tuple(tuple(p) for p in sim.get_action_space()[1 : 1 + sum(sim.eli)])


def _pt(p) -> tuple[int, int]:
    return int(round(p[0])), int(round(p[1]))
