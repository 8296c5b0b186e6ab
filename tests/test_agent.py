"""Users' own agents (deepphy/agent.py, `deepphy run --agent`): the interface, the two example
agents (examples/), and an agent through everything a model goes through: Ray, resume after
kill -9, suites, the leaderboard, the dry run."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

# The examples live at the repository's root: importable here, and by the Ray workers the
# session's cluster starts (they inherit this environment when it starts, after collection).
REPO = str(Path(__file__).resolve().parents[1])
if REPO not in sys.path:
    sys.path.insert(0, REPO)
os.environ["PYTHONPATH"] = os.pathsep.join(p for p in [REPO, os.environ.get("PYTHONPATH", "")] if p)

import gymnasium  # noqa: E402

import deepphy.gym as dgym  # noqa: E402
from deepphy.agent import (  # noqa: E402
    AgentClient, AgentError, AgentFailed, AgentReply, Episode, declared, load_agent,
)
from deepphy.cli import main  # noqa: E402
from deepphy.config import AgentSpec, RunConfig, RuntimeOptions  # noqa: E402
from deepphy.envs import get_spec  # noqa: E402
from deepphy.estimate import estimate  # noqa: E402
from deepphy.models.limiter import LocalLimiter  # noqa: E402
from deepphy.prompts import PastAttempt, PastStep, PromptFormat, build_messages  # noqa: E402
from deepphy.protocol import LocalEnv, MemoryArtifacts, run_episode  # noqa: E402
from deepphy.plan import plan  # noqa: E402
from deepphy.runner import evaluate  # noqa: E402
from deepphy.runs.store import ATTEMPTS, CONFIG, RunDirError, RunStore, read_records  # noqa: E402
from deepphy.runs.manifest import read_manifest  # noqa: E402
from deepphy.testing.model_server import ServerConfig, ServerThread  # noqa: E402
from agent_support import probe_of  # noqa: E402
from deepphy.agents import MockModel  # noqa: E402

REFLECTION = "examples.reflection:ReflectionAgent"
GYM_POLICY = "examples.gym_policy:GymPolicyAgent"
BRIGHTNESS = "examples.gym_policy:iphyre_brightness_policy"
RUNTIME = RuntimeOptions(progress=False, env_workers=1)


@pytest.fixture(scope="module")
def server():
    with ServerThread(ServerConfig(seed=3, record_bodies=400)) as s:
        yield s


@pytest.fixture(scope="module")
def models_file(server, tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("models") / "models.yaml"
    path.write_text(yaml.safe_dump({"models": [{
        "name": "local", "provider": "openai", "model": "deepphy-mock", "base_url": server.url + "/v1",
        "send_context": True, "price": {"input_per_mtok": 3.0, "output_per_mtok": 15.0},
        "rate_limits": {"requests_per_min": 6000}, "timeouts": {"request_s": 10.0},
    }]}))
    return str(path)


def reflection(endpoint: str = "local", **args) -> AgentSpec:
    return load_agent(REFLECTION, {"endpoint": endpoint, **args})


def agent_config(spec: AgentSpec, **fields) -> RunConfig:
    return RunConfig(**{"model": spec.name, "agent": spec, **fields})


def play(config: RunConfig, client, runs: int = 1) -> list:
    """Every episode of `config`, in this process, through the attempt protocol."""
    the_plan = plan(config)
    spec, tasks, k_max = the_plan.spec, the_plan.tasks, the_plan.k_max
    env = LocalEnv(the_plan.make_env())
    prompt, artifacts = the_plan.prompt(), MemoryArtifacts()

    async def all_episodes():
        try:
            return [r for run in range(runs) for task in tasks
                    for r in await run_episode(spec, prompt, config, task, run, k_max, env, client, artifacts)]
        finally:
            await client.close()

    return asyncio.run(all_episodes())


def views(path) -> list[dict]:
    return sorted((r.deterministic_view() for r in read_records(path)),
                  key=lambda v: (v["task"], v["run"], v["attempt"]))


# -- the interface --------------------------------------------------------------------------------


def test_an_agent_is_named_by_its_entry_point_and_arguments_stably_and_filesystem_safely():
    spec = reflection("gpt-4o")
    assert (spec.entry, spec.args, spec.package, spec.version) == (REFLECTION, {"endpoint": "gpt-4o"}, "examples",
                                                                   "0.1.0")
    assert spec.name == "examples.reflection.ReflectionAgent+endpoint=gpt-4o"
    assert reflection("gpt-4o").name == spec.name  # stable
    assert reflection("gpt-4o", reflection_tokens=64).name == spec.name + "+reflection_tokens=64"
    # an argument outside the safe alphabet: cut to it, and the exact arguments' hash keeps names apart
    a, b = (load_agent(GYM_POLICY, {"policy": p}).name for p in ("a.b:c", "a.b/c"))
    assert a != b and a.startswith("examples.gym_policy.GymPolicyAgent+policy=a.b_c+")
    long = load_agent(GYM_POLICY, {"policy": "m:" + "x" * 300}).name
    for name in (spec.name, a, b, long):
        assert len(name) <= 120 and all(c.isalnum() or c in "._=+-" for c in name), name
    with pytest.raises(ValueError, match="is not the name of its agent"):
        RunConfig(model="mock", agent=spec)


def test_a_run_without_an_agent_writes_the_config_it_wrote_before_agents(tmp_path):
    config = RunConfig(env="iphyre", tasks=["support"], runs=1)
    store = RunStore.claim(tmp_path / "run", config)
    store.close()
    written = json.loads((tmp_path / "run" / CONFIG).read_text())
    assert "agent" not in written and list(written) == [f for f in RunConfig.model_fields if f != "agent"]
    with_agent = agent_config(reflection(), tasks=["support"], runs=1)
    assert json.loads(with_agent.model_dump_json())["agent"]["entry"] == REFLECTION
    assert RunConfig.model_validate_json(with_agent.model_dump_json()) == with_agent


@pytest.mark.parametrize("argv,said", [
    (["--agent", "nosuch_module_xyz:make"], "cannot import nosuch_module_xyz"),
    (["--agent", "examples.reflection:Nothing"], "examples.reflection has no Nothing"),
    (["--agent", "examples.reflection"], "expected an entry point package.module:factory"),
    (["--agent", REFLECTION], "missing 1 required positional argument: 'endpoint'"),
    (["--agent", REFLECTION, "--agent-arg", "endpoint=local", "--agent-arg", "colour=red"], "unexpected keyword"),
    (["--agent", REFLECTION, "--agent-arg", "endpoint=nosuch"], "unknown model 'nosuch'"),
    (["--agent", "agent_support:not_an_agent"], "returned a dict, not a deepphy.agent.Agent"),
    (["--agent-arg", "endpoint=local"], "--agent-arg needs --agent"),
    (["--agent", REFLECTION, "--model", "mock"], "--agent and --model name two agents"),
    (["--agent", REFLECTION, "--agent-arg", "endpoint"], "--agent-arg expects KEY=VALUE"),
])
def test_an_agent_that_cannot_be_loaded_is_a_one_line_error_before_anything_is_written(argv, said, tmp_path, capsys,
                                                                                      models_file):
    assert main(["run", *argv, "--models-file", models_file, "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("deepphy: error: ") and err.count("\n") == 1 and said in err, err
    assert not (tmp_path / "run").exists()


def test_a_reply_is_text_or_an_action_in_the_spaces_syntax(models_file):
    client = AgentClient(reflection(), models_file)
    spec = get_spec("iphyre")
    cls = spec.load()
    env = cls()
    task = cls.tasks(env.options)[0]
    observation = env.reset(task)
    space = observation.action_space
    action = space.parse('[{"time": 1.5, "index": 0}]')
    from deepphy.models import RequestContext

    def ctx(fmt):
        return RequestContext(env="iphyre", task_id=task.id, run=0, attempt=1, step=1, seed=0, format=fmt,
                              action_space=space.model_dump(mode="json"))

    assert client.reply_text("anything at all", ctx(PromptFormat.VLA)) == "anything at all"
    assert client.reply_text(action, ctx(PromptFormat.VLA)) == space.format(action)
    wm = client.reply_text(AgentReply(action=action, prediction="the ball falls", outcome="success"),
                           ctx(PromptFormat.WM))
    from deepphy.prompts import split_reply

    assert split_reply(PromptFormat.WM, wm) == ("the ball falls", "success", space.format(action))
    other = get_spec("phyre")
    other.load_package()
    from deepphy.envs.phyre.space import PhyreAction

    with pytest.raises(TypeError, match="is not an action of the decision's space"):
        client.reply_text(PhyreAction(cell=1, radius=1), ctx(PromptFormat.VLA))
    with pytest.raises(ValueError, match="exactly one of text and action"):
        AgentReply(text="x", action=action)


def test_an_episodes_state_lives_across_its_attempts_until_it_ends(models_file):
    import agent_support

    spec = load_agent("agent_support:ProbeAgent")
    client = AgentClient(spec)
    config = agent_config(spec, tasks=["support", "hinder"], runs=1, max_attempts=3)
    records = play(config, client)
    probes = [probe_of(r.steps[0].raw_output) for r in records]
    assert [p["seen"] for p in probes] == [r.attempt for r in records]  # one state per episode, kept
    assert len(client.states) == 2 and len(agent_support.LIVE) == 2  # nothing ends them in this loop
    for task in ("support", "hinder"):
        client.end_episode(Episode.of(_context(config, task)))
    assert client.states == {} and len(agent_support.LIVE) == 0


def _context(config: RunConfig, task: str):
    from deepphy.models import RequestContext

    return RequestContext(env=config.env, env_options=config.env_options, task_id=task, run=0, attempt=1, step=1,
                          seed=config.seed, format=config.format, action_space={})


# -- the reflection agent -----------------------------------------------------------------------


def test_the_reflection_agent_asks_what_went_wrong_then_acts_through_the_endpoint_and_its_limiter(server,
                                                                                               models_file):
    server.reset()  # its request bodies too
    granted: list[int] = []

    class Counting(LocalLimiter):
        async def acquire(self, tokens: int, lease_s: float) -> int:
            granted.append(tokens)
            return await super().acquire(tokens, lease_s)

    spec = reflection()
    config = agent_config(spec, tasks=["support", "hinder"], runs=1, max_attempts=4, seed=5)
    records = play(config, AgentClient(spec, models_file, limiter_for=lambda c: Counting(c.rate_limits)))
    mock = play(config.model_copy(update={"model": "mock", "agent": None}), MockModel())
    # the server answers as MOCK: the same decisions, through two requests after each failure
    assert [(r.task, r.attempt, r.steps[0].action_text) for r in records] == [
        (r.task, r.attempt, r.steps[0].action_text) for r in mock]
    later = [r for r in records if r.attempt > 1]
    assert later, "no attempt failed: nothing to reflect on"
    bodies = server.bodies()
    assert len(bodies) == len(granted) == len(records) + len(later)
    asked = [b["body"]["messages"] for b in bodies]
    reflections = [m for m in asked if "what went wrong" in json.dumps(m[-1]["content"][-1:])]
    actions_after = [m for m in asked if m[-2]["role"] == "assistant"]
    assert len(reflections) == len(actions_after) == len(later)
    for question, action in zip(reflections, actions_after):  # the analysis asked for, then shown before the action
        assert action[1]["content"] == question[1]["content"][:-1]
        assert action[-1]["content"] == [{"type": "text", "text": "Now give your action, in exactly the form the "
                                                                  "instructions ask for."}]
    # both requests of a decision are counted to it
    assert all(r.model_stats.usage.cost_usd > 0 for r in records)
    second = later[0]
    first = next(r for r in records if (r.task, r.attempt) == (second.task, 1))
    assert second.model_stats.usage.input_tokens > 2 * first.model_stats.usage.input_tokens


# -- the Gymnasium policy adapter ---------------------------------------------------------------


def test_observation_of_a_request_is_the_gymnasium_observation_of_its_decision():
    for name, task_id, action in [("cuttherope", "b1_l04", "sleep(0.5)"), ("iphyre", "support", None)]:
        env = gymnasium.make(dgym.env_id(name), task=task_id)
        first, _ = env.reset()
        inner = env.unwrapped
        spec = get_spec(name)
        prompt = spec.load_prompt()
        history = [PastAttempt(attempt=1, actions=["x"], outcome="failed.",
                               key_frames=list(inner._observation.images))]
        if action is not None:  # a later decision of an on-the-fly attempt, with the earlier one shown
            seen = inner._observation
            shown, *_ = env.step(action)
            recent = [PastStep(step=1, action=action, feedback="ok", frame=seen.images[0])]
        else:
            shown, recent = first, []
        messages = build_messages(prompt, PromptFormat.VLA, inner.task, inner._observation, history, recent)
        from deepphy.models import ModelRequest

        request = ModelRequest(messages=messages, context=_context(RunConfig(env=name), task_id))
        got = dgym.observation_of(request)
        assert got["text"] == shown["text"] and got["images"].dtype == shown["images"].dtype
        assert (got["images"] == shown["images"]).all(), name
        assert name != "cuttherope" or got["text"]  # a text state was there to find


def test_the_gym_policy_agent_decides_as_the_policy_does_in_gymnasium():
    from examples.gym_policy import iphyre_brightness_policy

    spec = load_agent(GYM_POLICY, {"policy": BRIGHTNESS})
    config = agent_config(spec, env="iphyre", tasks=["support", "hinder", "direction"], runs=1, max_attempts=2)
    records = play(config, AgentClient(spec))
    assert len(records) >= 3
    env = gymnasium.make(dgym.env_id("iphyre"))
    actions = set()
    for record in records:
        obs, _ = env.reset(options={"task": record.task})
        _, reward, _, _, info = env.step(iphyre_brightness_policy(obs))
        assert (info["action"], info["success"]) == (record.steps[0].action_text, record.success)
        actions.add(info["action"])
    assert len(actions) > 1  # the policy read the observations: the tasks' scenes differ


def test_the_dry_run_bounds_an_agent_from_its_endpoints_or_says_in_one_line_it_cannot(models_file, capsys):
    spec = reflection()
    config = agent_config(spec, tasks=["support", "hinder"], runs=1)
    agent = estimate(config, models_file)
    endpoint = estimate(config.model_copy(update={"model": "local", "agent": None}), models_file)
    assert declared(spec).endpoints == {"local": 2}
    assert agent.cost_input_max == pytest.approx(2 * endpoint.cost_input_max) and agent.cost_input_max > 0
    assert agent.requests_max == 2 * endpoint.requests_max and agent.note is None
    assert main(["run", "--agent", GYM_POLICY, "--agent-arg", f"policy={BRIGHTNESS}", "--tasks", "support",
                 "--runs", "1", "--dry-run"]) == 0
    out = capsys.readouterr().out
    said = [line for line in out.splitlines() if "cannot estimate" in line]
    assert len(said) == 1 and "declares no endpoint" in said[0], out
    row = next(line for line in out.splitlines() if line.startswith("iphyre examples.gym_policy"))
    assert row.split()[-4:-2] == ["unknown", "unknown"]


def test_a_resume_with_other_arguments_or_another_version_is_refused(tmp_path):
    config = agent_config(reflection(), tasks=["support"], runs=1)
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / CONFIG).write_text(config.model_dump_json(indent=2))
    other = agent_config(reflection(reflection_tokens=64), tasks=["support"], runs=1)
    with pytest.raises(RunDirError, match="different config .agent: "):
        RunStore.check(tmp_path / "run", other)
    newer = config.model_copy(update={"agent": config.agent.model_copy(update={"version": "0.2.0"})})
    with pytest.raises(RunDirError, match='"version": "0.1.0"} -> .*"version": "0.2.0"}'):
        RunStore.check(tmp_path / "run", newer)
    with pytest.raises(AgentError, match="this process has examples 0.1.0, the run was made with examples 0.2.0"):
        AgentClient(newer.agent)


# -- through Ray ---------------------------------------------------------------------------------


def test_an_agent_asking_for_resources_gets_its_own_actor_with_them_and_its_states_are_released(ray_cluster,
                                                                                                tmp_path):
    spec = load_agent("agent_support:ProbeAgent", {"num_cpus": 1})
    tasks = ["support", "hinder", "direction", "hole", "fill", "seesaw"]
    config = agent_config(spec, tasks=tasks, runs=1, max_attempts=3, seed=1)
    outcome = evaluate(config, tmp_path / "run", RUNTIME.model_copy(update={"max_in_flight": 2}))
    assert outcome.complete
    records = read_records(tmp_path / "run")
    probes = [(r, probe_of(s.raw_output)) for r in records for s in r.steps]
    assert {json.dumps(p["assigned"]) for _, p in probes} == {'{"CPU": 1.0}'}
    assert all(p["seen"] == r.attempt for r, p in probes)  # I-PHYRE: a decision per attempt
    # two episodes in flight: their states, and one ended whose release may still be on its way
    assert max(p["live"] for _, p in probes) <= 3 < len(tasks)


def test_an_agent_whose_setup_fails_stops_the_run_with_one_line_and_records_nothing(ray_cluster, tmp_path):
    spec = load_agent("agent_support:BrokenSetupAgent")
    with pytest.raises(AgentFailed) as failed:
        evaluate(agent_config(spec, tasks=["support", "hinder"], runs=1), tmp_path / "run", RUNTIME)
    assert "setup failed: FileNotFoundError: no checkpoint at /nonexistent/model.pt" in str(failed.value)
    assert "\n" not in str(failed.value) and not (tmp_path / "run").exists()


def test_an_agent_that_cannot_start_where_it_runs_is_one_line_and_records_nothing(ray_cluster, tmp_path, deepphy_cmd):
    done = subprocess.run([*deepphy_cmd, "run", "--agent", "agent_support:DriverOnlyAgent", "--tasks", "support",
                           "--runs", "1", "--address", ray_cluster, "--no-progress", "--env-workers", "1", "--out",
                           str(tmp_path / "run")], capture_output=True, text=True, timeout=300, cwd=REPO)
    assert done.returncode == 2, done.stderr
    # (a driver that joins a cluster also hears Ray print the worker's error; the run's own word is one line)
    said = done.stderr.splitlines()[-1]
    assert said == ("deepphy: error: agent agent_support:DriverOnlyAgent: ModuleNotFoundError: No module named "
                    "'mypolicy' (on this node) (in the agent's model worker, which could not start)"), said
    assert not (tmp_path / "run").exists()


SUITE = {
    "name": "byo",
    "envs": [{"env": "iphyre", "tasks": ["support", "hinder"], "max_attempts": 4},
             {"env": "phyre", "limit": 2, "max_attempts": 4}],
    "formats": ["vla"],
    "runs": 1,
    "seed": 2,
    "models": ["mock", "local"],
    "agents": [{"entry": REFLECTION, "args": {"endpoint": "local"}}],
}


@pytest.fixture(scope="module")
def suite_done(ray_cluster, server, models_file, tmp_path_factory):
    """The suite of mock, the endpoint and the reflection agent over it, run once without
    interruption; with the server's requests during it."""
    from deepphy.suite import Suite, run_suite

    root = tmp_path_factory.mktemp("byo") / "root"
    server.reset()
    outcomes = run_suite(Suite.model_validate(SUITE), root, RUNTIME.model_copy(update={"models_file": models_file}))
    assert all(o.done == o.total for o in outcomes)
    return root, server.stats(arrivals=False)["requests"]


