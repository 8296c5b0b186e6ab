"""Run configuration: what to evaluate (stored with the run) and how to run it (not stored)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from deepphy.chat import PromptFormat

DEFAULT_OUT = "runs/demo"
# What a run may ask for; its records are held to the same bounds (deepphy/runs/records.py).
RUNS_MAX = 100_000  # repetitions of every task
ATTEMPTS_MAX = 1_000  # attempts per task (the protocol's K is 10 at most)
SEED_MIN, SEED_MAX = -(2**63), 2**63 - 1  # a 64-bit integer, as datasets and NumPy hold it

# Which prompts a run is given: "paper", information-equivalent to the DeepPHY paper's
# (docs/comparability.md); "before-parity", deepphy's prompts before that (numeric state
# the paper's never gave, no retry instructions): the value a run directory made then reads
# as (its config.json has no `prompts`). Those runs are read (report, leaderboard, export),
# never resumed: their prompts are no longer made.
PromptSet = Literal["paper", "before-parity"]
PROMPTS = "paper"

HUMAN_PREFIX = "human:"  # a person's run (`deepphy play`) has the model `human:NAME`


def is_human(model: str) -> bool:
    """Whether a run's model is a person: its decision times are a person's, not a model's latency."""
    return model.startswith(HUMAN_PREFIX)


class RunConfig(BaseModel):
    """What a run evaluates. Written to <run dir>/config.json; a resume must match it exactly."""

    model_config = ConfigDict(extra="forbid")

    env: str = "iphyre"
    model: str = "mock"
    format: PromptFormat = PromptFormat.VLA
    runs: int = Field(3, ge=1, le=RUNS_MAX, description="independent repetitions of every task")
    seed: int = Field(0, ge=SEED_MIN, le=SEED_MAX)
    tasks: list[str] | None = Field(None, description="task ids; default: the environment's evaluation set")
    limit: int | None = Field(None, ge=1, description="only the first N tasks of the set")
    max_attempts: int | None = Field(None, ge=1, le=ATTEMPTS_MAX, description="attempts per task; default: the protocol's K")
    env_options: dict[str, Any] = Field(default_factory=dict)
    temperature: float = 0.1
    max_tokens: int = Field(1024, ge=1)
    prompts: PromptSet = PROMPTS

    @field_validator("tasks")
    @classmethod
    def _unique_tasks(cls, tasks: list[str] | None) -> list[str] | None:
        if tasks is not None:
            seen = set()
            twice = [t for t in tasks if t in seen or seen.add(t)]
            if twice:
                raise ValueError(f"task id(s) given more than once: {', '.join(dict.fromkeys(twice))}")
        return tasks

    @model_validator(mode="after")
    def _known_names(self) -> "RunConfig":
        from deepphy.envs import UnknownEnvironment, get_spec

        try:
            get_spec(self.env)
        except UnknownEnvironment as e:
            raise ValueError(str(e)) from None
        return self


class RuntimeOptions(BaseModel):
    """How a run executes. Free to change between a run and its resume."""

    model_config = ConfigDict(extra="forbid")

    address: str | None = None  # join an existing Ray cluster; None: start a local one
    num_cpus: int = Field(2, ge=1)  # local cluster only
    env_workers: int | None = Field(None, ge=1)  # default: one per CPU of the cluster
    env_resource: str | None = None  # custom Ray resource that marks the nodes for env workers
    max_in_flight: int = Field(256, ge=1)  # episodes (task x run) in progress at once
    progress: bool = True
    step_timeout_s: float = Field(600.0, gt=0)  # one env call (first Kinetix step compiles)
    model_timeout_s: float = Field(900.0, gt=0)  # one model call, retries included
    attempt_retries: int = Field(5, ge=0)  # re-runs of an attempt whose worker died (after 1, 2, 4, ... s)
    max_cost_usd: float | None = Field(None, gt=0)  # stop, resumably, once the run's model cost reaches this
    models_file: str | None = None  # YAML of model endpoints (absolute: workers may run elsewhere)
