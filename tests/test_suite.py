"""Suites (`deepphy run --suite`): a cell per environment setting x model x format, each an
ordinary run directory under the suite root, run in one Ray runtime, resumed as a whole."""

import io
import json
import os
import re
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest
import yaml

from deepphy.cli import main
from deepphy.config import RuntimeOptions
from deepphy.metrics.report import departures, report_of
from deepphy.runner import evaluate
from deepphy.runs.store import ATTEMPTS, read_config, read_records
from deepphy.runs.manifest import MANIFEST, read_manifest
from deepphy.suite import Suite, SuiteError, cells, checked_cells, load_suite, run_suite

SMALL = {
    "name": "small",
    "envs": [{"env": "iphyre", "tasks": ["support", "hinder"]}, {"env": "phyre", "limit": 2}],
    "formats": ["vla", "wm"],
    "runs": 1,
    "seed": 4,
}
RUNTIME = RuntimeOptions(progress=False, env_workers=2)


def views(path):
    return sorted((r.deterministic_view() for r in read_records(path)), key=lambda v: (v["task"], v["run"], v["attempt"]))


def test_the_paper_suite_is_the_reference_grid():
    """The paper's set-up: its prompts and options, PHYRE with the 5 runs its Pass@5 needs, and
    the reference rules of Pooltool."""
    suite = load_suite("paper")
    grid = cells(suite, ["mock", "gpt-4o"])
    settings = ["phyre", "iphyre", "kinetix-annotate=true", "kinetix-annotate=false", "pooltool-rules=reference",
                "angrybirds", "cuttherope"]
    assert [c.dir for c in grid] == [f"{m}/{s}/{f}" for s in settings for m in ("mock", "gpt-4o") for f in ("vla", "wm")]
    assert {(c.config.runs, c.config.seed, c.config.tasks, c.config.limit) for c in grid if c.config.env != "phyre"} == {
        (3, 0, None, None)}
    assert {c.config.runs for c in grid if c.config.env == "phyre"} == {5}
    assert {c.config.prompts for c in grid} == {"paper"}
    assert all(departures(c.config) == [] for c in grid)
    assert [c.config.env_options for c in grid if c.config.env == "kinetix"][::4] == [{"annotate": True},
                                                                                     {"annotate": False}]
    assert [c.dir for c in cells(suite)][:2] == ["mock/phyre/vla", "mock/phyre/wm"]  # the suite's default models


@pytest.fixture(scope="module")
def suite_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("suite-file") / "small.yaml"
    path.write_text(yaml.safe_dump(SMALL))
    return path


SPANS: dict[str, tuple[float, float]] = {}  # cell -> (start, end) of its evaluate in the `done` suite
THREADS: set[str] = set()  # the threads the `done` suite's cells ran on


@pytest.fixture(scope="module")
def done(ray_cluster, suite_file, tmp_path_factory):
    """The small suite, run once without interruption in the session's Ray runtime (each
    cell's evaluate timed, in SPANS)."""
    import deepphy.suite

    root = tmp_path_factory.mktemp("suite") / "root"
    evaluate_cell = deepphy.suite.evaluate_cell

    async def timed(config, out, *args, **kw):
        THREADS.add(threading.current_thread().name)
        start = time.monotonic()
        try:
            return await evaluate_cell(config, out, *args, **kw)
        finally:
            SPANS[str(Path(out).relative_to(root))] = (start, time.monotonic())

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(deepphy.suite, "evaluate_cell", timed)
        outcomes = run_suite(load_suite(str(suite_file)), root, RUNTIME)
    assert [(o.done, o.total) for o in outcomes] == [(2, 2)] * 2 + [(2, 2)] * 2
    return root


def test_cells_run_at_once_and_record_what_each_records_alone(done, tmp_path):
    # Two settings (I-PHYRE, PHYRE) x two formats: all four cells start before any ends, in
    # one event loop on the calling thread (no thread per cell).
    assert sorted(SPANS) == [c.dir for c in read_manifest(done)]
    assert max(start for start, _ in SPANS.values()) < min(end for _, end in SPANS.values())
    assert THREADS == {threading.main_thread().name}
    cell = read_manifest(done)[3]  # mock/phyre/wm, run alone (its own workers and Ray calls)
    assert evaluate(cell.config, tmp_path / "alone", RUNTIME).complete
    assert views(tmp_path / "alone") == views(done / cell.dir)


