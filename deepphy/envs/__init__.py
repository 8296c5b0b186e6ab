"""The environment registry: every package `deepphy/envs/<name>/` that defines `SPEC`.

Adding an environment = adding its package (environment, action space, renderer, prompt,
`SPEC` in `__init__.py`); nothing else in deepphy names it. Tests and plug-ins can add
one from elsewhere with `register(spec)`.
"""

from __future__ import annotations

from deepphy.chat import Image
from deepphy.envs.base import (
    Action,
    ActionSpace,
    EnvOptions,
    Environment,
    InvalidAction,
    Observation,
    Planning,
    StepResult,
    Task,
)
from deepphy.envs.spec import EnvSpec, ReportSpec
from deepphy.registry import Registry


class UnknownEnvironment(KeyError):
    def __str__(self) -> str:
        return f"unknown environment {self.args[0]!r}; choose from {', '.join(sorted(specs()))}"


_registry: Registry[EnvSpec] = Registry(EnvSpec, __name__, __path__, "environment", UnknownEnvironment,
                                        packages_only=True)
specs = _registry.all
get_spec = _registry.get
register = _registry.register
unregister = _registry.unregister


def get_env_class(name: str) -> type[Environment]:
    return get_spec(name).load()


__all__ = [
    "Action", "ActionSpace", "EnvOptions", "EnvSpec", "Environment", "Image", "InvalidAction", "Observation",
    "Planning", "ReportSpec", "StepResult", "Task", "UnknownEnvironment", "get_env_class", "get_spec",
    "register", "specs", "unregister",
]
