"""`EnvSpec`: everything the rest of deepphy needs to know about an environment.

Each environment is one package, `deepphy/envs/<name>/`, whose `__init__.py` defines
`SPEC = EnvSpec(...)`. The registry (`deepphy.envs`) finds the packages; the CLI, the
attempt protocol, the workers and the report read the spec and never name an
environment. A package's `__init__` must stay light (no simulator, JAX or numba
imports): the environment class, its prompt and its solver are named by import path
and loaded only when used.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any, Callable

from pydantic import BaseModel, ConfigDict, Field

from deepphy.envs.base import Planning

if TYPE_CHECKING:
    from deepphy.envs.base import Environment
    from deepphy.prompts.base import EnvPrompt


class ReportSpec(BaseModel):
    """Which of the protocol's figures the report shows for this environment."""

    model_config = ConfigDict(frozen=True)

    step_checkpoints: tuple[int, ...] = ()  # success within k decisions (Pooltool: shots 1, 3, 6, ...)
    step_noun: str = "step"  # what one decision is called in reports ("shot", "decision")
    group_noun: str = "group"  # what a task group is called in figures ("size", "setup")
    auccess: bool = False  # PHYRE's AUCCESS (invalid attempts not counted)
    stars: bool = False  # the games' stars
    leaderboard_groups: bool = False  # the leaderboard shows success per task group too (Kinetix S/M/L)
    pass_k: int | None = None  # the paper's headline Pass@k (PHYRE 5, I-PHYRE 3): leaderboard, VLA-vs-WM figure


class EnvSpec(BaseModel):
    model_config = ConfigDict(frozen=True)

    name: str = Field(pattern=r"^[a-z][a-z0-9_]*$")  # the --env name
    title: str
    environment: str  # "module:Class" of the Environment subclass
    prompt: str  # "module:Class" of its EnvPrompt
    planning: Planning
    max_attempts: int = Field(ge=1)  # attempts per task (the protocol's K)
    max_steps: int = Field(ge=1)  # decisions per attempt (1 for in-advance planning)
    report: ReportSpec = ReportSpec()
    solver: str | None = None  # "module:function(argv) -> exit status" of `deepphy solve --env`
    shortcuts: str | None = None  # "module:NAME" of its shortcut baselines (deepphy/envs/shortcuts.py)
    description: str = ""  # one line for `deepphy envs`

    def load_package(self) -> None:
        """Import the environment's package (light), which registers its action spaces."""
        importlib.import_module(self.environment.partition(":")[0].rpartition(".")[0])

    def load(self) -> type["Environment"]:
        """The environment class (imports the simulator)."""
        return _load(self.environment)

    def load_prompt(self) -> "EnvPrompt":
        return _load(self.prompt)()

    def load_solver(self) -> Callable[[list[str]], int] | None:
        return _load(self.solver) if self.solver else None


def _load(path: str) -> Any:
    module, _, attr = path.partition(":")
    return getattr(importlib.import_module(module), attr)
