"""The toy cart with one contract rule broken on purpose each (the checker must say so)."""

from __future__ import annotations

import itertools
import os

from deepphy.envs import EnvOptions, Observation, StepResult, Task
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


class ExplodeOptions(EnvOptions):
    explode_if_exists: str = ""  # a file: while it exists, task flag-05 raises at its second push


class Explodes(CartEnv):
    """A bug on purpose, in one task only (episode isolation)."""

    spec = _spec("explodes")
    Options = ExplodeOptions

    def step(self, action) -> StepResult:
        trigger = self.options.explode_if_exists
        if self.flag == 5 and self.pushes == 1 and trigger and os.path.exists(trigger):
            raise RuntimeError("the cart left the rail (a bug, on purpose)")
        return super().step(action)


for _cls in (RandomStart, UnsafeIds, NeverEnds, BadExample, Explodes):
    _cls.tasks = classmethod(lambda cls, options, _base=_cls.tasks: [
        t.model_copy(update={"env": cls.spec.name}) for t in _base.__func__(cls, options)])
