"""Kinetix on the real kinetix-env (no mocks).

Caches (converted levels, JAX compilation cache) are the machine's, which `make setup` warmed
(tests/conftest.py), so the tests load compiled functions instead of compiling them.
The fast tests run the S size only; M and L known-good runs are marked slow.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from deepphy.envs import ActionSpace, InvalidAction, get_env_class
from deepphy.envs.kinetix.env import KinetixEnv, KinetixOptions
from deepphy.envs.kinetix.space import KinetixAction, KinetixSpace

ROOT = Path(__file__).resolve().parents[1]
def task(tid: str):
    return next(t for t in KinetixEnv.tasks(KinetixOptions()) if t.id == tid)


# -- tasks --------------------------------------------------------------------------------


def test_registered_with_74_levels_by_size():
    cls = get_env_class("kinetix")
    assert cls is KinetixEnv
    tasks = cls.tasks(cls.Options())
    assert len(tasks) == 74
    assert [sum(t.group == g for t in tasks) for g in "SML"] == [10, 24, 40]
    ids = [t.id for t in tasks]
    assert len(set(ids)) == 74
    assert all(t.id.replace("_", "").isalnum() and t.id[0] in "sml" and t.id[1] == "_" for t in tasks)
    assert tasks[0].id == "s_h0_weak_thrust" and tasks[0].params == {"level": "s/h0_weak_thrust", "state_text": False}
    only_m = cls.tasks(cls.Options(sizes=["M"]))
    assert len(only_m) == 24 and {t.group for t in only_m} == {"M"}
    assert ids == [t.id for t in cls.tasks(cls.Options())]  # stable order


def test_action_space_importable_without_jax():
    code = (
        "import sys, json; import deepphy.envs.kinetix as k; from deepphy.envs import ActionSpace;"
        "s = ActionSpace.from_json({'kind': 'kinetix_vector', 'num_motors': 2, 'num_thrusters': 1});"
        "print(json.dumps([s.format(s.parse('[2, 0, 1]')), 'jax' in sys.modules, 'kinetix' in sys.modules]))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == ["[2, 0, 1]", False, False]


# -- parsing ------------------------------------------------------------------------------

SPACE = KinetixSpace(num_motors=2, num_thrusters=1)


@pytest.mark.parametrize(
    "text",
    [
        "[1, 2, 0]",
        "[1,2,0]",
        "```json\n[1, 2, 0]\n```",
        "```\n[1, 2, 0]\n```",
        "I will drive M0 forward, M1 in reverse and keep T0 off.\nAction: [1, 2, 0]",
        "ACTION: [1, 2, 0] because [M0, M1, T0] means the motors then the thruster",
        "The labels [M0, M1, T0] map to [1.0, 2, 0].",
        "  [ 1 ,\n 2 ,\n 0 ]  ",
    ],
)
def test_parse_accepts_the_syntax_robustly(text):
    assert SPACE.parse(text) == KinetixAction(motors=(1, 2), thrusters=(0,))


@pytest.mark.parametrize(
    "text, reason",
    [
        ("", "no JSON list"),
        ("I would turn the motor forward.", "no JSON list"),
        ("[M0=1, M1=2, T0=0]", "no JSON list"),
        ("[1, 2]", "expected a list of 3"),
        ("[1, 2, 0, 1]", "expected a list of 3"),
        ("[3, 0, 0]", "M0 must be 0"),
        ("[0, -1, 0]", "M1 must be 0"),
        ("[0, 0, 2]", "T0 must be 0 (off) or 1"),
        ("[1, 2, true]", "T0 must be an integer"),
        ('["1", 2, 0]', "M0 must be an integer"),
        ("[1.5, 2, 0]", "M0 must be an integer"),
        ("[[1, 2, 0]]", "flat list"),
        ('{"M0": 1, "M1": 2, "T0": 0}', "no JSON list"),
    ],
)
def test_parse_rejects_everything_else(text, reason):
    with pytest.raises(InvalidAction, match=reason.replace("(", r"\(").replace(")", r"\)")):
        SPACE.parse(text)


def test_sample_format_roundtrip_and_uniform():
    rng = np.random.default_rng(0)
    space = ActionSpace.from_json(KinetixSpace(num_motors=3, num_thrusters=2).model_dump(mode="json"))
    samples = [space.sample(rng) for _ in range(3000)]
    for a in samples[:200]:
        assert space.parse(space.format(a)) == a
        assert len(json.loads(space.format(a))) == 5
    motors = np.array([a.motors for a in samples])
    thrusters = np.array([a.thrusters for a in samples])
    assert set(np.unique(motors)) == {0, 1, 2} and set(np.unique(thrusters)) == {0, 1}
    assert np.allclose(np.bincount(motors.ravel()) / motors.size, 1 / 3, atol=0.03)
    assert abs(thrusters.mean() - 0.5) < 0.03
    assert KinetixSpace(num_motors=0, num_thrusters=1).labels() == ["T0"]


# -- observation and rendering (no compilation needed) -------------------------------------


@pytest.mark.parametrize(
    "tid, labels",
    [
        ("s_h3_point_the_thruster", ["M0", "T0"]),
        ("m_h7_car_flip", ["M0", "M0", "T0", "T1"]),  # two wheels share one binding
        ("l_grasp_easy", ["M0", "M0", "M1", "M2", "M3", "M3"]),
    ],
)
def test_annotated_render_differs_exactly_where_labels_are(tid, labels):
    from deepphy.envs.kinetix import render, sim

    state = sim.load_level(task(tid).params["level"]).state
    clean = render.render(state)
    annotated, boxes = render.annotate(clean, state, render.controls(state))
    assert clean.shape == annotated.shape == (500, 500, 3) and clean.dtype == np.uint8
    assert sorted(name for name, _ in boxes) == labels
    inside = np.zeros(clean.shape[:2], bool)
    for _, (x0, y0, x1, y1) in boxes:
        inside[y0:y1, x0:x1] = True
        assert (annotated[y0:y1, x0:x1] != clean[y0:y1, x0:x1]).any()  # every label is drawn
    changed = (annotated != clean).any(axis=2)
    assert changed.any() and not (changed & ~inside).any()  # and nothing outside the labels changed
    # Labels do not hide each other.
    for i, (_, a) in enumerate(boxes):
        for _, b in boxes[i + 1 :]:
            assert not (a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3])


def test_render_shows_roles_motors_and_thrusters_in_distinct_colours():
    from deepphy.envs.kinetix import render, sim

    img = render.render(sim.load_level("m/h7_car_flip").state)
    colours = {tuple(c) for c in img.reshape(-1, 3)}
    for colour in (render.MOTOR, render.THRUSTER, render.ROLE[1][0], render.ROLE[2][0], render.ROLE[3][0]):
        assert colour in colours


def test_observation_with_and_without_annotation():
    env = KinetixEnv(KinetixOptions(annotate=True))
    obs = env.reset(task("m_h7_car_flip"))
    assert [i.name for i in obs.images] == ["scene", "annotated"]
    assert obs.action_space == KinetixSpace(num_motors=1, num_thrusters=2)
    assert "[M0, T0, T1]" in obs.text and "Goal distance" in obs.text and "Decision" not in obs.text
    rich = KinetixEnv(KinetixOptions(state_text=True)).reset(task("m_h7_car_flip"))
    assert "Decision 1 of 16" in rich.text and "m_h7_car_flip" in rich.text  # the level's name: a hint
    plain = KinetixEnv(KinetixOptions(annotate=False)).reset(task("m_h7_car_flip"))
    assert [i.name for i in plain.images] == ["scene"]
    assert np.array_equal(plain.images[0].to_array(), obs.images[0].to_array())
    assert not np.array_equal(obs.images[0].to_array(), obs.images[1].to_array())


def test_controls_follow_the_levels_bindings():
    env = KinetixEnv()
    env.reset(task("s_h8_unicycle_balance"))  # its only motor uses binding 1, not 0
    assert env._vector(KinetixAction(motors=(2,), thrusters=())).tolist() == [0, 2, 0, 0, 0, 0]
    env.reset(task("m_h7_car_flip"))
    assert env._vector(KinetixAction(motors=(1,), thrusters=(0, 1))).tolist() == [1, 0, 0, 0, 0, 1]
    with pytest.raises(ValueError):
        env._vector(KinetixAction(motors=(1,), thrusters=(1,)))


def test_prompts_state_legend_syntax_and_example():
    from deepphy.envs import get_spec
    from deepphy.prompts import PastStep, PromptFormat, build_messages

    prompt = get_spec("kinetix").load_prompt()
    for annotate, state_text in ((True, False), (False, False), (True, True)):
        options = KinetixOptions(annotate=annotate, state_text=state_text)
        t = next(x for x in KinetixEnv.tasks(options) if x.id == "m_h7_car_flip")
        obs = KinetixEnv(options).reset(t)
        for fmt in PromptFormat:
            msgs = build_messages(prompt, fmt, t, obs, [], [PastStep(step=1, action="[1, 0, 0]", feedback="goal distance 10 px")])
            system = msgs[0].text
            assert "[M0, T0, T1]" in system and "green" in system and "red" in system
            assert ("16 decisions" in system and "car_flip" in system) == state_text  # not the paper's
            assert ("yellow label" in system) == annotate
            assert obs.action_space.parse(prompt.example(obs)) is not None
            assert "goal distance 10 px" in msgs[1].text


# -- stepping (compiles the S size) ----------------------------------------------------------


def _direct(level: str, vectors: list[list[int]]):
    """Step kinetix-env itself, 16 env steps per decision: (decision that ended it, GoalR, state)."""
    import jax
    import jax.numpy as jnp
    from kinetix.environment.env import make_kinetix_env
    from kinetix.environment.spaces import ActionType, ObservationType
    from kinetix.util.saving import load_from_json_file

    state, static_params, env_params = load_from_json_file(level)
    state = state.replace(timestep=jnp.int32(0), last_distance=jnp.float32(-1.0))
    env = make_kinetix_env(ActionType.MULTI_DISCRETE, ObservationType.SYMBOLIC_FLAT, None, env_params, static_params, auto_reset=False)
    key = jax.random.PRNGKey(0)
    for k, vec in enumerate(vectors, start=1):
        for _ in range(16):
            _, state, reward, done, info = env.step(key, state, jnp.asarray(vec, jnp.int32), env_params)
            if bool(done):
                return k, bool(info["GoalR"]), float(reward), jax.device_get(state)
    return None, False, 0.0, jax.device_get(state)


def _ours(tid: str, actions: list[list[int]]):
    env = KinetixEnv()
    obs = env.reset(task(tid))
    results = []
    for a in actions:
        r = env.step(obs.action_space.parse(json.dumps(a)))
        results.append(r)
        if r.done:
            break
        obs = r.observation
    return env, results


def _check_known_good(tid: str, actions: list[list[int]], vectors: list[list[int]]):
    from deepphy.envs.kinetix import render

    env, results = _ours(tid, actions)
    last = results[-1]
    assert last.done and last.success and last.info["outcome"] == "goal"
    assert len(results) == len(actions) and all(not r.done for r in results[:-1])
    assert [r.info["kinetix_action"] for r in results] == vectors
    k, goal, reward, state = _direct(task(tid).params["level"], vectors)
    assert (k, goal) == (len(actions), True) and reward > 0.5
    assert last.info["timestep"] == int(state.timestep)
    assert abs(render.goal_distance_px(state) - last.info["goal_distance_px"]) < 1.0


def test_known_good_small_level_matches_kinetix():
    # s_h0_weak_thrust: fire the only thruster twice; the ball reaches the goal in decision 2.
    _check_known_good("s_h0_weak_thrust", [[1], [1]], [[0, 0, 0, 0, 1, 0]] * 2)


def test_red_and_timeout_fail_like_kinetix():
    # Without thrust the ball of s_h0 drops onto the red floor.
    env, results = _ours("s_h0_weak_thrust", [[0]] * 16)
    last = results[-1]
    assert last.done and not last.success and last.info["outcome"] == "red"
    k, goal, reward, _ = _direct("s/h0_weak_thrust", [[0] * 6] * 16)
    assert (k, goal) == (len(results), False) and reward < -0.5
    # A one-wheel car that does nothing never reaches the goal: 16 decisions, then time is up.
    env, results = _ours("s_h2_one_wheel_car", [[0]] * 16)
    assert len(results) == 16 and [r.done for r in results] == [False] * 15 + [True]
    assert results[-1].info["outcome"] == "timeout" and results[-1].info["timestep"] == 256
    assert results[-1].observation is None and len(results[-1].key_frames) == 1


def test_step_many_equals_one_at_a_time():
    import jax

    ids = ["s_h0_weak_thrust", "s_h2_one_wheel_car", "s_h3_point_the_thruster", "s_h6_unicycle_right", "s_h9_explode_then_thrust_over"]
    rng = np.random.default_rng(3)
    single = [KinetixEnv() for _ in ids]
    batched = [KinetixEnv() for _ in ids]
    obs = [e.reset(task(t)) for e, t in zip(single, ids)]
    for e, t in zip(batched, ids):
        e.reset(task(t))
    live = list(range(len(ids)))
    for _ in range(3):
        acts = [obs[i].action_space.sample(rng) for i in live]
        one = [single[i].step(a) for i, a in zip(live, acts)]
        many = KinetixEnv.step_many([batched[i] for i in live], acts)  # one call, padded to sim.BATCH
        for i, a, b in zip(live, one, many):
            assert (a.done, a.success, a.feedback, a.info) == (b.done, b.success, b.feedback, b.info)
            assert a.key_frames[0].png == b.key_frames[0].png
            same = jax.tree.map(lambda x, y: np.allclose(x, y, atol=1e-4, equal_nan=True), single[i]._state, batched[i]._state)
            assert all(jax.tree.leaves(same))
        nxt = []
        for i, r in zip(live, one):
            if not r.done:
                obs[i] = r.observation
                nxt.append(i)
        live = nxt


@pytest.mark.slow
@pytest.mark.parametrize(
    "tid, actions, vectors",
    [
        ("m_h1_car_left", [[1], [1], [1]], [[1, 0, 0, 0, 0, 0]] * 3),
        ("m_h18_thrust_right_very_easy", [[1, 0], [1, 1], [1, 1]], [[0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 1, 1], [0, 0, 0, 0, 1, 1]]),
        ("l_h3_car_right", [[2], [2], [2]], [[2, 0, 0, 0, 0, 0]] * 3),
        ("l_h14_simple_thruster", [[1, 1], [0, 0], [1, 0]], [[0, 0, 0, 0, 1, 1], [0] * 6, [0, 0, 0, 0, 1, 0]]),
    ],
)
def test_known_good_medium_and_large_levels_match_kinetix(tid, actions, vectors):
    _check_known_good(tid, actions, vectors)


@pytest.mark.slow
def test_every_level_renders_with_exact_non_overlapping_labels():
    from deepphy.envs.kinetix import render, sim

    for t in KinetixEnv.tasks(KinetixOptions()):
        state = sim.load_level(t.params["level"]).state
        ctl = render.controls(state)
        assert 1 <= len(ctl.motor_bindings) + len(ctl.thruster_bindings) <= 6, t.id
        clean = render.render(state)
        annotated, boxes = render.annotate(clean, state, ctl)
        assert len(boxes) == sum(map(len, ctl.motor_joints)) + sum(map(len, ctl.thrusters)), t.id
        inside = np.zeros(clean.shape[:2], bool)
        for _, (x0, y0, x1, y1) in boxes:
            inside[y0:y1, x0:x1] = True
        changed = (annotated != clean).any(axis=2)
        assert not (changed & ~inside).any(), t.id
        for i, (_, a) in enumerate(boxes):
            for _, b in boxes[i + 1 :]:
                assert not (a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]), t.id
        assert render.goal_distance_px(state) is not None, t.id


# What logs when it loads a program from JAX's persistent compilation cache (jaxlib 0.9).
XLA_CACHE_NOISE = "cpu_aot_loader.cc"
GYM_KINETIX = """
import gymnasium, sys
import deepphy.gym
env = gymnasium.make("deepphy/kinetix-v0", task="s_h0_weak_thrust")
env.reset(seed=0)
env.step(env.action_space.sample())
print("stepped", flush=True)
if sys.argv[1:] == ["then-fail"]:  # our own error must still reach the terminal
    env.reset(options={"task": "no_such_level"})
