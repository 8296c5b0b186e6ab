"""PHYRE environment: task lists and ids, observations and prompts, attempts."""

from __future__ import annotations

import json

import pytest

from conftest import data_file
from pydantic import ValidationError

from deepphy.envs import Planning, Task, get_env_class
from deepphy.envs.phyre import PhyreAction, PhyreContinuousAction
from deepphy.envs.phyre.env import PhyreEnv, PhyreOptions, phyre_id, task_id
from deepphy.prompts import PromptFormat, build_messages

GROUND_TRUTH = json.loads(data_file("phyre_real_grid_outcomes.json").read_text())


@pytest.fixture(scope="module")
def default_tasks() -> dict[str, Task]:
    return {t.id: t for t in PhyreEnv.tasks(PhyreOptions())}


def test_registered_and_contract():
    cls = get_env_class("phyre")
    assert cls is PhyreEnv
    assert cls.spec.planning is Planning.IN_ADVANCE and cls.spec.max_steps == 1 and cls.spec.max_attempts == 10


def test_default_task_set_is_both_fold0_test_sets(default_tasks):
    tasks = list(default_tasks.values())
    assert len(tasks) == 1000
    assert [t.group for t in tasks] == ["within"] * 500 + ["cross"] * 500
    distinct = {t.params["phyre_id"] for t in tasks}
    assert len(distinct) == 900  # 100 tasks are test tasks of both setups
    cross_templates = sorted({t.params["template"] for t in tasks if t.group == "cross"})
    assert cross_templates == ["00003", "00004", "00014", "00015", "00019"]
    for t in tasks:
        assert t.id == task_id(t.group, t.params["phyre_id"]) and t.id.replace("_", "").replace("-", "").isalnum()
        assert phyre_id(Task(env="phyre", id=t.id)) == t.params["phyre_id"]  # the id alone suffices


def test_options_select_setup_split_and_fold():
    within_dev = PhyreEnv.tasks(PhyreOptions(setup="within", split="dev"))
    assert len(within_dev) == 400 and {t.group for t in within_dev} == {"within"}
    cross_train = PhyreEnv.tasks(PhyreOptions(setup="cross", split="train", fold=3))
    assert len(cross_train) == 1600 and len({t.params["template"] for t in cross_train}) == 16
    assert PhyreEnv.tasks(PhyreOptions(fold=1)) != PhyreEnv.tasks(PhyreOptions(fold=0))
    for bad in ({"fold": 10}, {"setup": "all"}, {"split": "val"}, {"actions": "grid6"}, {"grid": 5}):
        with pytest.raises(ValidationError):
            PhyreOptions(**bad)


@pytest.mark.parametrize("actions, second, syntax", [
    ("grid5", "grid", "Cell: <1..25>, Radius: <1..5>"),
    ("grid8", "grid", "Cell: <1..64>, Radius: <1..8>"),
    ("continuous", "axes", "X: <0..1>, Y: <0..1>, R: <0..1>"),
])
def test_observation_images_and_prompt(actions, second, syntax):
    for state_text in (False, True):
        options = PhyreOptions(actions=actions, state_text=state_text)
        task = next(t for t in PhyreEnv.tasks(options) if t.id == "cross_00003-004")
        env = PhyreEnv(options)
        obs = env.reset(task)
        assert [i.name for i in obs.images] == ["scene", second]
        scene, overlay = (i.to_array() for i in obs.images)
        assert scene.shape == overlay.shape == (512, 512, 3) and (scene != overlay).any()
        rich = state_text or actions == "continuous"  # the continuous space is a departure of its own
        if state_text:  # PHYRE's own sentence, its time and the task's id (a hint at its template)
            assert obs.text.startswith("Goal: Make sure the green") and task.params["phyre_id"] in obs.text
        else:  # the paper's: which objects must touch
            assert obs.text == "Goal: the green bar must end up touching the purple bar." and "000" not in obs.text
        for fmt in PromptFormat:
            text = build_messages(PhyreEnv.spec.load_prompt(), fmt, task, obs, [])[0].text
            assert syntax in text and ("3 seconds" in text and "16.7 seconds" in text) == rich
        if actions == "grid5" and state_text:
            assert "1 = 2 px, 2 = 10 px, 3 = 17 px, 4 = 24 px, 5 = 32 px" in text and "TOP-LEFT" in text
        if actions == "grid5" and not state_text:  # the paper's anchors: shares of the image's width
            assert "about\n1/128 of the image's width" in text and "about 1/8 of it" in text and " px" not in text


def test_attempts_reproduce_real_phyre(default_tasks):
    ground_truth_id = sorted(GROUND_TRUTH["outcomes"])[0]
    task = default_tasks[task_id("within", ground_truth_id)]
    env = PhyreEnv(PhyreOptions(state_text=True))  # with the words of what happened
    env.reset(task)
    statuses = GROUND_TRUTH["outcomes"][ground_truth_id]

    def grid_action(status: int) -> PhyreAction:
        cell, radius = GROUND_TRUTH["actions"][statuses.index(status)]
        return PhyreAction(cell=cell, radius=radius)

    result = env.step(grid_action(1))
    assert result.done and result.success and result.invalid_reason is None
    assert result.feedback.startswith("solved") and result.info["steps"] <= 1000
    strip = result.key_frames[0].to_array()
    assert strip.shape[0] == 256 and strip.shape[1] > 4 * 256
    assert env.step(grid_action(1)).model_dump() == result.model_dump()  # the same action, the same attempt
    bad = env.step(grid_action(0))
    assert bad.done and not bad.success and bad.invalid_reason and not bad.key_frames
    miss = env.step(grid_action(-1))
    assert miss.done and not miss.success and miss.invalid_reason is None and miss.feedback.startswith("not solved")
    # the paper's history: "failed", or "invalid: out of bounds or overlapping", and the key frames
    plain = PhyreEnv()
    plain.reset(task)
    assert plain.step(grid_action(-1)).feedback == "" and plain.step(grid_action(1)).feedback == ""
    invalid = plain.step(grid_action(0))
    assert invalid.invalid_reason == "the ball overlaps an object or is not wholly inside the scene"
    assert invalid.info["placement"] == bad.invalid_reason  # where, for the record


def test_continuous_attempt_and_bad_task(default_tasks):
    env = PhyreEnv(PhyreOptions(actions="continuous"))
    env.reset(next(iter(default_tasks.values())))
    out = env.step(PhyreContinuousAction(x=0.5, y=0.0, r=0.5))
    assert out.invalid_reason and "inside the scene" in out.invalid_reason
    ok = env.step(PhyreContinuousAction(x=0.1, y=0.9, r=0.1))
    assert ok.invalid_reason is None and ok.info["ball_px"] == [25, 229, 5]
    with pytest.raises(ValueError, match="not a PHYRE task id"):
        env.reset(Task(env="phyre", id="t07_v42"))
    with pytest.raises(ValueError, match="unknown PHYRE task"):
        env.reset(Task(env="phyre", id="within_00099-999"))
