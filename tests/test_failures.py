"""Clear, fast failures and nothing left behind: a cluster that is not there, a killed
driver, a file given as a run directory, a full disk, a read-only or unwritable run
directory, a key the endpoint refuses, a local Ray that does not start, a busy machine."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest
import yaml

from dashboard_support import IPHYRE_TASKS, copy_run, mock_run
from deepphy.local_ray import sessions_of
from deepphy.runs.store import ATTEMPTS, read_records

# Ray workers inherit the environment of the process that starts Ray (the session fixture):
# the key the endpoint refuses is set at import time, before any test runs.
WRONG_KEY = "sk-deepphy-WRONG-key-0123456789"
os.environ["DEEPPHY_WRONG_FAKE_KEY"] = WRONG_KEY


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.2", 0))
        return s.getsockname()[1]


def cli(*args: str, timeout: float = 60, env: dict | None = None, prefix: tuple = ()) -> subprocess.CompletedProcess:
    """The CLI's result, with `.started_ray`: whether it started a local Ray instance."""
    environ = {**os.environ, **(env or {})}
    environ.pop("RAY_ADDRESS", None)
    started = time.time()
    proc = subprocess.Popen([*prefix, sys.executable, "-m", "deepphy.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=environ)
    out, err = proc.communicate(timeout=timeout)
    done = subprocess.CompletedProcess(proc.args, proc.returncode, out, err)
    # a session named after this pid but older is another process's (pids are reused on a busy machine)
    done.started_ray = any(os.path.getmtime(s) >= started - 1 for s in sessions_of(proc.pid))
    return done


def one_error_line(done: subprocess.CompletedProcess) -> str:
    """The run's one `deepphy: error:` line (and no traceback anywhere)."""
    errors = [line for line in done.stderr.splitlines() if line.startswith("deepphy: error: ")]
    assert done.returncode == 2 and len(errors) == 1 and "Traceback" not in done.stderr, done.stderr[-3000:]
    return errors[0]


def views(path) -> list[str]:
    return sorted(json.dumps(r.deterministic_view(), sort_keys=True) for r in read_records(path))


MOCK_ARGS = ["--tasks", ",".join(IPHYRE_TASKS), "--runs", "2", "--seed", "3", "--env-workers", "2", "--no-progress"]


@pytest.fixture
def small_fs(tmp_path):
    """mount(size_kb) -> a fresh tmpfs of that size (needs root; skipped otherwise)."""
    points = []

    def mount(size_kb: int) -> Path:
        point = tmp_path / f"fs{len(points)}"
        point.mkdir()
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kb}k", "tmpfs", str(point)],
                              capture_output=True, text=True)
        if done.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here (root is needed): {done.stderr.strip()}")
        points.append(point)
        return point

    yield mount
    for point in points:
        subprocess.run(["umount", "-l", str(point)], capture_output=True)


def remount(point: Path, options: str) -> None:
    subprocess.run(["mount", "-o", f"remount,{options}", str(point)], check=True)


@pytest.mark.parametrize("command", [
    ["run", "--limit", "1", "--runs", "1"],
    ["watch", "--once"],
    ["dashboard", "--port", "0"],
])
def test_no_cluster_at_the_address_fails_fast_with_one_line_and_creates_nothing(tmp_path, command):
    address = f"127.0.0.2:{free_port()}"  # nothing listens there
    out = tmp_path / "run"
    extra = ["--out", str(out)] if command[0] == "run" else []
    done = cli(*command, *extra, "--address", address, timeout=120)  # not Ray's minutes of retries
    assert one_error_line(done) == f"deepphy: error: no Ray cluster answers at {address} (connection refused)"
    assert len(done.stderr.splitlines()) <= 2  # a progress line saying what it tried, at most
    assert not out.exists()


def test_report_of_a_file_says_it_is_a_file(tmp_path):
    f = tmp_path / "attempts.jsonl"
    f.write_text("")
    done = cli("report", str(f))
    assert done.returncode == 2 and done.stderr.strip() == f"deepphy: error: {f} is not a run directory (it is a file)"


