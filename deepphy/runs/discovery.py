"""Finding runs: run directories on disk, and runs live on a Ray cluster.

On disk a run directory is a folder holding a run's config (`config.json`); a directory
given to a command (a suite root, runs/) stands for the run directories below it. On a
cluster every actor of a run is named `deepphy/<run id>/<role>` (the run id a fresh one per
driver session); a run is found by its metrics actor, whose snapshot names its directory.
"""

from __future__ import annotations

import hashlib
import uuid
from pathlib import Path
from typing import Any

from deepphy.runs.store import CONFIG

RUN_SEARCH_DEPTH = 3  # how many folders below a directory given to a command its runs are looked for
ACTORS = "deepphy"  # the first part of every actor name of a run
METRICS = "metrics"  # the role of a run's metrics actor (what live views ask)
SNAPSHOT_TIMEOUT_S = 5.0  # a live run's metrics actor answers at once; one that does not is skipped


def is_run_dir(path: Path) -> bool:
    return (path / CONFIG).is_file()


def dir_id(path: Path) -> str:
    """A short stable id of a run directory's path (the pages' handle on it; not the run id
    of its Ray actors)."""
    return hashlib.sha1(str(path).encode()).hexdigest()[:10]


def runs_in(path: Path, depth: int = RUN_SEARCH_DEPTH) -> list[Path]:
    """The run directory `path`, or the run directories below it, at most `depth` folders
    down (runs/<model>/<env>/ included). A run directory's own folders and hidden folders
    are not searched."""
    if is_run_dir(path):
        return [path]
    if depth == 0 or not path.is_dir():
        return []
    try:
        children = sorted(p for p in path.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError:  # unreadable: nothing found here
        return []
    return [run for child in children for run in runs_in(child, depth - 1)]


def new_run_id() -> str:
    """The id of a driver session's actors (a run's, or a suite's)."""
    return uuid.uuid4().hex[:8]


def actor_name(run_id: str, role: str) -> str:
    """`deepphy/<run id>/<role>`: what a dashboard or an operator lists (ray.util.list_named_actors)."""
    return f"{ACTORS}/{run_id}/{role}"


def metrics_run_id(name: str) -> str | None:
    """The run id of a run's metrics actor from its name; None for any other actor."""
    parts = name.split("/")
    return parts[1] if len(parts) == 3 and parts[0] == ACTORS and parts[2] == METRICS else None


def live_snapshots(only: str | None = None, timeout_s: float = SNAPSHOT_TIMEOUT_S) -> dict[str, dict[str, Any]]:
    """run id -> the metrics actor's snapshot, for every deepphy run live on the cluster this
    process is connected to (`only`: that run alone). A snapshot carries `run_dir` when the
    run's driver reports it."""
    import ray  # connected already (deepphy.ray_connect): loaded

    out = {}
    for actor in ray.util.list_named_actors(all_namespaces=True):
        run_id = metrics_run_id(actor["name"])
        if run_id is None or only not in (None, run_id):
            continue
        try:
            handle = ray.get_actor(actor["name"], namespace=actor["namespace"])
            out[run_id] = ray.get(handle.snapshot.remote(), timeout=timeout_s)
        except Exception:  # noqa: BLE001 - the run ended between listing and asking
            continue
    return out
