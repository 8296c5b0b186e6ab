"""One entry point for an evaluation: plan the config, connect to Ray, open the run store,
start the actors, drive the scheduler with a live progress view, and clean up."""

from __future__ import annotations

import asyncio
import os
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from deepphy.actors.env_worker import EnvWorkerImpl, make_env_worker
from deepphy.actors.metrics_actor import MetricsImpl, make_metrics_actor
from deepphy.actors.model_worker import make_model_worker
from deepphy.agent import AgentError
from deepphy.agents import make_agent, run_endpoints
from deepphy.collector import frozen_heap
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.envs import EnvOptions, EnvSpec
from deepphy.in_process import Actor, ThreadLoop
from deepphy.metrics.live import _duration, format_progress
from deepphy.plan import RunPlan, plan
from deepphy.ray_connect import ClusterUnavailable, disconnect, ensure_ray
from deepphy.runs.discovery import METRICS, actor_name, new_run_id
from deepphy.runs.records import summaries_json
from deepphy.runs.status import RunStatus, remove_status, write_status
from deepphy.runs.store import CONFIG, RunStore, check_records, read_records
from deepphy.scheduler import AgentWorkerModel, EnvPool, LocalAgentModel, Scheduler, WorkerModel, ray_errors
from deepphy.start_view import LOG_S, StartView

RAY_TIMEOUT_S = 60.0
CLOSE_TIMEOUT_S = 10.0  # for model workers to close their connections (an agent: what its setup took); then killed


@dataclass
class RunOutcome:
    out: Path
    episodes_total: int
    episodes_done: int
    new_records: int
    unfinished: list[str]  # episodes left for a resume: model or worker failures, the budget
    errored: list[str] = field(default_factory=list)  # attempts that raised (see errors.jsonl)
    worker_stats: list[dict[str, int]] = field(default_factory=list)  # per environment worker

    @property
    def complete(self) -> bool:
        return self.episodes_done == self.episodes_total


@dataclass
class Shared:
    """What a suite lends a cell (`evaluate_cell`), and stops itself when its last cell is
    done: the environment workers of the cell's setting as one `EnvPool` (the cells of a
    setting running at once share its calls), the endpoints' rate limiters (created by the
    suite, so one cell ending never kills the limiter another cell of that endpoint is
    using) and the model worker of each user's agent, by model name (its setup, a checkpoint
    loaded on a GPU say, done once for all its cells). `watch(metrics, scheduler)` hears them
    once the cell's actors are up: the suite's progress view reads them, and a suite that
    stops stops the scheduler (all in the suite's one event loop)."""

    pool: EnvPool
    watch: Callable[[Any, Any], None] = lambda metrics, scheduler: None
    agent_workers: dict[str, Any] = field(default_factory=dict)


def make_env_workers(spec: EnvSpec, options: EnvOptions, runtime: RuntimeOptions, name: str,
                     log_path: Callable[[int], str], cpus: float = 1.0) -> list[Any]:
    """The environment workers of one run or suite setting: `runtime.env_workers`, default
    one per CPU of the nodes that may host them, each asking `cpus` logical CPUs."""
    return [make_env_worker(spec, options, name=f"{name}{i}", resource=runtime.env_resource, log_path=log_path(i),
                            max_concurrency=max(1000, runtime.max_in_flight), num_cpus=cpus)
            for i in range(runtime.env_workers or _default_workers(runtime.env_resource))]


def evaluate(config: RunConfig, out: str | Path, runtime: RuntimeOptions | None = None, *,
             stream=None, view: StartView | None = None) -> RunOutcome:
    """Run (or resume) an evaluation into `out`. Every check that needs no Ray comes first
    and raises ConfigError / RunDirError / the models' errors (unknown model, missing key)
    before Ray starts and without writing anything; a finished run returns at once, without
    Ray. `runtime.in_process`: the workers in this process, no Ray (deepphy.in_process).
    `view`: the command's start view (one is made here if the runtime shows progress)."""
    stream = stream or sys.stderr  # looked up per call: pytest and others swap sys.stderr after import
    runtime = runtime or RuntimeOptions()
    run = _Run.checked(config, out, runtime, stream)
    if isinstance(run, RunOutcome):
        return run
    if view is None and runtime.progress:
        view = StartView(stream)
    if view:
        view.repeat()
    run.view = view
    try:
        if runtime.in_process:
            return run.in_process()
        started_ray = ensure_ray(runtime, run.say)  # no cluster at the address: fails before anything is written
        try:
            with frozen_heap():  # the heap of the start, Ray's included, is not scanned again (deepphy/collector.py)
                return asyncio.run(run.on_ray())
        finally:
            disconnect(started_ray)
    finally:
        if view:
            view.stop()
        run.close()