@pytest.mark.slow
def test_kill_9_of_a_local_run_leaves_no_ray_process_and_the_resume_is_exact(tmp_path):
    """Ray's agents ignore SIGTERM and outlive a killed driver; the watchdog must stop every
    process of the run's local Ray instance within seconds."""
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


# -- the disk ---------------------------------------------------------------------------


def test_a_full_disk_stops_the_store_with_one_line_and_leaves_no_temporary_file(small_fs):
    from deepphy.config import RunConfig
    from deepphy.runs.records import AttemptRecord, StepRecord
    from deepphy.runs.store import RunStore, RunWriteError

    fs = small_fs(96)
    store = RunStore.create_or_resume(fs / "run", RunConfig(runs=1))
    with pytest.raises(RunWriteError) as e:
        for i in range(1000):
            store.write_frame("support", 0, i + 1, "s1_outcome", os.urandom(6000))
    assert "No space left on device" in str(e.value) and "\n" not in str(e.value)
    assert not list((fs / "run").rglob("*.tmp"))
    # a record that does not fit is cut off again: the log stays whole lines
    (fs / "run" / "frames" / "support" / "r0_a1_s1_outcome.png").unlink()  # room for part of a record
    big = AttemptRecord(env="iphyre", task="support", run=0, attempt=1, model="mock", format="vla", seed=0,
                        steps=[StepRecord(step=1, prompt="ab12cd34", raw_output="x" * 30_000)], success=False)
    with pytest.raises(RunWriteError):
        for _ in range(10):
            store.append(big)
    store.close()
    data = (fs / "run" / ATTEMPTS).read_bytes()
    assert data.endswith(b"\n") or data == b""
    assert len(read_records(fs / "run")) == data.count(b"\n")


def test_a_prompt_line_that_does_not_fit_is_cut_off(small_fs):
    """The episode's prompt log stays whole lines when the disk fills up in the middle of one."""
    from deepphy.chat import Message, TextPart
    from deepphy.config import RunConfig
    from deepphy.prompts import prompt_digest
    from deepphy.runs.store import RunStore, RunWriteError, episode_prompts

    fs = small_fs(64)
    store = RunStore.create_or_resume(fs / "run", RunConfig(runs=1))
    with pytest.raises(RunWriteError) as e:
        for i in range(1000):
            messages = [Message(role="user", content=[TextPart(text=f"decision {i}: " + "y" * 5000)])]
            store.write_prompt("support", 0, prompt_digest(messages), messages)
    store.close()
    assert "cannot write prompts/support/r0.jsonl" in str(e.value) and "\n" not in str(e.value)
    data = (fs / "run" / "prompts" / "support" / "r0.jsonl").read_bytes()
    assert data.endswith(b"\n") and len(episode_prompts(fs / "run", "support", 0)) == data.count(b"\n") == i


@pytest.mark.slow
def test_a_full_disk_mid_run_is_one_line_and_the_resume_is_exact(ray_cluster, tmp_path_factory, small_fs):
    reference = mock_run(tmp_path_factory)
    fs = small_fs(320)
    out = fs / "run"
    args = ["run", *MOCK_ARGS, "--address", ray_cluster, "--out", str(out)]
    line = one_error_line(cli(*args, timeout=600))
    assert "No space left on device" in line and "run the same command again to resume" in line
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]
    assert 0 < len(read_records(out)) < len(read_records(reference))
    remount(fs, "size=16m")
    again = cli(*args, timeout=600)
    assert again.returncode == 0, again.stderr[-2000:]
    assert views(out) == views(reference)


