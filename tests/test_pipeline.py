"""The full pipeline on a real local Ray runtime and the real I-PHYRE."""

import asyncio
import io
import os
import signal
import threading
import time
from collections import Counter

import pytest

from deepphy.config import RunConfig, RuntimeOptions
from deepphy.runner import evaluate
from deepphy.runs.store import ATTEMPTS, episode_prompts, read_records, stored_prompt_json

RAY_TIMEOUT_S = 120

TASKS = ["support", "hinder", "direction", "hole", "spring_flick", "multi_ball_lever"]
CONFIG = RunConfig(env="iphyre", model="mock", runs=2, seed=7, tasks=TASKS)
RUNTIME = RuntimeOptions(progress=False, env_workers=2)


def views(path):
    return sorted((r.deterministic_view() for r in read_records(path)), key=lambda v: (v["task"], v["run"], v["attempt"]))


def assert_complete(path, config, k=10):
    records = read_records(path)
    keys = Counter((r.task, r.run, r.attempt) for r in records)
    assert max(keys.values()) == 1, "duplicate attempt records"
    for task in config.tasks:
        for run in range(config.runs):
            attempts = sorted(r.attempt for r in records if (r.task, r.run) == (task, run))
            assert attempts == list(range(1, len(attempts) + 1))
            last = next(r for r in records if (r.task, r.run, r.attempt) == (task, run, attempts[-1]))
            assert last.success or len(attempts) == k
            assert not any(r.success for r in records if (r.task, r.run) == (task, run) and r.attempt < attempts[-1])
    return records


@pytest.fixture(scope="module")
def baseline(ray_cluster, tmp_path_factory):
    out = tmp_path_factory.mktemp("baseline")
    outcome = evaluate(CONFIG, out, RUNTIME)
    assert outcome.complete and outcome.episodes_total == len(TASKS) * 2
    return out


def test_run_completes_one_record_per_attempt(baseline):
    records = assert_complete(baseline, CONFIG)
    assert any(r.success for r in records) and any(not r.success for r in records)
    assert all(len(r.key_frames) == 1 and (baseline / r.key_frames[0].path).exists() for r in records)
    # spring_flick is solved by doing nothing; MOCK always removes something, so it never is
    # at attempt 1 -- a weak check that history and prompts are stored
    # Prompts: a log per episode, a line per distinct prompt in the order first asked, no
    # file per prompt.
    episodes = sorted({(r.task, r.run) for r in records})
    logs = sorted(str(p.relative_to(baseline)) for p in (baseline / "prompts").rglob("*") if p.is_file())
    assert logs == sorted(f"prompts/{task}/r{run}.jsonl" for task, run in episodes)
    for task, run in episodes:
        asked = [s.prompt for r in sorted(records, key=lambda r: r.attempt) if (r.task, r.run) == (task, run)
                 for s in r.steps]
        assert list(episode_prompts(baseline, task, run)) == list(dict.fromkeys(asked))
        lines = (baseline / "prompts" / task / f"r{run}.jsonl").read_bytes().count(b"\n")
        assert lines == len(set(asked))


def test_same_seed_same_records(baseline, tmp_path):
    evaluate(CONFIG, tmp_path, RUNTIME.model_copy(update={"env_workers": 1}))
    assert views(tmp_path) == views(baseline)


def test_other_seed_other_actions(baseline, tmp_path):
    evaluate(RunConfig(**{**CONFIG.model_dump(), "seed": 8}), tmp_path, RUNTIME)
    ours = {(v["task"], v["run"], v["attempt"]): v["steps"][0]["action_text"] for v in views(tmp_path)}
    base = {(v["task"], v["run"], v["attempt"]): v["steps"][0]["action_text"] for v in views(baseline)}
    assert ours != base