async def evaluate_cell(config: RunConfig, out: str | Path, runtime: RuntimeOptions, shared: Shared, *,
                        stream) -> RunOutcome:
    """Run (or resume) a suite's cell into `out`, as `evaluate` does, in the suite's event
    loop (connected to Ray already) on what the suite lends it (`shared`, used and left
    running), without a view of its own."""
    run = _Run.checked(config, out, runtime, stream)
    if isinstance(run, RunOutcome):
        return run
    try:
        return await run.on_ray(shared)
    finally:
        run.close()


@dataclass
class _Run:
    """One evaluation once its checks have passed: its workers (on Ray, or in this process),
    its scheduler and the live views, driven to the end."""

    plan: RunPlan
    runtime: RuntimeOptions
    store: RunStore
    existing: list
    done: int  # episodes finished before this session
    stream: Any
    began: float  # time.time() when the run began: its elapsed time counts from here
    endpoints: list  # the model's endpoints (deepphy.agents.run_endpoints), read once
    view: StartView | None = None  # what the run is doing until its progress line begins

    @classmethod
    def checked(cls, config: RunConfig, out: str | Path, runtime: RuntimeOptions, stream) -> _Run | RunOutcome:
        """The run into `out` with its directory claimed, once every check that needs no Ray
        has passed (nothing written if one fails); a finished run's outcome, at once."""
        began = time.time()
        the_plan = plan(config)
        endpoints = run_endpoints(config, runtime.models_file)  # an endpoint the models file lacks fails here
        # a missing key (an agent that cannot be built) fails here, before anything is written
        make_agent(config.model, runtime.models_file, env=config.env, agent=config.agent)
        store = RunStore.claim(out, config)  # another run's directory, or one in use: fails here
        try:
            existing = read_records(out)
            check_records(out, existing, the_plan.k_max)
            total = the_plan.episodes_total
            done = the_plan.episodes_done(existing)
            if done == total:  # nothing to do: no Ray
                store.close()
                return RunOutcome(out=Path(out), episodes_total=total, episodes_done=done, new_records=0,
                                  unfinished=[])
            store.start_writing()  # a read-only or unwritable directory: fails here
        except BaseException:
            store.discard()
            raise
        return cls(the_plan, runtime, store, existing, done, stream, began, endpoints)

    def close(self) -> None:
        remove_status(self.store.path)
        self.store.discard()  # closes; removes a directory this run made and recorded nothing in

    @property
    def config(self) -> RunConfig:
        return self.plan.config

    @property
    def total(self) -> int:
        return self.plan.episodes_total

    def say(self, phase: str) -> None:
        if self.view:
            self.view.say(phase)

    def in_process(self) -> RunOutcome:
        """The workers in this process (deepphy.in_process): no Ray imported or started."""
        self.say("starting the environment in this process")
        status = RunStatus(run_id=new_run_id(), pid=os.getpid(), phase="starting", since=time.time())
        write_status(self.store.path, status)
        spec, options = self.plan.spec, self.plan.options
        loops = [ThreadLoop(f"deepphy-env{i}") for i in range(self.runtime.env_workers or 1)]
        try:
            env_workers = [Actor(lambda: EnvWorkerImpl(spec, options), t.loop) for t in loops]
            model = make_agent(self.config.model, self.runtime.models_file, agent=self.config.agent)  # its own limiter
            if self.config.agent is not None:  # told when an episode ends, to release its state
                model = LocalAgentModel(model, self.config)
            metrics = Actor(lambda: MetricsImpl(self.total, self.plan.k_max, spec.max_steps, run=self._run_info(),
                                                started=self.began))
            with frozen_heap():  # the heap of the start is not scanned again (deepphy/collector.py)
                return asyncio.run(self._drive(EnvPool(env_workers, self.runtime.step_timeout_s), model, metrics,
                                               status, close_model=model.close))
        finally:
            for t in loops:
                t.close()

    async def on_ray(self, shared: Shared | None = None) -> RunOutcome:
        """The workers as Ray actors (this process is connected to Ray): the run's own, or
        those a suite lends it (`shared`)."""
        # Ray at import (seconds): loaded by ensure_ray by now, never by a run in this process
        import ray
        from deepphy.actors.rate_limiter import ensure_limiter

        config, runtime, store, spec, endpoints = self.config, self.runtime, self.store, self.plan.spec, self.endpoints
        env_workers: list[Any] = []  # the actors this run started, stopped at its end however it ends
        model_actors: list[Any] = []
        limiters: list[Any] = []
        metrics = None
        try:
            self.say("starting workers")
            # Named (deepphy.runs.discovery): a dashboard or an operator can find a live run's
            # metrics actor (ray.util.list_named_actors) and poll its snapshot.
            run_id = new_run_id()
            status = RunStatus(run_id=run_id, pid=os.getpid(), phase="starting", since=time.time(),
                               ray_address=ray.get_runtime_context().gcs_address,
                               ray_auth=os.environ.get("RAY_AUTH_MODE"))
            write_status(store.path, status)
            if self.view:  # where `deepphy watch` and `deepphy dashboard --address` find this run
                self.view.line(f"deepphy: run {status.run_id} on Ray at {status.ray_address}; follow it with "
                               f"`deepphy watch {store.path}`")
            if shared is not None:
                pool, env_workers = shared.pool, []
            else:
                env_workers = make_env_workers(spec, self.plan.options, runtime, actor_name(run_id, "env"),
                                               lambda i: store.log_path(f"env{i}"))
                pool = EnvPool(env_workers, runtime.step_timeout_s)
            # The driver owns the endpoints' limiters, so a model worker's restart keeps their windows.
            limiters = [limiter for e in endpoints if (limiter := ensure_limiter(e)) is not None]
            if not endpoints and config.agent is None:  # a baseline answers in this process: no worker, no Ray call
                model, model_actors = make_agent(config.model), []
            else:
                worker = shared.agent_workers.get(config.model) if shared is not None else None
                model_actors = [] if worker is not None else [
                    make_model_worker(config.model, spec, name=actor_name(run_id, "model"), models_file=runtime.models_file,
                                      max_concurrency=max(1000, runtime.max_in_flight), agent=config.agent)]
                worker = worker or model_actors[0]
                probe = (store.path / CONFIG).resolve()
                try:
                    seen = await _started(worker.read_file.remote(str(probe)), "the model worker", runtime)
                except ray.exceptions.RayActorError as e:
                    if config.agent is None or not e.actor_init_failed:
                        raise
                    # its node's install differs from the driver's (another version, a missing dependency)
                    said = _raised(e).removeprefix(f"{AgentError.__module__}.{AgentError.__name__}: ")
                    raise AgentError(f"{said} (in the agent's model worker, which could not start)") from None
                shares_files = seen == probe.read_bytes()
                model = (AgentWorkerModel(worker, shares_files, config) if config.agent is not None
                         else WorkerModel(worker, shares_files))
            metrics = make_metrics_actor(self.total, self.plan.k_max, spec.max_steps, name=actor_name(run_id, METRICS),
                                         run=self._run_info(), started=self.began)
            return await self._drive(pool, model, metrics, status, shared=shared)
        finally:
            # A model worker closes its connections itself, or its client complains as it dies.
            try:
                async with asyncio.timeout(CLOSE_TIMEOUT_S):
                    await asyncio.gather(*(worker.close.remote() for worker in model_actors))
            except Exception:  # noqa: BLE001 - a lost worker has nothing to close
                pass
            finally:  # also when the wait above is cancelled (Ctrl-C)
                for actor in [*env_workers, *model_actors, *([metrics] if metrics else []),
                              *(limiters if shared is None else [])]:
                    try:
                        ray.kill(actor)
                    except Exception:  # noqa: BLE001 - already gone
                        pass

    def _run_info(self) -> dict[str, Any]:
        """What the metrics actor tells dashboards about the run."""
        return {"run_dir": str(self.store.path.resolve()), "config": self.config.model_dump(mode="json")}

    async def _drive(self, pool: EnvPool, model: Any, metrics: Any, status: RunStatus,
                     shared: Shared | None = None, close_model: Callable[[], Any] | None = None) -> RunOutcome:
        # Not waited for here: the metrics actor's process starts while the workers start and the
        # first attempts run (its calls queue in order until it is up); `_drive` checks it came up.
        metrics_ready = metrics.add.remote(summaries_json([r.summary() for r in self.existing]), resumed=True)
        scheduler = Scheduler(self.plan, self.runtime, self.store, pool, model, metrics)
        if shared is not None:
            shared.watch(metrics, scheduler)
        if self.view:  # the progress line from here on
            self.view.stop()

        def without_figures(phase: str) -> str:  # the progress line while the metrics actor does not answer
            return (f"{phase} · episodes {self.done + scheduler.episodes_finished}/{self.total} · attempts "
                    f"{scheduler.recorded} · {_duration(time.time() - self.began)} (no figures yet: the "
                    "metrics actor has not answered)")

        try:
            await _drive(scheduler, self.existing, pool.workers, metrics, metrics_ready, self.runtime, self.stream,
                         self.store.path, status, without_figures)
            worker_stats = await _worker_stats(pool.workers)
        finally:
            if close_model is not None:
                await close_model()
        # What the directory held at the start and what this session wrote to it (the store
        # raises on a write that fails): not the log read back, which took ~0.13 ms a record
        # (0.3 s at the end of a 2,500-attempt run).
        return RunOutcome(
            out=Path(self.store.path),
            episodes_total=self.total,
            episodes_done=self.done + scheduler.episodes_finished,
            new_records=scheduler.recorded,
            unfinished=scheduler.failed,
            errored=scheduler.errored,
            worker_stats=worker_stats,
        )


