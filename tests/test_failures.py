"""Clear, fast failures and nothing left behind: a cluster that is not there, a killed
driver, a file given as a run directory."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import psutil
import pytest


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.2", 0))
        return s.getsockname()[1]


def cli(*args: str, timeout: float = 60, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "deepphy.cli", *args], capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, **(env or {})})


@pytest.mark.parametrize("command", [
    ["run", "--limit", "1", "--runs", "1"],
    ["watch", "--once"],
    ["dashboard", "--port", "0"],
])
def test_no_cluster_at_the_address_fails_fast_with_one_line_and_creates_nothing(tmp_path, command):
    address = f"127.0.0.2:{free_port()}"  # nothing listens there
    out = tmp_path / "run"
    extra = ["--out", str(out)] if command[0] == "run" else []
    t0 = time.monotonic()
    done = cli(*command, *extra, "--address", address, timeout=120)
    took = time.monotonic() - t0
    assert done.returncode == 2, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert lines == [f"deepphy: error: no Ray cluster answers at {address} (connection refused)"], done.stderr
    assert not out.exists()
    assert took < 30, f"took {took:.0f} s"  # seconds, not Ray's minutes of retries (the CLI's own start is most of it)


def test_report_of_a_file_says_it_is_a_file(tmp_path):
    f = tmp_path / "attempts.jsonl"
    f.write_text("")
    done = cli("report", str(f))
    assert done.returncode == 2 and done.stderr.strip() == f"deepphy: error: {f} is not a run directory (it is a file)"


@pytest.mark.slow
def test_kill_9_of_a_local_run_leaves_no_ray_process_and_the_resume_is_exact(tmp_path):
    """Ray's agents ignore SIGTERM and outlive a killed driver; the watchdog must stop every
    process of the run's local Ray instance within seconds."""
    from deepphy.runs.store import ATTEMPTS, read_records

    out = tmp_path / "run"
    env = {**os.environ}
    env.pop("RAY_ADDRESS", None)
    cmd = [sys.executable, "-m", "deepphy.cli", "run", "--runs", "2", "--out", str(out), "--no-progress"]
    driver = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    try:
        deadline = time.time() + 240
        while time.time() < deadline and driver.poll() is None:
            log = out / ATTEMPTS
            if log.exists() and log.read_bytes().count(b"\n") >= 20:
                break
            time.sleep(0.2)
        assert driver.poll() is None, "the run ended before it could be killed"
        family = [p for p in psutil.Process(driver.pid).children(recursive=True)
                  if "deepphy.reaper" not in " ".join(p.cmdline())]
        names = {p.pid: p.name() for p in family}
        assert any("raylet" in n for n in names.values()) and any("Agent" in n for n in names.values()), names
        os.kill(driver.pid, signal.SIGKILL)
        driver.wait(timeout=30)
        deadline = time.time() + 15
        alive = family
        while alive and time.time() < deadline:
            time.sleep(0.5)
            alive = [p for p in family if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        assert not alive, f"left behind: {sorted(names[p.pid] for p in alive)}"
    finally:
        if driver.poll() is None:
            driver.kill()
    resumed = cli("run", "--runs", "2", "--out", str(out), "--no-progress", timeout=600, env=env)
    assert resumed.returncode == 0, resumed.stderr
    keys = [(r.task, r.run, r.attempt) for r in read_records(out)]
    assert len(keys) == len(set(keys))
