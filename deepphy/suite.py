"""Suites: the benchmark's grid as one unit of work (`deepphy run --suite paper|FILE.yaml`).

A suite file names environments (each with fixed options and option axes, e.g. Kinetix
`annotate: [true, false]`), prompt formats, repetitions, a seed and default models; `--model
a,b` replaces the models. Its cells are environments x option values x models x formats,
and each cell is an ordinary run directory under the suite root,
`ROOT/<model>/<env>[-<option>=<value>...]/<format>`, holding its `runs` repetitions, so
report, dashboard, plot, export, repair and resume work on a cell as on any run. The
root's `suite.json` (the manifest) names every cell and its config.

Re-running the same command resumes every cell. A suite whose cells changed is refused
(a cell's config differs, or a cell is gone); one that only adds cells (another model,
say) extends the manifest. Every cell is checked (options, tasks, models and keys, its
directory) before Ray starts; the cells then run one after another in ONE Ray runtime,
started once (not interleaved: each cell has the runtime's CPUs to itself), and the cells
of one environment setting (consecutive: cells are ordered by setting) share its
environment workers, started once (their output goes to `ROOT/logs/`).
"""

from __future__ import annotations

import itertools
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from deepphy.chat import PromptFormat
from deepphy.config import RunConfig, RuntimeOptions

MANIFEST = "suite.json"
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

    @field_validator("axes")
    @classmethod
    def _axes_have_values(cls, axes: dict[str, list[Any]]) -> dict[str, list[Any]]:
        empty = [k for k, values in axes.items() if not values]
        if empty:
            raise ValueError(f"axis {empty[0]} has no values")
        return axes


class Suite(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str = Field(pattern=r"^[A-Za-z0-9._-]+$")
    description: str = ""
    envs: list[SuiteEnv] = Field(min_length=1)
    formats: list[PromptFormat] = Field([PromptFormat.VLA, PromptFormat.WM], min_length=1)
    runs: int = Field(3, ge=1)
    seed: int = 0
    models: list[str] = Field(["mock"], min_length=1)


@dataclass(frozen=True)
class Cell:
    dir: str  # relative to the suite root
    config: RunConfig


def load_suite(name_or_path: str) -> Suite:
    """A shipped suite by name, or a suite file."""
    path = SHIPPED / f"{name_or_path}.yaml" if re.fullmatch(r"[a-z0-9_-]+", name_or_path) else None
    if path is None or not path.is_file():
        path = Path(name_or_path)
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in SHIPPED.glob("*.yaml")))
        raise SuiteError(f"no suite {name_or_path!r}: give a suite file or one of {known}")
    try:
        data = yaml.safe_load(path.read_text())
        return Suite.model_validate(data)
    except OSError as e:
        raise SuiteError(f"suite file {path}: {e.strerror or e}") from None
    except yaml.YAMLError as e:
        raise SuiteError(f"suite file {path}: not valid YAML ({_one_line(str(e))})") from None
    except ValidationError as e:
        err = e.errors()[0]
        where = ".".join(map(str, err["loc"]))
        raise SuiteError(f"suite file {path}: {where}: {err['msg'].removeprefix('Value error, ')}") from None


def _name_part(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value)
    return re.sub(r"[^A-Za-z0-9._=+-]", "_", text)


def cells(suite: Suite, models: list[str] | None = None) -> list[Cell]:
    """Every cell: environments x option values x models x formats, in that order."""
    out: list[Cell] = []
    for entry in suite.envs:
        keys = list(entry.axes)
        for values in itertools.product(*(entry.axes[k] for k in keys)):
            options = {**entry.options, **dict(zip(keys, values))}
            setting = entry.env + "".join(f"-{_name_part(k)}={_name_part(v)}" for k, v in sorted(options.items()))
            for model in models or suite.models:
                for fmt in suite.formats:
                    try:
                        config = RunConfig(env=entry.env, model=model, format=fmt, runs=suite.runs, seed=suite.seed,
                                           tasks=entry.tasks, limit=entry.limit, max_attempts=entry.max_attempts,
                                           env_options=options)
                    except ValidationError as e:
                        raise SuiteError(f"suite {suite.name}, {setting}: "
                                         f"{e.errors()[0]['msg'].removeprefix('Value error, ')}") from None
                    out.append(Cell(f"{_name_part(model)}/{setting}/{fmt.value}", config))
    seen: dict[str, Cell] = {}
    for cell in out:
        if cell.dir in seen:
            raise SuiteError(f"suite {suite.name}: two cells would share the directory {cell.dir}; give their "
                             "environments different options")
        seen[cell.dir] = cell
    return out


