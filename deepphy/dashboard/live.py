"""Runs live on a Ray cluster, found by their named metrics actors (`deepphy/<run id>/metrics`)."""

from __future__ import annotations

from typing import Any

SNAPSHOT_TIMEOUT_S = 5.0


def connect(address: str) -> None:
    from deepphy.config import RuntimeOptions
    from deepphy.runner import ensure_ray

    ensure_ray(RuntimeOptions(address=address))


def live_snapshots() -> dict[str, dict[str, Any]]:
    """run id -> the metrics actor's snapshot, for every deepphy run live on the cluster.
    A snapshot carries `run_dir` when the run's driver reports it."""
    import ray

    out = {}
    for actor in ray.util.list_named_actors(all_namespaces=True):
        name = actor["name"]
        if not (name.startswith("deepphy/") and name.endswith("/metrics")):
            continue
        try:
            handle = ray.get_actor(name, namespace=actor["namespace"])
            out[name.split("/")[1]] = ray.get(handle.snapshot.remote(), timeout=SNAPSHOT_TIMEOUT_S)
        except Exception:  # noqa: BLE001 - the run ended between listing and asking
            continue
    return out
