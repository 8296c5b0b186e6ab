"""The asyncio scheduler: keeps many episodes in flight across environment and model actors.

An episode is one (task, run). Its attempts are sequential (each sees the history of the
failed ones); episodes are independent, so up to `max_in_flight` of them progress at once.
Data flows one way per decision:
    env worker (observation) -> prompt -> model worker (text) -> parsed action
    -> env worker (step) -> ... -> attempt record -> run store + metrics actor.

Everything an attempt depends on is derived from the run store's records (history,
previously tried actions), never from in-memory state, so a resumed run makes exactly
the decisions an uninterrupted one would have.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, Sequence

import ray
from ray.exceptions import ActorDiedError, ActorUnavailableError, RayActorError

from deepphy.actors.env_worker import LostEpisode
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.envs import Environment, Image, InvalidAction, Observation, Planning, StepResult, Task
from deepphy.models import ModelError, ModelRequest, RequestContext
from deepphy.prompts import PastAttempt, PastStep, build_messages, get_prompt, split_reply
from deepphy.prompts.base import prompt_as_json, prompt_digest
from deepphy.runs.records import AttemptRecord, KeyFrame, ModelStats, StepRecord, Timing
from deepphy.runs.store import RunStore

log = logging.getLogger(__name__)

WORKER_LOST = (LostEpisode, ActorDiedError, ActorUnavailableError, RayActorError)


class WorkerLost(RuntimeError):
    """An environment worker died or was restarted during an attempt."""


class ModelUnavailable(RuntimeError):
    """A model request failed for good (after the client's own retries)."""

    def __init__(self, message: str, retries: int = 0) -> None:
        super().__init__(message)
        self.retries = retries  # transport retries the failed request spent


class BudgetExhausted(RuntimeError):
    """The run's cost budget (--max-cost) is spent; the attempt is left for a resume."""


@dataclass
class EpisodeState:
    """What the store already holds for one (task, run)."""

    records: list[AttemptRecord] = field(default_factory=list)

    def finished(self, k_max: int) -> bool:
        return any(r.success for r in self.records) or len(self.records) >= k_max


class Scheduler:
    def __init__(
        self,
        config: RunConfig,
        runtime: RuntimeOptions,
        env_cls: type[Environment],
        tasks: Sequence[Task],
        store: RunStore,
        env_workers: list[Any],
        model_worker: Any,
        metrics: Any,
        k_max: int,
        max_model_requeues: int = 5,
    ) -> None:
        self.config = config
        self.runtime = runtime
        self.env_cls = env_cls
        self.tasks = list(tasks)
        self.store = store
        self.env_workers = env_workers
        self.load = [0] * len(env_workers)  # live episodes per worker
        self.model_worker = model_worker
        self.metrics = metrics
        self.k_max = k_max
        self.max_model_requeues = max_model_requeues
        self.prompt = get_prompt(config.env)
        self.failed: list[str] = []  # episodes abandoned (model or worker failures), for the caller
        self.stop_requested = False
        self.spent_usd = 0.0  # model cost of the run so far (stored records + requests of this session)
        self.budget_hit = False

    # -- top level --------------------------------------------------------------------

    async def run(self, existing: Sequence[AttemptRecord]) -> None:
        state: dict[tuple[str, int], EpisodeState] = defaultdict(EpisodeState)
        for r in existing:
            state[(r.task, r.run)].records.append(r)
        todo = [
            (task, run)
            for run in range(self.config.runs)
            for task in self.tasks
            if not state[(task.id, run)].finished(self.k_max)
        ]
        gate = asyncio.Semaphore(self.runtime.max_in_flight)
        self._charge(sum(r.model_stats.usage.cost_usd for r in existing))

        async def guarded(task: Task, run: int) -> None:
            async with gate:
                if self.stop_requested:
                    return
                try:
                    await self._episode(task, run, state[(task.id, run)])
                except (ModelUnavailable, WorkerLost, BudgetExhausted) as e:
                    self.failed.append(f"{task.id} run {run}: {e}")
                    log.warning("episode %s run %d left unfinished: %s", task.id, run, e)

        await asyncio.gather(*(guarded(t, r) for t, r in todo))

    async def _episode(self, task: Task, run: int, state: EpisodeState) -> None:
        while not state.finished(self.k_max) and not self.stop_requested:
            attempt = len(state.records) + 1
            record = await self._attempt_with_retries(task, run, attempt, state.records)
            self.store.append(record)
            state.records.append(record)
            self.metrics.add.remote([record])

    async def _attempt_with_retries(
        self, task: Task, run: int, attempt: int, previous: list[AttemptRecord]
    ) -> AttemptRecord:
        """Run one attempt; re-run it from the start if its worker died or the model failed."""
        lost = model_errors = failed_retries = 0
        while True:
            try:
                record = await self._attempt(task, run, attempt, previous)
            except WorkerLost as e:
                lost += 1
                if lost > self.runtime.attempt_retries:
                    raise
                log.warning("attempt %s/%d/%d lost its worker (%s); re-running it", task.id, run, attempt, e)
                continue
            except ModelUnavailable as e:
                model_errors += 1
                failed_retries += e.retries
                if model_errors > self.max_model_requeues:
                    raise
                log.warning("attempt %s/%d/%d: model error (%s); re-queued", task.id, run, attempt, e)
                await asyncio.sleep(min(60.0, 2.0**model_errors))
                continue
            record.model_stats.model_errors += model_errors
            record.model_stats.retries += failed_retries
            return record

    # -- one attempt ------------------------------------------------------------------

    async def _attempt(self, task: Task, run: int, attempt: int, previous: list[AttemptRecord]) -> AttemptRecord:
        cfg = self.config
        history = [self._past_attempt(r) for r in previous]
        tried = [s.action_text for r in previous for s in r.steps if s.action_text is not None]
        worker_index = min(range(len(self.env_workers)), key=lambda i: self.load[i])
        worker = self.env_workers[worker_index]
        episode = f"{task.id}|{run}|{attempt}|{time.monotonic_ns()}"
        self.load[worker_index] += 1
        timing = Timing(started=time.time())
        stats = ModelStats()
        steps: list[StepRecord] = []
        recent: list[PastStep] = []
        frames: list[KeyFrame] = []
        result: StepResult | None = None
        invalid_reason: str | None = None
        try:
            t0 = time.perf_counter()
            observation: Observation = await self._env_call(worker.reset.remote(episode, task))
            timing.env_s += time.perf_counter() - t0
            for step in range(1, self.env_cls.max_steps + 1):
                messages = build_messages(self.prompt, cfg.format, task, observation, history, recent)
                digest = prompt_digest(messages)
                self.store.write_prompt(digest, prompt_as_json(messages))
                request = ModelRequest(
                    messages=messages,
                    temperature=cfg.temperature,
                    max_tokens=cfg.max_tokens,
                    context=RequestContext(
                        env=cfg.env, task_id=task.id, run=run, attempt=attempt, step=step, seed=cfg.seed,
                        format=cfg.format, action_space=observation.action_space.model_dump(mode="json"),
                        tried=tried,
                    ),
                )
                if self.budget_hit:  # abandon the attempt unrecorded: a resume re-runs it
                    raise BudgetExhausted(
                        f"cost budget ${self.runtime.max_cost_usd:g} reached (${self.spent_usd:.4f} spent)"
                    )
                t0 = time.perf_counter()
                response = await self._model_call(request)
                timing.model_s += time.perf_counter() - t0
                self._charge(response.usage.cost_usd)
                stats.usage = stats.usage + response.usage
                stats.retries += response.retries
                stats.images_dropped += response.images_dropped
                prediction, action_text = split_reply(cfg.format, response.text)
                try:
                    action = observation.action_space.parse(action_text)
                except InvalidAction as e:
                    invalid_reason = f"unparseable action: {e}"
                    steps.append(StepRecord(step=step, prompt=digest, raw_output=response.text,
                                            prediction=prediction, invalid_reason=invalid_reason))
                    break
                canonical = observation.action_space.format(action)
                t0 = time.perf_counter()
                result = await self._env_call(worker.step.remote(episode, action))
                timing.env_s += time.perf_counter() - t0
                for frame in result.key_frames:
                    rel = self.store.write_frame(task.id, run, attempt, f"s{step}_{frame.name}", frame.png)
                    frames.append(KeyFrame(path=rel, caption=f"step {step}, {frame.caption}"))
                steps.append(StepRecord(
                    step=step, prompt=digest, raw_output=response.text, prediction=prediction,
                    action=action.model_dump(mode="json"), action_text=canonical,
                    invalid_reason=result.invalid_reason, feedback=result.feedback, info=result.info,
                ))
                if result.invalid_reason:
                    invalid_reason = result.invalid_reason
                if result.done or result.observation is None:
                    break
                # The scene the agent saw at this decision; the newest scene is the observation itself.
                recent.append(PastStep(step=step, action=canonical, feedback=result.feedback,
                                       frame=observation.images[0]))
                observation = result.observation
        finally:
            self.load[worker_index] -= 1
            try:
                worker.release.remote(episode)
            except Exception:  # noqa: BLE001 - a dead worker holds nothing to release
                pass
        timing.finished = time.time()
        success = bool(result and result.success and not invalid_reason)
        return AttemptRecord(
            env=cfg.env, task=task.id, group=task.group, run=run, attempt=attempt, model=cfg.model,
            format=cfg.format.value, seed=cfg.seed, steps=steps, success=success,
            invalid_reason=invalid_reason,
            stars=result.stars if result else None, score=result.score if result else None,
            key_frames=frames, feedback=self._outcome_words(success, invalid_reason, result, steps),
            timing=timing, model_stats=stats,
        )

    async def _env_call(self, ref: Any) -> Any:
        try:
            return await asyncio.wait_for(ref, timeout=self.runtime.step_timeout_s)
        except WORKER_LOST as e:
            raise WorkerLost(type(e).__name__) from e
        except asyncio.TimeoutError:
            ray.cancel(ref, force=False)
            raise WorkerLost(f"no answer within {self.runtime.step_timeout_s:g} s") from None

    async def _model_call(self, request: ModelRequest):
        ref = self.model_worker.complete.remote(request)
        try:
            return await asyncio.wait_for(ref, timeout=self.runtime.model_timeout_s)
        except ModelError as e:
            raise ModelUnavailable(str(e), retries=getattr(e, "retries", 0)) from e
        except (asyncio.TimeoutError, RayActorError) as e:
            raise ModelUnavailable(f"model worker: {type(e).__name__}") from e

    def _charge(self, cost_usd: float) -> None:
        self.spent_usd += cost_usd
        limit = self.runtime.max_cost_usd
        if limit is not None and self.spent_usd >= limit and not self.budget_hit:
            self.budget_hit = True
            self.stop_requested = True
            self.failed.append(f"cost budget ${limit:g} reached (${self.spent_usd:.4f} spent); raise --max-cost to continue")
            log.warning("cost budget $%g reached ($%.4f spent): stopping; raise --max-cost and resume", limit, self.spent_usd)

    # -- history ----------------------------------------------------------------------

    def _past_attempt(self, r: AttemptRecord) -> PastAttempt:
        actions = [s.action_text if s.action_text is not None else f"(invalid) {s.raw_output.strip()[:200]}" for s in r.steps]
        frames = [
            Image(name=f.path.rsplit("/", 1)[-1], caption=f.caption, png=self.store.read_frame(f.path))
            for f in r.key_frames
        ]
        if self.env_cls.planning is Planning.ON_THE_FLY:
            frames = frames[-1:]  # the final state; the decisions are listed as text
        return PastAttempt(attempt=r.attempt, actions=actions, outcome=r.feedback, key_frames=frames)

    @staticmethod
    def _outcome_words(success: bool, invalid: str | None, result: StepResult | None, steps: list[StepRecord]) -> str:
        if invalid:
            return f"invalid attempt ({invalid})"
        words = result.feedback if result else ""
        if success:
            return f"solved. {words}".strip()
        if result is not None and not result.done:
            words = f"{words}; the attempt ran out of decisions ({len(steps)})".lstrip("; ")
        return f"failed. {words}".strip()
