"""`deepphy run --in-process`: the run's scheduler and attempt protocol with the workers in
this process and no Ray, writing what a Ray run writes."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from pathlib import Path

import yaml

from dashboard_support import IPHYRE_TASKS, mock_run
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.runner import evaluate
from deepphy.runs.store import ATTEMPTS, read_records
from deepphy.testing.model_server import ServerConfig, ServerThread

# The shared Ray run of dashboard_support.mock_run: MOCK on six I-PHYRE games, 2 runs, seed 3.
MOCK = RunConfig(env="iphyre", model="mock", runs=2, seed=3, tasks=IPHYRE_TASKS)
IN_PROCESS = RuntimeOptions(in_process=True, progress=False)


def views(path: Path, model: bool = True) -> list[str]:
    """The records without their timings and provider facts (and without the model's name)."""
    out = []
    for record in read_records(path):
        view = record.deterministic_view()
        if not model:
            view.pop("model")
        out.append(json.dumps(view, sort_keys=True))
    return sorted(out)


def files(path: Path) -> dict[str, bytes]:
    """The prompts, images and key frames a run wrote, by path."""
    return {str(f.relative_to(path)): f.read_bytes() for sub in ("prompts", "images", "frames")
            for f in sorted((path / sub).rglob("*")) if f.is_file()}


def test_an_in_process_run_writes_the_records_of_a_ray_run(ray_cluster, tmp_path_factory, tmp_path):
    ray_run = mock_run(tmp_path_factory)
    out = tmp_path / "run"
    outcome = evaluate(MOCK, out, IN_PROCESS)
    assert outcome.complete and outcome.new_records == len(read_records(ray_run))
    assert views(out) == views(ray_run)
    assert files(out) == files(ray_run)
    assert outcome.worker_stats and outcome.worker_stats[0]["steps"] > 0  # the worker's own counters
    # the same directory, read the same way: a resume has nothing left to do
    assert evaluate(MOCK, out, IN_PROCESS).new_records == 0


def test_an_endpoint_check_in_process_over_http_with_faults(ray_cluster, tmp_path_factory, tmp_path):
    """An endpoint's smoke test: the local model server (MOCK's answers over real HTTP, the
    first arrival of every request faulted in turn) through the in-process run; retries and
    re-queues as on Ray, the decisions of the MOCK run, the progress line on the stream."""
    ray_run = mock_run(tmp_path_factory)
    with ServerThread(ServerConfig(seed=3, faults={"first_tries": 1, "in_turn": True, "retry_after_s": 0.2,
                                                   "kinds": ["429", "500", "malformed", "empty"]})) as server:
        models = tmp_path / "models.yaml"
        models.write_text(yaml.safe_dump({"models": [{
            "name": "local", "provider": "openai", "model": "deepphy-mock", "base_url": server.url + "/v1",
            "send_context": True, "retry": {"max_retries": 1, "base_delay_s": 0.05, "max_delay_s": 0.2}}]}))
        stream = io.StringIO()
        config = RunConfig(**{**MOCK.model_dump(), "model": "local"})
        outcome = evaluate(config, tmp_path / "run", IN_PROCESS.model_copy(
            update={"progress": True, "models_file": str(models)}), stream=stream)
        faults = server.stats(arrivals=False)["faults"]
    assert outcome.complete, outcome.unfinished
    assert views(tmp_path / "run", model=False) == views(ray_run, model=False)
    records = read_records(tmp_path / "run")
    assert set(faults) == {"429", "500", "malformed", "empty"}
    assert sum(r.model_stats.retries + r.model_stats.model_errors for r in records) >= sum(faults.values())
    said = stream.getvalue().splitlines()
    assert said[0] == "starting the environment in this process ..." and said[-1].startswith("episodes 12/12 · ")


def test_an_in_process_run_imports_no_ray(tmp_path):
    code = ("import sys; from deepphy.cli import main; status = main(sys.argv[1:]); "
            "assert 'ray' not in sys.modules, 'ray was imported'; sys.exit(status)")
    out = tmp_path / "run"
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    done = subprocess.run([sys.executable, "-c", code, "run", "--in-process", "--tasks", "support,hinder", "--runs",
                           "1", "--out", str(out)], capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    assert "(2/2 episodes complete" in done.stdout and (out / ATTEMPTS).exists()
    assert "starting Ray" not in done.stderr and "Ray at" not in done.stderr


def test_in_process_refuses_what_needs_ray(capsys):
    from deepphy.cli import main

    for argv, words in ((["--address", "127.0.0.1:6379"], "it takes no --address"),
                        (["--num-cpus", "4"], "it takes no --num-cpus"),
                        (["--suite", "paper"], "a suite runs on Ray")):
        assert main(["run", "--in-process", *argv]) == 2
        (line,) = capsys.readouterr().err.splitlines()
        assert line.startswith("deepphy: error: ") and words in line, line
