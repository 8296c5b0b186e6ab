"""Suites: the benchmark's grid as one unit of work (`deepphy run --suite paper|FILE.yaml`).

A suite file names environments (each with fixed options and option axes, e.g. Kinetix
`annotate: [true, false]`), prompt formats, repetitions, a seed, default models and users'
agents (`agents: [{entry: package.module:factory, args: {...}}]`, deepphy/agent.py); `--model
a,b` replaces the models (a group of the models file, e.g. `paper`, stands for its models),
`--agent` the agents. Its cells are environments x option values x models (then agents) x formats,
and each cell is an ordinary run directory under the suite root,
`ROOT/<model>/<env>[-<option>=<value>...]/<format>`, holding its `runs` repetitions, so
report, dashboard, plot, export, repair and resume work on a cell as on any run. The
root's `suite.json` (the manifest) names every cell and its config.

Re-running the same command resumes every cell. A suite whose cells changed is refused
(a cell's config differs, or a cell is gone); one that only adds cells (another model,
say) extends the manifest. Every cell is checked (options, tasks, models and keys, its
directory) before Ray starts; the cells then run interleaved in ONE Ray runtime, started
once, and one event loop (`Interleaved`: bounded numbers of cells and environment settings
at once, the cells of one setting sharing its environment workers and their calls, the
cells of one endpoint its rate limiter), with one progress view for the suite.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from deepphy.actors.model_worker import make_model_worker
from deepphy.agent import AgentError, load_agent
from deepphy.agents import expand_models, make_agent, run_endpoints
from deepphy.chat import PromptFormat
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.envs.shortcuts import is_shortcut, shortcut_for
from deepphy.messages import one_line, validation_message
from deepphy.yamlfile import read_yaml_model
from deepphy.metrics.live import _duration, _rate, format_progress
from deepphy.plan import plan
from deepphy.ray_connect import disconnect, ensure_ray
from deepphy.collector import frozen_heap
from deepphy.runner import CLOSE_TIMEOUT_S, RunOutcome, Shared, evaluate_cell, make_env_workers
from deepphy.scheduler import EnvPool
from deepphy.start_view import LOG_S, TTY_S
from deepphy.runs.discovery import SNAPSHOT_TIMEOUT_S, actor_name, is_run_dir, new_run_id
from deepphy.runs.manifest import MANIFEST, Cell, read_manifest, write_manifest
from deepphy.runs.store import RunStore, read_records

LOGS = "logs"  # the environment workers' output (shared by the cells of one environment setting)
SHIPPED = Path(__file__).with_name("suites")  # <name>.yaml: the suites `--suite NAME` knows


class SuiteError(ValueError):
    """A suite that cannot be run as asked. The message is for the user."""


class SuiteEnv(BaseModel):
    model_config = ConfigDict(extra="forbid")

    env: str
    options: dict[str, Any] = Field(default_factory=dict, description="environment options of every cell")
    axes: dict[str, list[Any]] = Field(default_factory=dict, description="option -> values: a cell per value")
    tasks: list[str] | None = None
    limit: int | None = Field(None, ge=1)
    max_attempts: int | None = Field(None, ge=1)
    runs: int | None = Field(None, ge=1, description="repetitions of this environment's cells; default: the suite's")

    @field_validator("axes")
    @classmethod
    def _axes_have_values(cls, axes: dict[str, list[Any]]) -> dict[str, list[Any]]:
        empty = [k for k, values in axes.items() if not values]
        if empty:
            raise ValueError(f"axis {empty[0]} has no values")
        return axes


class SuiteAgent(BaseModel):
    """A user's agent in a suite: as `--agent ENTRY --agent-arg KEY=VALUE ...`."""

    model_config = ConfigDict(extra="forbid")

    entry: str
    args: dict[str, Any] = Field(default_factory=dict)


