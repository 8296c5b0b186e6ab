"""The environment registry: every package `deepphy/envs/<name>/` that defines `SPEC`.

Adding an environment = adding its package (environment, action space, renderer, prompt,
`SPEC` in `__init__.py`); nothing else in deepphy names it. Tests and plug-ins can add
one from elsewhere with `register(spec)`.
"""

from __future__ import annotations

import importlib
import pkgutil

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

_registry: dict[str, EnvSpec] = {}
_discovered = False


class UnknownEnvironment(KeyError):
    def __str__(self) -> str:
        return f"unknown environment {self.args[0]!r}; choose from {', '.join(sorted(specs()))}"


def _discover() -> None:
    global _discovered
    if _discovered:
        return
    _discovered = True
    for module in pkgutil.iter_modules(__path__):
        if module.ispkg:
            spec = getattr(importlib.import_module(f"{__name__}.{module.name}"), "SPEC", None)
            if isinstance(spec, EnvSpec):
                _registry.setdefault(spec.name, spec)


def specs() -> dict[str, EnvSpec]:
    """Every registered environment, by name (the packages' order, then registrations)."""
    _discover()
    return dict(_registry)


def get_spec(name: str) -> EnvSpec:
    _discover()
    try:
        return _registry[name]
    except KeyError:
        raise UnknownEnvironment(name) from None


def register(spec: EnvSpec) -> EnvSpec:
    """Add an environment that does not live in deepphy/envs/ (a test's, a plug-in's)."""
    _discover()
    if spec.name in _registry and _registry[spec.name] != spec:
        raise ValueError(f"another environment is already registered as {spec.name!r}")
    _registry[spec.name] = spec
    return spec


def unregister(name: str) -> None:
    _registry.pop(name, None)


def get_env_class(name: str) -> type[Environment]:
    return get_spec(name).load()


__all__ = [
    "Action", "ActionSpace", "EnvOptions", "EnvSpec", "Environment", "Image", "InvalidAction", "Observation",
    "Planning", "ReportSpec", "StepResult", "Task", "UnknownEnvironment", "get_env_class", "get_spec",
    "register", "specs", "unregister",
]
