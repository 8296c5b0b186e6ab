"""deepphy's environments through Gymnasium (deepphy/gym.py): Gymnasium's own checker for all
six, and the same actions through Gymnasium and through `deepphy run` give the same outcome."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import deepphy.gym as dgym
from deepphy.envs import specs

CHEAP = ["angrybirds", "cuttherope", "iphyre", "phyre"]
SLOW = ["kinetix", "pooltool"]  # the first simulation compiles (JAX, numba): minutes on a cold cache


def checked(name: str) -> None:
    env = gymnasium.make(dgym.env_id(name), render_mode="rgb_array")
    with warnings.catch_warnings(record=True) as caught:  # the checker reports its findings as warnings
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    # the checker's own findings; warnings are process-wide, so other threads' (a play test's
    # simulator still compiling, say) are not the checker's
    findings = [str(w.message) for w in caught if not issubclass(w.category, DeprecationWarning)
                and ("gymnasium" in w.filename or "deepphy" in w.filename)]
    assert not findings, findings
    env.close()


@pytest.mark.parametrize("name", CHEAP)
def test_gymnasium_checker_passes(name):
    checked(name)


@pytest.mark.slow
@pytest.mark.parametrize("name", SLOW)
def test_gymnasium_checker_passes_on_the_compiled_environments(name):
    checked(name)


def test_every_environment_is_registered():
    assert set(CHEAP + SLOW) == set(specs())
    assert {dgym.env_id(n) for n in specs()} <= set(gymnasium.registry)
    assert dgym.register_all() == [dgym.env_id(n) for n in specs()]  # idempotent


def test_observation_action_reward_and_render():
    env = gymnasium.make("deepphy/cuttherope-v0", task="b1_l04", render_mode="rgb_array")
    obs, info = env.reset(seed=0)
    assert info["task"] == "b1_l04" and obs in env.observation_space
    assert obs["images"].dtype == np.uint8 and obs["images"].shape == (1, 720, 480, 3)
    assert "Level b1_l04" in obs["text"]
    assert np.array_equal(env.render(), obs["images"][0])
    # An action in the environment's syntax, with prose around it, as the harness accepts it.
    obs, reward, terminated, truncated, info = env.step("I will wait: sleep(0.5)")
    assert (reward, terminated, truncated, info["action"]) == (0.0, False, False, "sleep(0.5)")
    assert "runs for 0.5 s" in info["feedback"]  # the paper gives no clock: the feedback names no time
    obs, reward, terminated, truncated, info = env.step("fail()")
    assert (reward, terminated, truncated, info["success"]) == (0.0, True, False, False)
    assert env.render().shape == (720, 480, 3)  # the scene after the last step
    with pytest.raises(RuntimeError, match="call reset"):
        env.step("fail()")


@pytest.mark.parametrize("name, task, action", [
    ("iphyre", "support", '[{"time": 1.0, "index": 0}]'),
    ("phyre", "within_00000-000", "Cell: 5, Radius: 4"),
    ("angrybirds", "s1_l01", None),  # drawn: shots until the birds run out or the pig is dead
])
def test_render_keeps_its_shape_after_the_last_step(name, task, action):
    """A video recorder stacks render()'s pictures: after the last step it is the final scene
    at the observation's size (I-PHYRE's 600x600 became a 300x1212 strip)."""
    env = gymnasium.make(dgym.env_id(name), task=task, render_mode="rgb_array")
    obs, _ = env.reset(seed=1)
    env.action_space.seed(1)
    pictures, done = [env.render()], False
    while not done:
        obs, _, terminated, truncated, _ = env.step(action or env.action_space.sample())
        pictures.append(env.render())
        done = terminated or truncated
    assert {p.shape for p in pictures} == {obs["images"].shape[1:]} and all(p.dtype == np.uint8 for p in pictures)
    assert not np.array_equal(pictures[-1], pictures[-2])  # the scene after the last step, not the one before it
    assert np.stack(pictures).shape[0] == len(pictures)


def test_angry_birds_out_of_birds_is_a_terminal_state():
    """Every bird launched and a pig alive: the level is lost, a state of the game with no
    action left (`terminated`), not an episode cut short (`truncated`)."""
    env = gymnasium.make("deepphy/angrybirds-v0", task="s1_l01")
    env.reset(seed=0)
    ends = [env.step("shoot(angle=90, power=0.3)")[2:4] for _ in range(3)]  # straight up: each falls back
    assert ends == [(False, False), (False, False), (True, False)]


def test_an_invalid_action_ends_the_episode_with_the_documented_reward():
    env = gymnasium.make("deepphy/cuttherope-v0", task="b1_l01")
    env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step("jump around")
    assert (reward, terminated, truncated) == (dgym.INVALID_REWARD, True, False)
    assert info["invalid_reason"].startswith("unparseable action:") and not info["success"]
    custom = gymnasium.make("deepphy/cuttherope-v0", task="b1_l01", invalid_reward=-5)
    custom.reset()
    assert custom.step("cut_pin(99)")[1:3] == (-5.0, True)  # an unknown pin: does not parse


def test_a_physically_invalid_action_is_the_environments_own_invalid_attempt():
    env = gymnasium.make("deepphy/phyre-v0", task="within_00000-000")
    rejected = None  # the first large ball that overlaps a body
    for cell in range(1, 26):
        env.reset()
        _, reward, terminated, _, info = env.step(f"Cell: {cell}, Radius: 5")
        if info["invalid_reason"]:
            rejected = (reward, terminated, info)
            break
    assert rejected is not None, "no grid action overlaps a body on this task"
    reward, terminated, info = rejected
    assert (reward, terminated) == (dgym.INVALID_REWARD, True) and not info["invalid_reason"].startswith("unparseable")


def test_seeding_same_seed_same_tasks_and_actions():
    def tasks_and_actions(seed: int) -> list[tuple[str, str]]:
        env = gymnasium.make("deepphy/cuttherope-v0", tasks=["b1_l01", "b2_l03", "b3_l01", "b5_l02"])
        env.action_space.seed(seed)
        out = [(env.reset(seed=seed)[1]["task"], env.action_space.sample())]
        for _ in range(7):
            out.append((env.reset()[1]["task"], env.action_space.sample()))
        return out

    first = tasks_and_actions(7)
    assert first == tasks_and_actions(7)
    assert first != tasks_and_actions(8)
    assert len({t for t, _ in first}) > 1
    env = gymnasium.make("deepphy/cuttherope-v0", task="b1_l04")
    env.reset(seed=1)
    # A sampled action is valid for the current decision: it parses, so it is never an invalid step.
    for _ in range(5):
        env.reset()
        _, _, _, _, info = env.step(env.action_space.sample())
        assert info["invalid_reason"] is None or not info["invalid_reason"].startswith("unparseable")


def test_bad_arguments_are_one_line_errors():
    with pytest.raises(ValueError, match="unknown cuttherope task"):
        gymnasium.make("deepphy/cuttherope-v0", task="b9_l99")
    env = gymnasium.make("deepphy/cuttherope-v0")
    with pytest.raises(ValueError, match="unknown cuttherope task"):
        env.reset(options={"task": "nope"})
    with pytest.raises(ValueError, match="render_mode"):
        dgym.DeepPhyEnv("cuttherope", render_mode="ansi")


@pytest.mark.parametrize("name, tasks, attempts", [
    ("cuttherope", ["b1_l01", "b1_l04", "b2_l03", "b4_l02", "b5_l01"], 1),
    ("phyre", ["within_00000-000", "within_00000-015", "cross_00003-001"], 10),
])
def test_the_same_actions_give_the_same_outcome_as_deepphy_run(ray_cluster, tmp_path, name, tasks, attempts):
    """A MOCK run through the harness (Ray workers, the protocol, records on disk), then every
    recorded reply of every attempt replayed through Gymnasium: the same steps, outcomes,
    invalid attempts and end."""
    from deepphy.config import RunConfig, RuntimeOptions
    from deepphy.runner import evaluate
    from deepphy.runs.store import read_records

    config = RunConfig(env=name, model="mock", runs=2, seed=5, tasks=tasks, max_attempts=attempts)
    assert evaluate(config, tmp_path, RuntimeOptions(progress=False, env_workers=1)).complete
    records = read_records(tmp_path)
    assert len(records) >= len(tasks) * 2
    env = gymnasium.make(dgym.env_id(name))
    kinds = set()
    for record in records:
        env.reset(options={"task": record.task})
        for n, step in enumerate(record.steps, 1):
            _, reward, terminated, truncated, info = env.step(step.raw_output)
            assert info.get("action") == step.action_text
            assert info["invalid_reason"] == step.invalid_reason
            assert info["feedback"] == step.feedback and (terminated, truncated) == (step.terminated, step.truncated)
            last = n == len(record.steps)
            assert (terminated or truncated) == last, f"{record.task} attempt {record.attempt} step {n}"
        assert info["success"] == record.success and reward == (
            dgym.INVALID_REWARD if record.invalid_reason else dgym.SUCCESS_REWARD if record.success else 0.0)
        assert truncated == record.truncated
        if not record.invalid_reason:
            assert (info["stars"], info["score"]) == (record.stars, record.score)
        kinds.add("unparseable" if (record.invalid_reason or "").startswith("unparseable") else
                  "invalid" if record.invalid_reason else "solved" if record.success else "failed")
    # The replays covered more than one kind of ending (PHYRE's MOCK also refuses, 10%).
    assert len(kinds) >= 2, kinds
    if name == "phyre":
        assert {"unparseable", "invalid", "failed"} <= kinds, kinds


def test_the_documented_example_runs():
    page = (Path(__file__).parent.parent / "docs" / "export.md").read_text()
    example = re.search(r"```python\n(import gymnasium\n.*?)```", page, re.S)
    assert example, "the Gymnasium example of docs/export.md"
    namespace: dict = {}
    exec(compile(example.group(1), "docs/export.md", "exec"), namespace)
    assert namespace["returns"] and all(isinstance(r, float) for r in namespace["returns"])
