"""Environment registry. Modules are imported lazily: Kinetix pulls in JAX, Pooltool numba."""

from __future__ import annotations

import importlib

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
    seeded_rng,
)
from deepphy.envs.images import Image

# name -> "module:Class". One line per environment.
ENVIRONMENTS: dict[str, str] = {
    "iphyre": "deepphy.envs.iphyre:IPhyreEnv",
    "kinetix": "deepphy.envs.kinetix:KinetixEnv",
    "pooltool": "deepphy.envs.pooltool:PooltoolEnv",
    "phyre": "deepphy.envs.phyre:PhyreEnv",
}


class UnknownEnvironment(KeyError):
    def __str__(self) -> str:
        return f"unknown environment {self.args[0]!r}; choose from {', '.join(sorted(ENVIRONMENTS))}"


def get_env_class(name: str) -> type[Environment]:
    try:
        module, cls = ENVIRONMENTS[name].split(":")
    except KeyError:
        raise UnknownEnvironment(name) from None
    return getattr(importlib.import_module(module), cls)


__all__ = [
    "Action", "ActionSpace", "ENVIRONMENTS", "EnvOptions", "Environment", "Image", "InvalidAction",
    "Observation", "Planning", "StepResult", "Task", "UnknownEnvironment", "get_env_class", "seeded_rng",
]
