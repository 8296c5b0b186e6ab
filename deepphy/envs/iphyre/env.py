"""I-PHYRE on the real `iphyre` package: remove gray blocks at chosen times so every red
ball falls out of the bottom of the scene.

The simulation is iphyre's own: we build `iphyre.simulator.IPHYRE`, reset it and advance
it with the same loop as its `simulate()` (one click fires per 1/60 s step, in time
order, a click is the centre of an eliminable block), pausing only to take key frames.
Rendering is ours, with OpenCV from the live pymunk state, so no display is needed.

Decisions (documented in docs/environments.md):
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
import os
from typing import Any

import cv2
import numpy as np

from deepphy.envs.base import (
    FILM_FPS, Action, Environment, Frame, Observation, ObservationCache, StepResult, Task,
)
from deepphy.envs.images import Image, draw_label, stack_frames
from deepphy.envs.iphyre import SPEC
from deepphy.envs.iphyre.space import MAX_TIME, IPhyrePlan, IPhyreSpace

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")  # iphyre imports pygame, which greets on stdout

GROUPS = ("basic", "noisy", "compositional", "multi_ball")  # iphyre's FOLD_LIST, 10 games each


# Colours (RGB) of the rendering; the prompt's legend names them.
WHITE, BLACK, GRAY, BLUE, RED = (255, 255, 255), (0, 0, 0), (150, 150, 150), (40, 90, 220), (220, 30, 30)
LINK = (0, 160, 0)  # joints and springs
BLOCK_RADIUS = 10  # iphyre's segment radius


INITIAL = ObservationCache()  # every attempt starts from the same scene: render and encode it once


class IPhyreEnv(Environment):
    spec = SPEC

    def __init__(self, options=None) -> None:
        super().__init__(options)
        self._sim: Any = None
        self._task: Task | None = None

    @classmethod
    def tasks(cls, options) -> list[Task]:
        from iphyre.games import GAMES  # the simulator's package: loaded when tasks are asked for

        return [Task(env=SPEC.name, id=g, group=GROUPS[i // 10], params={"state_text": options.state_text})
                for i, g in enumerate(GAMES)]

    # -- the contract ---------------------------------------------------------------

    def reset(self, task: Task) -> Observation:
        self._task = task
        self._centres = _block_centres(task.id)
        key = (task.id, self.options.state_text)
        known = INITIAL.get(key)
        if known is not None:
            return known  # step() builds its own fresh simulator
        self._sim = _fresh_sim(task.id)
        scene = self.render()
        annotated = self.render(labels=True)
        return INITIAL.put(key, Observation(
            images=[
                Image.from_array("scene", "The scene at the start.", scene),
                Image.from_array("annotated", "The same scene with each gray block's index.", annotated),
            ],
            text=self._describe(),
            action_space=IPhyreSpace(num_blocks=len(self._centres)),
        ))

    def step(self, action: Action) -> StepResult:
        return self._play(action, film=False)[0]

    def film(self, action: Action) -> tuple[StepResult, list[Frame]]:
        return self._play(action, film=True)

    def _play(self, action: Action, film: bool) -> tuple[StepResult, list[Frame]]:
        assert isinstance(action, IPhyrePlan) and self._task is not None, "reset() first"
        clicks = [(self._centres[c.index], c.time) for c in action.clicks]
        success, removed, end_time, frames, pictures = self._simulate(clicks, film)
        end_time = round(end_time, 4)
        # The paper's history says no more than "failed" (its key frames show what happened)
        feedback = ""
        if self.options.state_text:
            if success:
                feedback = f"all red balls left the scene at t = {end_time:.2f} s"
            else:
                feedback = f"not every red ball fell out of the scene within {MAX_TIME:g} s"
            feedback += f"; {removed} of {len(clicks)} removal(s) took effect"
        strip = stack_frames([f for _, f in frames], [f"t={t:.1f}s" for t, _ in frames])
        return StepResult(
            terminated=success,
            truncated=not success,  # the only way to fail: MAX_TIME ran out
            success=success,
            feedback=feedback,
            key_frames=[Image.from_array("outcome", "frames of what happened (left to right)", strip)],
            info={"end_time": end_time, "removed": removed},
        ), pictures

    # -- simulation -----------------------------------------------------------------

    def _simulate(self, clicks: list[tuple[tuple[float, float], float]], film: bool = False):
        """iphyre's `simulate()` loop, with t = 0 firing at the first step, and key frames
        (and, with `film`, a picture FILM_FPS times per simulated second).

        Returns (success, effective removals, end time, [(t, frame)], [Frame]).
        """
        # A fresh simulator per attempt: a reset pymunk space keeps internal state, and
        # outcomes must not depend on which attempts an instance ran before.
        sim = self._sim = _fresh_sim(self._task.id)
        clicks = sorted(clicks, key=lambda c: c[1])
        step = removed = 0
        time_count = 0.0
        snapshots = [MAX_TIME / 4, MAX_TIME / 2, 3 * MAX_TIME / 4]
        frames: list[tuple[float, np.ndarray]] = []
        pictures: list[Frame] = [Frame(self.render(), "t = 0.00 s")] if film else []
        film_every = round(1 / (sim.timestep * FILM_FPS))  # physics steps between pictures
        ticks = 0
        while time_count < sim.max_time:
            if step < len(clicks):
                pos, t = clicks[step]
                if time_count >= t:
                    if sim.eliminate(list(pos)) != -1:
                        removed += 1
                    step += 1
            sim.space.step(sim.timestep)
            time_count += sim.timestep
            ticks += 1
            if film and ticks % film_every == 0:
                pictures.append(Frame(self.render(), f"t = {time_count:.2f} s"))
            if snapshots and time_count >= snapshots[0]:
                frames.append((time_count, self.render()))
                snapshots.pop(0)
            if sim.examine_success():
                frames.append((time_count, self.render()))
                return True, removed, time_count, frames, pictures
        frames.append((time_count, self.render()))
        return False, removed, time_count, frames, pictures

    # -- rendering ------------------------------------------------------------------

    def render(self, labels: bool = False) -> np.ndarray:
        """The live scene as RGB, 600x600, y down as in iphyre."""
        import pymunk  # the simulator's physics: loaded when a scene is drawn

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
        n = len(self._centres)
        if not self.options.state_text:  # the paper's: how many, and the highest index
            return f"Gray blocks you may remove: {n} (indices 0 to {n - 1})."
        lines = [f"Gray blocks you may remove ({n}), by index and centre (x, y) in pixels:"]
        lines += [f"  {i}: ({x:.0f}, {y:.0f})" for i, (x, y) in enumerate(self._centres)]
        lines.append(f"The scene is {self._sim.WIDTH}x{self._sim.HEIGHT} px, y grows downward.")
        return "\n".join(lines)


def _fresh_sim(game: str):
    from iphyre.simulator import IPHYRE  # the simulator: loaded when a task is played

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
