"""The attempt protocol: what one attempt of one task is, and what the model is shown.

One attempt, readable in one place (`run_attempt`):
    observation -> prompt -> model -> parse -> step -> ... -> AttemptRecord
An in-advance environment takes one decision per attempt (the whole plan); an on-the-fly
one takes decisions until the environment says the attempt is over (terminated or
truncated, at its spec's `max_steps` at the latest). Text that does not parse is recorded
as an invalid action; it ends the attempt, failed.

The history policy lives here too: before each attempt the model sees its failed
attempts (actions, outcome in words, key frames: every frame of an in-advance attempt,
the final scene of an on-the-fly one), and within an attempt its earlier decisions.
Everything an attempt depends on is rebuilt from the stored records of earlier attempts,
so a resumed run makes exactly the decisions an uninterrupted one would have.

Ray-free: the environment and the model are reached through small async handles
(`EnvHandle`, `ModelHandle`), so the scheduler runs this over Ray actors and the tests
and benchmarks run the very same code in-process (`LocalEnv`, `MemoryArtifacts`).
"""

from __future__ import annotations

import time
from typing import Callable, Protocol, Sequence

from deepphy.chat import Image, Message
from deepphy.config import RunConfig
from deepphy.envs import Action, EnvSpec, Environment, InvalidAction, Observation, Planning, StepResult, Task
from deepphy.envs.parsing import cut_reply
from deepphy.models.base import ModelRequest, ModelResponse, RequestContext
from deepphy.prompts import (
    EnvPrompt, PastAttempt, PastStep, build_messages, prompt_as_json, prompt_digest, split_reply,
)
from deepphy.runs.records import AttemptRecord, KeyFrame, ModelStats, StepRecord, Timing, episode_finished


class EnvHandle(Protocol):
    """One live environment instance, for the duration of one attempt."""

    async def reset(self, task: Task) -> Observation: ...

    async def step(self, action: Action) -> StepResult: ...


class ModelHandle(Protocol):
    async def complete(self, request: ModelRequest) -> ModelResponse: ...


class Artifacts(Protocol):
    """Where an attempt's prompts and key frames go (the run store, or memory)."""

    def write_prompt(self, task: str, run: int, digest: str, messages: list[Message]) -> None:
        """The prompt, once per episode (task, run), and every image in it, once
        (content-addressed)."""
        ...

    def write_frame(self, task: str, run: int, attempt: int, name: str, png: bytes) -> str: ...

    def frame_image(self, rel: str, caption: str) -> Image:
        """A stored key frame as a prompt image (the run store names the file rather than
        holding its bytes)."""
        ...