def _manifest(suite: Suite, cell_list: list[Cell]) -> dict[str, Any]:
    return {"suite": suite.name, "description": suite.description,
            "cells": [{"dir": c.dir, "config": c.config.model_dump(mode="json")} for c in cell_list]}


def read_manifest(root: Path) -> list[Cell]:
    """The cells a suite root's manifest names (validated: each a directory inside the root)."""
    path = root / MANIFEST
    try:
        data = json.loads(path.read_text())
        listed = [Cell(str(c["dir"]), RunConfig.model_validate(c["config"])) for c in data["cells"]]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise SuiteError(f"{path} is not a suite manifest ({_one_line(str(e))[:200]})") from None
    for cell in listed:
        if not re.fullmatch(r"[A-Za-z0-9._=+-]+(/[A-Za-z0-9._=+-]+)*", cell.dir) or ".." in cell.dir.split("/"):
            raise SuiteError(f"{path} names a cell outside the suite root: {cell.dir[:100]!r}")
    return listed


def plan(suite: Suite, root: str | Path, models: list[str] | None, models_file: str | None) -> list[Cell]:
    """The cells to run into `root`, every check that needs no Ray done (and nothing
    written): the root is new, empty or this suite's; each cell's options, tasks and
    model (its key included) are valid and its directory new or holding that config."""
    from deepphy.agents import endpoint_config, make_agent
    from deepphy.runner import resolve
    from deepphy.runs.store import RunStore

    root = Path(root)
    wanted = cells(suite, models)
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
    for model in dict.fromkeys(c.config.model for c in wanted):
        endpoint_config(model, models_file)
        make_agent(model, models_file)  # a missing key fails here
    for cell in wanted:
        resolve(cell.config)
        RunStore.check(root / cell.dir, cell.config)
    return wanted


@dataclass
class CellOutcome:
    cell: Cell
    done: int
    total: int
    new_records: int


def run_suite(suite: Suite, root: str | Path, runtime: RuntimeOptions, models: list[str] | None = None,
              stream=sys.stderr) -> list[CellOutcome]:
    """Run (or resume) every cell of `suite` into `root`, one after another in one Ray
    runtime (started here unless this process is connected already)."""
    from deepphy.runner import EnvWorkerPool, ensure_ray, evaluate, episodes_done
    from deepphy.runs.store import _atomic_write

    root = Path(root)
    wanted = plan(suite, root, models, runtime.models_file)
    added = len(wanted) - len(read_manifest(root)) if (root / MANIFEST).exists() else 0
    try:
        root.mkdir(parents=True, exist_ok=True)
        _atomic_write(root / MANIFEST, json.dumps(_manifest(suite, wanted), indent=2).encode())
    except OSError as e:
        raise SuiteError(f"cannot write {root / MANIFEST}: {e.strerror or e}") from None
    if added:
        print(f"suite {suite.name}: extended by {added} cell(s)", file=stream, flush=True)
    progress = {c.dir: episodes_done(c.config, root / c.dir) for c in wanted}
    left = [c for c in wanted if progress[c.dir][0] < progress[c.dir][1]]
    outcomes: list[CellOutcome] = []
    started = ensure_ray(runtime, lambda line: print(f"{line} ...", file=stream, flush=True)) if left else False
    pool = EnvWorkerPool(root / LOGS)
    try:
        for i, cell in enumerate(wanted, 1):
            if cell not in left:
                outcomes.append(CellOutcome(cell, *progress[cell.dir], 0))
                continue
            print(f"suite {suite.name}: cell {i}/{len(wanted)} {cell.dir}", file=stream, flush=True)
            outcome = evaluate(cell.config, root / cell.dir, runtime, stream=stream, env_pool=pool)
            outcomes.append(CellOutcome(cell, outcome.episodes_done, outcome.episodes_total, outcome.new_records))
    finally:
        pool.close()
        if started:
            import ray

            ray.shutdown()
    return outcomes


def _one_line(text: str) -> str:
    return " ".join(line.strip() for line in text.splitlines() if line.strip())
