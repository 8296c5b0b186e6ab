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
    def __init__(self, episodes_total: int, max_attempts: int, max_steps: int = 1,
                 clock: Callable[[], float] = time.time, started: float | None = None) -> None:
        self.episodes_total = episodes_total
        self.max_attempts = max_attempts
        self.max_steps = max_steps  # decisions per attempt: an episode is at most K x this many
        self.clock = clock
        self.started = clock() if started is None else started  # the elapsed time counts from here
        self.running_since: float | None = None  # when the "running" phase began: rates count from here
        # Snapshots are polled twice a second: keep each episode's figures up to date as its
        # attempts arrive instead of re-deriving every episode per poll.
        self.attempts: dict[tuple[str, int], list[AttemptSummary]] = defaultdict(list)
        self.episodes: dict[tuple[str, int], F.Episode] = {}
        self.finished: set[tuple[str, int]] = set()
        self.finished_before = 0  # episodes already finished when this session started
        self.new_attempts = 0
        self.new_decisions: dict[tuple[str, int], int] = defaultdict(int)  # per episode, this session's
        self.activity: dict[str, Any] = {"phase": "starting", "in_flight": 0, "decisions": 0, "errored": 0}

    def add(self, summaries: Iterable[AttemptSummary], resumed: bool = False) -> None:
        touched = set()
        for s in summaries:
            self.attempts[(s.task, s.run)].append(s)
            touched.add((s.task, s.run))
            self.new_attempts += not resumed
            if not resumed:
                self.new_decisions[(s.task, s.run)] += s.decisions
        for key in touched:
            self.episodes[key] = F.episodes(self.attempts[key], self.max_attempts)[0]
            if key not in self.finished and self.episodes[key].finished:
                self.finished.add(key)
                self.finished_before += resumed

    def update(self, **activity: Any) -> None:
        """The driver's counters: phase, episodes in flight, decisions made, episodes errored.
        Attempts/s and the ETA count from the start of the "running" phase, so that starting
        workers and compiling kernels (minutes for Pooltool) do not dilute them."""
        if activity.get("phase") == "running" and self.running_since is None:
            self.running_since = self.clock()
        self.activity.update(activity)

    def snapshot(self) -> dict[str, Any]:
        eps = list(self.episodes.values())
        now = self.clock()
        running = None if self.running_since is None else now - self.running_since
        done = len(self.finished)
        left = self.episodes_total - done
        # Work done this session, in episodes: the finished ones, plus the episodes in flight
        # at their decisions so far over the most an episode takes (K x decisions); so many
        # episodes in flight at once (Pooltool, Kinetix) do not make the ETA run long.
        decisions = self.activity.get("decisions", 0)
        in_finished = sum(self.new_decisions[k] for k in self.finished if k in self.new_decisions)
        partial = min(self.activity.get("in_flight", 0),
                      max(0, decisions - in_finished) / (self.max_attempts * self.max_steps))
        progress = done - self.finished_before + partial
        eta = 0.0 if not left else max(0.0, left - partial) * running / progress if progress and running else None
        return {
            "episodes_done": done,
            "episodes_total": self.episodes_total,
            **F.totals(eps),
            "new_attempts": self.new_attempts,
            "attempts_per_s": self.new_attempts / running if running else None,
            "decisions_per_s": decisions / running if running else None,
            "solved": sum(e.solved for e in eps),
            "elapsed_s": now - self.started,
            "running_s": running,
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
    parts.append(f"attempts {s['attempts']}" + _rate(s.get("attempts_per_s")))
    if s.get("decisions", 0) > s["new_attempts"]:
        parts.append(f"decisions {s['decisions']}" + _rate(s.get("decisions_per_s")))
    if s["invalid_attempts"]:
        parts.append(f"invalid {s['invalid_attempts']}")
    if s["model_errors"] or s["retries"]:
        parts.append(f"model errors {s['model_errors']} · retries {s['retries']}")
    waiting = endpoint_waits(s)
    if waiting:
        parts.append(waiting)
    if s.get("errored"):
        parts.append(f"errored {s['errored']}")
    if s["input_tokens"]:
        parts.append(f"tokens {s['input_tokens']}/{s['output_tokens']} · ${s['cost_usd']:.4f}")
    if s.get("eta_s") is not None and s["episodes_done"] < s["episodes_total"]:
        parts.append(f"ETA {_duration(s['eta_s'])}")
    parts.append(_duration(s["elapsed_s"]))
    return " · ".join(parts)


def endpoint_waits(s: dict[str, Any]) -> str:
    """What the model's requests are waiting for, named so a run that seems stuck says why:
    "gpt-4o: 12 requests waiting 30 s to retry (429), 3 for the rate limit, 1 for an answer
    for 95 s" ("" when none waits). The figures are the model client's (`activity()`)."""
    waits = []
    if s.get("retrying"):
        why = f" ({s['retry_reason']})" if s.get("retry_reason") else ""
        waits.append((s["retrying"], f"waiting {_seconds(s.get('retry_wait_s', 0))} to retry{why}"))
    if s.get("rate_limited"):
        waits.append((s["rate_limited"], "waiting for the rate limit"))
    if s.get("answering_slow"):
        waits.append((s["answering_slow"], f"waiting for an answer for {_seconds(s.get('answer_wait_s', 0))}"))
    if not waits:
        return ""
    model = (s.get("config") or {}).get("model", "model")
    (n, first), rest = waits[0], waits[1:]
    said = [f"{n} request{'s' if n != 1 else ''} {first}", *(f"{n} {what.removeprefix('waiting ')}" for n, what in rest)]
    return f"{model}: " + ", ".join(said)


def _seconds(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else _duration(s)


def _rate(per_s: float | None) -> str:
    """" (12/s)", " (1.5/s)", " (0.04/s)": two significant digits below 10/s; nothing before running."""
    if per_s is None:
        return ""
    return f" ({per_s:.0f}/s)" if per_s >= 10 else f" ({per_s:.2g}/s)"


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds}s"
    if seconds < 3600:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
