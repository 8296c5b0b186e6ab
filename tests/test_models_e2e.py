"""I-PHYRE runs through the whole pipeline against the local model server over HTTP:
injected faults, the cost budget and key secrecy, compared with the same seed's MOCK run."""

from __future__ import annotations

import io
import os
from collections import Counter
from pathlib import Path

import pytest
import yaml

from deepphy.config import RunConfig, RuntimeOptions
from deepphy.metrics.report import build_report, render_text
from deepphy.testing.model_server import PROSE_REPLY, ServerConfig, ServerThread
from deepphy.plan import plan
from deepphy.runner import evaluate
from deepphy.runs.store import read_records

# Ray workers inherit the environment of the process that starts Ray (the session
# fixture), so the fake key must be set at import time, before any test runs.
FAKE_KEY = "sk-deepphy-E2E-fake-7f3a9c0d5e1b2468"
KEY_ENV = "DEEPPHY_E2E_FAKE_KEY"
os.environ[KEY_ENV] = FAKE_KEY

TASKS = ["support", "hinder", "direction", "hole"]
MOCK = RunConfig(env="iphyre", model="mock", runs=2, seed=7, tasks=TASKS)
LOCAL = RunConfig(**{**MOCK.model_dump(), "model": "local"})
RUNTIME = RuntimeOptions(progress=False, env_workers=2)
TRANSPORT_FAULTS = ["429", "500", "hang", "malformed", "empty"]

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def server():
    with ServerThread(ServerConfig(seed=3, require_key_env=KEY_ENV)) as s:
        yield s


@pytest.fixture
def models_file(server, tmp_path_factory):
    def write(**extra) -> str:
        entry = {
            "name": "local", "provider": "openai", "model": "deepphy-mock", "base_url": server.url + "/v1",
            "api_key_env": KEY_ENV, "send_context": True,
            "timeouts": {"request_s": 2.0, "connect_s": 2.0},
            "retry": {"max_retries": 1, "base_delay_s": 0.05, "max_delay_s": 0.2},  # few: some requests fail for good
            "price": {"input_per_mtok": 3.0, "output_per_mtok": 15.0},
            **extra,
        }
        path = tmp_path_factory.mktemp("models") / "models.yaml"  # not in a run directory: --out refuses that
        path.write_text(yaml.safe_dump({"models": [entry]}))
        return str(path)

    return write


@pytest.fixture(scope="module")
def mock_run(ray_cluster, tmp_path_factory):
    out = tmp_path_factory.mktemp("mock")
    assert evaluate(MOCK, out, RUNTIME).complete
    return out


def views(path) -> list[dict]:
    """Records without wall-clock/provider facts and without the model's name."""
    out = []
    for r in read_records(path):
        v = r.deterministic_view()
        v.pop("model")
        out.append(v)
    return sorted(out, key=lambda v: (v["task"], v["run"], v["attempt"]))


def assert_one_record_per_attempt(path) -> list:
    records = read_records(path)
    keys = Counter(r.key for r in records)
    assert max(keys.values()) == 1
    for task in TASKS:
        for run in range(MOCK.runs):
            attempts = sorted(r.attempt for r in records if (r.task, r.run) == (task, run))
            assert attempts == list(range(1, len(attempts) + 1))
    return records


def report_of(config, path):
    the_plan = plan(config)
    return build_report(config, the_plan.tasks, read_records(path), the_plan.k_max)


def test_faulty_server_run_equals_the_mock_run(server, models_file, mock_run, tmp_path, request):
    server.reset()
    # Every distinct request's first arrival is faulted, the kinds in turn: each kind is served
    # whatever the requests' bytes (drawn kinds over ~4 faults missed one after a PNG change).
    server.configure(faults={"rate": 0.2, "first_tries": 1, "in_turn": True, "kinds": TRANSPORT_FAULTS,
                             "retry_after_s": 0.2, "hang_s": 30.0})
    request.addfinalizer(lambda: server.configure(faults={"first_tries": 0, "in_turn": False}))  # the module's server
    out = tmp_path / "run"
    stream = io.StringIO()
    outcome = evaluate(LOCAL, out, RUNTIME.model_copy(update={"progress": True, "models_file": models_file()}), stream=stream)
    assert outcome.complete, outcome.unfinished
    records = assert_one_record_per_attempt(out)
    # exactly the decisions and outcomes of --model mock with the same seed
    assert views(out) == views(mock_run)
    ours, base = report_of(LOCAL, out), report_of(MOCK, mock_run)
    for a, b in zip(ours.overall.per_run, base.overall.per_run):
        assert a.success_at == b.success_at and a.solved == b.solved
    # every fault kind was served, and shows up as retries / model errors
    st = server.stats(arrivals=False)
    assert set(st["faults"]) == set(TRANSPORT_FAULTS), st["faults"]
    retries = sum(r.model_stats.retries for r in records)
    errors = sum(r.model_stats.model_errors for r in records)
    assert errors > 0 and retries > 0
    assert retries + errors >= sum(st["faults"].values())  # each failed try is one or the other
    mean = ours.overall.mean
    assert mean.model_errors * LOCAL.runs == errors and mean.retries * LOCAL.runs == retries
    assert mean.cost_usd > 0 and mean.input_tokens > 0
    table = render_text(ours)
    for column in ("ModelErr", "Retries", "TokensIn", "TokensOut", "Cost$"):
        assert column in table
    # the key reached the server (it requires it) but nothing written or printed holds it
    for f in out.rglob("*"):
        if f.is_file():
            assert FAKE_KEY.encode() not in f.read_bytes(), f
    assert FAKE_KEY not in stream.getvalue() and FAKE_KEY not in table