def test_resume_after_a_cut_log_finishes_the_same_run(baseline, tmp_path):
    import json

    evaluate(CONFIG, tmp_path, RUNTIME)
    log = tmp_path / ATTEMPTS
    lines = log.read_bytes().split(b"\n")
    kept = len(lines) // 3
    log.write_bytes(b"\n".join(lines[:kept]) + b"\n" + lines[kept][:40])  # whole lines + a torn one
    cut = json.loads(lines[kept])
    prompts = tmp_path / "prompts" / cut["task"] / f"r{cut['run']}.jsonl"
    with open(prompts, "ab") as f:  # the kill tore a prompt line of that episode too
        f.write(prompts.read_bytes().splitlines()[-1][:60])
    outcome = evaluate(CONFIG, tmp_path, RUNTIME)
    assert outcome.complete and outcome.new_records == len(lines) - 1 - kept
    records = assert_complete(tmp_path, CONFIG)
    assert views(tmp_path) == views(baseline)
    assert all(json.loads(line) for line in prompts.read_bytes().split(b"\n")[:-1])  # the torn tail was cut
    assert prompts.read_bytes().endswith(b"}\n")
    assert all(s.prompt in episode_prompts(tmp_path, r.task, r.run) for r in records for s in r.steps)


def test_a_gap_in_an_episode_is_refused_then_repaired_and_the_resume_is_exact(baseline, tmp_path):
    """A deleted line in the middle of an episode: the resume refuses (it used to number the
    next attempt len+1 and write a second attempt of that number); `deepphy repair` keeps
    the attempts before the gap and the resume finishes the same run."""
    import shutil

    from deepphy.cli import main
    from deepphy.runs.store import RunDirError

    shutil.copytree(baseline, tmp_path / "run")
    log = tmp_path / "run" / ATTEMPTS
    lines = log.read_bytes().splitlines(keepends=True)
    records = read_records(baseline)
    long_one = next(r for r in records if r.attempt == 4 and any(
        (x.task, x.run, x.attempt) == (r.task, r.run, 5) for x in records))
    gap = next(i for i, r in enumerate(records) if r.key == long_one.key)
    log.write_bytes(b"".join(lines[:gap] + lines[gap + 1:]))  # attempt 4 gone, 5 still there
    with pytest.raises(RunDirError, match=f"task {long_one.task} run {long_one.run} has attempts .*attempt 4 is missing"):
        evaluate(CONFIG, tmp_path / "run", RUNTIME)
    assert main(["report", str(tmp_path / "run")]) == 2  # a report would count the episode wrong
    assert main(["repair", str(tmp_path / "run")]) == 0
    outcome = evaluate(CONFIG, tmp_path / "run", RUNTIME)
    assert outcome.complete
    assert_complete(tmp_path / "run", CONFIG)
    assert views(tmp_path / "run") == views(baseline)


def test_resume_of_a_complete_run_adds_nothing(baseline, tmp_path):
    import shutil

    shutil.copytree(baseline, tmp_path / "copy")
    outcome = evaluate(CONFIG, tmp_path / "copy", RUNTIME)
    assert outcome.complete and outcome.new_records == 0
    assert views(tmp_path / "copy") == views(baseline)


def test_crashed_env_worker_attempt_is_retried(baseline, tmp_path):
    """kill -9 one environment worker mid-run: Ray restarts it, the scheduler re-runs its
    attempts, and the finished run equals the uninterrupted one."""
    import ray

    result = {}
    thread = threading.Thread(target=lambda: result.update(outcome=evaluate(CONFIG, tmp_path, RUNTIME)))
    thread.start()
    deadline = time.time() + RAY_TIMEOUT_S
    killed = None
    while killed is None and time.time() < deadline and thread.is_alive():
        names = [a["name"] for a in ray.util.list_named_actors(all_namespaces=True)]
        workers = [n for n in names if n.startswith("deepphy/") and "/env" in n]
        log = tmp_path / ATTEMPTS
        if workers and log.exists() and log.read_bytes().count(b"\n") >= 5:
            pid = ray.get(ray.get_actor(workers[0]).stats.remote(), timeout=RAY_TIMEOUT_S)["pid"]
            os.kill(pid, signal.SIGKILL)
            killed = pid
        time.sleep(0.05)
    thread.join(timeout=300)
    assert killed is not None, "the run finished before a worker could be killed"
    assert result["outcome"].complete
    assert_complete(tmp_path, CONFIG)
    assert views(tmp_path) == views(baseline)


