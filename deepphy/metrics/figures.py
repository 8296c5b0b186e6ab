"""The protocol's figures, as pure functions of attempt records.

Every figure is computed per run (one repetition of every task) and then averaged over
runs with a sample standard deviation. An episode is one (task, run): its attempts run
until the first success or until K attempts are used.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from statistics import mean, stdev
from typing import Iterable, Sequence

from deepphy.runs.records import AttemptRecord, AttemptSummary, episode_finished


@dataclass(frozen=True)
class Episode:
    task: str
    group: str
    run: int
    finished: bool  # solved, or out of attempts (deepphy.runs.records.episode_finished)
    attempts: int  # attempts used
    solved_at: int | None  # attempt number of the success, if any
    invalid: int  # attempts that ended on an invalid action
    steps_to_solve: int | None  # decisions used in the solving attempt
    stars: int | None  # stars of the best attempt (solved attempt if any)
    model_errors: int
    retries: int
    input_tokens: int
    output_tokens: int
    cost_usd: float

    @property
    def solved(self) -> bool:
        return self.solved_at is not None

    @property
    def valid_attempts_to_solve(self) -> int | None:
        """Attempt number of the success counting valid attempts only (PHYRE's AUCCESS rule)."""
        return None if self.solved_at is None else self.solved_at - self.invalid


def episodes(records: Iterable[AttemptRecord | AttemptSummary], max_attempts: int) -> list[Episode]:
    """Group records (or their summaries) into episodes of at most `max_attempts` attempts.
    Attempts after a success (there should be none) are ignored."""
    by_episode: dict[tuple[str, int], list[AttemptRecord | AttemptSummary]] = defaultdict(list)
    for r in records:
        by_episode[(r.task, r.run)].append(r)
    out = []
    for (task, run), recs in sorted(by_episode.items()):
        recs.sort(key=lambda r: r.attempt)
        solved = next((r for r in recs if r.success), None)
        if solved is not None:
            recs = [r for r in recs if r.attempt <= solved.attempt]
        stars = [r.stars for r in recs if r.stars is not None]
        out.append(
            Episode(
                task=task,
                group=recs[0].group,
                run=run,
                finished=episode_finished(recs, max_attempts),
                attempts=len(recs),
                solved_at=solved.attempt if solved else None,
                invalid=sum(r.invalid for r in recs),
                steps_to_solve=solved.decisions if solved else None,
                stars=(solved.stars if solved and solved.stars is not None else (max(stars) if stars else None)),
                model_errors=sum(r.model_stats.model_errors for r in recs),
                retries=sum(r.model_stats.retries for r in recs),
                input_tokens=sum(r.model_stats.usage.input_tokens for r in recs),
                output_tokens=sum(r.model_stats.usage.output_tokens for r in recs),
                cost_usd=sum(r.model_stats.usage.cost_usd for r in recs),
            )
        )
    return out


def totals(eps: Sequence[Episode]) -> dict[str, float]:
    """Counters summed over episodes: attempts, invalid attempts, model errors, usage."""
    return {
        "attempts": sum(e.attempts for e in eps),
        "invalid_attempts": sum(e.invalid for e in eps),
        "model_errors": sum(e.model_errors for e in eps),
        "retries": sum(e.retries for e in eps),
        "input_tokens": sum(e.input_tokens for e in eps),
        "output_tokens": sum(e.output_tokens for e in eps),
        "cost_usd": sum(e.cost_usd for e in eps),
    }


def success_at(eps: Sequence[Episode], k: int, n_tasks: int | None = None) -> float:
    """Fraction of tasks solved within k attempts (cumulative; the paper's Att. k)."""
    n = n_tasks if n_tasks is not None else len(eps)
    return sum(1 for e in eps if e.solved_at is not None and e.solved_at <= k) / n if n else 0.0


def pass_at(eps: Sequence[Episode], k: int, runs: int, n_tasks: int) -> float | None:
    """The paper's Pass@k, as its tables compute it: the share of tasks solved within the
    attempt budget in at least one of k independent runs (not "within k attempts", which
    is Att. k; shared/notes/paper-prompts.md gives the evidence). With n >= k runs of each
    task, c of them solved, the unbiased estimator 1 - C(n - c, k) / C(n, k) per task,
    averaged over the tasks. None when there are fewer runs than k: no number is invented.
    An unfinished episode counts as unsolved, as it does for Att. k."""
    if k > runs or not n_tasks:
        return None
    solved: dict[str, int] = defaultdict(int)
    for e in eps:
        if e.solved and e.run < runs:
            solved[e.task] += 1
    total = math.comb(runs, k)
    return sum(1 - math.comb(runs - c, k) / total for c in solved.values()) / n_tasks


def success_within_steps(eps: Sequence[Episode], k: int, n_tasks: int | None = None) -> float:
    """Fraction of tasks solved within k decisions (Pooltool's shots 1, 3, 6, ...)."""
    n = n_tasks if n_tasks is not None else len(eps)
    return sum(1 for e in eps if e.steps_to_solve is not None and e.steps_to_solve <= k) / n if n else 0.0


def average_attempts(eps: Sequence[Episode]) -> float | None:
    """Mean attempts used, over solved episodes only (None if nothing was solved)."""
    solved = [e.solved_at for e in eps if e.solved_at is not None]
    return mean(solved) if solved else None


def average_steps(eps: Sequence[Episode]) -> float | None:
    """Mean decisions used by the solving attempt, over solved episodes only."""
    solved = [e.steps_to_solve for e in eps if e.steps_to_solve is not None]
    return mean(solved) if solved else None


def auccess(eps: Sequence[Episode], n_tasks: int | None = None, max_k: int = 100) -> float:
    """PHYRE's AUCCESS: sum_k w_k s_k / sum_k w_k, w_k = log(k+1) - log(k), k = 1..100,
    with s_k counting valid attempts only. With at most K attempts recorded, s_k stays at
    s_K for k > K, so this is a lower bound on the original 100-attempt figure."""
    weights = [math.log(k + 1) - math.log(k) for k in range(1, max_k + 1)]
    n = n_tasks if n_tasks is not None else len(eps)
    if not n:
        return 0.0
    solved = sorted(e.valid_attempts_to_solve for e in eps if e.valid_attempts_to_solve is not None)
    total, i = 0.0, 0
    for k, w in enumerate(weights, 1):
        while i < len(solved) and solved[i] <= k:
            i += 1
        total += w * i / n
    return total / sum(weights)


@dataclass
class StarFigures:
    total: int
    mean_all: float  # over all tasks (unfinished count 0)
    mean_completed: float | None  # over solved tasks
    levels_with: dict[int, int]  # stars (0-3) -> number of solved tasks with exactly that many


def stars(eps: Sequence[Episode], n_tasks: int | None = None) -> StarFigures:
    n = n_tasks if n_tasks is not None else len(eps)
    got = [e.stars or 0 for e in eps]
    completed = [e.stars or 0 for e in eps if e.solved]
    return StarFigures(
        total=sum(got),
        mean_all=sum(got) / n if n else 0.0,
        mean_completed=mean(completed) if completed else None,
        levels_with={s: sum(1 for c in completed if c == s) for s in (0, 1, 2, 3)},
    )


@dataclass
class PredictionScores:
    """WM predicted outcomes against what happened. Each decision with a stated outcome is
    scored against its attempt's result; a decision without one is counted as unstated."""

    decisions: int  # decisions made
    stated: int  # decisions with a stated outcome
    accuracy: float | None  # share of stated outcomes that came true
    predicted_success_failed: float | None  # of the "success" predictions, the share whose attempt failed
    confusion: dict[str, dict[str, int]]  # predicted -> actual -> decisions


def prediction_scores(records: Iterable[AttemptRecord]) -> PredictionScores:
    outcomes = ("success", "failure")
    confusion = {p: {a: 0 for a in outcomes} for p in outcomes}
    decisions = 0
    for r in records:
        actual = "success" if r.success else "failure"
        for s in r.steps:
            decisions += 1
            if s.predicted_outcome in confusion:
                confusion[s.predicted_outcome][actual] += 1
    stated = sum(sum(row.values()) for row in confusion.values())
    said_success = sum(confusion["success"].values())
    return PredictionScores(
        decisions=decisions,
        stated=stated,
        accuracy=(confusion["success"]["success"] + confusion["failure"]["failure"]) / stated if stated else None,
        predicted_success_failed=confusion["success"]["failure"] / said_success if said_success else None,
        confusion=confusion,
    )


@dataclass
class MeanStd:
    mean: float | None
    std: float | None
    values: list[float | None] = field(default_factory=list)

    @classmethod
    def of(cls, values: Sequence[float | None]) -> "MeanStd":
        present = [v for v in values if v is not None]
        if not present:
            return cls(None, None, list(values))
        return cls(mean(present), stdev(present) if len(present) > 1 else 0.0, list(values))
