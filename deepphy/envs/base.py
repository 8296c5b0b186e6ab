"""The environment contract every DeepPHY environment implements.

Gymnasium-shaped: `reset(task)` starts an attempt and returns the first observation,
`step(action)` applies one decision. An in-advance environment (PHYRE, I-PHYRE) takes one
step per attempt (the whole plan); an on-the-fly one takes up to `max_steps` decisions.

What the rest of deepphy needs to know about an environment (planning mode, attempts and
steps, report figures, prompt, solver) is declared once, in its package's `EnvSpec`
(deepphy/envs/spec.py); the class carries it as `spec`.

The action syntax lives in the environment's `ActionSpace`: it parses model text into a
validated `Action` (or raises `InvalidAction` with a reason), samples a random valid
action for MOCK and writes an action back as text. The space travels inside every
observation, so whoever holds an observation can parse and sample without a live
simulator.

Environments know nothing of Ray, prompts or models.
"""

from __future__ import annotations

import functools
import re
from abc import ABC, abstractmethod
from collections import OrderedDict
from enum import Enum
from typing import Any, Callable, ClassVar, NamedTuple, Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from deepphy.chat import Image
from deepphy.envs.parsing import cut_reply


class Planning(str, Enum):
    IN_ADVANCE = "in_advance"  # one complete plan per attempt, simulated to the end
    ON_THE_FLY = "on_the_fly"  # act, observe, act again within an attempt


class InvalidAction(ValueError):
    """Model text that is not a valid action. The message is the recorded reason."""


# What a task id may be: it names directories of run directories (frames/<task>/).
SAFE_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,127}$")


class Task(BaseModel):
    """One benchmark task. `id` is unique within its environment and filesystem-safe (SAFE_ID)."""

    model_config = ConfigDict(frozen=True)

    env: str
    id: str
    group: str = ""  # reporting breakdown: Kinetix size, PHYRE split, ...
    params: dict[str, Any] = Field(default_factory=dict)


class Action(BaseModel):
    """A validated action. Subclasses hold the environment's fields."""

    model_config = ConfigDict(frozen=True)


class ActionSpace(BaseModel, ABC):
    """A typed, serialisable action space that owns the action syntax.

    Subclasses set a unique `kind` so a space can be rebuilt from JSON
    (`ActionSpace.from_json`), e.g. by a model server that only sees the request.
    """

    kind: str
    _registry: ClassVar[dict[str, type["ActionSpace"]]] = {}

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(**kwargs)
        default = cls.model_fields["kind"].default
        if isinstance(default, str):
            ActionSpace._registry[default] = cls
        if "parse" in cls.__dict__:
            cls.parse = _bounded(cls.__dict__["parse"])  # type: ignore[method-assign]

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> "ActionSpace":
        try:
            space_cls = ActionSpace._registry[data["kind"]]
        except KeyError:
            raise ValueError(f"unknown action space kind {data.get('kind')!r}") from None
        return space_cls.model_validate(data)

    @abstractmethod
    def parse(self, text: str) -> Action:
        """Model text -> validated action; raises InvalidAction(reason).

        Total and fast: any string gives an action or InvalidAction, in time linear in its
        length. When a reply states several answers, the last one counts. Every space's
        parse sees at most the reply's last MAX_REPLY_CHARS characters (deepphy/envs/parsing.py).
        """

    @abstractmethod
    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> Action:
        """A uniformly random valid action, avoiding `exclude` where the space allows
        (the `mock-uniform` baseline)."""

    def reference_reply(self, rng: np.random.Generator, earlier: Sequence[str] = ()) -> str:
        """The reply text of the reference implementation's random baseline (`mock`) for
        this decision: what it would send, unparseable replies included. `earlier`: this
        attempt's earlier actions (canonical text). Default: a uniformly random valid action."""
        return self.format(self.sample(rng))

    @abstractmethod
    def format(self, action: Action) -> str:
        """The action in the exact syntax the prompt asks for (parse(format(a)) == a)."""


def _bounded(parse: Callable[[Any, str], Action]) -> Callable[[Any, str], Action]:
    """A space's parse, given at most the reply's last MAX_REPLY_CHARS characters: whatever
    a reply's length, parsing it takes bounded time (the protocol records the cut)."""

    @functools.wraps(parse)
    def bounded(self: Any, text: str) -> Action:
        if not isinstance(text, str):
            raise InvalidAction(f"expected text, got {type(text).__name__}")
        return parse(self, cut_reply(text)[0])

    return bounded


class Observation(BaseModel):
    """What the agent is shown before a decision."""

    model_config = ConfigDict(arbitrary_types_allowed=True)

    images: list[Image]  # e.g. the raw scene and the annotated scene
    text: str = ""  # textual state: remaining birds, balls on the table, goal distances
    action_space: ActionSpace

    def image(self, name: str) -> Image:
        return next(i for i in self.images if i.name == name)