async def run_attempt(
    spec: EnvSpec,
    prompt: EnvPrompt,
    config: RunConfig,
    task: Task,
    run: int,
    attempt: int,
    previous: Sequence[AttemptRecord],
    env: EnvHandle,
    model: ModelHandle,
    artifacts: Artifacts,
) -> AttemptRecord:
    """Run attempt `attempt` (1-based) of `task` in repetition `run`, after the failed
    attempts `previous`, and return its record. Errors of the handles propagate."""
    history = [_shown(r, spec, artifacts) for r in previous]
    tried = tried_actions(previous)
    timing = Timing(started=time.time())
    stats = ModelStats()
    steps: list[StepRecord] = []
    recent: list[PastStep] = []
    frames: list[KeyFrame] = []
    result: StepResult | None = None
    invalid_reason: str | None = None

    t0 = time.perf_counter()
    observation = await env.reset(task)
    timing.env_s += time.perf_counter() - t0
    for step in range(1, spec.max_steps + 1):
        messages = build_messages(prompt, config.format, task, observation, history, recent)
        digest = prompt_digest(messages)
        artifacts.write_prompt(task.id, run, digest, messages)
        request = ModelRequest(
            messages=messages,
            temperature=config.temperature,
            max_tokens=config.max_tokens,
            context=RequestContext(
                env=config.env, env_options=config.env_options, task_id=task.id, run=run, attempt=attempt, step=step,
                seed=config.seed,
                format=config.format, action_space=observation.action_space.model_dump(mode="json"), tried=tried,
                earlier=[p.action for p in recent],
            ),
        )
        t0 = time.perf_counter()
        response = await model.complete(request)
        seconds = response.seconds if response.seconds is not None else time.perf_counter() - t0
        timing.model_s += seconds
        timing.decision_s.append(round(seconds, 3))
        stats.usage = stats.usage + response.usage
        stats.retries += response.retries
        stats.images_dropped += response.images_dropped

        reply, cut = cut_reply(response.text)
        parts = split_reply(config.format, reply)
        said = dict(prompt=digest, raw_output=reply, reply_cut=cut, prediction=parts.prediction,
                    predicted_outcome=parts.outcome)
        try:
            action = observation.action_space.parse(parts.action_text)
        except InvalidAction as e:
            invalid_reason = f"unparseable action: {e}"
            steps.append(StepRecord(step=step, **said, invalid_reason=invalid_reason, terminated=True))
            break
        canonical = observation.action_space.format(action)
        t0 = time.perf_counter()
        result = await env.step(action)
        timing.env_s += time.perf_counter() - t0
        for frame in result.key_frames:
            rel = artifacts.write_frame(task.id, run, attempt, f"s{step}_{frame.name}", frame.png)
            frames.append(KeyFrame(path=rel, caption=f"step {step}, {frame.caption}"))
        steps.append(StepRecord(
            step=step, **said, action=action.model_dump(mode="json"), action_text=canonical, invalid_reason=result.invalid_reason,
            feedback=result.feedback, info=result.info, terminated=result.terminated, truncated=result.truncated,
        ))
        if result.invalid_reason:
            invalid_reason = result.invalid_reason
        if result.done or result.observation is None:
            break
        # The scene the agent saw at this decision; the newest scene is the observation itself.
        recent.append(PastStep(step=step, action=canonical, feedback=result.feedback, frame=observation.images[0]))
        observation = result.observation

    timing.finished = time.time()
    success = bool(result and result.success and not invalid_reason)
    # An environment truncates at max_steps; should one not, the protocol's bound still holds.
    truncated = invalid_reason is None and result is not None and (result.truncated or not result.done)
    return AttemptRecord(
        env=config.env, task=task.id, group=task.group, run=run, attempt=attempt, model=config.model,
        format=config.format.value, seed=config.seed, steps=steps, success=success, invalid_reason=invalid_reason,
        truncated=truncated, stars=result.stars if result else None, score=result.score if result else None,
        key_frames=frames, feedback=outcome_words(success, invalid_reason, result, len(steps)),
        timing=timing, model_stats=stats,
    )


async def run_episode(
    spec: EnvSpec,
    prompt: EnvPrompt,
    config: RunConfig,
    task: Task,
    run: int,
    k_max: int,
    env: EnvHandle,
    model: ModelHandle,
    artifacts: Artifacts,
    on_record: Callable[[AttemptRecord], None] | None = None,
) -> list[AttemptRecord]:
    """Every attempt of one episode (`task`, repetition `run`), one after another in this
    process, until it is finished (solved, or `k_max` attempts): the plain loop that tests,
    benchmarks and estimates run (the scheduler adds placement and retries around
    `run_attempt`). `on_record` sees each record as it is made (e.g. a store's `append`)."""
    records: list[AttemptRecord] = []
    while not episode_finished(records, k_max):
        record = await run_attempt(spec, prompt, config, task, run, len(records) + 1, records, env, model, artifacts)
        if on_record is not None:
            on_record(record)
        records.append(record)
    return records


# -- the history policy ------------------------------------------------------------------