def test_every_cell_is_a_run_directory_named_by_the_manifest(done):
    listed = read_manifest(done)
    assert [c.dir for c in listed] == ["mock/iphyre/vla", "mock/iphyre/wm", "mock/phyre/vla", "mock/phyre/wm"]
    for cell in listed:
        assert read_config(done / cell.dir) == cell.config
        report = report_of(done / cell.dir)  # what works on a run works on a cell
        assert report.overall.per_run[0].unfinished == 0


def test_leaderboard_of_the_root_has_a_row_per_setting_and_a_group_per_environment(done, capsys):
    assert main(["leaderboard", str(done), "--json"]) == 0
    board = json.loads(capsys.readouterr().out)
    assert [(r["model"], r["format"]) for r in board["rows"]] == [("mock", "vla"), ("mock", "wm")]
    assert [(c["title"], c["header"]) for c in board["columns"]] == [
        ("I-PHYRE", "n"), ("I-PHYRE", "Succ@10"), ("I-PHYRE", "Pass@3"), ("PHYRE-B", "n"), ("PHYRE-B", "Succ@10"),
        ("PHYRE-B", "Pass@5"), ("PHYRE-B", "AUCCESS")]
    phyre_vla = report_of(done / "mock/phyre/vla").overall.mean
    assert board["rows"][0]["cells"][4]["mean"] == phyre_vla.success_at[9]


def test_running_a_complete_suite_again_adds_nothing_and_starts_no_ray(done, monkeypatch):
    import deepphy.suite

    monkeypatch.setattr(deepphy.suite, "ensure_ray", lambda *a, **k: pytest.fail("Ray was started"))
    outcomes = run_suite(Suite.model_validate(SMALL), done, RUNTIME)
    assert [o.new_records for o in outcomes] == [0, 0, 0, 0]


def test_a_changed_suite_is_refused_and_an_added_model_extends_it(done, tmp_path):
    before = (done / MANIFEST).read_bytes()
    with pytest.raises(SuiteError, match="holds a different suite .cell mock/iphyre/vla has another config"):
        checked_cells(Suite.model_validate({**SMALL, "runs": 2}), done, None, None)
    with pytest.raises(SuiteError, match="2 of its cells .mock/phyre/vla, mock/phyre/wm. are not in this suite"):
        checked_cells(Suite.model_validate({**SMALL, "envs": SMALL["envs"][:1]}), done, None, None)
    extended = checked_cells(Suite.model_validate(SMALL), done, ["mock", "mock-uniform"], None)
    assert len(extended) == 8
    assert (done / MANIFEST).read_bytes() == before  # planning writes nothing
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(SuiteError, match="not empty and holds no suite"):
        checked_cells(Suite.model_validate(SMALL), tmp_path / "other", None, None)