class Suite(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str = Field(pattern=r"^[A-Za-z0-9._-]+$")
    description: str = ""
    envs: list[SuiteEnv] = Field(min_length=1)
    formats: list[PromptFormat] = Field([PromptFormat.VLA, PromptFormat.WM], min_length=1)
    runs: int = Field(3, ge=1)
    seed: int = 0
    models: list[str] = Field(["mock"], description="models and groups of the models file (may be empty when the "
                              "suite has agents)")
    agents: list[SuiteAgent] = Field(default_factory=list)


def load_suite(name_or_path: str) -> Suite:
    """A shipped suite by name, or a suite file."""
    path = SHIPPED / f"{name_or_path}.yaml" if re.fullmatch(r"[a-z0-9_-]+", name_or_path) else None
    if path is None or not path.is_file():
        path = Path(name_or_path)
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in SHIPPED.glob("*.yaml")))
        raise SuiteError(f"no suite {name_or_path!r}: give a suite file or one of {known}")
    return read_yaml_model(path, Suite, SuiteError, "suite file")


def _name_part(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value)
    return re.sub(r"[^A-Za-z0-9._=+-]", "_", text)


def suite_models(suite: Suite, models: list[str] | None = None, models_file: str | None = None) -> list[str]:
    """The models of a suite's cells: `models` (default the suite's own), each group of the
    models file replaced by its entries (`--model paper` is the paper's models)."""
    return expand_models(models or suite.models, models_file)


def cells(suite: Suite, models: list[str] | None = None, models_file: str | None = None) -> list[Cell]:
    """Every cell: environments x option values x models x formats, in that order."""
    out: list[Cell] = []
    models = suite_models(suite, models, models_file)
    try:
        agents = [load_agent(a.entry, a.args) for a in suite.agents]
    except AgentError as e:
        raise SuiteError(f"suite {suite.name}: {e}") from None
    if not models and not agents:
        raise SuiteError(f"suite {suite.name} has no model and no agent to evaluate (give --model or --agent)")
    for entry in suite.envs:
        keys = list(entry.axes)
        for values in itertools.product(*(entry.axes[k] for k in keys)):
            options = {**entry.options, **dict(zip(keys, values))}
            setting = entry.env + "".join(f"-{_name_part(k)}={_name_part(v)}" for k, v in sorted(options.items()))
            for model, agent in [*((m, None) for m in models), *((a.name, a) for a in agents)]:
                for fmt in suite.formats:
                    try:
                        config = RunConfig(env=entry.env, model=model, format=fmt, runs=entry.runs or suite.runs,
                                           seed=suite.seed,
                                           tasks=entry.tasks, limit=entry.limit, max_attempts=entry.max_attempts,
                                           env_options=options, agent=agent)
                    except ValidationError as e:
                        raise SuiteError(f"suite {suite.name}, {setting}: {validation_message(e)}") from None
                    out.append(Cell(f"{_name_part(model)}/{setting}/{fmt.value}", config))
    seen: dict[str, Cell] = {}
    for cell in out:
        if cell.dir in seen:
            raise SuiteError(f"suite {suite.name}: two cells would share the directory {cell.dir}; give their "
                             "environments different options")
        seen[cell.dir] = cell
    return out


def checked_cells(suite: Suite, root: str | Path, models: list[str] | None, models_file: str | None) -> list[Cell]:
    """The cells to run into `root`, every check that needs no Ray done (and nothing
    written): the root is new, empty or this suite's; each cell's options, tasks and
    model (its key included) are valid and its directory new or holding that config."""
    root = Path(root)
    wanted = cells(suite, models, models_file)
    if root.exists() and not root.is_dir():
        raise SuiteError(f"{root} exists and is not a directory")
    if (root / MANIFEST).exists():
        before = {c.dir: c.config for c in read_manifest(root)}
        now = {c.dir: c.config for c in wanted}
        changed = [d for d in before if d in now and before[d] != now[d]]
        gone = [d for d in before if d not in now]
        if changed or gone:
            what = (f"cell {changed[0]} has another config" if changed
                    else f"{len(gone)} of its cells ({', '.join(gone[:3])}) are not in this suite")
            raise SuiteError(f"{root} holds a different suite ({what}); run the same suite and models to resume, "
                             "or choose another --out")
    elif root.exists() and any(root.iterdir()):
        raise SuiteError(f"{root} is not empty and holds no suite (no {MANIFEST}); choose another --out")
    for config in {c.config.model: c.config for c in wanted}.values():
        run_endpoints(config, models_file)
        make_agent(config.model, models_file, agent=config.agent)  # a missing key fails here
    for cell in wanted:
        cell_plan = plan(cell.config)
        if is_shortcut(cell.config.model):  # one of the cell's environment's own shortcuts
            shortcut_for(cell_plan.spec, cell.config.model)
        RunStore.check(root / cell.dir, cell.config)
    return wanted


