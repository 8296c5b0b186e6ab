"""Metrics actor: receives every attempt record and serves live aggregates to progress views."""

from __future__ import annotations

import time
from collections import defaultdict
from typing import Any

import ray

from deepphy.metrics import figures as F
from deepphy.runs.records import AttemptRecord


class MetricsImpl:
    def __init__(self, episodes_total: int, max_attempts: int, run: dict[str, Any] | None = None) -> None:
        self.episodes_total = episodes_total
        self.max_attempts = max_attempts
        self.run = run or {}  # where the run writes and what it evaluates: dashboards find it here
        # Snapshots are polled twice a second: keep each episode's figures up to date as its
        # records arrive instead of re-deriving every episode from every record per poll.
        self.records: dict[tuple[str, int], list[AttemptRecord]] = defaultdict(list)
        self.episodes: dict[tuple[str, int], F.Episode] = {}
        self.started = time.time()
        self.resumed = 0  # records that were already on disk when this run started
        self.new = 0  # records made by this run

    def add(self, records: list[AttemptRecord], resumed: bool = False) -> None:
        touched = set()
        for r in records:
            self.records[(r.task, r.run)].append(r)
            touched.add((r.task, r.run))
        for key in touched:
            self.episodes[key] = F.episodes(self.records[key])[0]
        if resumed:
            self.resumed += len(records)
        else:
            self.new += len(records)

    def snapshot(self) -> dict[str, Any]:
        eps = list(self.episodes.values())
        finished = [e for e in eps if e.solved or e.attempts >= self.max_attempts]
        elapsed = time.time() - self.started
        return {
            "episodes_done": len(finished),
            "episodes_total": self.episodes_total,
            **F.totals(eps),
            "attempts_per_s": self.new / elapsed if elapsed > 0 else 0.0,
            "solved": sum(e.solved for e in eps),
            "success_rate": sum(e.solved for e in finished) / len(finished) if finished else 0.0,
            "elapsed_s": elapsed,
            **self.run,
        }


def make_metrics_actor(episodes_total: int, max_attempts: int, *, name: str | None = None,
                       run: dict[str, Any] | None = None):
    return ray.remote(num_cpus=0)(MetricsImpl).options(name=name).remote(episodes_total, max_attempts, run)