"""


@pytest.mark.slow
def test_kinetix_outside_a_run_prints_none_of_xlas_cache_log(tmp_path):
    """Through Gymnasium and `--dry-run` (a run sends it to logs/), a Kinetix simulation
    loaded from the compilation cache printed an XLA error line per program: 128 lines for
    a `gymnasium.make`. The first command fills the cache (a cold one compiles, quietly)."""
    env = dict(os.environ)  # conftest pinned DEEPPHY_CACHE_DIR to the warmed cache
    env.pop("TF_CPP_MIN_LOG_LEVEL", None)
    warm = subprocess.run([sys.executable, "-c", GYM_KINETIX], capture_output=True, text=True, timeout=900, env=env)
    assert warm.returncode == 0 and "stepped" in warm.stdout, warm.stderr[-2000:]
    done = subprocess.run([sys.executable, "-c", GYM_KINETIX, "then-fail"], capture_output=True, text=True,
                          timeout=900, env=env)
    assert "stepped" in done.stdout and XLA_CACHE_NOISE not in done.stderr, done.stderr[:2000]
    assert done.returncode == 1 and "no_such_level" in done.stderr.splitlines()[-1]  # our error, as Python raised it
    dry = subprocess.run([sys.executable, "-m", "deepphy.cli", "run", "--env", "kinetix", "--limit", "1", "--runs",
                          "1", "--dry-run", "--out", str(tmp_path / "run")], capture_output=True, text=True,
                         timeout=900, env=env)
    assert dry.returncode == 0 and dry.stdout.startswith("run "), dry.stderr[-2000:]
    # only what the command says itself while it measures (a line every 10 s in a log)
    assert all(line.startswith(("checking the run ...", "measuring the prompts")) for line in dry.stderr.splitlines()), \
        dry.stderr[:2000]