SETTINGS_AT_ONCE = 2  # environment settings whose workers live at once: one simulates while the other's
# cells wait on their models or compile; each worker asks 1/SETTINGS_AT_ONCE CPU, so together they ask the
# CPUs one run's workers would (a third setting would add processes and memory for little more overlap)
CELLS_AT_ONCE = 8  # cells running at once: each has a model worker process and its own episodes in flight


@dataclass
class CellOutcome:
    cell: Cell
    done: int
    total: int
    new_records: int


def run_suite(suite: Suite, root: str | Path, runtime: RuntimeOptions, models: list[str] | None = None,
              stream=None, cell_lines: bool = False, view=None) -> list[CellOutcome]:
    """Run (or resume) every cell of `suite` into `root`, interleaved in one Ray runtime
    (started here unless this process is connected already), with one progress view
    (`cell_lines`: a line per running cell too). `view`: the command's start view, which
    says the Ray start and ends where the suite's own view begins."""
    stream = stream or sys.stderr  # looked up per call: pytest and others swap sys.stderr after import
    root = Path(root)
    wanted = checked_cells(suite, root, models, runtime.models_file)
    added = len(wanted) - len(read_manifest(root)) if (root / MANIFEST).exists() else 0
    try:
        write_manifest(root, suite.name, suite.description, wanted)
    except OSError as e:
        raise SuiteError(f"cannot write {root / MANIFEST}: {e.strerror or e}") from None
    if added:
        said = f"suite {suite.name}: extended by {added} cell(s)"
        if view:
            view.line(said)
        else:
            print(said, file=stream, flush=True)
    progress = {c.dir: episodes_done(c.config, root / c.dir) for c in wanted}
    left = [c for c in wanted if progress[c.dir][0] < progress[c.dir][1]]
    finished = {c.dir: CellOutcome(c, *progress[c.dir], 0) for c in wanted if c not in left}
    if left:
        started = ensure_ray(runtime, view.say if view else lambda line: print(f"{line} ...", file=stream, flush=True))
        if view:
            view.stop()
        try:
            finished.update(Interleaved(suite.name, root, runtime, wanted, left, progress, stream, cell_lines).run())
        finally:
            disconnect(started)
    return [finished[c.dir] for c in wanted]


def episodes_done(config: RunConfig, run_dir: Path) -> tuple[int, int]:
    """(episodes complete, episodes) of a cell: none complete while its directory holds no run.
    Reads the log without taking the run's lock."""
    cell_plan = plan(config)
    done = cell_plan.episodes_done(read_records(run_dir)) if is_run_dir(run_dir) else 0
    return done, cell_plan.episodes_total


def setting_of(config: RunConfig) -> str:
    """The environment setting of a cell: cells of one setting share environment workers."""
    return config.env + json.dumps(config.env_options, sort_keys=True)