def test_prose_replies_are_invalid_attempts_and_image_cuts_are_recorded(server, models_file, tmp_path):
    server.reset()
    server.configure(faults={"rate": 0.2, "kinds": ["prose"]})
    config = RunConfig(**{**LOCAL.model_dump(), "runs": 1})
    f = models_file(max_images=1)  # also: only the newest image goes; the cut is recorded
    assert evaluate(config, tmp_path, RUNTIME.model_copy(update={"models_file": f})).complete
    records = assert_one_record_per_attempt(tmp_path)
    # attempt k shows the key frames of attempts 1..k-1 (none for an invalid one) + 2 observation images
    frames = {r.key: len(r.key_frames) for r in records}
    for r in records:
        shown = sum(frames[(r.task, r.run, k)] for k in range(1, r.attempt)) + 2
        assert r.model_stats.images_dropped == shown - 1
    prose = [r for r in records if r.steps[0].raw_output == PROSE_REPLY]
    assert len(prose) == server.stats(arrivals=False)["faults"]["prose"] > 0
    assert all(r.invalid and not r.success and r.steps[0].action is None for r in prose)
    assert sum(r.model_stats.model_errors for r in records) == 0  # a wrong answer, not a model error


def test_cost_budget_stops_cleanly_and_resumes(server, models_file, mock_run, tmp_path):
    server.reset()
    server.configure(faults={"rate": 0.0})
    f = models_file(price={"input_per_mtok": 100.0, "output_per_mtok": 0.0})  # ~ $0.14 per request
    budget = 1.0
    first = evaluate(LOCAL, tmp_path, RUNTIME.model_copy(update={"max_cost_usd": budget, "models_file": f}))
    assert not first.complete and any("cost budget" in u for u in first.unfinished)
    records = assert_one_record_per_attempt(tmp_path)
    spent = sum(r.model_stats.usage.cost_usd for r in records)
    per_request = max(r.model_stats.usage.cost_usd for r in records)
    assert budget <= spent + per_request * RUNTIME.max_in_flight and spent < budget + 10 * per_request
    # resuming with the same budget does nothing new; a larger one finishes the same run
    again = evaluate(LOCAL, tmp_path, RUNTIME.model_copy(update={"max_cost_usd": budget, "models_file": f}))
    assert again.new_records == 0
    done = evaluate(LOCAL, tmp_path, RUNTIME.model_copy(update={"models_file": f}))
    assert done.complete
    assert_one_record_per_attempt(tmp_path)
    assert views(tmp_path) == views(mock_run)


def test_cli_models_file_and_missing_key(server, models_file, tmp_path, deepphy_cmd, ray_cluster):
    import subprocess

    f = models_file()
    env = {**os.environ, "RAY_AUTH_MODE": "disabled"}
    env.pop(KEY_ENV)
    r = subprocess.run([*deepphy_cmd, "run", "--model", "local", "--models-file", f, "--out", str(tmp_path / "x"),
                        "--tasks", "support", "--runs", "1"], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and KEY_ENV in r.stderr and "Traceback" not in r.stderr
    r = subprocess.run([*deepphy_cmd, "run", "--model", "nope", "--models-file", f, "--out", str(tmp_path / "y")],
                       env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "unknown model 'nope'" in r.stderr and "local" in r.stderr
    assert not Path(tmp_path / "x").exists() and not Path(tmp_path / "y").exists()


def test_wm_run_over_http_reports_prediction_accuracy(server, models_file, tmp_path):
    """The local server answers WM requests with a prediction, an outcome and an action; the
    report scores the stated outcomes against what happened."""
    from deepphy.metrics.report import report_of

    server.configure(faults={"rate": 0.0})
    config = RunConfig(**{**LOCAL.model_dump(), "format": "wm", "runs": 1})
    assert evaluate(config, tmp_path, RUNTIME.model_copy(update={"models_file": models_file()})).complete
    records = read_records(tmp_path)
    assert all(s.predicted_outcome in ("success", "failure") for r in records for s in r.steps)
    wm = report_of(tmp_path).overall.mean.wm
    assert wm.stated == wm.decisions == sum(len(r.steps) for r in records)
    right = sum(s.predicted_outcome == ("success" if r.success else "failure") for r in records for s in r.steps)
    assert wm.accuracy == pytest.approx(right / wm.stated)
    assert "PredAcc" in render_text(report_of(tmp_path))
