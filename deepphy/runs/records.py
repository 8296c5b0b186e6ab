"""Attempt records: one per (task, run, attempt), the unit the run store keeps and metrics read.

Every number of a record is bounded, far beyond what deepphy writes and within what its
readers hold (a 32-bit column for counts, 64 bits for tokens and the seed): a record outside
the bounds is not one of ours, and every reader refuses it with its line (`deepphy repair`
sets it aside) instead of overflowing or ignoring it.

    run        0 .. RUNS_MAX - 1 (100,000 repetitions)    attempt   1 .. ATTEMPTS_MAX (1,000)
    step       1 .. STEPS_MAX (10,000 decisions)          stars     0 .. STARS_MAX (3)
    seed       a 64-bit integer                           tokens    0 .. TOKENS_MAX (10**12) each, per attempt
    cost_usd   0 or more, finite                          counts    0 .. COUNT_MAX (2**31 - 1): reply_cut,
                                                                     retries, model_errors, images_dropped
"""

from __future__ import annotations

import math
from typing import Any, Sequence

from pydantic import BaseModel, Field, TypeAdapter, field_validator

from deepphy.chat import Usage
from deepphy.config import ATTEMPTS_MAX, RUNS_MAX, SEED_MAX, SEED_MIN
from deepphy.envs.base import SAFE_ID

STEPS_MAX = 10_000  # decisions of one attempt (the environments take 15 at most)
STARS_MAX = 3  # the games' three stars
TOKENS_MAX = 10**12  # input (or output) tokens of one attempt
COUNT_MAX = 2**31 - 1  # any other count

# A record names files of its run directory; these patterns keep it to its own kinds of file
# (the store also resolves every path it reads inside the directory: symlinks cannot lead out).
DIGEST = r"^[0-9a-f]{8,64}$"  # prompt_digest: a line of prompts/<task>/r<run>.jsonl
FRAME = r"^frames/" + SAFE_ID.pattern[1:-1] + r"/[A-Za-z0-9][A-Za-z0-9._-]{0,200}\.png$"  # frames/<task>/<file>.png


class StepRecord(BaseModel):
    """One decision: what was asked, what came back, what it did."""

    step: int = Field(ge=1, le=STEPS_MAX)
    prompt: str = Field(pattern=DIGEST)  # digest of the prompt; its text is in the episode's prompt log
    raw_output: str  # the reply, cut to its last MAX_REPLY_CHARS characters (deepphy/envs/parsing.py)
    reply_cut: int = Field(0, ge=0, le=COUNT_MAX)  # characters cut from the start of an over-long reply
    prediction: str | None = None  # WM format only
    predicted_outcome: str | None = None  # WM: "success" | "failure" as stated; None if not stated
    action: dict[str, Any] | None = None  # the parsed action; None if invalid
    action_text: str | None = None  # the action in canonical syntax
    invalid_reason: str | None = None
    feedback: str = ""
    info: dict[str, Any] = Field(default_factory=dict)
    terminated: bool = False  # the environment's facts after this decision (see StepResult)
    truncated: bool = False


class KeyFrame(BaseModel):
    path: str = Field(pattern=FRAME)  # relative to the run directory
    caption: str


class Timing(BaseModel):
    """Wall-clock facts; the only part of a record that differs between identical runs."""

    started: float = 0.0  # unix time
    finished: float = 0.0
    env_s: float = 0.0
    model_s: float = 0.0
    decision_s: list[float] = Field(default_factory=list)  # per decision: the time the agent took to answer


class ModelStats(BaseModel):
    """Provider-side facts; with a real model these vary between identical runs."""

    usage: Usage = Field(default_factory=Usage)
    retries: int = Field(0, ge=0, le=COUNT_MAX)  # transport retries, those of requests that failed for good included
    model_errors: int = Field(0, ge=0, le=COUNT_MAX)  # requests that failed for good; each re-queued the attempt
    images_dropped: int = Field(0, ge=0, le=COUNT_MAX)  # oldest images left out of requests to meet the provider's image limit

    @field_validator("usage")
    @classmethod
    def _bounded(cls, usage: Usage) -> Usage:
        """An attempt's usage within the record's bounds (`Usage` itself also carries a
        provider's answer and a run's totals)."""
        for name in ("input_tokens", "output_tokens"):
            if not 0 <= getattr(usage, name) <= TOKENS_MAX:
                raise ValueError(f"{name} must be 0..{TOKENS_MAX:,}, got {getattr(usage, name)}"[:120])
        if not (math.isfinite(usage.cost_usd) and usage.cost_usd >= 0):
            raise ValueError(f"cost_usd must be a finite amount of 0 or more, got {usage.cost_usd}")
        return usage


class AttemptRecord(BaseModel):
    env: str
    task: str = Field(pattern=SAFE_ID.pattern)
    group: str = ""
    run: int = Field(ge=0, lt=RUNS_MAX)
    attempt: int = Field(ge=1, le=ATTEMPTS_MAX)  # 1-based
    model: str
    format: str
    seed: int = Field(ge=SEED_MIN, le=SEED_MAX)
    steps: list[StepRecord]
    success: bool
    invalid_reason: str | None = None  # set when the attempt ended on an invalid action
    truncated: bool = False  # the attempt ran out of time or decisions (the environment says so)
    stars: int | None = Field(None, ge=0, le=STARS_MAX)
    score: float | None = None
    key_frames: list[KeyFrame] = Field(default_factory=list)
    feedback: str = ""  # outcome in words, shown as history in later attempts
    timing: Timing = Field(default_factory=Timing)
    model_stats: ModelStats = Field(default_factory=ModelStats)

    @property
    def key(self) -> tuple[str, int, int]:
        return self.task, self.run, self.attempt

    @property
    def invalid(self) -> bool:
        return self.invalid_reason is not None

    @property
    def decisions(self) -> int:
        return len(self.steps)

    def summary(self) -> "AttemptSummary":
        return AttemptSummary(
            task=self.task, group=self.group, run=self.run, attempt=self.attempt, success=self.success,
            invalid=self.invalid, decisions=self.decisions, stars=self.stars, truncated=self.truncated,
            model_stats=self.model_stats,
        )

    def deterministic_view(self) -> dict[str, Any]:
        """The record without wall-clock and provider facts: equal for equal seeds."""
        return self.model_dump(exclude={"timing", "model_stats"})


class AttemptSummary(BaseModel):
    """What the metrics need of an attempt; small, so live views get one per attempt cheaply.
    Field names match AttemptRecord's, so the figures take either."""

    task: str
    group: str = ""
    run: int
    attempt: int
    success: bool
    invalid: bool
    decisions: int
    stars: int | None = None
    truncated: bool = False
    model_stats: ModelStats = Field(default_factory=ModelStats)


# Summaries cross to the metrics actor as one JSON document per batch: Ray pickles a list of
# pydantic models object by object (6 us a summary to pickle, 10 to unpickle), the JSON in
# under 1 us a summary, and the actor validates it back in 3.
_SUMMARIES = TypeAdapter(list[AttemptSummary])


def summaries_json(summaries: Sequence[AttemptSummary]) -> bytes:
    return _SUMMARIES.dump_json(list(summaries))


def summaries_from_json(data: bytes) -> list[AttemptSummary]:
    return _SUMMARIES.validate_json(data)


def episode_finished(attempts: Sequence[AttemptRecord | AttemptSummary], max_attempts: int) -> bool:
    """An episode (task, run) is finished once an attempt succeeded or K attempts are used.
    The one definition: the scheduler, the metrics actor and the report all use it."""
    return any(r.success for r in attempts) or len(attempts) >= max_attempts