class Interleaved:
    """Runs a suite's cells at once in this driver, in one event loop: each cell is a task
    (its own scheduler over its plan), the cells of one setting share its workers' `EnvPool`,
    and stopping a cell is setting its scheduler's flag in that same loop.

    Bounds: at most SETTINGS_AT_ONCE environment settings have workers (started when their
    first cell starts, stopped after their last cell ends; cells come in setting order) and
    at most CELLS_AT_ONCE cells run. The next cell is the first waiting one, among those
    whose setting has or may get workers, of the endpoint with the fewest cells running, so
    every endpoint has cells in flight while any are left. The endpoints' limiters are made
    here and outlive every cell. A cell that fails (or Ctrl-C) stops the suite: no new cell
    starts, the running ones finish their attempts in flight, then the error is raised."""

    def __init__(self, name: str, root: Path, runtime: RuntimeOptions, wanted: list[Cell], left: list[Cell],
                 progress: dict[str, tuple[int, int]], stream, cell_lines: bool) -> None:
        self.name, self.root, self.stream, self.cell_lines = name, root, stream, cell_lines
        self.show = runtime.progress
        self.runtime = runtime.model_copy(update={"progress": False})  # this view replaces the cells' own
        self.wanted, self.waiting = wanted, list(left)
        self.progress = dict(progress)  # cell -> (episodes done, total): at the start, then as snapshots come
        self.new_attempts: dict[str, int] = {}
        self.id = new_run_id()
        self.pools: dict[str, EnvPool] = {}  # setting -> its environment workers, as the cells share them
        self.settings_started = 0
        self.running: dict[asyncio.Task, Cell] = {}  # a cell's task -> the cell
        self.watched: dict[str, tuple[Any, Any]] = {}  # cell -> (metrics actor, scheduler)
        self.limiters: dict[str, Any] = {}  # endpoint key -> its limiter actor
        self.agent_workers: dict[str, Any] = {}  # a user's agent (model name) -> the model worker of its cells
        self.error: BaseException | None = None
        self.tty = stream.isatty()
        self.last_view = self.last_cell_lines = 0.0
        self.began = self.episodes_at_start = 0.0

    def run(self) -> dict[str, CellOutcome]:
        # Ray at import: loaded by run_suite's ensure_ray by now
        from deepphy.actors.rate_limiter import ensure_limiter

        for cell in self.waiting:
            for endpoint in run_endpoints(cell.config, self.runtime.models_file):
                if endpoint.limiter_key not in self.limiters:
                    limiter = ensure_limiter(endpoint)
                    if limiter is not None:
                        self.limiters[endpoint.limiter_key] = limiter
        self._start_agent_workers()
        self.began, self.episodes_at_start = time.monotonic(), sum(d for d, _ in self.progress.values())
        try:
            with frozen_heap():  # the heap of the start, Ray's included, is not scanned again (deepphy/collector.py)
                outcomes = asyncio.run(self._cells())
        finally:
            for setting in list(self.pools):
                self._release_setting(setting, force=True)
            for limiter in self.limiters.values():
                _kill(limiter)
            self._stop_agent_workers()
            if self.tty and self.show:
                self.stream.write("\n")
                self.stream.flush()
        if self.error is not None:
            raise self.error
        return outcomes

    async def _cells(self) -> dict[str, CellOutcome]:
        """Start cells while there is room, take each as it ends, show the view. Ctrl-C (which
        `asyncio.run` turns into cancelling this task) stops the suite as a failing cell does."""
        outcomes: dict[str, CellOutcome] = {}
        while self.running or (self.waiting and self.error is None):
            try:
                while self.error is None and len(self.running) < CELLS_AT_ONCE and (cell := self._next()):
                    self.running[asyncio.ensure_future(self._evaluate(cell))] = cell
                done, _ = await asyncio.wait(self.running, timeout=TTY_S if self.tty else LOG_S,
                                             return_when=asyncio.FIRST_COMPLETED)
                for task in done:
                    cell = self.running.pop(task)
                    try:
                        outcome = task.result()
                    except BaseException as e:  # noqa: BLE001 - raised once the other cells have stopped
                        self._stop(e)
                        self._say(f"cell {cell.dir} failed: {one_line(str(e)) or type(e).__name__}")
                    else:
                        outcomes[cell.dir] = CellOutcome(cell, outcome.episodes_done, outcome.episodes_total,
                                                         outcome.new_records)
                        self.progress[cell.dir] = (outcome.episodes_done, outcome.episodes_total)
                        self.new_attempts[cell.dir] = outcome.new_records
                        self._say(f"cell {cell.dir}: {outcome.episodes_done}/{outcome.episodes_total} episodes "
                                  f"complete ({outcome.new_records} new attempt records)")
                    self.watched.pop(cell.dir, None)
                    self._release_setting(setting_of(cell.config))
                await self._view()
            except asyncio.CancelledError:  # Ctrl-C: the running cells finish their attempts in flight
                asyncio.current_task().uncancel()  # (so this task's own deadlines work again)
                self._stop(KeyboardInterrupt())
            except BaseException as e:  # the running cells stop before it is raised
                self._stop(e)
                await asyncio.gather(*self.running, return_exceptions=True)
                raise
        return outcomes

    def _start_agent_workers(self) -> None:
        """One model worker per user's agent, for all its cells (one setup, one GPU)."""
        for n, model in enumerate(dict.fromkeys(c.config.model for c in self.waiting if c.config.agent is not None)):
            configs = [c.config for c in self.waiting if c.config.model == model]
            specs = list({c.env: plan(c).spec for c in configs}.values())
            self.agent_workers[model] = make_model_worker(
                model, specs, name=actor_name(self.id, f"agent{n}"), models_file=self.runtime.models_file,
                max_concurrency=max(1000, CELLS_AT_ONCE * self.runtime.max_in_flight), agent=configs[0].agent)

    def _stop_agent_workers(self) -> None:
        import ray  # loaded by run_suite's ensure_ray (a dry run never imports it)

        workers = list(self.agent_workers.values())
        if not workers:
            return
        try:  # an agent's close (its endpoints' connections, what its setup took), then the actor
            ray.wait([w.close.remote() for w in workers], num_returns=len(workers), timeout=CLOSE_TIMEOUT_S)
        except Exception:  # noqa: BLE001 - a lost worker has nothing to close
            pass
        for worker in workers:
            _kill(worker)
        self.agent_workers.clear()

    # -- which cell next, and the workers of its setting ---------------------------------

    def _next(self) -> Cell | None:
        active = set(self.pools)
        room = len(active) < SETTINGS_AT_ONCE
        candidates = [c for c in self.waiting if setting_of(c.config) in active]
        if room:
            fresh = next((setting_of(c.config) for c in self.waiting if setting_of(c.config) not in active), None)
            candidates += [c for c in self.waiting if setting_of(c.config) == fresh]
        if not candidates:
            return None

        def endpoint(cell: Cell) -> str:
            endpoints = run_endpoints(cell.config, self.runtime.models_file)
            return endpoints[0].limiter_key if endpoints else cell.config.model

        busy = [endpoint(c) for c in self.running.values()]
        cell = min(candidates, key=lambda c: (busy.count(endpoint(c)), self.waiting.index(c)))
        self.waiting.remove(cell)
        setting = setting_of(cell.config)
        if setting not in self.pools:
            self.pools[setting] = self._start_workers(cell.config)
        return cell

    def _start_workers(self, config: RunConfig) -> EnvPool:
        setting = plan(config)
        n = self.settings_started
        self.settings_started += 1
        (self.root / LOGS).mkdir(parents=True, exist_ok=True)
        workers = make_env_workers(setting.spec, setting.options, self.runtime, actor_name(self.id, f"{n}-env"),
                                   lambda i: str(self.root / LOGS / f"{n}-{setting.spec.name}-env{i}.log"),
                                   cpus=1 / SETTINGS_AT_ONCE)
        return EnvPool(workers, self.runtime.step_timeout_s)

    def _release_setting(self, setting: str, force: bool = False) -> None:
        """Stop a setting's workers once none of its cells runs or waits."""
        still = any(setting_of(c.config) == setting for c in [*self.waiting, *self.running.values()])
        if setting in self.pools and (force or not still):
            for worker in self.pools.pop(setting).workers:
                _kill(worker)

    async def _evaluate(self, cell: Cell) -> RunOutcome:
        shared = Shared(self.pools[setting_of(cell.config)], lambda m, s: self._watch(cell, m, s), self.agent_workers)
        return await evaluate_cell(cell.config, self.root / cell.dir, self.runtime, shared, stream=self.stream)

    def _watch(self, cell: Cell, metrics: Any, scheduler: Any) -> None:
        self.watched[cell.dir] = (metrics, scheduler)
        if self.error is not None:
            scheduler.stop_requested = True

    def _stop(self, error: BaseException) -> None:
        self.error = self.error or error
        for _, scheduler in list(self.watched.values()):
            scheduler.stop_requested = True

    # -- the progress view ----------------------------------------------------------------

    def _say(self, line: str) -> None:
        if not self.show:
            return
        self.stream.write(("\r\x1b[2K" if self.tty else "") + line + "\n")
        self.stream.flush()
        self.last_view = 0.0  # the suite line again at once, below what was said

    async def _view(self) -> None:
        now = time.monotonic()
        if not self.show or now - self.last_view < (TTY_S if self.tty else LOG_S) - 0.05:
            return
        self.last_view = now
        watched = dict(self.watched)
        snaps: dict[str, dict] = {}
        try:
            async with asyncio.timeout(SNAPSHOT_TIMEOUT_S):
                got = await asyncio.gather(*(m.snapshot.remote() for m, _ in watched.values()))
                snaps = dict(zip(watched, got))
                limits = dict(zip(self.limiters, await asyncio.gather(*(lim.stats.remote()
                                                                        for lim in self.limiters.values()))))
        except Exception:  # noqa: BLE001 - progress is best effort
            return
        for cell, snap in snaps.items():
            self.progress[cell] = (snap["episodes_done"], snap["episodes_total"])
            self.new_attempts[cell] = snap["new_attempts"]
        line = suite_line(self.name, self.wanted, self.progress, len(self.running), sum(self.new_attempts.values()),
                          now - self.began, self.episodes_at_start, limits)
        if self.cell_lines and now - self.last_cell_lines >= LOG_S - 0.05:
            self.last_cell_lines = now
            for cell, snap in snaps.items():
                self.stream.write(("\r\x1b[2K" if self.tty else "") + f"  {cell}: {format_progress(snap)}\n")
        self.stream.write(f"\r\x1b[2K{line}" if self.tty else f"{line}\n")
        self.stream.flush()