def test_a_suite_of_mock_an_endpoint_and_an_agent_makes_one_leaderboard(suite_done, capsys):
    root, requests = suite_done
    agent = reflection()
    cells = {c.dir: c for c in read_manifest(root)}
    assert sorted(cells) == sorted(f"{m}/{e}/vla" for m in ("mock", "local", agent.name) for e in ("iphyre", "phyre"))
    # every request of the endpoint's and the agent's cells reached the server: the agent's two after each failure
    local = [r for e in ("iphyre", "phyre") for r in read_records(root / f"local/{e}/vla")]
    ours = [r for e in ("iphyre", "phyre") for r in read_records(root / f"{agent.name}/{e}/vla")]
    assert requests == len(local) + len(ours) + sum(r.attempt > 1 for r in ours)
    assert main(["leaderboard", str(root), "--json"]) == 0
    board = json.loads(capsys.readouterr().out)
    rows = {(r["model"], r["format"]): r for r in board["rows"]}
    label = f"{agent.name} (examples 0.1.0)"
    assert set(rows) == {("mock", "vla"), ("local", "vla"), (label, "vla")}
    assert rows[(label, "vla")]["agent"] == agent.model_dump(mode="json") and "agent" not in rows[("mock", "vla")]
    assert {c["title"] for c in board["columns"]} == {"I-PHYRE", "PHYRE-B"}
    for row in board["rows"]:  # every row has its figures in both environments' groups
        assert [c["mean"] is not None for c in row["cells"]] == [c["header"] not in ("n", "Pass@3", "Pass@5")
                                                                 for c in board["columns"]]  # n: words; Pass@: 1 run
    assert main(["leaderboard", str(root)]) == 0
    assert f"{label} VLA" in capsys.readouterr().out


