"""The PHYRE environment: place one red ball so that the green object reaches its goal.

Tasks are PHYRE-B: 25 templates (00..24) x 100 variants each (see `templates/`). The
evaluation set follows PHYRE's folds, selected by `fold` (a seed):
- within-template: every template's 100 variants are shuffled; the last 20 are test
  tasks (80/20) -> 25 x 20 = 500 tasks, group "within";
- cross-template: the 25 templates are shuffled; the last 5 are test templates (80/20),
  all their variants are test tasks -> 5 x 100 = 500 tasks, group "cross".
Task ids are `<group>_t<template>_v<variant>`, e.g. `within_t07_v42`; a variant that is in
both sets appears twice, once per group.

Action: `Cell: N, Radius: R` (see `space.py` for the grid numbering). A placement that
overlaps an object or sticks out of the scene is an invalid attempt (done, not solved,
`invalid_reason` set), as in PHYRE where such attempts do not count for AUCCESS.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from deepphy.envs.base import Action, EnvOptions, Environment, Observation, StepResult, Task
from deepphy.envs.images import Image, draw_label, stack_frames
from deepphy.envs.phyre import SPEC
from deepphy.envs.phyre import scene as S
from deepphy.envs.phyre.space import PhyreAction, PhyreSpace
from deepphy.envs.phyre.templates import NUM_TEMPLATES, VARIANTS, templates, variant_scene
from deepphy.seeding import seeded_rng

TEST_FRACTION = 0.2


class PhyreOptions(EnvOptions):
    fold: int = 0  # seed of the within- and cross-template splits
    grid: int = 5  # the grid is grid x grid cells
    radius_levels: int = 5
    r_min: float = 2.0  # px, smallest radius level (1/128 of the 256 px scene)
    r_max: float = 32.0  # px, largest radius level (1/8 of the scene)
    image_size: int = 512  # rendered images are image_size x image_size
    splits: str = "within,cross"  # which test sets make up the task list


def within_test_variants(fold: int, template: int) -> list[int]:
    order = seeded_rng("phyre-within", fold, template).permutation(VARIANTS)
    return sorted(int(v) for v in order[int(VARIANTS * (1 - TEST_FRACTION)) :])


def cross_test_templates(fold: int) -> list[int]:
    order = seeded_rng("phyre-cross", fold).permutation(NUM_TEMPLATES)
    return sorted(int(t) for t in order[int(NUM_TEMPLATES * (1 - TEST_FRACTION)) :])


def task_id(group: str, template: int, variant: int) -> str:
    return f"{group}_t{template:02d}_v{variant:02d}"


def parse_task_id(task_id_: str) -> tuple[str, int, int]:
    group, t, v = task_id_.split("_")
    return group, int(t[1:]), int(v[1:])


class PhyreEnv(Environment):
    spec = SPEC
    Options = PhyreOptions

    def __init__(self, options: PhyreOptions | None = None) -> None:
        super().__init__(options)
        self._task: Task | None = None
        self._scene: S.Scene | None = None
        # Every attempt starts from the same scene: render and encode it once per task.
        self._initial: dict[str, Observation] = {}

    @classmethod
    def tasks(cls, options: PhyreOptions) -> list[Task]:
        available = templates()
        out: list[Task] = []
        splits = [s.strip() for s in options.splits.split(",") if s.strip()]
        for split in splits:
            if split == "within":
                pairs = [(t, v) for t in range(NUM_TEMPLATES) for v in within_test_variants(options.fold, t)]
            elif split == "cross":
                pairs = [(t, v) for t in cross_test_templates(options.fold) for v in range(VARIANTS)]
            elif split == "all":
                pairs = [(t, v) for t in range(NUM_TEMPLATES) for v in range(VARIANTS)]
            else:
                raise ValueError(f"unknown PHYRE split {split!r} (within, cross, all)")
            for t, v in pairs:
                if t in available:
                    out.append(Task(env=SPEC.name, id=task_id(split, t, v), group=split,
                                    params={"template": t, "variant": v}))
        return out

    # -- the contract ---------------------------------------------------------------

    @property
    def space(self) -> PhyreSpace:
        o = self.options
        return PhyreSpace(grid=o.grid, radius_levels=o.radius_levels, r_min=o.r_min, r_max=o.r_max)

    def reset(self, task: Task) -> Observation:
        self._task = task
        self._scene = scene_of(task)
        if task.id in self._initial:
            return self._initial[task.id]
        img = self.render_scene(self._scene)
        grid = self.draw_grid(img.copy())
        self._initial[task.id] = Observation(
            images=[
                Image.from_array("scene", "The initial scene.", img),
                Image.from_array("grid", f"The same scene with the numbered {self.options.grid}x{self.options.grid} "
                                 "grid of cells where the red ball's centre can go.", grid),
            ],
            text=describe_goal(self._scene),
            action_space=self.space,
        )
        return self._initial[task.id]

    def step(self, action: Action) -> StepResult:
        assert isinstance(action, PhyreAction) and self._scene is not None
        x, y, r = self.space.to_scene(action)
        problem = S.placement_problem(self._scene, x, y, r)
        info: dict[str, Any] = {"x": x, "y": y, "r": r}
        if problem is not None:
            return StepResult(terminated=True, success=False, invalid_reason=problem,
                              feedback=f"invalid placement: {problem}; nothing was simulated", info=info)
        extra = S.ball(x, y, r, "red")
        world = S.World(self._scene, extra)
        outcome = world.run(snapshot_every=15)
        t_end = outcome.steps / S.FPS
        if outcome.success:
            feedback = f"solved: the goal holds for 3 s (decided at t = {t_end:.1f} s)"
        else:
            feedback = {
                "at_rest": f"not solved: everything came to rest at t = {t_end:.1f} s without the goal holding",
                "time_out": f"not solved within {S.MAX_STEPS / S.FPS:.1f} s",
                "exploded": "not solved (the simulation became unstable)",
            }.get(outcome.reason, "not solved")
            feedback += "; the green object " + ("did touch" if outcome.touched_ever else "never touched") + \
                (" the goal" if self._scene.relation == "touching" else " the blue ball")
        frames = _pick(outcome.snapshots, 4)
        objects = world.objects
        walls = [g for g in self._scene.goal if isinstance(g, str)]
        imgs = [S.render(objects, st, walls, size=256) for _, st in frames]
        strip = stack_frames(imgs, [f"t={s / S.FPS:.1f}s" for s, _ in frames], height=256)
        return StepResult(
            terminated=outcome.reason != "time_out",
            truncated=outcome.reason == "time_out",
            success=outcome.success,
            feedback=feedback,
            key_frames=[Image.from_array("outcome", "frames of what happened (left to right)", strip)],
            info={**info, "steps": outcome.steps, "end": outcome.reason, "touched": outcome.touched_ever},
        )

    # -- rendering ------------------------------------------------------------------

    def render_scene(self, scene: S.Scene) -> np.ndarray:
        walls = [g for g in scene.goal if isinstance(g, str)]
        return S.render(scene.objects, None, walls, size=self.options.image_size)

    def draw_grid(self, img: np.ndarray) -> np.ndarray:
        import cv2

        n = self.options.grid
        size = img.shape[0]
        cell = size / n
        for i in range(1, n):
            p = int(round(i * cell))
            cv2.line(img, (p, 0), (p, size - 1), (255, 140, 0), 1, cv2.LINE_AA)
            cv2.line(img, (0, p), (size - 1, p), (255, 140, 0), 1, cv2.LINE_AA)
        scale = 0.45 * size / 512 * (5 / n) ** 0.5
        for k in range(n * n):
            row, col = divmod(k, n)
            cx, cy = (col + 0.5) * cell, (row + 0.5) * cell
            cv2.drawMarker(img, (int(cx), int(cy)), (255, 140, 0), cv2.MARKER_CROSS, max(5, int(cell / 10)), 1)
            draw_label(img, str(k + 1), (col * cell + cell * 0.18, row * cell + cell * 0.14), scale=scale,
                       background=(255, 255, 190))
        return img


def scene_of(task: Task) -> S.Scene:
    t = int(task.params.get("template", parse_task_id(task.id)[1]))
    v = int(task.params.get("variant", parse_task_id(task.id)[2]))
    return variant_scene(t, v)


def describe_goal(scene: S.Scene) -> str:
    names = []
    for g in scene.goal:
        if isinstance(g, str):
            names.append(f"the {g} wall (purple edge)")
        else:
            o = scene.objects[g]
            names.append(f"the {o.color} {o.kind}")
    subject = scene.objects[scene.subject]
    targets = " or ".join(names)
    if scene.relation == "touching":
        goal = f"Goal: make the green {subject.kind} touch {targets} and keep touching for 3 seconds."
    else:
        goal = f"Goal: make sure the green {subject.kind} does NOT touch {targets} (apart for 3 seconds or more)."
    return goal + (f"\nTask: {scene.description}" if scene.description else "")


def _pick(snapshots: list, n: int) -> list:
    if len(snapshots) <= n:
        return snapshots
    idx = np.linspace(0, len(snapshots) - 1, n).round().astype(int)
    return [snapshots[i] for i in idx]
