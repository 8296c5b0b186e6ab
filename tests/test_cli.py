"""The command line: clear one-line errors, envs/show/report, and resume after kill -9."""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

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
    (tmp_path / "config.json").write_text('{"env": "iphyre", "runs": 1, "prompts": "paper"}')
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


def test_envs_task_ids_paste_into_run_tasks(capsys):
    """`deepphy envs --tasks ENV` prints ids, one a line (`--groups`: the group after a tab),
    and its lines paste into `run --tasks` as they are (the tab made an unknown task id)."""
    assert main(["envs", "--tasks", "iphyre"]) == 0
    ids = capsys.readouterr().out.splitlines()
    assert len(ids) == 40 and ids[:2] == ["support", "hinder"] and not any("\t" in i or " " in i for i in ids)
    assert main(["envs", "--tasks", "iphyre", "--groups"]) == 0
    assert capsys.readouterr().out.splitlines()[0] == "support\tbasic"
    pasted = "\n".join(ids[:3]) + "\n"  # as `--tasks "$(deepphy envs --tasks iphyre | head -3)"` gives it
    assert main(["run", "--env", "iphyre", "--tasks", pasted, "--runs", "1", "--dry-run"]) == 0
    table = capsys.readouterr().out.splitlines()
    assert table[2].split()[:4] == ["iphyre", "mock", "vla", "3"], table
    assert main(["run", "--env", "iphyre", "--tasks", "support, hinder", "--runs", "1", "--dry-run"]) == 0
    assert capsys.readouterr().out.splitlines()[2].split()[3] == "2"


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


def test_version(capsys):
    from deepphy import __version__

    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out == f"deepphy {__version__}\n"
    assert re.fullmatch(r"\d+\.\d+\.\d+.*", __version__)


