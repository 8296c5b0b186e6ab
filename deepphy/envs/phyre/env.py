"""The PHYRE environment: place one red ball so that PHYRE's goal holds for 3 seconds.

Tasks are the real PHYRE-B tasks (`data.py`: 25 templates x 100 tasks, PHYRE's geometry),
simulated on Box2D with PHYRE's rules (`sim.py`). The task list follows PHYRE's evaluation
setups and folds (`splits.py`): options `setup` (within | cross | both), `fold` (0-9) and
`split` (train | dev | test). Default: the fold-0 test tasks of both setups, 500 + 500; the
100 within-template test tasks of the five held-out templates are in both and appear once
per setup.

Task ids carry the setup and PHYRE's id, written filesystem-safe: `within_00022-004` is
PHYRE task `00022:004` in `ball_within_template`, `cross_00003-012` is `00003:012` in
`ball_cross_template`; the group is the setup (`within` / `cross`).

Actions (option `actions`): `grid5` (the paper's 5 x 5 cells x 5 radii, `Cell: N,
Radius: R`), `grid8` (the reference code's 8 x 8 cells x 8 radii) or `continuous`
(PHYRE's own action, `X: 0.31, Y: 0.72, R: 0.4`; meant for AUCCESS over up to 100
attempts, e.g. `--max-attempts 100`). A ball that overlaps a body or leaves the scene is
an invalid attempt (done, not solved, `invalid_reason` set), as in PHYRE, where such
attempts do not count for AUCCESS.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from deepphy.envs.base import (
    FILM_FPS, Action, EnvOptions, Environment, Frame, Observation, ObservationCache, StepResult, Task,
)
from deepphy.envs.images import Image, draw_label, stack_frames
from deepphy.envs.phyre import SPEC, data, sim
from deepphy.envs.phyre.render import render
from deepphy.envs.phyre.space import SCENE, InvalidPlacement, PhyreContinuousSpace, PhyreSpace
from deepphy.envs.phyre.splits import FOLDS, SETUPS, get_fold

ActionSpaces = Literal["grid5", "grid8", "continuous"]
SPACES: dict[str, PhyreSpace | PhyreContinuousSpace] = {
    "grid5": PhyreSpace(grid=5, radius_levels=5, r_min=2.0, r_max=32.0),  # the paper's
    "grid8": PhyreSpace(grid=8, radius_levels=8, r_min=3.875, r_max=32.0),  # the reference code's: r 0.0625..1
    "continuous": PhyreContinuousSpace(),
}
FRAME_EVERY = 10  # steps between recorded poses (key frames are picked from these)
FILM_EVERY = sim.FPS // FILM_FPS  # steps between the pictures of a replay (5: divides FRAME_EVERY)
KEY_FRAMES = 4
OVERLAY = (255, 140, 0)  # grid lines and labels drawn over the scene


class PhyreOptions(EnvOptions):
    setup: Literal["within", "cross", "both"] = "both"  # PHYRE's ball_within_template / ball_cross_template
    fold: int = Field(0, ge=0, lt=FOLDS)
    split: Literal["train", "dev", "test"] = "test"
    actions: ActionSpaces = "grid5"
    image_size: int = Field(512, ge=128, le=2048)  # rendered images are image_size x image_size

    PAPER: ClassVar[dict[str, Any]] = {"actions": "grid5"}  # the paper's 5 x 5 cells, 5 radius levels


def task_id(setup: str, phyre_id: str) -> str:
    """`within_00022-004` for PHYRE's `00022:004` in the within-template setup."""
    return f"{setup}_{phyre_id.replace(':', '-')}"


def phyre_id(task: Task) -> str:
    """PHYRE's id (`00022:004`) of one of our tasks."""
    if "phyre_id" in task.params:
        return str(task.params["phyre_id"])
    setup, sep, rest = task.id.partition("_")
    if not sep or setup not in SETUPS:
        raise ValueError(f"not a PHYRE task id: {task.id!r} (expected e.g. within_00022-004)")
    return rest.replace("-", ":")


INITIAL = ObservationCache()  # every attempt of a task starts from the same scene: render and encode it once


