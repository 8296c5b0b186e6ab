"""Metrics actor: receives every attempt's summary and serves live aggregates to progress
views (the driver's progress line, `deepphy watch`, the dashboard)."""

from __future__ import annotations

from typing import Any

import ray

from deepphy.metrics.live import LiveMetrics
from deepphy.runs.records import AttemptSummary


class MetricsImpl:
    def __init__(self, episodes_total: int, max_attempts: int) -> None:
        self.live = LiveMetrics(episodes_total, max_attempts)

    def add(self, summaries: list[AttemptSummary], resumed: bool = False) -> None:
        self.live.add(summaries, resumed)

    def update(self, activity: dict[str, Any]) -> None:
        self.live.update(**activity)

    def snapshot(self) -> dict[str, Any]:
        return self.live.snapshot()


def make_metrics_actor(episodes_total: int, max_attempts: int, *, name: str | None = None):
    return ray.remote(num_cpus=0)(MetricsImpl).options(name=name).remote(episodes_total, max_attempts)