def _raised(error: BaseException) -> str:
    """The exception an actor's constructor raised, as its one line in Ray's error text."""
    raised = [line.strip() for line in str(error).splitlines() if re.match(r"^\s*[\w.]+(Error|Exception): ", line)]
    return raised[-1] if raised else str(error).strip().splitlines()[0]


async def _started(ref: Any, what: str, runtime: RuntimeOptions) -> Any:
    """The result of an actor's first call: its process must start first, which takes long on
    a busy machine (bounded like an environment step); one line if it never does."""
    try:
        async with asyncio.timeout(runtime.step_timeout_s):
            return await ref
    except TimeoutError:
        raise ClusterUnavailable(f"{what} did not start within {runtime.step_timeout_s:g} s (an overloaded "
                                 "machine, or no room on the cluster); run the same command again to resume") from None


async def _worker_stats(env_workers: list[Any]) -> list[dict[str, int]]:
    """Each live environment worker's counters (a worker lost with its node has none)."""
    answers = await asyncio.gather(*(asyncio.wait_for(w.stats.remote(), RAY_TIMEOUT_S) for w in env_workers),
                                   return_exceptions=True)
    return [a for a in answers if isinstance(a, dict)]


def _default_workers(resource: str | None) -> int:
    """One worker per CPU of the nodes that may host environment workers."""
    import ray  # loaded by ensure_ray: a run in this process never comes here

    nodes = [n for n in ray.nodes() if n.get("Alive") and (resource is None or resource in n["Resources"])]
    return max(1, int(sum(n["Resources"].get("CPU", 0) for n in nodes)))


