"""One entry point for an evaluation: resolve the config, open the run store, start Ray
and the actors, drive the scheduler with a live progress view, and clean up."""

from __future__ import annotations

import asyncio
import logging
import os
import sys
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from pydantic import ValidationError

from deepphy.config import RunConfig, RuntimeOptions
from deepphy.envs import Environment, Task, get_env_class
from deepphy.runs.store import RunDirError, RunStore, read_records

RAY_TIMEOUT_S = 60.0
# Ray takes 127.0.0.1 as "no address given" and advertises the machine's primary interface;
# any other loopback address keeps the local cluster's traffic on loopback. macOS only
# configures 127.0.0.1, so there we fall back to it.
LOOPBACK_NODE_IP = "127.0.0.2" if sys.platform.startswith("linux") else "127.0.0.1"


class ConfigError(ValueError):
    """A run config that cannot be evaluated. The message is for the user."""


@dataclass
class RunOutcome:
    out: Path
    episodes_total: int
    episodes_done: int
    new_records: int
    unfinished: list[str]

    @property
    def complete(self) -> bool:
        return self.episodes_done == self.episodes_total


def resolve(config: RunConfig) -> tuple[type[Environment], list[Task], int]:
    """(environment class, task list, attempts per task) for a config, or ConfigError."""
    env_cls = get_env_class(config.env)
    try:
        options = env_cls.Options(**config.env_options)
    except ValidationError as e:
        err = e.errors()[0]
        raise ConfigError(f"bad option for {config.env}: {'.'.join(map(str, err['loc']))}: {err['msg']}") from None
    tasks = env_cls.tasks(options)
    if config.tasks:
        by_id = {t.id: t for t in tasks}
        unknown = [t for t in config.tasks if t not in by_id]
        if unknown:
            raise ConfigError(
                f"unknown {config.env} task(s) {', '.join(unknown[:5])}; see `deepphy envs --tasks {config.env}`"
            )
        tasks = [by_id[t] for t in config.tasks]
    if config.limit:
        tasks = tasks[: config.limit]
    if not tasks:
        raise ConfigError("the task selection is empty")
    return env_cls, tasks, config.max_attempts or env_cls.max_attempts


