"""A run's plan: the one place a config becomes something to run.

`plan(config)` checks what a config asks of its environment (its options, its tasks) and
resolves it once: the environment's spec, its validated options, the task list and the
attempts per task. Everything that runs, resumes, reads or shows a run (the runner, the
suite, the report, the dashboard, play, export, the dry-run) starts from a `RunPlan`, so
a config is validated in one way and its options travel typed from here on.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable

from pydantic import ValidationError

from deepphy.config import RunConfig
from deepphy.envs import EnvOptions, EnvSpec, Environment, Task, get_spec
from deepphy.messages import validation_message
from deepphy.prompts import EnvPrompt
from deepphy.runs.records import AttemptRecord, AttemptSummary, episode_finished


class ConfigError(ValueError):
    """A run config that cannot be evaluated. The message is for the user."""


def env_options(spec: EnvSpec, options: dict[str, Any]) -> EnvOptions:
    """`options` (as a config or a command line holds them) validated as the environment's
    Options, or ConfigError naming the bad one."""
    try:
        return spec.load().Options(**options)
    except ValidationError as e:
        raise ConfigError(f"bad option for {spec.name}: {validation_message(e)}") from None


@dataclass(frozen=True)
class RunPlan:
    """What a config evaluates, checked: its environment, options, tasks and attempt budget."""

    config: RunConfig
    spec: EnvSpec
    options: EnvOptions  # the config's env_options, validated
    tasks: tuple[Task, ...]  # the task selection, in the environment's order
    k_max: int  # attempts per task (the protocol's K unless the config sets it)

    @property
    def episodes_total(self) -> int:
        """Every (task, run) of the plan."""
        return len(self.tasks) * self.config.runs

    def make_env(self) -> Environment:
        """A fresh environment instance with the plan's options (imports the simulator)."""
        return self.spec.load()(self.options)

    def prompt(self) -> EnvPrompt:
        """The environment's prompt builder."""
        return self.spec.load_prompt()

    def episodes_done(self, records: Iterable[AttemptRecord | AttemptSummary]) -> int:
        """Episodes of the plan that `records` finish (solved, or out of attempts); records
        of other tasks or runs (a run directory's, read as they are) are not counted."""
        wanted = {t.id for t in self.tasks}
        episodes: dict[tuple[str, int], list[AttemptRecord | AttemptSummary]] = {}
        for r in records:
            if r.task in wanted and r.run < self.config.runs:
                episodes.setdefault((r.task, r.run), []).append(r)
        return sum(episode_finished(attempts, self.k_max) for attempts in episodes.values())


def plan(config: RunConfig) -> RunPlan:
    """The plan of `config`, or ConfigError (a bad option, an unknown task, no task left)."""
    spec = get_spec(config.env)
    options = env_options(spec, config.env_options)
    tasks = spec.load().tasks(options)
    if config.tasks:
        by_id = {t.id: t for t in tasks}
        unknown = [t for t in config.tasks if t not in by_id]
        if unknown:
            raise ConfigError(
                f"unknown {config.env} task(s) {', '.join(unknown[:5])}; see `deepphy envs --tasks {config.env}`"
            )
        tasks = [by_id[t] for t in config.tasks]
    if config.limit:
        tasks = tasks[: config.limit]
    if not tasks:
        raise ConfigError("the task selection is empty")
    return RunPlan(config, spec, options, tuple(tasks), config.max_attempts or spec.max_attempts)
