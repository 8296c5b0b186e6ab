"""Metrics actor: receives every attempt's summary and serves live aggregates to progress
views (the driver's progress line, `deepphy watch`, the dashboard)."""

from __future__ import annotations

from typing import Any

from deepphy.actors import remote_class
from deepphy.metrics.live import LiveMetrics
from deepphy.runs.records import summaries_from_json


class MetricsImpl:
    def __init__(self, episodes_total: int, max_attempts: int, max_steps: int = 1,
                 run: dict[str, Any] | None = None, started: float | None = None) -> None:
        self.live = LiveMetrics(episodes_total, max_attempts, max_steps, started=started)  # started: the command's
        self.run = run or {}  # where the run writes and what it evaluates: dashboards find it here

    def add(self, summaries: bytes, resumed: bool = False) -> None:
        """A batch of attempt summaries, as `deepphy.runs.records.summaries_json` wrote it."""
        self.live.add(summaries_from_json(summaries), resumed)

    def update(self, activity: dict[str, Any]) -> None:
        self.live.update(**activity)

    def snapshot(self) -> dict[str, Any]:
        return {**self.live.snapshot(), **self.run}


def make_metrics_actor(episodes_total: int, max_attempts: int, max_steps: int = 1, *, name: str | None = None,
                       run: dict[str, Any] | None = None, started: float | None = None):
    from deepphy.actors.placement import beside_driver  # imports Ray: a run in this process never comes here

    return MetricsActor.options(num_cpus=0, name=name, scheduling_strategy=beside_driver()).remote(
        episodes_total, max_attempts, max_steps, run, started)


MetricsActor = remote_class(MetricsImpl)  # one class per process (see env_worker.EnvWorker)