def test_attempts_do_not_wait_for_the_metrics_actor_but_it_must_start(baseline, tmp_path, monkeypatch):
    """The metrics actor's process starts while the attempts run. One that never starts (here:
    it asks for a resource no node has) stops the run within the step timeout with one line,
    after recording attempts meanwhile; the resume finishes the run as if nothing happened."""
    import deepphy.actors.metrics_actor as metrics_actor
    import deepphy.runner as runner
    from deepphy.ray_connect import ClusterUnavailable

    def never_placed(total, k_max, max_steps=1, *, name=None, run=None, started=None):
        return metrics_actor.MetricsActor.options(num_cpus=0, name=name, resources={"nowhere": 1}).remote(
            total, k_max, max_steps, run, started)

    monkeypatch.setattr(runner, "make_metrics_actor", never_placed)
    # 15 s: the step timeout bounds the workers' start too, which a loaded machine makes slow
    stream = io.StringIO()
    with pytest.raises(ClusterUnavailable, match="the metrics actor did not start within 15 s"):
        evaluate(CONFIG, tmp_path, RUNTIME.model_copy(update={"step_timeout_s": 15.0, "progress": True}),
                 stream=stream)
    assert read_records(tmp_path), "no attempt ran while the metrics actor was starting"
    # the progress line went on meanwhile (every 10 s in a log), without the actor's figures
    waiting = [line for line in stream.getvalue().splitlines() if "(no figures yet: the metrics actor" in line]
    assert len(waiting) >= 2 and waiting[0].startswith("starting · episodes 0/"), stream.getvalue()
    monkeypatch.undo()
    assert evaluate(CONFIG, tmp_path, RUNTIME).complete
    assert_complete(tmp_path, CONFIG)
    assert views(tmp_path) == views(baseline)


def test_workers_that_die_while_starting_stop_the_run_with_one_line_and_it_resumes(baseline, tmp_path, monkeypatch):
    """Workers lost before their first call (here killed; seen: a local Ray's raylet dying
    with its dashboard agent) stop the run with a ClusterUnavailable that says so (the CLI's
    one line), not an unexpected error; the same command then finishes the run."""
    import ray

    import deepphy.runner as runner
    from deepphy.ray_connect import ClusterUnavailable

    made = runner.make_env_workers

    def dead_on_arrival(*args, **kwargs):
        workers = made(*args, **kwargs)
        for worker in workers:
            ray.kill(worker, no_restart=True)
        return workers

    monkeypatch.setattr(runner, "make_env_workers", dead_on_arrival)
    with pytest.raises(ClusterUnavailable, match=r"the environment workers died while starting \(.+\); run the same"):
        evaluate(CONFIG, tmp_path, RUNTIME)
    assert not read_records(tmp_path)
    monkeypatch.undo()
    assert evaluate(CONFIG, tmp_path, RUNTIME).complete
    assert views(tmp_path) == views(baseline)