def test_a_read_only_run_directory(tmp_path_factory, small_fs):
    """An unfinished run there fails with one line before Ray starts; a finished one says
    it is complete, also without Ray."""
    reference = mock_run(tmp_path_factory)
    fs = small_fs(8192)
    copy_run(reference, fs / "partial", lines=10)
    shutil.copytree(reference, fs / "complete")
    remount(fs, "ro")
    failed = cli("run", *MOCK_ARGS, "--out", str(fs / "partial"), timeout=120)
    assert "Read-only file system" in one_error_line(failed) and not failed.started_ray
    finished = cli("run", *MOCK_ARGS, "--out", str(fs / "complete"), timeout=120)
    assert finished.returncode == 0 and "(12/12 episodes complete, 0 new attempt records)" in finished.stdout
    assert not finished.started_ray


def test_an_unwritable_run_directory(tmp_path_factory, tmp_path):
    """EACCES: root without its file-permission override (as a user is) meets a read-only
    mode."""
    if os.geteuid() != 0 or not shutil.which("setpriv"):
        pytest.skip("needs root and setpriv (to drop the permission override)")
    reference = mock_run(tmp_path_factory)
    copy_run(reference, tmp_path / "partial", lines=10)
    for p in [tmp_path / "partial", *(tmp_path / "partial").rglob("*")]:
        p.chmod(0o555 if p.is_dir() else 0o444)
    try:
        failed = cli("run", *MOCK_ARGS, "--out", str(tmp_path / "partial"), timeout=120,
                     prefix=("setpriv", "--bounding-set=-dac_override,-dac_read_search"))
    finally:
        for p in [tmp_path / "partial", *(tmp_path / "partial").rglob("*")]:
            p.chmod(0o755 if p.is_dir() else 0o644)
    assert "Permission denied" in one_error_line(failed) and not failed.started_ray


# -- before Ray -------------------------------------------------------------------------


def test_checks_that_need_no_ray_fail_before_ray_starts(tmp_path_factory, tmp_path):
    reference = mock_run(tmp_path_factory)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("")
    gap = tmp_path / "gap"
    copy_run(reference, gap, lines=0)
    lines = (reference / ATTEMPTS).read_bytes().splitlines(keepends=True)
    records = read_records(reference)  # the lines' order depends on timing: find an attempt 1 with a second
    first = next(i for i, r in enumerate(records) if r.attempt == 1 and any(
        (x.task, x.run, x.attempt) == (r.task, r.run, 2) for x in records))
    (gap / ATTEMPTS).write_bytes(b"".join(lines[:first] + lines[first + 1:]))
    cases = {
        "is not empty and holds no run": ["--out", str(tmp_path / "mine")],
        "holds a run with a different config": ["--out", str(reference), "--seed", "4"],
        "is missing; run `deepphy repair": ["--out", str(gap)],
    }
    for words, extra in cases.items():
        done = cli("run", *MOCK_ARGS, *extra)  # the last --seed counts
        assert words in one_error_line(done) and not done.started_ray, words
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["thesis.tex"]


def test_a_finished_run_says_so_without_starting_ray(tmp_path_factory):
    reference = mock_run(tmp_path_factory)
    done = cli("run", *MOCK_ARGS, "--out", str(reference))
    assert done.returncode == 0 and "(12/12 episodes complete, 0 new attempt records)" in done.stdout
    assert not done.started_ray


def test_a_local_ray_that_does_not_start_is_one_line_with_its_logs(tmp_path):
    """Ray's own wait for its GCS cut to nothing: every try fails; the run says why, where
    the logs are, and leaves neither a directory nor a process behind."""
    out = tmp_path / "run"
    done = cli("run", "--tasks", "support", "--runs", "1", "--out", str(out), timeout=300,
               env={"RAY_gcs_server_port_wait_time_s": "0"})
    line = one_error_line(done)
    assert "the local Ray instance did not start (3 tries; last: " in line and "its logs: " in line
    logs = line.rsplit("its logs: ", 1)[1]
    assert Path(logs).is_dir() and Path(logs).parent.name.startswith("session_")
    assert done.stderr.splitlines()[0] == "starting Ray (local, 2 CPUs) ..."  # said at once
    assert not out.exists()
    time.sleep(3)  # the watchdog's sweep after the driver's exit
    assert not _session_processes(Path(logs).parent)