async def _drive(scheduler, existing, env_workers, metrics, metrics_ready, runtime: RuntimeOptions, stream,
                 run_dir: Path, status: RunStatus, without_figures: Callable[[str], str]) -> None:
    """Start the workers, warm them up (compiling kernels on first use), then run the
    scheduler, with the progress view alongside. Each phase is told to the metrics actor
    (attempts/s and ETA count from "running") and written to the run directory.

    `metrics_ready`: the metrics actor's first call. Its process is a third one to start (a
    local Ray has one ready per CPU, which the workers take); waiting for it delayed the first
    attempt by ~0.3 s on the 2-core machine, so nothing waits for it. Should it not start
    within the step timeout, the run stops (the attempts in flight are recorded first) with
    one line, as for the workers. Until it answers, the progress line is `without_figures`."""
    phase = [status.phase]
    metrics_up = asyncio.ensure_future(_metrics_started(metrics_ready, scheduler, runtime))

    def enter(name: str) -> None:
        phase[0] = name
        metrics.update.remote({"phase": name})
        write_status(run_dir, status.model_copy(update={"phase": name, "since": time.time()}))

    view = (asyncio.ensure_future(_progress(scheduler, metrics, phase, stream, without_figures))
            if runtime.progress else None)
    try:
        try:
            await asyncio.wait_for(asyncio.gather(*(w.stats.remote() for w in env_workers)),
                                   timeout=runtime.step_timeout_s)  # the workers' processes are up
            enter("compiling")
            await asyncio.wait_for(asyncio.gather(*(w.warm_up.remote(scheduler.tasks) for w in env_workers)),
                                   timeout=runtime.step_timeout_s)
        except asyncio.TimeoutError:
            raise ClusterUnavailable(f"the environment workers did not start within {runtime.step_timeout_s:g} s "
                                     "(an overloaded machine, or no room on the cluster for them); run the same "
                                     "command again to resume") from None
        except ray_errors("RayActorError") as e:
            if e.actor_init_failed:  # the environment cannot be built in a worker: not the cluster's doing
                raise
            raise ClusterUnavailable(f"the environment workers died while starting ({_why_died(e)}); run the same "
                                     "command again to resume") from None
        enter("running")
        await scheduler.run(existing)
        await metrics_up  # a run shorter than the metrics actor's start waits for it here
        if scheduler.fatal is not None:
            raise scheduler.fatal
    finally:
        metrics_up.cancel()
        if view is not None:
            view.cancel()
            try:
                await view
            except asyncio.CancelledError:
                pass
            await _print_snapshot(scheduler, metrics, phase[0], stream, without_figures, final=True)


