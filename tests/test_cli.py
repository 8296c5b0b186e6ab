"""The command line: clear one-line errors, envs/show/report, and resume after kill -9."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from deepphy.cli import main
from deepphy.runs.store import ATTEMPTS, read_records

TASKS = "support,hinder,direction,hole,fill,seesaw"


@pytest.mark.parametrize("argv,message", [
    (["run", "--env", "nosuch"], "unknown environment 'nosuch'"),
    (["run", "--model", "gpt-nothing"], "unknown model 'gpt-nothing'"),
    (["run", "--bogus-flag"], "unrecognized arguments: --bogus-flag"),
    (["run", "--runs", "0"], "runs"),
    (["run", "--format", "xml"], "invalid choice"),
    (["run", "--tasks", "support,nosuch"], "unknown iphyre task(s) nosuch"),
    (["run", "--env-option", "annotate"], "KEY=VALUE"),
    (["run", "--env-option", "annotate=1"], "bad option for iphyre"),
    (["run", "--tasks", "support,hinder,support"], "tasks: task id(s) given more than once: support"),
    (["run", "--env-option", "a=" + "[" * 100_000 + "]" * 100_000], "nested deeper than 16 levels"),
    (["run", "--env-option", "a=" + "[" * 17 + "]" * 17], "nested deeper than 16 levels"),
    (["report", "/nonexistent/run"], "does not exist"),
    (["show", "--env", "iphyre", "--task", "nosuch", "--out", "x"], "unknown iphyre task"),
])
def test_user_errors_are_one_line_and_exit_2(argv, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith("deepphy: error: ") and message in err, err
    assert not (tmp_path / "runs").exists(), "an error must not write a run directory"


def test_unreadable_run_dir_and_mismatched_resume_write_nothing(tmp_path, capsys):
    (tmp_path / "config.json").write_text('{"env": "iphyre", "runs": 1}')
    (tmp_path / ATTEMPTS).write_text("")
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["run", "--out", str(tmp_path), "--runs", "2"]) == 2
    assert "different config (runs: 1 -> 2)" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    (tmp_path / "config.json").write_text("[]")
    assert main(["report", str(tmp_path)]) == 2
    assert "not a valid run config" in capsys.readouterr().err


def test_report_refuses_to_mix_environments(tmp_path, capsys):
    for name, env in (("a", "iphyre"), ("b", "pooltool")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "config.json").write_text(json.dumps({"env": env, "runs": 1, "limit": 1}))
    assert main(["report", str(tmp_path / "a"), str(tmp_path / "b")]) == 2
    assert "one environment" in capsys.readouterr().err


def test_envs_lists_iphyre(capsys):
    assert main(["envs"]) == 0
    line = next(l for l in capsys.readouterr().out.splitlines() if l.startswith("iphyre"))
    assert " 40 " in line and "in_advance" in line


def test_show_writes_the_images_a_model_sees(tmp_path, capsys):
    assert main(["show", "--env", "iphyre", "--task", "support", "--out", str(tmp_path)]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["iphyre_support_annotated.png", "iphyre_support_scene.png", "iphyre_support_state.txt"]
    assert (tmp_path / "iphyre_support_scene.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _run(args, **kw):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "deepphy.cli", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)


def test_kill_9_then_resume_equals_uninterrupted(ray_cluster, tmp_path):
    common = ["run", "--tasks", TASKS, "--runs", "2", "--seed", "3", "--address", ray_cluster, "--no-progress",
              "--env-workers", "1"]
    full = _run([*common, "--out", str(tmp_path / "full")])
    assert full.wait(timeout=300) == 0, full.stderr.read().decode()

    cut = tmp_path / "cut"
    proc = _run([*common, "--out", str(cut)])
    log = cut / ATTEMPTS
    deadline = time.time() + 240
    while time.time() < deadline and proc.poll() is None:
        if log.exists() and log.read_bytes().count(b"\n") >= 10:
            proc.send_signal(signal.SIGKILL)
            break
        time.sleep(0.02)
    assert proc.wait(timeout=60) == -signal.SIGKILL, "the run ended before it could be killed"
    partial = len(read_records(cut))
    total = len(read_records(tmp_path / "full"))
    assert 10 <= partial < total

    again = _run([*common, "--out", str(cut)])
    out, err = again.communicate(timeout=300)
    assert again.returncode == 0, err.decode()
    records = read_records(cut)
    keys = [(r.task, r.run, r.attempt) for r in records]
    assert len(keys) == len(set(keys)) == total

    def view(path):
        return sorted(json.dumps(r.deterministic_view(), sort_keys=True) for r in read_records(path))

    assert view(cut) == view(tmp_path / "full")
    reports = [subprocess.run([sys.executable, "-m", "deepphy.cli", "report", "--json", str(p)],
                              capture_output=True, timeout=120, check=True).stdout for p in (cut, tmp_path / "full")]
    assert json.loads(reports[0])["overall"] == json.loads(reports[1])["overall"]


def test_solve_reports_phyre_solvability(tmp_path, capsys):
    out = tmp_path / "solvability.json"
    assert main(["solve", "--env", "phyre", "report", "--limit", "2", "--jobs", "1", "--out", str(out)]) == 0
    report = json.loads(out.read_text())
    summary = report["summary"]
    assert summary["tasks"] == 2 and len(report["actions"]) == 125
    for row in report["tasks"]:
        assert len(row["statuses"]) == 125 and set(row["statuses"]) <= {-1, 0, 1}
        assert row["solving_grid_actions"] == row["statuses"].count(1) == len(row["solving"])
    assert summary["solvable_on_grid"] == sum(r["solving_grid_actions"] > 0 for r in report["tasks"])
    assert "solvable on the grid" in capsys.readouterr().out