def test_the_agents_ports_are_free_and_outside_the_range_the_kernel_hands_out(tmp_path, monkeypatch):
    """Ray's processes bind port 0 and connect out while its agents still import: a port
    chosen in the kernel's ephemeral range was taken before the dashboard agent bound it (the
    raylet died with the agent). The agents' ports are chosen below that range, free on
    every address; where the machine leaves no room below it, from the kernel as before."""
    import socket

    from deepphy import local_ray

    ephemeral = int(Path(local_ray.EPHEMERAL_RANGE).read_text().split()[0])
    ports = local_ray.free_ports("127.0.0.1", 4)
    assert len(set(ports)) == 4
    assert all(local_ray.AGENT_PORTS[0] <= p < min(local_ray.AGENT_PORTS[1], ephemeral) for p in ports), ports
    assert all(local_ray._bindable(p, "127.0.0.1") for p in ports)
    with socket.socket() as held:
        held.bind(("127.0.0.1", ports[0]))
        assert not local_ray._bindable(ports[0], "127.0.0.1")  # in use on one address: not free
    squeezed = tmp_path / "ip_local_port_range"
    squeezed.write_text(f"{local_ray.AGENT_PORTS[0] + 500}\t60999\n")
    monkeypatch.setattr(local_ray, "EPHEMERAL_RANGE", str(squeezed))
    fallback = local_ray.free_ports("127.0.0.1", 4)
    assert len(set(fallback)) == 4 and all(local_ray._bindable(p, "127.0.0.1") for p in fallback)


def _session_processes(session: Path) -> list[str]:
    found = []
    for p in psutil.process_iter():
        try:
            if any(f.path.startswith(str(session)) for f in p.open_files()):
                found.append(p.name())
        except psutil.Error:
            continue
    return found


# -- the model endpoint -----------------------------------------------------------------


def test_a_refused_key_stops_the_run_at_once_with_one_line(ray_cluster, tmp_path, monkeypatch):
    from deepphy.testing.model_server import ServerConfig, ServerThread

    monkeypatch.setenv("DEEPPHY_RIGHT_KEY", "sk-right")
    with ServerThread(ServerConfig(require_key_env="DEEPPHY_RIGHT_KEY")) as server:
        models = tmp_path / "models.yaml"
        models.write_text(yaml.safe_dump({"models": [{
            "name": "local", "provider": "openai", "model": "deepphy-mock", "base_url": server.url + "/v1",
            "api_key_env": "DEEPPHY_WRONG_FAKE_KEY", "send_context": True}]}))
        done = cli("run", "--model", "local", "--models-file", str(models), "--tasks", "support,hinder,hole",
                   "--runs", "2", "--address", ray_cluster, "--no-progress", "--out", str(tmp_path / "run"),
                   timeout=300)
        requests = server.stats()["requests"]
    line = one_error_line(done)
    assert f"model local at {server.url}/v1 refused the key in $DEEPPHY_WRONG_FAKE_KEY: HTTP 401" in line
    assert WRONG_KEY not in done.stderr + done.stdout
    assert requests <= 6, requests  # at once: no retries, no re-queues
    assert read_records(tmp_path / "run") == []


# -- leftovers --------------------------------------------------------------------------


def _benchmark_server(bench: subprocess.Popen) -> psutil.Process:
    deadline = time.time() + 120
    while time.time() < deadline and bench.poll() is None:
        for child in psutil.Process(bench.pid).children():
            if "deepphy.testing.model_server" in " ".join(child.cmdline()):
                return child
        time.sleep(0.05)
    raise AssertionError("the benchmark's model server was not seen")