def _why_died(error: BaseException) -> str:
    """Why Ray says workers died: their node's death where their node died (a local instance's
    raylet dies with a failed agent), else the error's own words."""
    import ray  # loaded by ensure_ray: a run in this process never comes here

    lines = str(error).splitlines() or [type(error).__name__]
    ips = [line.split(":", 1)[1].strip() for line in lines if line.startswith("\tip:")]
    try:
        dead = [n.get("DeathReasonMessage") or "no reason given" for n in ray.nodes()
                if not n.get("Alive", True) and n.get("NodeManagerAddress") in ips]
    except Exception:  # noqa: BLE001 - Ray's control process may be gone too
        dead = []
    if dead:
        return f"their node died: {dead[-1]}"
    said = [line.strip() for line in lines[1:] if line.strip() and not line.startswith("\t")]  # not the actor's ids
    return " ".join([lines[0].strip(), *said[:1]])


async def _metrics_started(ready, scheduler, runtime: RuntimeOptions) -> None:
    """Wait for the metrics actor's first call; if it never returns, stop the run (as a
    fatal error: the episodes' attempts in flight finish and are recorded, then it raises)."""
    try:
        async with asyncio.timeout(runtime.step_timeout_s):  # not `wait_for`: see _print_snapshot
            await ready
    except asyncio.TimeoutError:
        scheduler.fatal = scheduler.fatal or ClusterUnavailable(
            f"the metrics actor did not start within {runtime.step_timeout_s:g} s (an overloaded machine, or no "
            "room on the cluster); run the same command again to resume")
        scheduler.stop_requested = True


PROGRESS_TTY_S = 0.5  # the progress line on a terminal (in a log: start_view.LOG_S)
SNAPSHOT_WAIT_S = 2.0  # for the figures of a progress line; past it, the line goes without them


async def _progress(scheduler, metrics, phase: list[str], stream, without_figures: Callable[[str], str]) -> None:
    """The progress line: at once, then every PROGRESS_TTY_S on a terminal (in place) and
    every LOG_S in a log, never waiting long for the figures."""
    every = PROGRESS_TTY_S if stream.isatty() else LOG_S
    while True:
        shown = time.monotonic()
        await _print_snapshot(scheduler, metrics, phase[0], stream, without_figures, final=False)
        await asyncio.sleep(max(0.0, shown + every - time.monotonic()))


async def _print_snapshot(scheduler, metrics, phase: str, stream, without_figures: Callable[[str], str],
                          final: bool) -> None:
    # Deadlines by `asyncio.timeout`, not `asyncio.wait_for`: Python 3.11's `wait_for` returns
    # the result of a call that completes in the same turn of the loop as a cancellation and
    # drops the cancellation (fixed in 3.12), so `_drive` stopping the view could wait for it
    # forever while it went on printing.
    wait_s = 10.0 if final else SNAPSHOT_WAIT_S
    line = without_figures(phase)
    try:
        # The driver's own counters go to the metrics actor, so `deepphy watch` sees them too.
        scheduler.send_summaries()
        try:  # what the model's requests are waiting for: a run that seems stuck says why
            async with asyncio.timeout(wait_s / 2):
                waiting = await scheduler.model.activity()
        except Exception:  # noqa: BLE001 - a restarting model worker: no figures this time
            waiting = {}
        metrics.update.remote({**scheduler.activity(), **waiting, "phase": phase})  # also while warming up
        async with asyncio.timeout(wait_s / 2):
            snap = await metrics.snapshot.remote()
        line = format_progress(snap)
    except Exception:  # noqa: BLE001 - the metrics actor is starting (or lost): the line without its figures
        pass
    try:
        stream.write(("\r\x1b[2K" + line + ("\n" if final else "")) if stream.isatty() else line + "\n")
        stream.flush()
    except (OSError, ValueError):  # a closed stream: progress is best effort
        pass