def suite_line(name: str, wanted: list[Cell], progress: dict[str, tuple[int, int]], running: int, attempts: int,
               elapsed_s: float, episodes_at_start: float, limits: dict[str, dict]) -> str:
    """The suite's progress line: cells done, episodes, attempts/s, each endpoint's
    requests in its limiter's window against its requests/min, ETA, time taken."""
    cells_done = sum(progress[c.dir][0] == progress[c.dir][1] for c in wanted)
    done = sum(progress[c.dir][0] for c in wanted)
    total = sum(progress[c.dir][1] for c in wanted)
    parts = [f"suite {name}", f"cells {cells_done}/{len(wanted)}" + (f" ({running} running)" if running else ""),
             f"episodes {done}/{total}", f"attempts {attempts}" + _rate(attempts / elapsed_s if elapsed_s else None)]
    for key, stats in limits.items():
        rpm = stats["limits"].get("requests_per_min")
        if rpm:
            used = stats["requests_in_window"]
            parts.append(f"{key} {used}/{rpm:g} per min ({100 * used / rpm:.0f}%)")
    new = done - episodes_at_start
    if new > 0 and done < total:
        parts.append(f"ETA {_duration((total - done) * elapsed_s / new)}")
    parts.append(_duration(elapsed_s))
    return " · ".join(parts)


def _kill(actor: Any) -> None:
    import ray  # loaded by run_suite's ensure_ray (a dry run never imports it)

    try:
        ray.kill(actor)
    except Exception:  # noqa: BLE001 - already gone
        pass

