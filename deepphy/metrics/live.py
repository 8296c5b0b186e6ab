"""Live aggregates of a run for progress views (the terminal line, `deepphy watch`, the
dashboard): fed attempt summaries as they are recorded and the driver's activity
counters, asked for snapshots. Pure Python; the metrics actor wraps it."""

from __future__ import annotations

import time
from collections import defaultdict
from typing import Any, Callable, Iterable

from deepphy.metrics import figures as F
from deepphy.runs.records import AttemptSummary


class LiveMetrics:
    def __init__(self, episodes_total: int, max_attempts: int, clock: Callable[[], float] = time.time) -> None:
        self.episodes_total = episodes_total
        self.max_attempts = max_attempts
        self.clock = clock
        self.started = clock()
        # Snapshots are polled twice a second: keep each episode's figures up to date as its
        # attempts arrive instead of re-deriving every episode per poll.
        self.attempts: dict[tuple[str, int], list[AttemptSummary]] = defaultdict(list)
        self.episodes: dict[tuple[str, int], F.Episode] = {}
        self.finished: set[tuple[str, int]] = set()
        self.finished_before = 0  # episodes already finished when this session started
        self.new_attempts = 0
        self.activity: dict[str, Any] = {"phase": "starting", "in_flight": 0, "decisions": 0, "errored": 0}

    def add(self, summaries: Iterable[AttemptSummary], resumed: bool = False) -> None:
        touched = set()
        for s in summaries:
            self.attempts[(s.task, s.run)].append(s)
            touched.add((s.task, s.run))
            self.new_attempts += not resumed
        for key in touched:
            self.episodes[key] = F.episodes(self.attempts[key], self.max_attempts)[0]
            if key not in self.finished and self.episodes[key].finished:
                self.finished.add(key)
                self.finished_before += resumed

    def update(self, **activity: Any) -> None:
        """The driver's counters: phase, episodes in flight, decisions made, episodes errored."""
        self.activity.update(activity)

    def snapshot(self) -> dict[str, Any]:
        eps = list(self.episodes.values())
        elapsed = self.clock() - self.started
        done = len(self.finished)
        done_now = done - self.finished_before
        left = self.episodes_total - done
        eta = left * elapsed / done_now if done_now and left else (0.0 if not left else None)
        return {
            "episodes_done": done,
            "episodes_total": self.episodes_total,
            **F.totals(eps),
            "new_attempts": self.new_attempts,
            "attempts_per_s": self.new_attempts / elapsed if elapsed > 0 else 0.0,
            "solved": sum(e.solved for e in eps),
            "elapsed_s": elapsed,
            "eta_s": eta,
            **self.activity,
        }


def format_progress(s: dict[str, Any]) -> str:
    """One line a person can read: what is happening, done/total, solved so far, rate, ETA."""
    parts = [] if s.get("phase", "running") == "running" else [str(s["phase"])]
    parts.append(f"episodes {s['episodes_done']}/{s['episodes_total']}")
    if s.get("in_flight"):
        parts.append(f"in flight {s['in_flight']}")
    parts.append(f"solved {s['solved']}")
    parts.append(f"attempts {s['attempts']} ({s['attempts_per_s']:.1f}/s)")
    if s.get("decisions", 0) > s["new_attempts"]:
        parts.append(f"decisions {s['decisions']}")
    if s["invalid_attempts"]:
        parts.append(f"invalid {s['invalid_attempts']}")
    if s["model_errors"] or s["retries"]:
        parts.append(f"model errors {s['model_errors']} · retries {s['retries']}")
    waiting = [f"{n} {what}" for what, n in (("for the rate limit", s.get("rate_limited", 0)),
                                             ("to retry", s.get("retrying", 0))) if n]
    if waiting:
        parts.append("waiting " + ", ".join(waiting))
    if s.get("errored"):
        parts.append(f"errored {s['errored']}")
    if s["input_tokens"]:
        parts.append(f"tokens {s['input_tokens']}/{s['output_tokens']} · ${s['cost_usd']:.4f}")
    if s.get("eta_s") is not None and s["episodes_done"] < s["episodes_total"]:
        parts.append(f"ETA {_duration(s['eta_s'])}")
    parts.append(_duration(s["elapsed_s"]))
    return " · ".join(parts)


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds}s"
    if seconds < 3600:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
