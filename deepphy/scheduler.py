"""The asyncio scheduler: keeps many episodes in flight across environment and model actors.

An episode is one (task, run). Its attempts are sequential (each sees the history of the
failed ones) and each attempt is `deepphy.protocol.run_attempt`; episodes are
independent, so up to `max_in_flight` of them progress at once. The scheduler adds only
what Ray needs: placement (the least-loaded environment worker), retries (an attempt
whose worker died or whose model failed is re-run from its start), isolation (an
attempt that raises anything else is logged to the run directory and its episode left
for a resume; the other episodes go on) and the cost budget.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import logging
import sys
import time
import traceback
from collections import defaultdict
from contextlib import contextmanager
from typing import Any, Iterator, Sequence

from deepphy.actors.env_worker import LostEpisode
from deepphy.agent import AgentFailed, Episode
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.envs import Action, Observation, StepResult, Task
from deepphy.envs.base import ObservationCache
from deepphy.models import AccessDenied, ModelError, ModelRequest, ModelResponse, RequestRejected
from deepphy.plan import RunPlan
from deepphy.protocol import ModelHandle, run_attempt
from deepphy.runs.records import AttemptRecord, AttemptSummary, episode_finished, summaries_json
from deepphy.runs.store import RunStore, RunWriteError

log = logging.getLogger(__name__)

# Failures no retry can mend, that end the whole run at once (raised by `Scheduler.run`).
FATAL = (RunWriteError, AccessDenied, RequestRejected, AgentFailed)
# Re-runs of an attempt whose model request failed for good (after the client's own retries,
# within its deadline: deepphy.models.config.Timeouts): a dead endpoint holds an episode for
# 3 requests' deadlines, minutes, and the progress line says what they are waiting for.
MODEL_REQUEUES = 2
# Calls on their way per environment worker: the worker runs one call while the next waits
# in its queue, so it never idles for a round trip. A call carries as many of the decisions
# waiting for that worker as take it about `CALL_S` at the pace of its last call, at most
# `BATCH_MAX` (the first call: one). A Ray call costs the driver and the worker about a
# millisecond each, so cheap decisions go many a call (PHYRE, ~5 ms each: 32; measured with
# benchmarks/cpu_per_attempt.py: ~0.4 ms less CPU per attempt than 8 a call), while a slow
# environment's (Pooltool, ~0.7 s a shot: 1) come back one by one and a run's last calls on
# the two workers end close together.
CALLS_IN_FLIGHT = 2
CALL_S = 0.25  # Ray's ~2 ms a call is then ~1 % of it; results still come back four times a second
BATCH_MAX = 32  # 32 PHYRE decisions are ~0.16 s of work; larger calls were not measured


def ray_errors(*names: str) -> tuple[type[BaseException], ...]:
    """Ray's exception classes of these names once Ray is loaded; none before (a run in
    this process never loads Ray, and no Ray error can reach it)."""
    errors = sys.modules.get("ray.exceptions")
    return tuple(getattr(errors, name) for name in names) if errors is not None else ()


def worker_lost() -> tuple[type[BaseException], ...]:
    """What an environment worker's death looks like to its caller: the actor gone, or the
    answer it gave lost with its node (a call's result too large to travel inside the reply
    waits in the node's object store, and Ray cannot rebuild an actor call's result)."""
    return (LostEpisode, *ray_errors("ActorDiedError", "ActorUnavailableError", "RayActorError", "ObjectLostError"))


def cancel(ref: Any) -> None:
    """Cancel a call that did not answer in time: a Ray task, or an in-process one."""
    if isinstance(ref, asyncio.Future):
        ref.cancel()
    else:
        import ray  # a Ray call's ref: Ray is loaded (a run in this process has futures only)

        ray.cancel(ref, force=False)


class WorkerLost(RuntimeError):
    """An environment worker died or was restarted during an attempt."""


class ModelUnavailable(RuntimeError):
    """A model request failed for good (after the client's own retries)."""

    def __init__(self, message: str, retries: int = 0) -> None:
        super().__init__(message)
        self.retries = retries  # transport retries the failed request spent


class BudgetExhausted(RuntimeError):
    """The run's cost budget (--max-cost) is spent; the attempt is left for a resume."""


class StepBatcher:
    """The decisions bound for one environment worker, sent as few Ray calls as keep it busy:
    requests made while `CALLS_IN_FLIGHT` calls are already on their way wait, and go out
    together (as many as the worker's pace fits in `CALL_S`) when one comes back.

    Errors stay per episode: the worker answers each request with its result or its own
    error; a call that fails as a whole (the worker died, no answer within `timeout_s`)
    fails each of its requests."""

    def __init__(self, worker: Any, timeout_s: float) -> None:
        self.worker, self.timeout_s = worker, timeout_s
        self.waiting: list[tuple[tuple[str, Action, Task | None], asyncio.Future]] = []
        self.calls = 0  # calls on their way
        self.in_flight: set[asyncio.Task] = set()
        self.size = 1  # decisions the next call takes, at most
        self.last_done = 0.0  # when the last call came back (time.monotonic)

    def step(self, episode: str, action: Action, reset: Task | None) -> asyncio.Future:
        future = asyncio.get_running_loop().create_future()
        self.waiting.append(((episode, action, reset), future))
        if len(self.waiting) == 1:  # the first of this loop turn: send after the turn's other requests
            asyncio.get_running_loop().call_soon(self._send)
        return future

    def _send(self) -> None:
        self.waiting = [w for w in self.waiting if not w[1].done()]  # their attempts were cancelled meanwhile
        while self.waiting and self.calls < CALLS_IN_FLIGHT:
            batch, self.waiting = self.waiting[:self.size], self.waiting[self.size:]
            self.calls += 1
            call = asyncio.ensure_future(self._call(batch))
            self.in_flight.add(call)  # a task the loop holds only weakly
            call.add_done_callback(self.in_flight.discard)

    async def _call(self, batch: list[tuple[tuple[str, Action, Task | None], asyncio.Future]]) -> None:
        sent = time.monotonic()
        ref = self.worker.step_batch.remote([request for request, _ in batch])
        try:
            outcomes = await asyncio.wait_for(ref, timeout=self.timeout_s)
            self._paced(sent, len(batch))
        except worker_lost() as e:
            outcomes = [WorkerLost(type(e).__name__) for _ in batch]
        except asyncio.TimeoutError:
            cancel(ref)
            outcomes = [WorkerLost(f"no answer within {self.timeout_s:g} s") for _ in batch]
        except Exception as e:  # noqa: BLE001 - the call as a whole failed: each of its attempts says so
            outcomes = [e for _ in batch]
        finally:
            self.calls -= 1
            self._send()
        for (_, future), outcome in zip(batch, outcomes):
            if future.done():  # its attempt was cancelled
                continue
            if isinstance(outcome, LostEpisode):
                future.set_exception(WorkerLost(type(outcome).__name__))
            elif isinstance(outcome, BaseException):
                future.set_exception(outcome)
            else:
                future.set_result(outcome)

    def _paced(self, sent: float, decisions: int) -> None:
        """Size the next call from this one's pace. A call sent while the previous one was
        still out waited in the worker's queue and started when that one ended: its time on
        the worker is from then (its round trip would count the wait)."""
        done = time.monotonic()
        per_decision = max(done - max(sent, self.last_done), 1e-6) / decisions
        self.last_done = done
        self.size = max(1, min(BATCH_MAX, int(CALL_S / per_decision)))


class EnvPool:
    """The environment workers of one setting as the runs that use them see them: a
    `StepBatcher` per worker and the attempts each worker holds. A run has one of its own; a
    suite's cells of one setting share one in the suite's event loop, so their decisions
    travel in the same calls and an attempt goes to the worker with the fewest of anyone's."""

    def __init__(self, workers: Sequence[Any], timeout_s: float) -> None:
        self.workers = list(workers)
        self.batchers = [StepBatcher(w, timeout_s) for w in self.workers]
        self.load = [0] * len(self.workers)  # live attempts per worker
        self.attempts = itertools.count()  # an attempt's instance on its worker is named uniquely

    @contextmanager
    def attempt(self, episode: str, initial: FirstObservations) -> Iterator[WorkerEnv]:
        """The least-loaded worker's handle for one attempt, released when it ends."""
        index = min(range(len(self.workers)), key=lambda i: self.load[i])
        env = WorkerEnv(self.batchers[index], f"{episode}|{next(self.attempts)}", initial)
        self.load[index] += 1
        try:
            yield env
        finally:
            self.load[index] -= 1
            env.release()


class FirstObservations:
    """The driver's first observations by task (reset is deterministic: the contract), each
    asked of a worker once. An attempt that starts while its task's is on its way waits for
    that answer instead of asking too: a run starts hundreds of episodes at once, and each
    asking had both workers render every task's first scene before their first step."""

    def __init__(self, size: int) -> None:
        self.cache = ObservationCache(size)
        self.asking: dict[str, asyncio.Event] = {}  # set when that answer came (or failed)

    async def get(self, task: Task) -> Observation | None:
        while (asking := self.asking.get(task.id)) is not None:  # (another waiter may have asked again)
            await asking.wait()  # bounded: the asker's call has the step timeout
        return self.cache.get(task.id)  # None if the asker failed: then this attempt asks

    @contextmanager
    def asking_for(self, task: Task) -> Iterator[None]:
        event = self.asking[task.id] = asyncio.Event()
        try:
            yield
        finally:
            event.set()
            if self.asking.get(task.id) is event:
                del self.asking[task.id]


class WorkerEnv:
    """The protocol's `EnvHandle` over one environment worker, for one attempt: each decision
    goes through the worker's `StepBatcher` (the reset rides with the first step when the
    observation is known; the worker releases the instance when a step ends the attempt)."""

    def __init__(self, batcher: StepBatcher, episode: str, initial: FirstObservations) -> None:
        self.batcher, self.worker, self.episode, self.initial = batcher, batcher.worker, episode, initial
        self.pending_reset: Task | None = None
        self.held = False  # the worker holds an instance for this attempt

    async def reset(self, task: Task) -> Observation:
        known = await self.initial.get(task)
        if known is not None:
            self.pending_reset = task
            return known
        self.held = True
        with self.initial.asking_for(task):
            ref = self.worker.reset.remote(self.episode, task)
            try:
                obs = await asyncio.wait_for(ref, timeout=self.batcher.timeout_s)
            except worker_lost() as e:
                raise WorkerLost(type(e).__name__) from e
            except asyncio.TimeoutError:
                cancel(ref)
                raise WorkerLost(f"no answer within {self.batcher.timeout_s:g} s") from None
            return self.initial.cache.put(task.id, obs)

    async def step(self, action: Action) -> StepResult:
        reset, self.pending_reset = self.pending_reset, None
        self.held = True
        result = await self.batcher.step(self.episode, action, reset)
        self.held = not result.done
        return result

    def release(self) -> None:
        """Free the worker's instance if the attempt ended without a final step."""
        if not self.held:
            return
        try:
            self.worker.release.remote(self.episode)
        except Exception:  # noqa: BLE001 - a dead worker holds nothing to release
            pass


class WorkerModel:
    """The protocol's `ModelHandle` over a model worker actor. Key frames of earlier
    attempts travel as file names (the worker reads them from the run directory) when the
    worker shares the driver's file system, which it does beside the driver; else as bytes."""

    def __init__(self, worker: Any, shares_files: bool = True) -> None:
        self.worker, self.shares_files = worker, shares_files

    async def complete(self, request: ModelRequest) -> ModelResponse:
        if not self.shares_files:
            request = request.with_images_loaded()
        return await self.worker.complete.remote(request)

    async def activity(self) -> dict[str, int]:
        return await self.worker.activity.remote()


class AgentWorkerModel(WorkerModel):
    """A `WorkerModel` over a user's agent, which keeps a state per episode: the worker hears
    when an episode of this run ends, to release it (a call not waited for: an episode's state
    is a cache, so one released a little late is only memory held a little longer)."""

    def __init__(self, worker: Any, shares_files: bool, config: RunConfig) -> None:
        super().__init__(worker, shares_files)
        self.config = config

    def end_episode(self, task: str, run: int) -> None:
        c = self.config
        try:
            self.worker.end_episode.remote(Episode(c.env, json.dumps(c.env_options, sort_keys=True), c.format.value,
                                                   task, run))
        except Exception:  # noqa: BLE001 - a lost worker holds no state
            pass


class LocalAgentModel:
    """A user's agent in this process (`deepphy run --in-process`): its client, told when an
    episode ends to release the episode's state, as a model worker is."""

    def __init__(self, client: Any, config: RunConfig) -> None:
        self.client, self.config = client, config

    async def complete(self, request: ModelRequest) -> ModelResponse:
        return await self.client.complete(request)

    def end_episode(self, task: str, run: int) -> None:
        c = self.config
        self.client.end_episode(Episode(c.env, json.dumps(c.env_options, sort_keys=True), c.format.value, task, run))

    async def activity(self) -> dict[str, int]:
        return await self.client.activity()

    async def close(self) -> None:
        await self.client.close()


class Scheduler:
    def __init__(
        self,
        plan: RunPlan,
        runtime: RuntimeOptions,
        store: RunStore,
        env_workers: EnvPool | Sequence[Any],  # a suite's pool shared by the cells of a setting, or this run's workers
        model: ModelHandle,
        metrics: Any,  # the metrics actor; None: no live figures (`deepphy play`)
        max_model_requeues: int = MODEL_REQUEUES,
        local_env: Any = None,  # a protocol.EnvHandle
    ) -> None:
        self.plan = plan
        self.config = plan.config
        self.runtime = runtime
        self.spec = plan.spec
        self.prompt = plan.prompt()
        self.tasks = list(plan.tasks)
        self.store = store
        self.pool = env_workers if isinstance(env_workers, EnvPool) else EnvPool(env_workers, runtime.step_timeout_s)
        self.model = model
        self.answers_at_once = getattr(model, "answers_at_once", False)
        self.metrics = metrics
        self.k_max = plan.k_max
        self.max_model_requeues = max_model_requeues
        self.local_env = local_env  # `deepphy play`: one environment in this process instead of the workers
        self.failed: list[str] = []  # episodes left unfinished (model or worker failures, budget), for the caller
        self.errored: list[str] = []  # episodes whose attempt raised an unexpected error
        self.stop_requested = False
        self.fatal: BaseException | None = None  # the first FATAL error: the run stops and raises it
        self.spent_usd = 0.0  # model cost of the run so far (stored records + requests of this session)
        self.budget_hit = False
        self.in_flight = 0
        self.decisions = 0  # model requests answered in this session
        self.recorded = 0  # attempt records this session wrote to the run directory
        self.episodes_finished = 0  # episodes this session brought to their end (solved, or out of attempts)
        self.initial = FirstObservations(256)  # an attempt's reset rides with its first step
        self.unsent: list[AttemptSummary] = []  # for the metrics actor, sent in batches (flush)

    # -- top level --------------------------------------------------------------------

    async def run(self, existing: Sequence[AttemptRecord]) -> None:
        """Every unfinished episode, at most `max_in_flight` at once. Memory stays flat: a
        fixed pool of episode loops, and an episode's records are dropped when it ends."""
        self._charge(sum(r.model_stats.usage.cost_usd for r in existing))
        records: dict[tuple[str, int], list[AttemptRecord]] = defaultdict(list)
        for r in existing:
            records[(r.task, r.run)].append(r)
        todo = [
            (task, run)
            for run in range(self.config.runs)
            for task in self.tasks
            if not episode_finished(records.get((task.id, run), []), self.k_max)
        ]
        records = defaultdict(list, {(t.id, r): records[(t.id, r)] for t, r in todo if (t.id, r) in records})
        queue = iter(todo)

        async def episodes() -> None:
            for task, run in queue:  # one shared iterator: each episode is taken once
                if self.stop_requested:
                    return
                self.in_flight += 1
                try:
                    await self._episode(task, run, records.pop((task.id, run), []))
                except (ModelUnavailable, WorkerLost, BudgetExhausted) as e:
                    self.failed.append(f"{task.id} run {run}: {e}")
                    log.warning("episode %s run %d left unfinished: %s", task.id, run, e)
                except FATAL as e:  # the other episodes finish their attempts in flight, then stop
                    self.fatal = self.fatal or e
                    self.stop_requested = True
                finally:
                    self.in_flight -= 1

        flusher = asyncio.ensure_future(self._send_summaries_every(0.5))
        try:
            await asyncio.gather(*(episodes() for _ in range(min(self.runtime.max_in_flight, len(todo)))))
        finally:
            flusher.cancel()
            self.send_summaries()
        if self.fatal is not None:
            raise self.fatal

    async def _episode(self, task: Task, run: int, records: list[AttemptRecord]) -> None:
        """`records`: the episode's attempts 1..n so far (the store checked them on resume)."""
        try:
            await self._attempts(task, run, records)
        finally:  # finished or left for a resume: an agent's state of it is released
            end = getattr(self.model, "end_episode", None)
            if end is not None:
                end(task.id, run)

    async def _attempts(self, task: Task, run: int, records: list[AttemptRecord]) -> None:
        while not episode_finished(records, self.k_max) and not self.stop_requested:
            attempt = len(records) + 1
            try:
                record = await self._attempt_with_retries(task, run, attempt, records)
            except (ModelUnavailable, WorkerLost, BudgetExhausted, asyncio.CancelledError, *FATAL):
                raise
            except Exception as error:  # noqa: BLE001 - one attempt's bug must not end the run
                self._record_error(task, run, attempt, error)
                return
            self.store.append(record)
            self.recorded += 1
            records.append(record)
            self.unsent.append(record.summary())
        if episode_finished(records, self.k_max):
            self.episodes_finished += 1

    def send_summaries(self) -> None:
        """Hand the new attempts' summaries to the metrics actor, in one call."""
        if self.unsent:
            batch, self.unsent = self.unsent, []
            if self.metrics is not None:
                self.metrics.add.remote(summaries_json(batch))

    async def _send_summaries_every(self, seconds: float) -> None:
        told: dict[str, Any] = {}
        while True:
            await asyncio.sleep(seconds)
            self.send_summaries()
            activity = {**self.activity(), "phase": "running"}
            if self.metrics is not None and activity != told:  # a Ray call only for news (a waiting run idles)
                self.metrics.update.remote(activity)
                told = activity

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
                # Ray restarts a dead worker (seconds; longer on a loaded machine or a new node).
                await asyncio.sleep(min(30.0, 2.0 ** (lost - 1)))
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

    async def _attempt(self, task: Task, run: int, attempt: int, previous: list[AttemptRecord]) -> AttemptRecord:
        if self.local_env is not None:
            return await run_attempt(self.spec, self.prompt, self.config, task, run, attempt, previous,
                                     self.local_env, self, self.store)
        with self.pool.attempt(f"{task.id}|{run}|{attempt}", self.initial) as env:
            return await run_attempt(self.spec, self.prompt, self.config, task, run, attempt, previous,
                                     env, self, self.store)

    # -- the model, as the protocol's ModelHandle: budget, timeout, errors ---------------

    async def complete(self, request: ModelRequest) -> ModelResponse:
        if self.budget_hit:  # abandon the attempt unrecorded: a resume re-runs it
            raise BudgetExhausted(f"cost budget ${self.runtime.max_cost_usd:g} reached (${self.spent_usd:.4f} spent)")
        try:
            if self.answers_at_once:  # a random baseline in this process: no deadline to keep (a timer costs 20 us)
                response = await self.model.complete(request)
            else:  # a deadline on this task, not `wait_for`'s task per request
                async with asyncio.timeout(self.runtime.model_timeout_s):
                    response = await self.model.complete(request)
        except (AccessDenied, RequestRejected) as e:  # the key or the request refused: no attempt can succeed
            cause = getattr(e, "cause", e)  # from a model worker: the error itself, not Ray's wrapping
            raise type(cause)(str(cause), kind=cause.kind) from None
        except AgentFailed as e:  # an agent that could not set up: neither can its other requests
            raise AgentFailed(str(getattr(e, "cause", e))) from None
        except ModelError as e:  # from a model worker: the error's own words, not Ray's wrapping
            raise ModelUnavailable(str(getattr(e, "cause", e)), retries=getattr(e, "retries", 0)) from e
        except (asyncio.TimeoutError, *ray_errors("RayActorError")) as e:
            raise ModelUnavailable(f"model worker: {type(e).__name__}") from e
        self.decisions += 1
        self._charge(response.usage.cost_usd)
        return response

    def _charge(self, cost_usd: float) -> None:
        self.spent_usd += cost_usd
        limit = self.runtime.max_cost_usd
        if limit is not None and self.spent_usd >= limit and not self.budget_hit:
            self.budget_hit = True
            self.stop_requested = True
            self.failed.append(f"cost budget ${limit:g} reached (${self.spent_usd:.4f} spent); raise --max-cost to continue")
            log.warning("cost budget $%g reached ($%.4f spent): stopping; raise --max-cost and resume", limit, self.spent_usd)

    # -- isolation ----------------------------------------------------------------------

    def _record_error(self, task: Task, run: int, attempt: int, error: BaseException) -> None:
        self.errored.append(f"{task.id} run {run} attempt {attempt}: {type(error).__name__}: {error}"[:300])
        self.store.append_error({
            "time": time.time(), "task": task.id, "run": run, "attempt": attempt,
            "type": type(error).__name__, "message": str(error)[:2000],
            "traceback": "".join(traceback.format_exception(error))[-20000:],
        })

    def activity(self) -> dict[str, Any]:
        """Counters for the progress views (pushed to the metrics actor by the driver)."""
        return {"in_flight": self.in_flight, "decisions": self.decisions, "errored": len(self.errored)}