def quiet_environment() -> None:
    """Environment variables for this process and the Ray processes it starts.
    Must run before `ray` is imported (Ray reads some of them at import time)."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    os.environ.setdefault("RAY_DEDUP_LOGS", "0")
    # Under `uv run`, Ray would otherwise package the working directory and build a second
    # virtual environment for its workers; ours is already installed and identical.
    os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")


def ensure_ray(runtime: RuntimeOptions) -> bool:
    """Connect to Ray; returns True if this call started a local cluster (to shut down later)."""
    import ray

    if ray.is_initialized():
        return False
    quiet_environment()
    if runtime.address:
        ray.init(address=runtime.address, logging_level=logging.WARNING)
        return True
    # A local cluster on loopback keeps Ray's default token auth; its notice is noise here.
    logging.getLogger("ray._private.authentication.authentication_token_setup").setLevel(logging.ERROR)
    ray.init(
        num_cpus=runtime.num_cpus,
        _node_ip_address=LOOPBACK_NODE_IP,
        include_dashboard=False,
        object_store_memory=256 * 1024**2,
        logging_level=logging.WARNING,
    )
    return True


def evaluate(
    config: RunConfig,
    out: str | Path,
    runtime: RuntimeOptions | None = None,
    *,
    client_options: dict[str, Any] | None = None,
    stream=sys.stderr,
) -> RunOutcome:
    """Run (or resume) an evaluation into `out`. Raises ConfigError / RunDirError for user errors."""
    import ray

    from deepphy.actors.env_worker import make_env_worker
    from deepphy.actors.metrics_actor import make_metrics_actor
    from deepphy.actors.model_worker import make_model_worker
    from deepphy.actors.scheduler import Scheduler
    from deepphy.actors.rate_limiter import ensure_limiter
    from deepphy.models import make_client, model_config

    runtime = runtime or RuntimeOptions()
    env_cls, tasks, k_max = resolve(config)
    make_client(config.model, **(client_options or {}))  # unknown model: fail before writing anything
    store = RunStore.create_or_resume(out, config)
    started_ray = False
    actors: list[Any] = []
    try:
        existing = read_records(out)
        _check_unique(existing, out)
        started_ray = ensure_ray(runtime)
        n_workers = runtime.env_workers or _default_workers(runtime.env_resource)
        # Named "deepphy/<run id>/<role>": a dashboard or an operator can find a live run's
        # metrics actor (ray.util.list_named_actors) and poll its snapshot.
        prefix = f"deepphy/{uuid.uuid4().hex[:8]}"
        env_workers = [
            make_env_worker(config.env, config.env_options, name=f"{prefix}/env{i}", resource=runtime.env_resource)
            for i in range(n_workers)
        ]
        model_cfg = model_config(config.model, (client_options or {}).get("models_file"))
        # The driver owns the endpoint's limiter, so a model worker's restart keeps its windows.
        limiter = ensure_limiter(model_cfg) if model_cfg is not None else None
        model_worker = make_model_worker(config.model, name=f"{prefix}/model", **(client_options or {}))
        total = len(tasks) * config.runs
        metrics = make_metrics_actor(total, k_max, name=f"{prefix}/metrics", run={
            "run_dir": str(Path(out).resolve()), "config": config.model_dump(mode="json")})
        actors = [*env_workers, model_worker, metrics, *([limiter] if limiter is not None else [])]
        ray.get(metrics.add.remote(existing, resumed=True), timeout=RAY_TIMEOUT_S)
        scheduler = Scheduler(config, runtime, env_cls, tasks, store, env_workers, model_worker, metrics, k_max)
        asyncio.run(_drive(scheduler, existing, metrics, runtime.progress, stream))
        snap = ray.get(metrics.snapshot.remote(), timeout=RAY_TIMEOUT_S)
        return RunOutcome(
            out=Path(out),
            episodes_total=total,
            episodes_done=snap["episodes_done"],
            new_records=snap["attempts"] - len(existing),
            unfinished=scheduler.failed,
        )
    finally:
        store.close()
        for actor in actors:
            try:
                ray.kill(actor)
            except Exception:  # noqa: BLE001 - already gone
                pass
        if started_ray:
            ray.shutdown()


def _default_workers(resource: str | None) -> int:
    """One worker per CPU of the nodes that may host environment workers."""
    import ray

    nodes = [n for n in ray.nodes() if n.get("Alive") and (resource is None or resource in n["Resources"])]
    return max(1, int(sum(n["Resources"].get("CPU", 0) for n in nodes)))


def _check_unique(records: Sequence[Any], out: str | Path) -> None:
    seen: set[tuple[str, int, int]] = set()
    for r in records:
        if r.key in seen:
            raise RunDirError(f"{out}: duplicate record for task {r.task} run {r.run} attempt {r.attempt}")
        seen.add(r.key)


async def _drive(scheduler, existing, metrics, progress: bool, stream) -> None:
    work = asyncio.ensure_future(scheduler.run(existing))
    view = asyncio.ensure_future(_progress(metrics, stream)) if progress else None
    try:
        await work
    finally:
        if view is not None:
            view.cancel()
            try:
                await view
            except asyncio.CancelledError:
                pass
            await _print_snapshot(metrics, stream, final=True)


async def _progress(metrics, stream) -> None:
    tty = stream.isatty()
    last_line = 0.0
    while True:
        await asyncio.sleep(0.5 if tty else 1.0)
        if tty or time.time() - last_line >= 10:
            await _print_snapshot(metrics, stream, final=False)
            last_line = time.time()


async def _print_snapshot(metrics, stream, final: bool) -> None:
    try:
        snap = await asyncio.wait_for(metrics.snapshot.remote(), timeout=10)
    except Exception:  # noqa: BLE001 - progress is best effort
        return
    line = format_progress(snap)
    if stream.isatty():
        stream.write("\r" + line.ljust(100) + ("\n" if final else ""))
    else:
        stream.write(line + "\n")
    stream.flush()


def format_progress(s: dict[str, Any]) -> str:
    line = (
        f"episodes {s['episodes_done']}/{s['episodes_total']} · attempts {s['attempts']} "
        f"({s['attempts_per_s']:.1f}/s) · solved {s['solved']} ({100 * s['success_rate']:.1f}% of finished) · "
        f"invalid {s['invalid_attempts']}"
    )
    if s["model_errors"] or s["retries"]:
        line += f" · model errors {s['model_errors']} · retries {s['retries']}"
    if s["input_tokens"]:
        line += f" · tokens {s['input_tokens']}/{s['output_tokens']} · ${s['cost_usd']:.4f}"
    return line + f" · {s['elapsed_s']:.0f}s"