def test_the_progress_view_stops_when_its_snapshot_arrives_as_the_run_ends():
    """The driver's last act is to stop its progress view and wait for it. Seen (1 run in 8
    against a faulty endpoint): the view's snapshot call came back in the same turn of the
    loop as the stop, Python 3.11's `asyncio.wait_for` returned the snapshot and dropped the
    cancellation, and the view printed `episodes 0/1` every 10 s while the run waited for it
    forever. The actor handles are stand-ins here: only they let the test choose that turn."""
    import io
    from types import SimpleNamespace

    from deepphy.metrics.live import LiveMetrics
    from deepphy.runner import _progress

    class Method:  # an actor method: `.remote()` returns what the driver awaits
        def __init__(self, answer=lambda: None) -> None:
            self.answer = answer

        def remote(self, *args):
            return self.answer()

    async def scenario() -> bool:
        asked, answer = asyncio.Event(), asyncio.get_running_loop().create_future()

        def snapshot():
            asked.set()
            return answer

        async def waiting() -> dict:
            return {}

        metrics = SimpleNamespace(update=Method(), snapshot=Method(snapshot))
        scheduler = SimpleNamespace(send_summaries=lambda: None, activity=lambda: {},
                                    model=SimpleNamespace(activity=waiting))
        view = asyncio.ensure_future(_progress(scheduler, metrics, ["running"], io.StringIO(), lambda phase: phase))
        await asyncio.wait_for(asked.wait(), 30)
        answer.set_result(LiveMetrics(1, 1).snapshot())  # the snapshot comes back ...
        view.cancel()  # ... in the turn that stops the view
        await asyncio.wait({view}, timeout=30)
        stopped = view.cancelled()
        view.cancel()
        return stopped

    assert asyncio.run(scenario()), "the progress view went on after it was stopped"


def test_wm_format_records_predictions(ray_cluster, tmp_path):
    config = RunConfig(**{**CONFIG.model_dump(), "format": "wm", "runs": 1, "tasks": TASKS[:2]})
    evaluate(config, tmp_path, RUNTIME)
    records = read_records(tmp_path)
    assert records and all(s.prediction and s.action_text for r in records for s in r.steps)
    assert all(s.raw_output.startswith("Prediction:") for r in records for s in r.steps)


def test_watch_streams_a_live_runs_snapshot(ray_cluster, tmp_path, capsys):
    """`deepphy watch` finds the run's metrics actor on the cluster and prints its progress."""
    import json

    from deepphy.cli import main

    thread = threading.Thread(target=lambda: evaluate(CONFIG, tmp_path, RUNTIME))
    thread.start()
    snapshots = []
    deadline = time.time() + RAY_TIMEOUT_S
    while thread.is_alive() and time.time() < deadline and not snapshots:
        if main(["watch", "--address", ray_cluster, "--once", "--json"]) == 0:
            snapshots = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
        time.sleep(0.2)
    thread.join(timeout=300)
    assert snapshots, "no live snapshot seen while the run was going"
    snap = snapshots[0]
    assert snap["episodes_total"] == len(TASKS) * CONFIG.runs and 0 <= snap["episodes_done"] <= snap["episodes_total"]
    assert main(["watch", "--address", ray_cluster, "--once"]) == 1  # the run is over: nothing live


@pytest.mark.parametrize("env, tasks", [
    ("pooltool", ["rack_000", "rack_001", "rack_002"]),
    ("kinetix", ["s_h0_weak_thrust", "s_h1_thrust_over_ball", "s_h2_one_wheel_car", "s_h3_point_the_thruster"]),
])
def test_on_the_fly_episodes_through_ray(ray_cluster, tmp_path, env, tasks):
    """Multi-decision attempts through real Ray: records hold every decision, prompts show the
    earlier decisions of the attempt, and the worker steps waiting episodes together."""

    config = RunConfig(env=env, model="mock", runs=2, seed=5, tasks=tasks)
    outcome = evaluate(config, tmp_path, RuntimeOptions(progress=False, env_workers=1, max_in_flight=16))
    assert outcome.complete and outcome.new_records == len(tasks) * 2  # K = 1: one attempt per episode
    records = assert_complete(tmp_path, config, k=1)
    multi = [r for r in records if len(r.steps) > 1]
    assert multi, "no attempt took more than one decision"
    for r in records:
        assert [s.step for s in r.steps] == list(range(1, len(r.steps) + 1))
        assert len(r.key_frames) == len(r.steps)  # one key frame per decision
        assert r.success or r.truncated or r.steps[-1].terminated
        assert all(not (s.terminated or s.truncated) for s in r.steps[:-1])
    second = stored_prompt_json(tmp_path, multi[0].task, multi[0].run, multi[0].steps[1].prompt)
    user = "\n".join(p for m in second for p in m["content"] if isinstance(p, str))  # texts; images are references
    if env == "pooltool":  # the paper's Pooltool prompt: the updated table is the only feedback
        assert "Your earlier decisions in this attempt" not in user
    else:
        assert "Your earlier decisions in this attempt" in user and f"Step 1: {multi[0].steps[0].action_text}" in user
    # Kinetix overrides step_many (one jitted call for many episodes): waiting episodes are
    # stepped together. Pooltool does not, so its worker steps one request per loop turn.
    from deepphy.envs import get_env_class
    from deepphy.envs.base import Environment

    batching = get_env_class(env).step_many.__func__ is not Environment.step_many.__func__
    largest = max(s["max_batch"] for s in outcome.worker_stats)
    assert (largest > 1) if batching else (largest == 1), outcome.worker_stats