class ObservationCache:
    """First observations by key (a task, with the options that shape it). Reset is
    deterministic, so a task's first observation need only be rendered and encoded once:
    share one cache between the instances of an environment class (a worker holds many), and
    the driver keeps one too. Bounded (least recently used out), so memory stays flat."""

    def __init__(self, size: int = 128) -> None:
        self.size = size
        self._by_key: OrderedDict[Any, Observation] = OrderedDict()

    def get(self, key: Any) -> Observation | None:
        obs = self._by_key.get(key)
        if obs is not None:
            self._by_key.move_to_end(key)
        return obs

    def put(self, key: Any, obs: Observation) -> Observation:
        self._by_key[key] = obs
        self._by_key.move_to_end(key)
        while len(self._by_key) > self.size:
            self._by_key.popitem(last=False)
        return obs


class StepResult(BaseModel):
    """The consequence of one decision.

    The attempt is over when it is `terminated` (the task reached an outcome: solved,
    lost, an invalid placement) or `truncated` (its time or decision budget ran out
    first). An environment truncates at its spec's `max_steps` decisions at the latest.
    """

    model_config = ConfigDict(arbitrary_types_allowed=True)

    terminated: bool = False
    truncated: bool = False
    success: bool = False
    invalid_reason: str | None = None  # a physically invalid action (e.g. overlapping placement)
    observation: Observation | None = None  # next observation while not done
    feedback: str = ""  # what happened, in words, for the history shown in later prompts
    key_frames: list[Image] = Field(default_factory=list)  # what happened, as images
    stars: int | None = None
    score: float | None = None
    info: dict[str, Any] = Field(default_factory=dict)  # JSON-able details (end time, ...)

    @property
    def done(self) -> bool:
        return self.terminated or self.truncated


class EnvOptions(BaseModel):
    """Options of an environment, set from the run config. Subclass to add fields.

    By default an environment shows a model the information the DeepPHY paper's prompts
    gave it, no more, no less (docs/comparability.md): images, labels, counts and rules, no
    numeric state. `state_text=true` is the one opt-in departure every environment shares:
    the richer text deepphy gave before (positions, velocities, distances, physical
    constants, the level's name), a setting of its own in every report, never mixed with
    default rows."""

    model_config = ConfigDict(extra="forbid")

    state_text: bool = False

    # The value the paper used, per option whose other values depart from its set-up (a
    # subclass adds its own). Options not named here (a task subset, an ablation the paper
    # ran itself, an image size) do not depart from it.
    PAPER: ClassVar[dict[str, Any]] = {"state_text": False}

    @classmethod
    def departures_from_paper(cls, options: dict[str, Any]) -> list[str]:
        """`key=value` for every option of `options` (as a run's config holds them) set
        otherwise than the paper's set-up; empty: the paper's."""
        paper: dict[str, Any] = {}
        for klass in reversed(cls.__mro__):
            paper.update(getattr(klass, "PAPER", {}))
        out = []
        for key, value in paper.items():
            given = options.get(key, cls.model_fields[key].default)
            if given != value:
                out.append(f"{key}={given}")
        return out


class Environment(ABC):
    """One live environment instance: runs attempts of any of its tasks, one at a time."""

    # Its package's EnvSpec. Not annotated as one: the spec names this class by import path and
    # imports this module (Planning), so the class knows its spec only by value.
    spec: ClassVar[Any]
    Options: ClassVar[type[EnvOptions]] = EnvOptions

    def __init__(self, options: EnvOptions | None = None) -> None:
        self.options = options if options is not None else self.Options()

    @classmethod
    @abstractmethod
    def tasks(cls, options: EnvOptions) -> list[Task]:
        """The default evaluation set, in a stable order."""

    @abstractmethod
    def reset(self, task: Task) -> Observation:
        """Start an attempt from the task's initial state."""

    @abstractmethod
    def step(self, action: Action) -> StepResult:
        """Apply one decision of the current attempt."""

    @classmethod
    def warm_up(cls, options: EnvOptions, tasks: Sequence[Task]) -> None:
        """One-time, per-process preparation before these tasks run (compiling kernels).
        Workers call it before their first episode, so progress can say so."""

    @classmethod
    def step_many(cls, envs: Sequence["Environment"], actions: Sequence[Action]) -> list[StepResult]:
        """Step several instances at once. Environments that can batch (vmap) override this."""
        return [env.step(action) for env, action in zip(envs, actions)]

    def film(self, action: Action) -> tuple[StepResult, list["Frame"]]:
        """`step`, with pictures of the simulated world while it runs (about FILM_FPS per
        simulated second), for watching a replay. The result must equal `step`'s. Optional:
        by default the pictures are the step's key frames."""
        result = self.step(action)
        return result, [Frame(f.to_array(), f.caption) for f in result.key_frames]


FILM_FPS = 12  # pictures per simulated second in a replay (Environment.film)


class Frame(NamedTuple):
    """One picture of the simulated world in a replay."""

    rgb: np.ndarray
    caption: str  # when it is, e.g. "t = 1.25 s"

