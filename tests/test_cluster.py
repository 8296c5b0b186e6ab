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


def cluster_family(cluster_dir: str, port: int) -> list[psutil.Process]:
    """The cluster's processes: those naming its directory or its head's address (the Ray
    client server), and all their descendants."""
    roots = [p for p in psutil.process_iter(["cmdline"])
             if cluster_dir in " ".join(p.info["cmdline"] or [])
             or f"--address=127.0.0.2:{port}" in (p.info["cmdline"] or [])]
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
        family = cluster_family(cluster_dir, 6391)
        assert any("Agent" in p.name() for p in family), "the agents (renamed processes) are found as descendants"
        assert any("ray.util.client.server" in " ".join(p.cmdline()) for p in family), "the Ray client server"

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
        family = {p.pid: p for p in [*family, *cluster_family(cluster_dir, 6391)]}.values()
    finally:
        subprocess.run([str(script), "stop"], env=env, timeout=60)
        time.sleep(1)
        left = [p for p in family if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        shutil.rmtree(cluster_dir, ignore_errors=True)
    assert not left, f"left behind by stop: {sorted(p.name() for p in left)}"


@pytest.mark.slow
def test_a_node_that_dies_mid_run_loses_nothing(tmp_path):
    """Kill the worker node's raylet mid-run: its environment worker is restarted on the
    head, the attempts it held are run again, and the records equal an uninterrupted run."""
    from deepphy.runs.store import ATTEMPTS

    cluster_dir = tempfile.mkdtemp(prefix="dpn", dir="/tmp")
    env = {**os.environ, "DEEPPHY_CLUSTER_DIR": cluster_dir, "DEEPPHY_CLUSTER_PORT": "6392", "HEAD_CPUS": "2",
           "WORKER_CPUS": "1", "RAY_AUTH_MODE": "token", "RAY": str(Path(sys.executable).parent / "ray")}
    script = ROOT / "cluster" / "local-cluster.sh"
    started = subprocess.run([str(script), "start"], env=env, capture_output=True, text=True, timeout=180)
    family = cluster_family(cluster_dir, 6392)
    try:
        assert started.returncode == 0, started.stderr
        address = started.stdout.strip().splitlines()[-1]
        # Long enough (~700 attempts) that the node dies mid-run: attempts cost ~15 ms since the
        # PNG encoding got cheaper, and 32 episodes could end before the kill.
        run = [sys.executable, "-m", "deepphy.cli", "run", "--address", address, "--env-workers", "2",
               "--limit", "40", "--runs", "3", "--seed", "4", "--no-progress"]
        whole = subprocess.run([*run, "--out", str(tmp_path / "whole")], env=env, capture_output=True, text=True,
                               timeout=600)
        assert whole.returncode == 0, whole.stderr

        out = tmp_path / "cut"
        driver = subprocess.Popen([*run, "--out", str(out)], env=env, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        deadline = time.time() + 300
        while time.time() < deadline and driver.poll() is None:
            if (out / ATTEMPTS).exists() and (out / ATTEMPTS).read_bytes().count(b"\n") >= 10:
                break
            time.sleep(0.1)
        raylet = next(p for p in psutil.process_iter(["cmdline"])
                      if "raylet" in " ".join(p.info["cmdline"] or []) and "127.0.0.3" in " ".join(p.info["cmdline"]))
        on_node = [c.name() for c in raylet.children(recursive=True)]
        assert any("EnvWorker" in n for n in on_node), f"no environment worker on the worker node: {on_node}"
        assert driver.poll() is None, "the run ended before the node could be killed"
        killed_at = time.time()
        raylet.kill()
        _, err = driver.communicate(timeout=900)
        assert driver.returncode == 0, err
        reruns = err.count("lost its worker")  # the scheduler's warnings: attempts run again
        assert reruns >= 1, err

        def views(path):
            return sorted((r.deterministic_view() for r in read_records(path)),
                          key=lambda v: (v["task"], v["run"], v["attempt"]))

        records = read_records(out)
        keys = [(r.task, r.run, r.attempt) for r in records]
        assert len(keys) == len(set(keys)), "an attempt was recorded twice"
        assert views(out) == views(tmp_path / "whole")
        ends = sorted(r.timing.finished for r in records)
        after = [t for t in ends if t > killed_at]
        gaps = [b - a for a, b in zip(ends, ends[1:]) if b > killed_at]
        print(f"node killed after {len(ends) - len(after)} records; {reruns} attempt re-runs; "
              f"{len(after)} records after it, the first {after[0] - killed_at:.1f} s later; "
              f"longest pause between records afterwards {max(gaps):.1f} s; run ended "
              f"{ends[-1] - killed_at:.0f} s after the kill")
    finally:
        subprocess.run([str(script), "stop"], env=env, timeout=60)
        time.sleep(1)
        left = [p for p in family if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        shutil.rmtree(cluster_dir, ignore_errors=True)
    assert not left, f"left behind by stop: {sorted(p.name() for p in left)}"
