"""Shortcut baselines: policies that understand nothing but exploit something.

A level or task that such a policy wins measures nothing, so every environment declares
the shortcuts a sceptical lab would try first (aim straight at the nearest target, act on
the first id, act on everything at once, always the strongest action ...) and the
calibration reports and `benchmarks/mock_figures.py` print their rates beside the random
baselines'. They are probes, not models: they may read privileged state (the level's
data, the simulator's world after this attempt's earlier decisions).

An environment declares its shortcuts in its EnvSpec (`shortcuts="module:NAME"`, a dict
of name -> `Shortcut`); a run evaluates one as the agent `shortcut-<name>` (e.g.
`deepphy run --env angrybirds --model shortcut-aim`), recorded like any model. A shortcut
answers in the environment's action syntax, so its text goes through the same parser and
records as a model's; it is deterministic: its generator is seeded by the request's
position (seed, task, run, attempt, step), never by scheduling.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
import importlib
from typing import Any, Callable

import numpy as np

from deepphy.envs.base import ActionSpace, Environment, EnvOptions, Observation, Task
from deepphy.envs.spec import EnvSpec

PREFIX = "shortcut-"  # an agent named shortcut-<name> is environment's shortcut <name>


@dataclass
class ShortcutContext:
    """What a shortcut may look at for one decision."""

    spec: EnvSpec
    options: EnvOptions
    task: Task
    action_space: ActionSpace  # the decision's action space (what can be used now)
    earlier: list[str]  # this attempt's earlier decisions, canonical syntax, oldest first
    tried: list[str]  # the actions of this task's earlier (failed) attempts
    rng: np.random.Generator
    _replayed: tuple[Environment, Observation] | None = field(default=None, repr=False)

    @property
    def step(self) -> int:
        """This decision's number within the attempt (1-based)."""
        return len(self.earlier) + 1

    def replay(self) -> tuple[Environment, Observation]:
        """Privileged: a fresh environment reset to the task and stepped through this
        attempt's earlier decisions, with the observation it now shows (made once)."""
        if self._replayed is None:
            cls = self.spec.load()
            env = cls(self.options)
            observation = env.reset(self.task)
            for text in self.earlier:
                result = env.step(observation.action_space.parse(text))
                if result.observation is None:
                    raise RuntimeError(f"{self.task.id}: the attempt ended before decision {self.step}")
                observation = result.observation
            self._replayed = (env, observation)
        return self._replayed


Shortcut = Callable[[ShortcutContext], str]  # the reply: an action in the environment's syntax


@dataclass(frozen=True)
class ShortcutPolicy:
    """One declared shortcut: the policy and, for the docs and `deepphy envs`, what it exploits."""

    policy: Shortcut
    exploits: str
    draws: bool = False  # it uses its generator: its runs differ (else every run is the first's)


class UnknownShortcut(ValueError):
    pass


def shortcuts(spec: EnvSpec) -> dict[str, ShortcutPolicy]:
    """The environment's declared shortcuts, by name (none when it declares none)."""
    if not spec.shortcuts:
        return {}
    module, _, attr = spec.shortcuts.partition(":")
    return dict(getattr(importlib.import_module(module), attr))


def is_shortcut(agent: str) -> bool:
    return agent.startswith(PREFIX)


def shortcut_for(spec: EnvSpec, agent: str) -> ShortcutPolicy:
    """The policy of agent `shortcut-<name>` in this environment; UnknownShortcut (one line
    naming the environment's shortcuts) otherwise."""
    name = agent[len(PREFIX):]
    declared = shortcuts(spec)
    if name not in declared:
        have = ", ".join(PREFIX + n for n in declared) or "none"
        raise UnknownShortcut(f"{spec.name} has no shortcut baseline {agent!r} (its shortcuts: {have})")
    return declared[name]


@functools.lru_cache(maxsize=16)
def _tasks(spec: EnvSpec, options_json: str) -> dict[str, Task]:
    cls = spec.load()
    return {t.id: t for t in cls.tasks(cls.Options(**json.loads(options_json)))}


def context(spec: EnvSpec, options: dict[str, Any], task_id: str, action_space: ActionSpace,
            earlier: list[str], tried: list[str], rng: np.random.Generator) -> ShortcutContext:
    """A shortcut's view of one decision, from what a request carries."""
    cls = spec.load()
    typed = cls.Options(**options)
    task = _tasks(spec, json.dumps(typed.model_dump(mode="json"), sort_keys=True)).get(task_id)
    if task is None:
        raise ValueError(f"{spec.name}: no task {task_id!r} with options {options}")
    return ShortcutContext(spec=spec, options=typed, task=task, action_space=action_space, earlier=list(earlier),
                           tried=list(tried), rng=rng)
