"""The toy cart with one contract rule broken on purpose each (the checker must say so)."""

from __future__ import annotations

import itertools

from deepphy.envs import Observation, StepResult, Task
from toy_env import SPEC
from toy_env.env import CartEnv
from toy_env.prompt import CartPrompt

_calls = itertools.count()


def _spec(name: str, **update):
    return SPEC.model_copy(update={"name": name, "environment": f"toy_env.broken:{name.title().replace('_', '')}",
                                   **update})


class RandomStart(CartEnv):
    """reset() is not deterministic."""

    spec = _spec("random_start")

    def reset(self, task: Task) -> Observation:
        obs = super().reset(task)
        self.x = next(_calls) % 3
        return self._observation() if self.x else obs


class UnsafeIds(CartEnv):
    spec = _spec("unsafe_ids")

    @classmethod
    def tasks(cls, options) -> list[Task]:
        return [t.model_copy(update={"id": t.id.replace("-", "/"), "env": cls.spec.name})
                for t in super().tasks(options)]


class NeverEnds(CartEnv):
    """Never truncates: an attempt would outlive max_steps."""

    spec = _spec("never_ends")

    def step(self, action) -> StepResult:
        result = super().step(action)
        return result.model_copy(update={"truncated": False, "observation": result.observation or self._observation()})


class BadExamplePrompt(CartPrompt):
    def example(self, observation: Observation) -> str:
        return "push(7)"


class BadExample(CartEnv):
    spec = _spec("bad_example", prompt="toy_env.broken:BadExamplePrompt")


for _cls in (RandomStart, UnsafeIds, NeverEnds, BadExample):
    _cls.tasks = classmethod(lambda cls, options, _base=_cls.tasks: [
        t.model_copy(update={"env": cls.spec.name}) for t in _base.__func__(cls, options)])