@pytest.mark.slow
def test_the_reflection_agent_on_two_environments_resumes_after_kill_9_to_the_uninterrupted_records(
        suite_done, models_file, ray_cluster, tmp_path, deepphy_cmd):
    done, _ = suite_done
    agent = reflection()
    suite_file = tmp_path / "byo.yaml"
    suite_file.write_text(yaml.safe_dump({**SUITE, "models": [], "agents": []}))  # --agent gives the agent
    argv = [*deepphy_cmd, "run", "--suite", str(suite_file), "--agent", REFLECTION, "--agent-arg", "endpoint=local",
            "--models-file", models_file, "--out", str(tmp_path / "root"), "--address", ray_cluster, "--no-progress",
            "--env-workers", "1"]
    cells = [f"{agent.name}/iphyre/vla", f"{agent.name}/phyre/vla"]
    logs = [tmp_path / "root" / cell / ATTEMPTS for cell in cells]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                            cwd=REPO)
    deadline = time.time() + 300
    while proc.poll() is None and time.time() < deadline and sum(
            p.read_bytes().count(b"\n") for p in logs if p.exists()) < 3:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    lines = [p.read_bytes().count(b"\n") if p.exists() else 0 for p in logs]
    assert sum(lines) >= 3 and lines != [len(read_records(done / cell)) for cell in cells], \
        "the suite was not killed mid-way"
    again = subprocess.run(argv, capture_output=True, timeout=600, cwd=REPO)
    assert again.returncode == 0, again.stderr.decode()[-2000:]
    for cell in cells:  # the same decisions, outcomes and replies as the uninterrupted suite's
        assert views(tmp_path / "root" / cell) == views(done / cell), cell
