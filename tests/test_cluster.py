"""A real two-node Ray cluster on loopback (cluster/local-cluster.sh), joined with --address:
placement on the node with the custom resource, a clear error for a client without the
cluster's token, and a `stop` that leaves no process behind."""

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil
import pytest

from deepphy.runs.store import read_records

ROOT = Path(__file__).resolve().parents[1]


def cluster_family(cluster_dir: str) -> list[psutil.Process]:
    """The cluster's processes: those naming its directory, and all their descendants."""
    roots = [p for p in psutil.process_iter(["cmdline"]) if cluster_dir in " ".join(p.info["cmdline"] or [])]
    family = {p.pid: p for r in roots for p in [r, *r.children(recursive=True)]}
    return list(family.values())


@pytest.mark.slow
def test_two_node_cluster_run_auth_error_and_clean_stop(tmp_path):
    cluster_dir = tempfile.mkdtemp(prefix="dpc", dir="/tmp")  # short: AF_UNIX paths max 107 bytes
    env = {**os.environ, "DEEPPHY_CLUSTER_DIR": cluster_dir, "DEEPPHY_CLUSTER_PORT": "6391",
           "RAY_AUTH_MODE": "token", "RAY": str(Path(sys.executable).parent / "ray")}
    script = ROOT / "cluster" / "local-cluster.sh"
    started = subprocess.run([str(script), "start"], env=env, capture_output=True, text=True, timeout=180)
    family = []
    try:
        assert started.returncode == 0, started.stderr
        address = started.stdout.strip().splitlines()[-1]
        family = cluster_family(cluster_dir)
        assert any("Agent" in p.name() for p in family), "the agents (renamed processes) are found as descendants"

        # A client without the token: one line naming the address and the setting, nothing written.
        denied = subprocess.run(
            [sys.executable, "-m", "deepphy.cli", "run", "--address", address, "--limit", "1", "--runs", "1",
             "--out", str(tmp_path / "denied"), "--no-progress"],
            env={**env, "RAY_AUTH_MODE": "disabled"}, capture_output=True, text=True, timeout=120,
        )
        assert denied.returncode == 2, denied.stderr
        assert denied.stderr.startswith(f"deepphy: error: the Ray cluster at {address} refused") and \
            "RAY_AUTH_MODE" in denied.stderr and len(denied.stderr.strip().splitlines()) == 1, denied.stderr
        assert not (tmp_path / "denied").exists()

        run = subprocess.run(
            [sys.executable, "-m", "deepphy.cli", "run", "--address", address, "--env-resource", "physics",
             "--limit", "3", "--runs", "1", "--out", str(tmp_path / "run"), "--no-progress"],
            env=env, capture_output=True, text=True, timeout=300,
        )
        # Only the worker node has `physics`: had placement ignored it, workers would pend forever.
        assert run.returncode == 0, run.stderr
        assert len({r.task for r in read_records(tmp_path / "run")}) == 3
        family = {p.pid: p for p in [*family, *cluster_family(cluster_dir)]}.values()
    finally:
        subprocess.run([str(script), "stop"], env=env, timeout=60)
        time.sleep(1)
        left = [p for p in family if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        shutil.rmtree(cluster_dir, ignore_errors=True)
    assert not left, f"left behind by stop: {sorted(p.name() for p in left)}"
