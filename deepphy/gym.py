"""deepphy's environments as Gymnasium environments, for training agents outside deepphy's runner.

`import deepphy.gym` registers every environment as `deepphy/<name>-v0`:

    env = gymnasium.make("deepphy/cuttherope-v0", task="b1_l04", render_mode="rgb_array")
    # or, without the import: gymnasium.make("deepphy.gym:deepphy/cuttherope-v0", ...)

`DeepPhyEnv` wraps deepphy's own `Environment` (the simulator the harness runs; there is no
second implementation). One Gymnasium episode is one attempt at one task, as in
`deepphy.protocol.run_attempt`:

- Observation: `{"images": uint8 (n, H, W, 3), "text": str}`: the n images and the text
  state a model is shown at this decision (e.g. the scene and the annotated scene).
- Action: text in the environment's action syntax (what the prompt asks a model for),
  parsed by the environment's `ActionSpace`, as the harness parses a model's reply (prose
  around it is accepted, the last stated action counts). `action_space.sample()` draws a
  valid action of the current decision (the `mock-uniform` baseline's draw).
- Reward, on the step that ends the attempt: `SUCCESS_REWARD` if solved; `INVALID_REWARD`
  (or the `invalid_reward` given to make) when the action does not parse or the
  environment rejects it as physically invalid (e.g. a PHYRE ball overlapping a body):
  both end the attempt, `terminated`, with `info["invalid_reason"]` saying why; 0 for any
  other step. `terminated`/`truncated` are the environment's (truncated: its time or
  decision budget ran out). `info` carries the environment's outcome: success, stars,
  score, feedback (what happened, in words) and its details.
- Task: `task=` fixes one; otherwise every reset draws one from the evaluation set (or
  `tasks=[...]`) with Gymnasium's generator (`np_random`), so the same `reset(seed=...)`
  gives the same tasks, and deepphy's environments are deterministic: the same task and
  actions give bit-identical observations and outcomes. `reset(options={"task": id})`
  picks one for that episode.
- `render()` (render_mode "rgb_array") returns the current scene, and after the last step
  the environment's final key frame (the scene after it), always at the observation's size
  (video recorders need one shape): PHYRE's and I-PHYRE's final key frame, a strip of
  frames over the attempt, is scaled down into it.
- `env_options={...}`: the environment's options, as `deepphy run --env-option`.

A policy trained here is evaluated by `deepphy run` through an agent (deepphy/agent.py):
`observation_of(request)` is the observation above of the decision a model request asks
for (examples/gym_policy.py adapts any callable from it to an action).
"""

from __future__ import annotations

import string
from typing import Any, Sequence

import gymnasium
import numpy as np
from gymnasium import spaces

from deepphy.envs import (
    ActionSpace, EnvOptions, Environment, Image, InvalidAction, Observation, Task, get_spec, specs,
)
from deepphy.envs.parsing import MAX_REPLY_CHARS
from deepphy.models.base import ModelRequest
from deepphy.chat import ImagePart, TextPart
from deepphy.prompts.base import CURRENT_OBSERVATION

SUCCESS_REWARD = 1.0  # the step that solves the task
INVALID_REWARD = -1.0  # an action that does not parse, or one the environment rejects as invalid
MAX_STATE_CHARS = 65_536  # the text state's bound in the observation space (the longest is ~2,000)


def env_id(name: str) -> str:
    """The Gymnasium id of a deepphy environment."""
    return f"deepphy/{name}-v0"


class FreeText(spaces.Text):
    """Any string of at most `max_length` characters. Gymnasium's `Text` admits only its
    charset; the text state may hold any character and an action is judged by its parser."""

    def __init__(self, max_length: int, seed: int | np.random.Generator | None = None) -> None:
        super().__init__(max_length, min_length=0, charset=string.printable, seed=seed)

    def contains(self, x: Any) -> bool:
        return isinstance(x, str) and len(x) <= self.max_length