class PhyreEnv(Environment):
    spec = SPEC
    Options = PhyreOptions

    def __init__(self, options: PhyreOptions | None = None) -> None:
        super().__init__(options)
        self._task: data.PhyreTask | None = None

    @classmethod
    def tasks(cls, options: PhyreOptions) -> list[Task]:
        all_ids = data.task_ids()
        setups = list(SETUPS) if options.setup == "both" else [options.setup]
        out = []
        for setup in setups:
            for pid in get_fold(setup, options.fold, all_ids)[options.split]:
                out.append(Task(env=SPEC.name, id=task_id(setup, pid), group=setup,
                                params={"phyre_id": pid, "template": pid.split(":")[0], "setup": SETUPS[setup],
                                        "state_text": options.state_text}))
        return out

    @property
    def space(self) -> PhyreSpace | PhyreContinuousSpace:
        return SPACES[self.options.actions]

    # -- the contract ---------------------------------------------------------------------

    def reset(self, task: Task) -> Observation:
        try:
            self._task = data.load_task(phyre_id(task))
        except KeyError:
            raise ValueError(f"unknown PHYRE task {task.id!r}") from None
        key = (task.id, self.options.model_dump_json())
        known = INITIAL.get(key)
        if known is not None:
            return known
        scene = render(self._task, size=self.options.image_size)
        return INITIAL.put(key, Observation(
            images=[Image.from_array("scene", "The initial scene.", scene), self._overlay(scene)],
            text=describe_goal(self._task, self.options.state_text),
            action_space=self.space,
        ))

    def step(self, action: Action) -> StepResult:
        return self._simulate(action, FRAME_EVERY)[0]

    def film(self, action: Action) -> tuple[StepResult, list[Frame]]:
        result, ball, outcome = self._simulate(action, FILM_EVERY)
        if outcome is None:  # an invalid placement: nothing was simulated
            return result, []
        size = self.options.image_size
        return result, [Frame(render(self._task, ball, poses, size=size), f"t = {step / sim.FPS:.2f} s")
                        for step, poses in outcome.frames]

    def _simulate(self, action: Action, frame_every: int) -> tuple[StepResult, Any, sim.Outcome | None]:
        """The step, with poses recorded every `frame_every` steps (a divisor of FRAME_EVERY,
        so that the key frames are the same whatever the replay needs)."""
        assert self._task is not None, "reset() first"
        assert FRAME_EVERY % frame_every == 0
        task = self._task
        triple = self.space.to_phyre(action)
        info: dict[str, Any] = {"phyre_action": list(triple)}
        try:
            ball = sim.place(task, *triple)
        except InvalidPlacement as e:
            # The paper's history says "out of bounds or overlapping"; where is for state_text (and info)
            reason = str(e) if self.options.state_text else INVALID_PLACEMENT
            return StepResult(terminated=True, success=False, invalid_reason=reason,
                              feedback=f"invalid placement: {reason}; nothing was simulated",
                              info={**info, "placement": str(e)}), None, None
        outcome = sim.simulate(task, ball, frame_every=frame_every)
        return StepResult(
            terminated=outcome.end != "time_out",
            truncated=outcome.end == "time_out",  # 1000 steps ran out without a decision
            success=outcome.solved,
            feedback=describe_outcome(task, outcome) if self.options.state_text else "",
            key_frames=[self._strip(task, ball, outcome)],
            info={**info, "ball_px": list(ball), "steps": outcome.steps, "simulated_steps": outcome.simulated,
                  "end": outcome.end, "touched": outcome.touched},
        ), ball, outcome

    # -- images ---------------------------------------------------------------------------

    def _overlay(self, scene: np.ndarray) -> Image:
        img = scene.copy()
        space = self.space
        if isinstance(space, PhyreSpace):
            draw_grid(img, space.grid)
            n = space.grid
            return Image.from_array("grid", f"The same scene with the numbered {n}x{n} grid of cells where the "
                                    "red ball's centre can go.", img)
        draw_axes(img)
        return Image.from_array("axes", "The same scene with coordinate lines: X from 0 (left) to 1 (right), "
                                "Y from 0 (bottom) to 1 (top).", img)

    def _strip(self, task: data.PhyreTask, ball, outcome: sim.Outcome) -> Image:
        """Frames at 1/4, 1/2, 3/4 and the end of the simulated time, left to right.

        Past the last computed step the scene is at rest (or the goal completed), so the
        last recorded poses are the true poses of any later step."""
        # Up to the step the goal completed, or the world came to rest (the last computed step): a
        # resting world would repeat one picture (PHYRE's own steps run on to 1000 after it).
        end = outcome.steps if outcome.end == "solved" else outcome.simulated
        targets = [round(end * k / KEY_FRAMES) for k in range(1, KEY_FRAMES + 1)]
        frames = [f for f in outcome.frames if f[0] % FRAME_EVERY == 0 or f is outcome.frames[-1]]
        chosen = [max((f for f in frames if f[0] <= target), key=lambda f: f[0]) for target in targets]
        chosen = list({step: (step, poses) for step, poses in chosen}.values())  # distinct moments only
        images, captions = [], []
        for step, poses in chosen:
            images.append(render(task, ball, poses, size=256))
            captions.append(f"t={step / sim.FPS:.1f}s")
        strip = stack_frames(images, captions, height=256)
        return Image.from_array("outcome", "frames of what happened (left to right)", strip)