@pytest.mark.parametrize("env", ["phyre", "angrybirds", "cuttherope"])
def test_solve_help_is_the_solvers(env, capsys):
    assert main(["solve", "--env", env, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: deepphy solve --env {env}")
    # every command of the solver, with its options
    assert f"deepphy solve --env {env} report [" in out and "--json FILE" in out
    assert main(["solve", "--help"]) == 0
    assert "environments with a solver: angrybirds, cuttherope, phyre" in capsys.readouterr().out


def test_solve_reports_phyre_solvability(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["solve", "--env", "phyre", "report", "--limit", "1", "--jobs", "1"]) == 0
    assert "solvable on the grid" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []  # nothing written where it was run from
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


def test_watch_follows_a_local_run_by_its_directory(ray_cluster, tmp_path):
    """The run says where its Ray is and writes its status; `deepphy watch RUN_DIR` joins
    that Ray (the token mode taken from the status file) and shows the run by its
    directory; once the run has ended, the directory has no live run to watch."""
    from deepphy.runs.status import PHASES

    out = tmp_path / "run"
    run = _run(["run", "--limit", "40", "--runs", "3", "--address", ray_cluster, "--out", str(out),
                "--max-in-flight", "1", "--env-workers", "1"])
    try:
        deadline = time.time() + 120
        while time.time() < deadline and not ((out / "status.json").exists() and (out / ATTEMPTS).exists()
                                               and (out / ATTEMPTS).stat().st_size):
            assert run.poll() is None, run.stderr.read().decode()
            time.sleep(0.1)
        status = json.loads((out / "status.json").read_text())
        assert status["ray_address"] == ray_cluster and status["phase"] in PHASES and status["pid"] == run.pid
        env = {k: v for k, v in os.environ.items() if k != "RAY_AUTH_MODE"}
        watch = subprocess.run([sys.executable, "-m", "deepphy.cli", "watch", str(out), "--once"], env=env,
                               capture_output=True, text=True, timeout=120)
        assert watch.returncode == 0, watch.stderr
        (line,) = watch.stdout.splitlines()
        assert line.startswith(f"[{out} {status['run_id']}] ") and "episodes " in line
    finally:
        run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=120)
    assert f"run {status['run_id']} on Ray at {ray_cluster}; follow it with `deepphy watch {out}`" in err.decode()
    assert not (out / "status.json").exists()
    assert main(["watch", str(out), "--once"]) == 2


def test_kinetix_drops_only_grains_profiling_warning():
    import logging

    import deepphy.envs.kinetix.sim  # noqa: F401 - installs the filter

    def passes(message):
        return logging.getLogger("absl").filter(logging.LogRecord("absl", logging.WARNING, "x", 1, message, (), None))

    assert not passes("Grain multiprocess worker profiling requires jaxlib extension version 448 or later")
    assert passes("something else absl says")


@pytest.mark.slow
def test_show_kinetix_prints_no_library_warnings(tmp_path):
    done = subprocess.run([sys.executable, "-m", "deepphy.cli", "show", "--env", "kinetix", "--task",
                           "s_h0_weak_thrust", "--out", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert len(done.stdout.splitlines()) == 3  # two images and the text state


def test_report_and_plot_flag_runs_of_different_task_sets(tmp_path, capsys):
    from dashboard_support import synthetic_run

    a = synthetic_run(tmp_path / "a", env="iphyre", limit=3, runs=1)
    b = synthetic_run(tmp_path / "b", env="iphyre", limit=2, runs=1, fmt="wm")
    assert main(["report", str(a), str(b)]) == 0
    out, err = capsys.readouterr()
    assert "note: these runs evaluate different task sets (mock VLA: n=3, mock WM: n=2)" in out and not err
    for argv in (["report", "--csv", str(a), str(b)], ["plot", str(a), str(b), "--out", str(tmp_path / "figs")]):
        assert main(argv) == 0
        assert capsys.readouterr().err.startswith("deepphy: warning: these runs evaluate different task sets")


HEAVY = ("ray", "numpy", "pydantic", "jax", "iphyre", "pymunk", "Box2D", "pooltool", "kinetix", "pygame", "aiohttp",
         "yaml", "importlib.metadata", "typing", "subprocess")


@pytest.mark.parametrize("argv", [["--version"], ["--help"], ["run", "--help"], ["run", "--bogus-flag"],
                                  ["run", "--format", "xml"], ["nosuch"]])
def test_the_quick_answers_import_nothing_heavy(argv):
    """`--version`, `--help` and a bad flag answer within Python's own start: no Ray, no
    simulator, not even numpy or pydantic (`--version` took 8.6 s on a loaded machine)."""
    code = ("import sys; from deepphy.cli import main\n"
            "try: status = main(sys.argv[1:])\nexcept SystemExit as e: status = e.code\n"
            f"print(sorted(m for m in sys.modules if m in {HEAVY!r} or m.split('.')[0] in {HEAVY!r}), file=sys.stderr)\n"
            "sys.exit(status)")
    done = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=60)
    *said, loaded = done.stderr.splitlines()
    assert loaded == "[]", loaded
    if argv[-1] in ("--version", "--help"):
        assert done.returncode == 0 and done.stdout.startswith(("deepphy ", "usage: deepphy"))
    else:
        assert done.returncode == 2 and len(said) == 1 and said[0].startswith("deepphy: error: "), said


def test_a_run_says_what_it_does_before_its_first_heavy_import(tmp_path):
    """On a terminal the run's first line comes before it imports anything heavy (Python's
    own import log, on the same terminal, tells the order); then the one error line."""
    import pty

    master, terminal = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-X", "importtime", "-m", "deepphy.cli", "run", "--tasks", "nosuch",
                             "--out", str(tmp_path / "run")], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=terminal)
    os.close(terminal)
    chunks = []
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # the terminal's other end closed (Linux: EIO)
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(master)
    assert proc.wait(timeout=60) == 2
    said = b"".join(chunks).decode(errors="replace")
    first_line = said.find("checking the run ...")
    heavy = re.search(r"\| +(numpy|pydantic|iphyre)\r?$", said, re.MULTILINE)  # the first of them imported
    assert first_line >= 0 and heavy and first_line < heavy.start(), said[:3000]
    assert "deepphy: error: unknown iphyre task(s) nosuch" in said[first_line:]