def test_cli_errors_are_one_line_before_anything_is_written(suite_file, tmp_path, capsys):
    out = tmp_path / "root"
    for argv, said in [
        (["--suite", str(suite_file), "--env", "phyre"], "--env is set by the suite"),
        (["--suite", "nonesuch"], "no suite 'nonesuch'"),
        (["--suite", str(suite_file), "--model", "mock,nonesuch"], "nonesuch"),
        (["--model", "mock,mock-uniform"], "several models need --suite"),
    ]:
        assert main(["run", *argv, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert said in err and len(err.strip().splitlines()) == 1, err
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({**SMALL, "envs": [{"env": "kinetix", "axes": {"annotate": []}}]}))
    assert main(["run", "--suite", str(bad), "--out", str(out)]) == 2
    assert "axis annotate has no values" in capsys.readouterr().err
    assert not out.exists()


def test_dry_run_of_a_suite_prints_every_cell_and_the_total(suite_file, tmp_path, capsys):
    assert main(["run", "--suite", str(suite_file), "--dry-run", "--out", str(tmp_path / "root")]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = [line.split() for line in lines[2:7]]
    assert [r[0] for r in rows] == ["mock/iphyre/vla", "mock/iphyre/wm", "mock/phyre/vla", "mock/phyre/wm", "total"]
    expected = [int(r[4].replace(",", "")) for r in rows]  # requests~: between the bounds, summed in the total
    assert all(int(r[3].split("..")[0]) <= e <= int(r[3].split("..")[1]) for r, e in zip(rows, expected))
    assert expected[4] == sum(expected[:4])
    assert not (tmp_path / "root").exists()


@pytest.mark.slow
def test_a_killed_suite_resumes_to_the_records_of_an_uninterrupted_one(done, suite_file, ray_cluster, tmp_path,
                                                                        deepphy_cmd):
    root = tmp_path / "root"
    proc = subprocess.Popen([*deepphy_cmd, "run", "--suite", str(suite_file), "--out", str(root), "--address",
                             ray_cluster, "--no-progress", "--env-workers", "2"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    logs = [root / cell.dir / ATTEMPTS for cell in read_manifest(done)]  # kill it once a cell has records
    deadline = time.time() + 300
    while proc.poll() is None and time.time() < deadline and not any(p.exists() and p.stat().st_size for p in logs):
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    lines = [p.read_bytes().count(b"\n") if p.exists() else 0 for p in logs]
    assert any(lines) and lines != [len(read_records(done / c.dir)) for c in read_manifest(done)], \
        "the suite was not killed mid-way"
    outcomes = run_suite(Suite.model_validate(SMALL), root, RUNTIME)
    assert sum(o.new_records for o in outcomes) > 0
    for cell in read_manifest(done):
        assert views(root / cell.dir) == views(done / cell.dir), cell.dir


def test_ctrl_c_stops_the_suite_after_its_attempts_in_flight_and_the_same_command_resumes(done, tmp_path,
                                                                                         monkeypatch):
    """Ctrl-C (SIGINT: `asyncio.run` cancels the suite's task) once the first attempt is
    recorded, one cell at a time: the running cell finishes its attempts in flight, no other
    cell starts, KeyboardInterrupt is raised; the same suite then resumes to the records of
    an uninterrupted run."""
    import deepphy.suite
    from deepphy.runs.store import RunStore

    monkeypatch.setattr(deepphy.suite, "CELLS_AT_ONCE", 1)
    append, interrupted = RunStore.append, []

    def append_then_interrupt(store, record):
        append(store, record)
        if not interrupted:
            interrupted.append(store.path)
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(RunStore, "append", append_then_interrupt)
    root, suite = tmp_path / "root", Suite.model_validate({**SMALL, "envs": SMALL["envs"][:1]})  # I-PHYRE's 2 cells
    with pytest.raises(KeyboardInterrupt):
        run_suite(suite, root, RUNTIME)
    first, *others = read_manifest(done)[:2]
    assert interrupted == [root / first.dir]
    assert 1 <= len(read_records(root / first.dir)) < len(read_records(done / first.dir))
    assert not any((root / c.dir).exists() for c in others), "a cell started after Ctrl-C"
    monkeypatch.setattr(RunStore, "append", append)
    outcomes = run_suite(suite, root, RUNTIME)
    assert [(o.done, o.total) for o in outcomes] == [(2, 2)] * 2
    for cell in [first, *others]:
        assert views(root / cell.dir) == views(done / cell.dir), cell.dir


def test_leaderboard_of_a_suite_shows_cells_not_started_as_unfinished(done, tmp_path, capsys):
    root = tmp_path / "root"
    root.mkdir()
    (root / MANIFEST).write_bytes((done / MANIFEST).read_bytes())  # the suite, no cell run yet
    assert main(["leaderboard", str(root), "--csv"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1:3] == ["mock VLA,2x1 (0 done),unfinished 0/2,,2x1 (0 done),unfinished 0/2,,",
                          "mock WM,2x1 (0 done),unfinished 0/2,,2x1 (0 done),unfinished 0/2,,"]


def test_plot_of_a_suite_root_draws_every_environment(done, tmp_path, capsys):
    assert main(["plot", str(done), "--out", str(tmp_path / "fig")]) == 0
    data = json.loads((tmp_path / "fig" / "figures.json").read_text())
    assert {"cumulative_iphyre", "cumulative_phyre"} <= set(data)
    assert data["cumulative_phyre"]["labels"] == ["mock VLA", "mock WM"]


def test_cells_of_one_endpoint_share_its_limiter_and_the_view_shows_its_use(ray_cluster, tmp_path):
    """Two cells at once on one endpoint (the local model server) limited to 240 requests/min:
    the server sees them paced as ONE stream at that rate (two limiters would let twice as
    many through), and the suite's progress line shows the endpoint's use of its limit."""
    from deepphy.testing.model_server import ServerConfig, ServerThread

    rpm = 240
    with ServerThread(ServerConfig(seed=3)) as server:
        models = tmp_path / "models.yaml"
        models.write_text(yaml.safe_dump({"models": [{
            "name": "local", "provider": "openai", "model": "deepphy-mock", "base_url": server.url + "/v1",
            "send_context": True, "rate_limits": {"requests_per_min": rpm}}]}))
        suite = Suite.model_validate({**SMALL, "envs": [{"env": "iphyre", "tasks": ["support", "hinder"],
                                                         "max_attempts": 6}], "models": ["local"]})
        stream = io.StringIO()
        runtime = RUNTIME.model_copy(update={"models_file": str(models), "progress": True})
        outcomes = run_suite(suite, tmp_path / "root", runtime, stream=stream)
        arrivals = sorted(server.stats()["arrivals"])
    assert [(o.done, o.total) for o in outcomes] == [(2, 2), (2, 2)]
    assert len(arrivals) == sum(len(read_records(tmp_path / "root" / o.cell.dir)) for o in outcomes) >= 12
    interval = (60 + 1.0) / rpm  # the limiter's pacing (its window is 60 s + a 1 s margin)
    assert len(arrivals) - 1 <= (arrivals[-1] - arrivals[0]) / interval + 2, "more than one stream's rate"
    said = stream.getvalue()
    assert re.search(rf"^suite small · cells [0-2]/2 .*· local \d+/{rpm} per min \(\d+%\)", said, re.M), said
    assert "cell local/iphyre/vla: 2/2 episodes complete" in said


def test_a_failing_cell_stops_the_suite_with_its_error_and_the_same_command_resumes(ray_cluster, tmp_path,
                                                                                     monkeypatch):
    import deepphy.suite

    suite = Suite.model_validate({**SMALL, "envs": SMALL["envs"][:1]})
    evaluate_cell = deepphy.suite.evaluate_cell

    async def failing(config, out, *args, **kw):
        if config.format.value == "wm":
            raise RuntimeError("disk on fire")
        return await evaluate_cell(config, out, *args, **kw)

    monkeypatch.setattr(deepphy.suite, "evaluate_cell", failing)
    stream = io.StringIO()
    with pytest.raises(RuntimeError, match="disk on fire"):
        run_suite(suite, tmp_path, RUNTIME.model_copy(update={"progress": True}), stream=stream)
    assert "cell mock/iphyre/wm failed: disk on fire" in stream.getvalue()
    monkeypatch.setattr(deepphy.suite, "evaluate_cell", evaluate_cell)
    assert [(o.done, o.total) for o in run_suite(suite, tmp_path, RUNTIME)] == [(2, 2), (2, 2)]


def test_the_suite_line_counts_cells_episodes_rates_endpoints_and_eta():
    from deepphy.suite import suite_line

    grid = cells(Suite.model_validate(SMALL))
    progress = {grid[0].dir: (2, 2), grid[1].dir: (1, 2), grid[2].dir: (0, 2), grid[3].dir: (1, 2)}
    limits = {"gpt-4o": {"requests_in_window": 117, "limits": {"requests_per_min": 120.0}},
              "local": {"requests_in_window": 3, "limits": {"requests_per_min": None}}}  # no request limit: not shown
    # 4 of 8 episodes done, 1 of them before this session: 3 in 60 s, so 4 left take 80 s
    line = suite_line("small", grid, progress, 3, 30, 60.0, 1, limits)
    assert line == ("suite small · cells 1/4 (3 running) · episodes 4/8 · attempts 30 (0.5/s) · "
                    "gpt-4o 117/120 per min (98%) · ETA 1m20s · 1m00s")
