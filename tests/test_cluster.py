"""A real two-node Ray cluster on loopback (cluster/local-cluster.sh), joined with --address."""

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from deepphy.runs.store import read_records

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_run_on_two_node_cluster_with_env_workers_on_the_physics_node(tmp_path):
    cluster_dir = tempfile.mkdtemp(prefix="dpc", dir="/tmp")  # short: AF_UNIX paths max 107 bytes
    env = {**os.environ, "DEEPPHY_CLUSTER_DIR": cluster_dir, "DEEPPHY_CLUSTER_PORT": "6391",
           "RAY_AUTH_MODE": "token", "RAY": str(Path(sys.executable).parent / "ray")}
    script = ROOT / "cluster" / "local-cluster.sh"
    started = subprocess.run([str(script), "start"], env=env, capture_output=True, text=True, timeout=180)
    try:
        assert started.returncode == 0, started.stderr
        address = started.stdout.strip().splitlines()[-1]
        run = subprocess.run(
            [sys.executable, "-m", "deepphy.cli", "run", "--address", address, "--env-resource", "physics",
             "--limit", "3", "--runs", "1", "--out", str(tmp_path / "run"), "--no-progress"],
            env=env, capture_output=True, text=True, timeout=300,
        )
        # Only the worker node has `physics`: had placement ignored it, workers would pend forever.
        assert run.returncode == 0, run.stderr
        assert len({r.task for r in read_records(tmp_path / "run")}) == 3
    finally:
        subprocess.run([str(script), "stop"], env=env, timeout=60)
        shutil.rmtree(cluster_dir, ignore_errors=True)