def test_the_start_view_repeats_while_the_run_holds_the_gil():
    """Ray's start spends seconds in C code holding Python's GIL (28 s of silence were seen):
    the view's repeats come from a process of their own, so they go on meanwhile."""
    import ctypes

    from deepphy.start_view import StartView

    read, write = os.pipe()
    stream = os.fdopen(write, "w")
    view = StartView(stream, interval=0.2)
    try:
        view.say("starting Ray (local, 2 CPUs)")
        view.repeat()
        ctypes.PyDLL(None).usleep(3_000_000)  # 3 s in C with the GIL held: no thread of this process runs
        os.set_blocking(read, False)
        during = os.read(read, 65536).decode().splitlines()
    finally:
        view.stop()
        stream.close()
        os.close(read)
    assert during[0] == "starting Ray (local, 2 CPUs) ..."
    repeats = [line for line in during[1:] if line.startswith("starting Ray (local, 2 CPUs) ... ")]
    assert len(repeats) >= 3 and repeats[-1].endswith(("2s", "3s")), during


def test_every_default_a_help_states_is_the_one_used():
    """A default is said once. argparse's own default reaches its help as `%(default)s`; a flag
    left None takes a config model's or a CLI constant's, which its help repeats for the reader
    (`--help` imports no pydantic), so the help's word must be that value: checked for every
    `default X` in every command's help, so that a new one cannot drift either."""
    from deepphy import cli
    from deepphy.config import RunConfig, RuntimeOptions

    run_config, runtime = RunConfig.model_fields, RuntimeOptions.model_fields
    used = {("run", "--env"): run_config["env"].default, ("run", "--model"): run_config["model"].default,
            ("run", "--format"): run_config["format"].default.value, ("run", "--runs"): run_config["runs"].default,
            ("run", "--seed"): run_config["seed"].default, ("run", "--out"): cli.DEFAULT_OUT,
            ("run", "--num-cpus"): runtime["num_cpus"].default,
            ("run", "--max-in-flight"): runtime["max_in_flight"].default,
            ("play", "--runs"): cli.PLAY_RUNS, ("play", "--seed"): run_config["seed"].default,
            ("play", "--out"): cli.PLAY_OUT.format(player="<player>", env="<env>"),
            ("solve", "solver_args"): f"`{cli.SOLVER_COMMAND}`"}
    stated = re.compile(r"\bdefault ([^\s,;]+)")  # "default 3", not "default: <prose>"
    checked = set()
    for name, command in cli.build_parser()._subparsers._group_actions[0].choices.items():
        for action in command._actions:
            said = stated.search(action.help or "")
            if said is None or said[1].startswith("%(default)"):  # none, or argparse's own
                continue
            where = (name, action.option_strings[0] if action.option_strings else action.dest)
            assert where in used, f"{where}: its help states a default no test holds to its value: {action.help}"
            assert said[1] == str(used[where]), (where, action.help)
            assert action.default is None, where  # not argparse's: the value above applies
            checked.add(where)
        if name == "run":  # "default: $<the variable>, else the shipped <file>"
            from deepphy.models.config import DEFAULT_MODELS_FILE, MODELS_FILE_ENV

            shipped = DEFAULT_MODELS_FILE.relative_to(Path(cli.__file__).parent.parent)
            files_help = next(a.help for a in command._actions if "--models-file" in a.option_strings)
            assert f"${MODELS_FILE_ENV}, else the shipped {shipped}" in files_help, files_help
        if name == "play":  # "default: the run directory's, else <RunConfig's>"
            env_help = next(a.help for a in command._actions if "--env" in a.option_strings)
            assert env_help.endswith(f"else {run_config['env'].default}"), env_help
    assert checked == set(used)  # every entry above is still stated


def test_the_parsers_choices_are_the_codes():
    """`--help` imports neither the prompt formats nor the export: their choices and default,
    written in the parser, must be theirs."""
    from deepphy.chat import PromptFormat
    from deepphy.cli import build_parser
    from deepphy.export import DEFAULT_LAYOUT, LAYOUTS

    commands = build_parser()._subparsers._group_actions[0].choices
    flag = {(name, a.option_strings[0]): a for name, c in commands.items() for a in c._actions if a.option_strings}
    assert flag["run", "--format"].choices == [f.value for f in PromptFormat]
    assert flag["export", "--layout"].choices == list(LAYOUTS)
    assert flag["export", "--layout"].default == DEFAULT_LAYOUT