def tried_actions(previous: Sequence[AttemptRecord]) -> list[str]:
    """The actions of earlier attempts, in canonical syntax (MOCK avoids repeating them)."""
    return [s.action_text for r in previous for s in r.steps if s.action_text is not None]


# Each failed attempt as the model sees it, made once and shown again by the episode's later
# attempts (with its prompt parts, `PastAttempt.parts`): rebuilt for every new attempt, the
# history's cost grows with the episode (a PHYRE episode of 10 attempts: the prompt's history,
# messages, digest and JSON 126-200 -> 75-88 us per attempt). Keyed by the record's identity
# and checked against it (the entry holds the record, so its id is not reused while the entry
# lives); bounded, so a long run's memory stays flat. A resumed run's records are new
# objects: made again, the same from the same record.
_SHOWN: dict[int, tuple[AttemptRecord, EnvSpec, Artifacts, PastAttempt]] = {}
SHOWN_REMEMBERED = 4096


def _shown(record: AttemptRecord, spec: EnvSpec, artifacts: Artifacts) -> PastAttempt:
    entry = _SHOWN.get(id(record))
    if entry is not None and entry[0] is record and entry[1] is spec and entry[2] is artifacts:
        return entry[3]
    if len(_SHOWN) >= SHOWN_REMEMBERED:
        _SHOWN.clear()
    past = past_attempt(record, spec, artifacts)
    _SHOWN[id(record)] = (record, spec, artifacts, past)
    return past


def past_attempt(record: AttemptRecord, spec: EnvSpec, artifacts: Artifacts) -> PastAttempt:
    """A failed attempt as the model sees it before its next attempt."""
    actions = [
        s.action_text if s.action_text is not None else f"(invalid) {s.raw_output.strip()[:200]}"
        for s in record.steps
    ]
    frames = [artifacts.frame_image(f.path, f.caption) for f in record.key_frames]
    if spec.planning is Planning.ON_THE_FLY:
        frames = frames[-1:]  # the final state; the decisions are listed as text
    return PastAttempt(attempt=record.attempt, actions=actions, outcome=record.feedback, key_frames=frames)


def outcome_words(success: bool, invalid: str | None, result: StepResult | None, decisions: int) -> str:
    """The attempt's outcome in words, as later prompts show it."""
    if invalid:
        return f"invalid attempt ({invalid})"
    words = result.feedback if result else ""
    if success:
        return f"solved. {words}".strip()
    if result is not None and not result.done:
        words = f"{words}; the attempt ran out of decisions ({decisions})".lstrip("; ")
    return f"failed. {words}".strip()


# -- in-process handles --------------------------------------------------------------------


class LocalEnv:
    """An `EnvHandle` over an environment instance in this process."""

    def __init__(self, env: Environment) -> None:
        self.env = env

    async def reset(self, task: Task) -> Observation:
        return self.env.reset(task)

    async def step(self, action: Action) -> StepResult:
        return self.env.step(action)


class MemoryArtifacts:
    """`Artifacts` kept in memory: for runs that need no run directory (tests, benchmarks)."""

    def __init__(self) -> None:
        self.prompts: dict[str, str] = {}
        self.images: dict[str, bytes] = {}  # by Image.digest
        self.frames: dict[str, bytes] = {}

    def write_prompt(self, task: str, run: int, digest: str, messages: list[Message]) -> None:
        if digest not in self.prompts:  # by content alone: nothing reads them back by episode
            for image in (image for m in messages for image in m.images):
                if image.digest not in self.images:
                    self.images[image.digest] = image.load()
            self.prompts[digest] = prompt_as_json(messages)

    def write_frame(self, task: str, run: int, attempt: int, name: str, png: bytes) -> str:
        rel = f"frames/{task}/r{run}_a{attempt}_{name}.png"
        self.frames[rel] = png
        return rel

    def frame_image(self, rel: str, caption: str) -> Image:
        return Image(name=rel.rsplit("/", 1)[-1], caption=caption, png=self.frames[rel])