def draw_grid(img: np.ndarray, n: int) -> np.ndarray:
    """Number the n x n cells 1..n^2 row by row from the top-left; mark each cell's centre."""
    import cv2  # OpenCV: only where the grid or axes are drawn

    size = img.shape[0]
    cell = size / n
    for i in range(1, n):
        p = int(round(i * cell))
        cv2.line(img, (p, 0), (p, size - 1), OVERLAY, 1, cv2.LINE_AA)
        cv2.line(img, (0, p), (size - 1, p), OVERLAY, 1, cv2.LINE_AA)
    scale = 0.45 * size / 512 * (5 / n) ** 0.5
    for k in range(n * n):
        row, col = divmod(k, n)
        cx, cy = (col + 0.5) * cell, (row + 0.5) * cell
        cv2.drawMarker(img, (int(cx), int(cy)), OVERLAY, cv2.MARKER_CROSS, max(5, int(cell / 10)), 1)
        draw_label(img, str(k + 1), (col * cell + cell * 0.18, row * cell + cell * 0.14), scale=scale,
                   background=(255, 255, 190))
    return img


def draw_axes(img: np.ndarray, ticks: int = 10) -> np.ndarray:
    """Lines at X, Y = 0.1 .. 0.9 (PHYRE's action units: px = value * 255, y up), labelled."""
    import cv2  # OpenCV: only where the grid or axes are drawn

    size = img.shape[0]
    px = size / SCENE
    scale = 0.4 * size / 512
    for k in range(1, ticks):
        v = k / ticks
        x = int(round(v * (SCENE - 1) * px))
        y = int(round((SCENE - v * (SCENE - 1)) * px))
        cv2.line(img, (x, 0), (x, size - 1), OVERLAY, 1, cv2.LINE_AA)
        cv2.line(img, (0, y), (size - 1, y), OVERLAY, 1, cv2.LINE_AA)
        draw_label(img, f"{v:.1f}", (x, size - 10), scale=scale, background=(255, 255, 190))
        draw_label(img, f"{v:.1f}", (16, y), scale=scale, background=(255, 255, 190))
    return img


INVALID_PLACEMENT = "the ball overlaps an object or is not wholly inside the scene"


def describe_goal(task: data.PhyreTask, state_text: bool = False) -> str:
    """The task's goal in words: which two objects must touch (`state_text`: PHYRE's own
    sentence with the time it must hold and the task's id, a hint at its template)."""
    if state_text:
        seconds = sim.SOLVED_STEPS / sim.FPS
        return f"Goal: {task.description.rstrip('.')} for at least {seconds:g} seconds in a row (PHYRE task {task.id})."
    subject, target = (_name(b) for b in _goal_pair(task))
    return f"Goal: the {subject} must end up touching the {target}."


def _goal_pair(task: data.PhyreTask) -> list[data.Body]:
    pair = [task.bodies[task.body1], task.bodies[task.body2]]
    pair.sort(key=lambda b: b.color != "green")  # the green object is the subject of the sentence
    return pair


def describe_outcome(task: data.PhyreTask, outcome: sim.Outcome) -> str:
    """What happened, with its times (`state_text`; by default the history says only "failed",
    as the paper's does, and the key frames show what happened)."""
    subject, target = (_name(b) for b in _goal_pair(task))
    held, total = sim.SOLVED_STEPS / sim.FPS, sim.MAX_STEPS / sim.FPS
    if outcome.solved:
        return f"solved: the {subject} kept touching the {target} for {held:g} s (at t = {outcome.steps / sim.FPS:.1f} s)"
    how = {
        "at_rest": f"everything came to rest at t = {outcome.simulated / sim.FPS:.1f} s",
        "time_out": f"the goal was not held for {held:g} s within {total:.1f} s",
    }[outcome.end]
    touched = "touched" if outcome.touched else "never touched"
    return f"not solved: {how}; the {subject} {touched} the {target}"


def _name(body: data.Body) -> str:
    return f"{body.color} {body.kind}"