def test_earlier_frames_reach_the_model_as_stored(ray_cluster, tmp_path):
    """The driver sends earlier attempts' key frames by file name; the model worker (beside
    the driver) reads them from the run directory: the provider receives exactly the bytes
    stored as those attempts' key frames, in order, then the current observation."""
    import base64

    import yaml

    from deepphy.models.wire import CONTEXT_HEADER, decode_context
    from deepphy.testing.model_server import ServerConfig, ServerThread

    with ServerThread(ServerConfig(seed=2, record_bodies=500)) as server:
        models = tmp_path / "models.yaml"
        models.write_text(yaml.safe_dump({"models": [{
            "name": "local", "provider": "openai", "model": "deepphy-mock", "base_url": server.url + "/v1",
            "send_context": True}]}))
        config = RunConfig(env="iphyre", model="local", runs=1, seed=7, tasks=["support", "hinder"])
        out = tmp_path / "run"
        assert evaluate(config, out, RUNTIME.model_copy(update={"models_file": str(models)})).complete
        bodies = server.bodies()
    records = {r.key: r for r in read_records(out)}
    checked = 0
    for body in bodies:
        context = decode_context(body["headers"][CONTEXT_HEADER])
        sent = [base64.b64decode(p["image_url"]["url"].partition(",")[2])
                for m in body["body"]["messages"] if isinstance(m["content"], list)
                for p in m["content"] if p["type"] == "image_url"]
        stored = [(out / f.path).read_bytes() for k in range(1, context.attempt)
                  for f in records[(context.task_id, context.run, k)].key_frames]
        assert sent[:len(stored)] == stored and len(sent) > len(stored)
        checked += len(stored) > 0
    assert checked >= 3  # requests that carried earlier attempts' frames (4 with this seed)


@pytest.mark.parametrize("setting, packages", [(None, False), ("1", True)])
def test_a_run_does_not_package_the_working_directory_even_if_ray_was_imported_first(monkeypatch, setting, packages):
    """Under `uv run`, Ray uploads the working directory to its workers unless
    RAY_ENABLE_UV_RUN_RUNTIME_ENV is off, and it reads that variable when it is imported (a
    script importing deepphy.runner imports Ray first). A user's explicit setting stands."""
    from ray._private import ray_constants

    from deepphy.ray_env import quiet_environment

    if setting is None:
        monkeypatch.delenv("RAY_ENABLE_UV_RUN_RUNTIME_ENV", raising=False)
    else:
        monkeypatch.setenv("RAY_ENABLE_UV_RUN_RUNTIME_ENV", setting)
    monkeypatch.setattr(ray_constants, "RAY_ENABLE_UV_RUN_RUNTIME_ENV", not packages)  # as read at import
    quiet_environment()
    assert ray_constants.RAY_ENABLE_UV_RUN_RUNTIME_ENV is packages