@pytest.mark.slow
@pytest.mark.parametrize("how", ["ray does not start", "kill -9"])
def test_the_rate_limit_benchmark_leaves_no_model_server(how):
    env = {**os.environ, "RAY_gcs_server_port_wait_time_s": "0"} if how == "ray does not start" else dict(os.environ)
    bench = subprocess.Popen([sys.executable, "benchmarks/model_rate_limit.py", "--duration", "60"],
                             cwd=Path(__file__).resolve().parents[1], env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        server = _benchmark_server(bench)
        if how == "kill -9":
            bench.kill()
        _, err = bench.communicate(timeout=300)
        if how == "ray does not start":
            assert bench.returncode != 0 and "did not start" in err and "Traceback" not in err, err[-2000:]
        server.wait(timeout=30)  # raises if it is still there
    finally:
        if bench.poll() is None:
            bench.kill()


# -- a busy machine ---------------------------------------------------------------------


@pytest.mark.slow
def test_four_local_runs_started_at_once_all_complete(tmp_path):
    """Each starts its own local Ray on this host at the same moment (they used to collide
    on the dashboard agent's fixed port, and to time out while the agents started)."""
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    runs = [subprocess.Popen([sys.executable, "-m", "deepphy.cli", "run", "--tasks", "support,hinder", "--runs", "1",
                              "--seed", str(i), "--no-progress", "--out", str(tmp_path / f"run{i}")],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env) for i in range(4)]
    try:
        results = [(p.pid, *p.communicate(timeout=1500), p.returncode) for p in runs]
    finally:
        for p in runs:
            if p.poll() is None:
                p.kill()
    for pid, out, err, rc in results:
        assert rc == 0 and "(2/2 episodes complete" in out, err[-3000:]
    time.sleep(3)
    assert not [name for pid, *_ in results for s in sessions_of(pid) for name in _session_processes(Path(s))]


@pytest.mark.slow
def test_a_run_on_saturated_cores_starts_or_fails_with_one_line(tmp_path):
    """Both cores busy with a loop each (at the run's own priority): the run completes, or
    ends with one line that says why; never a traceback."""
    loops = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(os.cpu_count() or 2)]
    try:
        done = cli("run", "--tasks", "support,hinder", "--runs", "1", "--out", str(tmp_path / "run"), timeout=1500)
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()
    if done.returncode == 0:
        assert "(2/2 episodes complete" in done.stdout
    else:
        one_error_line(done)
    assert done.stderr.splitlines()[0] == "starting Ray (local, 2 CPUs) ..."


@pytest.mark.slow
def test_kill_9_while_ray_starts_leaves_no_ray_process(tmp_path):
    """Killed while Ray's agents are starting (the watchdog used to start only after Ray)."""
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    driver = subprocess.Popen([sys.executable, "-m", "deepphy.cli", "run", "--tasks", "support", "--runs", "1",
                               "--out", str(tmp_path / "run")],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    seen: dict[int, psutil.Process] = {}
    try:
        deadline = time.time() + 300
        while time.time() < deadline and driver.poll() is None:
            for p in psutil.Process(driver.pid).children(recursive=True):
                seen.setdefault(p.pid, p)
            try:
                names = " ".join(" ".join(p.cmdline()) for p in seen.values() if p.is_running())
            except psutil.Error:
                continue
            if "dashboard/agent.py" in names or "DashboardAgent" in names:
                break
            time.sleep(0.02)
        assert driver.poll() is None, "the run ended before Ray's agents started"
        assert not (tmp_path / "run" / ATTEMPTS).exists() or not (tmp_path / "run" / ATTEMPTS).read_bytes()
        driver.kill()
        driver.wait(timeout=30)
    finally:
        if driver.poll() is None:
            driver.kill()
    ray_family = {pid: p for pid, p in seen.items() if "deepphy.reaper" not in " ".join(_cmdline(p))}
    deadline = time.time() + 20
    alive = list(ray_family.values())
    while alive and time.time() < deadline:
        time.sleep(0.5)
        alive = [p for p in alive if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
    assert not alive, f"left behind: {[_cmdline(p)[:2] for p in alive]}"


def _cmdline(p: psutil.Process) -> list[str]:
    try:
        return p.cmdline()
    except psutil.Error:
        return []
