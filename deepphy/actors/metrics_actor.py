"""Metrics actor: receives every attempt record and serves live aggregates to progress views."""

from __future__ import annotations

import time
from typing import Any

import ray

from deepphy.metrics import figures as F
from deepphy.runs.records import AttemptRecord


class MetricsImpl:
    def __init__(self, episodes_total: int, max_attempts: int) -> None:
        self.episodes_total = episodes_total
        self.max_attempts = max_attempts
        self.records: list[AttemptRecord] = []
        self.started = time.time()
        self.resumed = 0  # records that were already on disk when this run started
        self.status = "running"

    def add(self, records: list[AttemptRecord], resumed: bool = False) -> None:
        self.records.extend(records)
        if resumed:
            self.resumed += len(records)

    def set_status(self, status: str) -> None:
        self.status = status

    def snapshot(self) -> dict[str, Any]:
        eps = F.episodes(self.records)
        finished = [e for e in eps if e.solved or e.attempts >= self.max_attempts]
        new = len(self.records) - self.resumed
        elapsed = time.time() - self.started
        return {
            "status": self.status,
            "episodes_done": len(finished),
            "episodes_total": self.episodes_total,
            **F.totals(eps),
            "attempts_per_s": new / elapsed if elapsed > 0 else 0.0,
            "solved": sum(e.solved for e in eps),
            "success_rate": sum(e.solved for e in finished) / len(finished) if finished else 0.0,
            "elapsed_s": elapsed,
        }


def make_metrics_actor(episodes_total: int, max_attempts: int, *, name: str | None = None):
    return ray.remote(num_cpus=0)(MetricsImpl).options(name=name).remote(episodes_total, max_attempts)
