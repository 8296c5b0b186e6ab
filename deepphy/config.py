"""Run configuration: what to evaluate (stored with the run) and how to run it (not stored)."""

from __future__ import annotations

import hashlib
import json
import re
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_serializer, model_validator

from deepphy.chat import PromptFormat
from deepphy.envs import UnknownEnvironment, get_spec

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


AGENT_ENTRY = r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$"
AGENT_NAME_MAX = 120  # an agent's model name names suite directories: kept well below a file name's 255 bytes
_UNSAFE = re.compile(r"[^A-Za-z0-9._=-]")  # in a model name: what a file name and a suite's cell path allow


class AgentSpec(BaseModel):
    """A user's agent (`deepphy run --agent ENTRY --agent-arg KEY=VALUE`, deepphy/agent.py):
    stored in the run's config, so a resume with other arguments, or with another version of
    the agent's package, is refused like any change of config."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    entry: str = Field(pattern=AGENT_ENTRY, description="package.module:factory")
    args: dict[str, Any] = Field(default_factory=dict, description="keyword arguments of the factory (JSON values)")
    package: str = Field(description="the distribution (else the top-level package) the entry point is in")
    version: str | None = Field(description="that package's version; None: it has none (not installed, no __version__)")

    @field_validator("args")
    @classmethod
    def _keyword_names(cls, args: dict[str, Any]) -> dict[str, Any]:
        bad = [k for k in args if not k.isidentifier()]
        if bad:
            raise ValueError(f"agent argument {bad[0][:40]!r} is not a keyword name (letters, digits and _)")
        return args

    @property
    def name(self) -> str:
        """The model name of the agent's runs: its entry point and arguments, stable and
        filesystem-safe (letters, digits, . _ = - joined by +), e.g.
        `examples.reflection.ReflectionAgent+endpoint=gpt-4o`. Where an argument does not
        fit that alphabet, or the name would be longer than AGENT_NAME_MAX, the readable part
        is cut and a hash of the exact entry point and arguments ends it, so two agents never
        share a name."""
        parts = [self.entry.replace(":", ".")]
        parts += [f"{k}={v if isinstance(v, str) else json.dumps(v, sort_keys=True)}"
                  for k, v in sorted(self.args.items())]
        exact = "+".join(parts)
        safe = "+".join(_UNSAFE.sub("_", p) for p in parts)
        if safe == exact and len(exact) <= AGENT_NAME_MAX:
            return exact
        digest = hashlib.sha256(json.dumps([self.entry, self.args], sort_keys=True).encode()).hexdigest()[:10]
        return f"{safe[:AGENT_NAME_MAX - len(digest) - 1]}+{digest}"

    @property
    def label(self) -> str:
        """The agent's package and version, for tables: `examples 0.1.0`."""
        return f"{self.package} {self.version or 'unversioned'}"


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
    agent: AgentSpec | None = Field(None, description="a user's agent (its name is `model`); None: a baseline or an "
                                    "endpoint of the models file")

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
        try:
            get_spec(self.env)
        except UnknownEnvironment as e:
            raise ValueError(str(e)) from None
        if self.agent is not None and self.model != self.agent.name:
            raise ValueError(f"model {self.model!r} is not the name of its agent ({self.agent.name})")
        return self

    @model_serializer(mode="wrap")
    def _no_agent_key_without_an_agent(self, handler):
        """A run of a baseline or an endpoint is written as before agents existed (config.json,
        suite manifests): byte for byte the same."""
        data = handler(self)
        if self.agent is None:
            data.pop("agent", None)
        return data


class RuntimeOptions(BaseModel):
    """How a run executes. Free to change between a run and its resume."""

    model_config = ConfigDict(extra="forbid")

    address: str | None = None  # join an existing Ray cluster; None: start a local one
    in_process: bool = False  # the workers in this process, no Ray (deepphy.in_process)
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

    @model_validator(mode="after")
    def _in_process_alone(self) -> "RuntimeOptions":
        if self.in_process and self.address:
            raise ValueError("--in-process runs without Ray: it takes no --address")
        if self.in_process and self.env_resource:
            raise ValueError("--in-process runs without Ray: it takes no --env-resource")
        return self
