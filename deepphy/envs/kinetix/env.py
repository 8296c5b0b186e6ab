"""Kinetix on the real `kinetix-env` (JAX): the 74 handcrafted levels, sizes S/M/L.

The agent controls a level's motors and thrusters. One decision = one value per
controllable motor (0 off, 1 forward, 2 reverse) and per thruster (0 off, 1 on), held for
16 environment steps (each env step is two physics substeps of 1/60 s, so a decision
lasts ~0.53 s). Kinetix ends an episode after 256 env steps, so an attempt has at most 16
decisions. Success = a green shape touches a blue one (kinetix's info["GoalR"]); touching
red, or running out of time, fails.

Decisions (documented in docs/environments.md):
- Controls follow the level's actual bindings. Kinetix's MultiDiscrete action has 4 motor
  and 2 thruster slots ("bindings"); all joints/thrusters sharing a binding move together,
  unused slots do nothing, and some levels use binding 1 but not 0. Our control M<i> is
  the i-th motor binding the level actually uses (ascending), T<i> the i-th thruster
  binding; the action vector has exactly one entry per control, so there are no dead
  entries and no hidden coupling. Motors with kinetix's `motor_auto` are not controls.
- max_attempts = 1: the protocol budgets Kinetix in decisions per episode (16), not in
  attempts, and reports a success rate per size; one episode per task and run.
- Rendering is ours (see render.py): high contrast, motors and thrusters drawn as clearly
  different symbols. Option `annotate` (default on) adds a second image with labels M<i>
  and T<i>; off gives the ablation without annotations (the clean render only; the text
  still says how many motors and thrusters there are).
- The goal distance shown to the model is the shortest centre-to-centre distance between
  a green and a blue shape, in pixels of the 500x500 render.
"""

from __future__ import annotations

from typing import Any, Literal, Sequence

import numpy as np
from pydantic import field_validator

from deepphy.envs.base import FILM_FPS, Action, EnvOptions, Environment, Frame, Observation, StepResult, Task
from deepphy.envs.images import Image
from deepphy.envs.kinetix import SPEC
from deepphy.envs.kinetix.levels import (
    MAX_DECISIONS,
    MAX_TIMESTEPS,
    SECONDS_PER_DECISION,
    SIZES,
    STEPS_PER_DECISION,
    level_names,
    task_id,
)
from deepphy.envs.kinetix.render import Controls, annotate, controls, goal_distance_px, render
from deepphy.envs.kinetix.space import KinetixAction, KinetixSpace


class KinetixOptions(EnvOptions):
    annotate: bool = True  # show the labelled render (the with/without-annotation ablation)
    sizes: tuple[Literal["S", "M", "L"], ...] = SIZES  # which level sizes make up the task set

    @field_validator("sizes", mode="before")
    @classmethod
    def _sizes(cls, v: Any) -> Any:
        """Also accept "S,M" or "s" (as given on the command line: --env-option sizes=S,M)."""
        if isinstance(v, str):
            v = [p for p in v.replace(" ", "").split(",") if p]
        if isinstance(v, (list, tuple)):
            v = tuple(p.upper() if isinstance(p, str) else p for p in v)
        return v