class ActionText(FreeText):
    """An environment's action text. `sample()` is a valid action of the current decision,
    drawn by the environment's ActionSpace with this space's generator (`seed()` it as usual);
    with a mask or probability, Gymnasium's character-wise sampling."""

    def __init__(self, seed: int | np.random.Generator | None = None) -> None:
        super().__init__(MAX_REPLY_CHARS, seed=seed)
        self.syntax: ActionSpace | None = None  # the current decision's space, set by DeepPhyEnv

    def sample(self, mask: Any = None, probability: Any = None) -> str:
        if mask is not None or probability is not None or self.syntax is None:
            return super().sample(mask=mask, probability=probability)
        return self.syntax.format(self.syntax.sample(self.np_random))


class DeepPhyEnv(gymnasium.Env):
    """One deepphy environment as a Gymnasium environment (see the module's docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(
        self,
        env: str,
        task: str | None = None,
        tasks: Sequence[str] | None = None,
        env_options: dict[str, Any] | None = None,
        invalid_reward: float = INVALID_REWARD,
        render_mode: str | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self.deepphy_spec = get_spec(env)
        env_cls: type[Environment] = self.deepphy_spec.load()
        self.env = env_cls(env_cls.Options(**(env_options or {})))
        evaluation_set = env_cls.tasks(self.env.options)
        by_id = {t.id: t for t in evaluation_set}
        wanted = [task] if task is not None else list(tasks) if tasks is not None else None
        unknown = [t for t in wanted or () if t not in by_id]
        if unknown:
            raise ValueError(f"unknown {env} task(s) {', '.join(unknown[:5])}; see `deepphy envs --tasks {env}`")
        self._by_id = by_id
        self.tasks: list[Task] = [by_id[t] for t in wanted] if wanted is not None else evaluation_set
        if not self.tasks:
            raise ValueError("the task selection is empty")
        self.invalid_reward = float(invalid_reward)
        warm_up(env_cls, self.env.options, self.tasks)

        # The images' shape is the environment's: read it from a first observation.
        first = self.env.reset(self.tasks[0])
        shape = _images(first).shape
        self.observation_space = spaces.Dict({
            "images": spaces.Box(0, 255, shape, np.uint8),
            "text": FreeText(MAX_STATE_CHARS),
        })
        self.action_space = ActionText()
        self.task: Task | None = None
        self._show(first)
        self._final_frame: np.ndarray | None = None
        self._decisions = 0
        self._done = True

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        super().reset(seed=seed)
        options = options or {}
        if "task" in options:
            if options["task"] not in self._by_id:
                raise ValueError(f"unknown {self.deepphy_spec.name} task {options['task']!r}")
            self.task = self._by_id[options["task"]]
        else:
            self.task = self.tasks[int(self.np_random.integers(len(self.tasks)))]
        self._show(self.env.reset(self.task))
        self._final_frame = None
        self._decisions = 0
        self._done = False
        return self._obs(), {"task": self.task.id, "group": self.task.group}

    def step(self, action: str) -> tuple[dict, float, bool, bool, dict]:
        if self._done:
            raise RuntimeError("the attempt is over: call reset() first")
        assert self.task is not None
        self._decisions += 1
        info: dict[str, Any] = {"task": self.task.id, "step": self._decisions}
        try:
            parsed = self._observation.action_space.parse(action)
        except InvalidAction as e:
            # As the harness records it: the attempt ends, failed and invalid.
            self._done = True
            info.update(success=False, invalid_reason=f"unparseable action: {e}", stars=None, score=None, feedback="")
            return self._obs(), self.invalid_reward, True, False, info
        info["action"] = self._observation.action_space.format(parsed)
        result = self.env.step(parsed)
        success = bool(result.success and not result.invalid_reason)
        info.update(success=success, invalid_reason=result.invalid_reason, stars=result.stars, score=result.score,
                    feedback=result.feedback, details=result.info)
        # An environment ends its attempts by max_steps; should one not, the protocol's bound holds here too.
        out_of_decisions = not result.done and (result.observation is None or self._decisions >= self.deepphy_spec.max_steps)
        self._done = result.done or out_of_decisions
        if result.observation is not None and not self._done:
            self._show(result.observation)
        elif result.key_frames:
            self._final_frame = _final_picture(result.key_frames, self.observation_space["images"].shape[1:])
        reward = self.invalid_reward if result.invalid_reason else SUCCESS_REWARD if success and self._done else 0.0
        return self._obs(), reward, bool(result.terminated), bool(result.truncated or out_of_decisions), info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        if self._final_frame is not None:
            return self._final_frame
        return self._observation.images[0].to_array()

    def _show(self, observation: Observation) -> None:
        images = _images(observation)
        if images.shape != self.observation_space["images"].shape:
            raise RuntimeError(f"{self.deepphy_spec.name} gave images of shape {images.shape}, "
                               f"not {self.observation_space['images'].shape}")
        self._observation = observation
        self._images = images
        self.action_space.syntax = observation.action_space

    def _obs(self) -> dict[str, Any]:
        return {"images": self._images, "text": self._observation.text}


_warmed: set[tuple[str, str, tuple[str, ...]]] = set()


def warm_up(env_cls: type[Environment], options: EnvOptions, tasks: Sequence[Task]) -> None:
    """The environment's one-time preparation in this process (as deepphy's workers do before
    their first episode: Pooltool's numba cache, Kinetix's compiled sizes), once per task set."""
    key = (env_cls.spec.name, options.model_dump_json(), tuple(t.id for t in tasks))
    if key not in _warmed:
        env_cls.warm_up(options, tasks)
        _warmed.add(key)


def _final_picture(key_frames: Sequence[Image], shape: tuple[int, ...]) -> np.ndarray:
    """The scene after the last step at the observation's `shape` (H, W, 3): the last key frame
    of that size (the settled scene), else the last key frame scaled into it, centred on its
    own background colour (PHYRE's and I-PHYRE's strips of frames over the attempt)."""
    import cv2  # OpenCV: only where a frame of another size is scaled

    frames = [f.to_array() for f in key_frames]
    same = [f for f in frames if f.shape == shape]
    if same:
        return same[-1]
    frame, (height, width) = frames[-1], shape[:2]
    scale = min(height / frame.shape[0], width / frame.shape[1])
    h, w = max(1, round(frame.shape[0] * scale)), max(1, round(frame.shape[1] * scale))
    canvas = np.empty(shape, np.uint8)
    canvas[:] = frame[0, 0]
    top, left = (height - h) // 2, (width - w) // 2
    canvas[top:top + h, left:left + w] = cv2.resize(frame, (w, h), interpolation=cv2.INTER_AREA)
    return canvas


def _images(observation: Observation) -> np.ndarray:
    arrays = [image.to_array() for image in observation.images]
    shapes = {a.shape for a in arrays}
    if len(shapes) != 1:
        raise RuntimeError(f"the observation's images differ in size ({sorted(shapes)}); stack needs one size")
    return np.stack(arrays)


def observation_of(request: ModelRequest) -> dict[str, Any]:
    """The observation `DeepPhyEnv` gives at the decision `request` asks for: the images its
    prompt shows as the current observation, and the text state it shows after them ("" where
    none; deepphy.prompts.build_messages lays the prompt out so)."""
    parts = request.messages[-1].content
    marks = [i for i, p in enumerate(parts) if isinstance(p, TextPart) and p.text == CURRENT_OBSERVATION]
    if not marks:
        raise ValueError(f"the request shows no {CURRENT_OBSERVATION!r} (not a deepphy decision prompt)")
    shown = parts[marks[-1] + 1:-1]  # the last part asks for the action
    images = [i for i, p in enumerate(shown) if isinstance(p, ImagePart)]
    after = shown[images[-1] + 1:] if images else []
    arrays = [shown[i].image.to_array() for i in images]
    if len({a.shape for a in arrays}) > 1:
        raise RuntimeError("the observation's images differ in size; stack needs one size")
    return {"images": np.stack(arrays), "text": after[0].text if after else ""}


def register_all() -> list[str]:
    """Register every deepphy environment with Gymnasium (idempotent); returns their ids."""
    ids = []
    for name in specs():
        ids.append(env_id(name))
        if ids[-1] not in gymnasium.registry:
            gymnasium.register(id=ids[-1], entry_point="deepphy.gym:DeepPhyEnv", kwargs={"env": name})
    return ids


register_all()