class KinetixEnv(Environment):
    spec = SPEC
    Options = KinetixOptions

    def __init__(self, options: KinetixOptions | None = None) -> None:
        super().__init__(options)
        self._task: Task | None = None
        self._level: Any = None
        self._state: Any = None
        self._controls: Controls | None = None
        self._decision = 0
        self._distance: float | None = None

    @classmethod
    def tasks(cls, options: EnvOptions) -> list[Task]:
        assert isinstance(options, KinetixOptions)
        out = []
        for size in SIZES:
            if size in options.sizes:
                out += [
                    Task(env=SPEC.name, id=task_id(name), group=size,
                         params={"level": name, "state_text": options.state_text})
                    for name in level_names(size)
                ]
        return out

    @classmethod
    def warm_up(cls, options: EnvOptions, tasks: Sequence[Task]) -> None:
        """Compile the decision function of every level size these tasks use (seconds each;
        the persistent JAX cache makes later processes faster)."""
        from deepphy.envs.kinetix import sim  # JAX: loaded when a task is played, not when tasks are listed

        first_of_size: dict[str, Task] = {}
        for task in tasks:
            first_of_size.setdefault(task.group, task)
        for task in first_of_size.values():
            level = sim.load_level(task.params["level"])
            sim.get_sim(level).decide([level.state], np.zeros((1, 6), np.int32))

    # -- the contract ---------------------------------------------------------------

    def reset(self, task: Task) -> Observation:
        from deepphy.envs.kinetix import sim  # JAX: loaded when a task is played, not when tasks are listed

        self._task = task
        self._level = sim.load_level(task.params["level"])
        self._state = self._level.state
        self._controls = controls(self._state)
        self._decision = 0
        self._distance = goal_distance_px(self._state)
        return self._observation()

    def step(self, action: Action) -> StepResult:
        return self.step_many([self], [action])[0]

    @classmethod
    def step_many(cls, envs: Sequence[Environment], actions: Sequence[Action]) -> list[StepResult]:
        """Step several episodes: those of the same level size go through the size's one compiled
        batch function (`sim.BATCH` per call), so a result never depends on the company."""
        from deepphy.envs.kinetix import sim  # JAX: loaded when a task is played, not when tasks are listed

        results: list[StepResult | None] = [None] * len(envs)
        groups: dict[Any, list[int]] = {}
        for i, env in enumerate(envs):
            assert isinstance(env, KinetixEnv) and env._state is not None, "reset() first"
            groups.setdefault(id(sim.get_sim(env._level)), []).append(i)
        for idx in groups.values():
            s = sim.get_sim(envs[idx[0]]._level)  # type: ignore[attr-defined]
            vectors = np.stack([envs[i]._vector(actions[i]) for i in idx])  # type: ignore[attr-defined]
            outs = s.decide([envs[i]._state for i in idx], vectors)  # type: ignore[attr-defined]
            for i, out in zip(idx, outs):
                results[i] = envs[i]._after(actions[i], out)  # type: ignore[attr-defined]
        return results  # type: ignore[return-value]

    def film(self, action: Action) -> tuple[StepResult, list[Frame]]:
        """The step (the record's program), and pictures of its env steps from a program that
        also returns the states on the way (it may round differently in the last bits)."""
        from deepphy.envs.kinetix import sim  # JAX: loaded when a task is played, not when tasks are listed

        assert self._controls is not None and self._state is not None, "reset() first"
        before, t0 = self._state, self._decision * SECONDS_PER_DECISION
        firing = tuple(t for k, ts in enumerate(self._controls.thrusters) if action.thrusters[k] for t in ts)
        path = sim.get_sim(self._level).path(before, self._vector(action))
        result = self.step(action)
        dt = SECONDS_PER_DECISION / STEPS_PER_DECISION
        every = max(1, round(1 / (dt * FILM_FPS)))
        steps = result.info["env_steps"]  # the episode may end before the decision's last env step
        return result, [Frame(render(path[k - 1], firing), f"t = {t0 + k * dt:.2f} s")
                        for k in range(1, steps + 1) if k % every == 0 or k == steps]

    # -- internals ------------------------------------------------------------------

    @property
    def space(self) -> KinetixSpace:
        assert self._controls is not None
        return KinetixSpace(
            num_motors=len(self._controls.motor_bindings), num_thrusters=len(self._controls.thruster_bindings)
        )

    def _vector(self, action: Action) -> np.ndarray:
        """Our action -> kinetix's MultiDiscrete 6-vector (4 motor bindings, 2 thruster bindings)."""
        assert isinstance(action, KinetixAction) and self._controls is not None
        c = self._controls
        if len(action.motors) != len(c.motor_bindings) or len(action.thrusters) != len(c.thruster_bindings):
            raise ValueError(f"action {action} does not fit this level's controls")
        vec = np.zeros(6, np.int32)
        for b, v in zip(c.motor_bindings, action.motors):
            vec[b] = v
        for b, v in zip(c.thruster_bindings, action.thrusters):
            vec[4 + b] = v
        return vec

    def _after(self, action: KinetixAction, out: Any) -> StepResult:
        assert self._controls is not None
        self._state = out.state
        self._decision += 1
        before = self._distance
        self._distance = goal_distance_px(out.state)
        firing = tuple(
            t for k, ts in enumerate(self._controls.thrusters) if action.thrusters[k] for t in ts
        )
        images = self._images(firing)  # rendered and encoded once: observation and key frame
        outcome = "running"
        if out.done and out.goal:
            outcome = "goal"
        elif out.done and out.reward < -0.5:
            outcome = "red"
        elif out.done or self._decision >= MAX_DECISIONS:
            outcome = "timeout" if out.timestep >= MAX_TIMESTEPS or self._decision >= MAX_DECISIONS else "unstable"
        done = outcome != "running"
        truncated = outcome == "timeout"
        dist = "n/a" if self._distance is None else f"{self._distance:.0f} px"
        was = "" if before is None else f" (was {before:.0f} px)"
        feedback = {
            "goal": "the green shape touched the blue goal: success",
            "red": f"a green shape touched a red shape: failed; goal distance {dist}",
            "timeout": f"time ran out after {MAX_DECISIONS} decisions: failed; goal distance {dist}{was}",
            "unstable": f"the simulation became unstable and ended: failed; goal distance {dist}",
            "running": f"goal distance {dist}{was}",
        }[outcome]
        return StepResult(
            terminated=done and not truncated,
            truncated=truncated,
            success=outcome == "goal",
            observation=None if done else self._observation(images),
            feedback=feedback,
            key_frames=[Image(name="after", caption=f"the scene after decision {self._decision}", png=images[-1].png)],
            info={
                "decision": self._decision,
                "outcome": outcome,
                "env_steps": out.steps,
                "timestep": out.timestep,
                "goal_distance_px": None if self._distance is None else round(self._distance, 2),
                "reward": round(out.reward, 6),
                "kinetix_action": self._vector(action).tolist(),
            },
        )

    def _images(self, firing: tuple[int, ...] = ()) -> list[Image]:
        """The current scene, clean and (with `annotate`) labelled, as PNG images."""
        assert self._controls is not None
        clean = render(self._state, firing)
        images = [Image.from_array("scene", "The scene now.", clean)]
        if self.options.annotate:  # type: ignore[attr-defined]
            labelled = annotate(clean, self._state, self._controls)[0]
            caption = "The same scene with each motor (M<i>) and thruster (T<i>) labelled."
            images.append(Image.from_array("annotated", caption, labelled))
        return images

    def _observation(self, images: list[Image] | None = None) -> Observation:
        return Observation(images=images or self._images(), text=self._describe(), action_space=self.space)

    def _describe(self) -> str:
        assert self._controls is not None and self._task is not None
        c = self._controls
        space = self.space
        parts = [f"M{i} ({len(j)} motor{'s' if len(j) > 1 else ''})" for i, j in enumerate(c.motor_joints)]
        parts += [f"T{i} ({len(t)} thruster{'s' if len(t) > 1 else ''})" for i, t in enumerate(c.thrusters)]
        dist = "n/a" if self._distance is None else f"{self._distance:.0f} px"
        # The level's name (a hint: "car_flip"), the decisions left and a decision's duration are
        # not in the paper's prompt: state_text only
        head = [f"Level {self._task.id} (size {self._task.group}). Decision {self._decision + 1} of {MAX_DECISIONS}; "
                f"each decision is held for {SECONDS_PER_DECISION:.2f} s of simulated time."] if self.options.state_text else []
        return "\n".join(
            [
                *head,
                f"Controls, in action order: {', '.join(parts)}.",
                f"Your action is a JSON list of {space.length} integer{'s' if space.length != 1 else ''}: [{', '.join(space.labels())}].",
                f"Goal distance (centre of the green shape to centre of the nearest blue shape): {dist}.",
            ]
        )
