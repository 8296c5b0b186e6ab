"""PHYRE environment: task list, folds, observations, invalid placements, determinism."""

import json
import subprocess
import sys
import time

from deepphy.envs import Planning, get_env_class
from deepphy.envs.phyre.env import PhyreEnv, PhyreOptions
from deepphy.envs.phyre.space import PhyreAction
from deepphy.envs.phyre import scene as S
from deepphy.envs.phyre.env import cross_test_templates, within_test_variants
from deepphy.envs.phyre.templates import templates, variant_scene
from deepphy.prompts import PromptFormat, build_messages


def test_registered_and_contract():
    cls = get_env_class("phyre")
    assert cls is PhyreEnv
    assert cls.spec.planning is Planning.IN_ADVANCE and cls.spec.max_steps == 1 and cls.spec.max_attempts == 10


def test_default_task_set_is_fast_and_follows_the_folds():
    t0 = time.time()
    tasks = PhyreEnv.tasks(PhyreOptions())
    assert time.time() - t0 < 1.0
    assert len({t.id for t in tasks}) == len(tasks)
    within = [t for t in tasks if t.group == "within"]
    cross = [t for t in tasks if t.group == "cross"]
    n = len(templates())
    assert len(within) == 20 * n
    assert len(cross) == 100 * len([t for t in cross_test_templates(0) if t in templates()])
    if n == 25:
        assert len(tasks) == 1000
    assert len(cross_test_templates(0)) == 5 and len(within_test_variants(0, 3)) == 20
    assert cross_test_templates(1) != cross_test_templates(0)  # the fold seed selects the split
    all_tasks = PhyreEnv.tasks(PhyreOptions(splits="all"))
    assert len(all_tasks) == 100 * n


def test_observation_images_and_prompt():
    task = PhyreEnv.tasks(PhyreOptions())[0]
    env = PhyreEnv()
    obs = env.reset(task)
    assert [i.name for i in obs.images] == ["scene", "grid"]
    scene, grid = (i.to_array() for i in obs.images)
    assert scene.shape == grid.shape == (512, 512, 3) and (scene != grid).any()
    assert "Goal" in obs.text
    for fmt in PromptFormat:
        msgs = build_messages(PhyreEnv.spec.load_prompt(), fmt, task, obs, [])
        assert "Cell: <1..25>, Radius: <1..5>" in msgs[0].text and "TOP-LEFT" in msgs[0].text


def test_overlapping_and_outside_placements_are_invalid():
    env = PhyreEnv()
    task = next(t for t in PhyreEnv.tasks(PhyreOptions(splits="all")) if t.params["template"] == 0)
    env.reset(task)
    scene = variant_scene(0, task.params["variant"])
    green = scene.objects[scene.subject]
    # a grid action whose ball covers the green ball's centre
    space = env.space
    hit = next(a for a in space.all_actions() if a.radius == 5 and
               abs(space.to_scene(a)[0] - green.x) < 26 and abs(space.to_scene(a)[1] - green.y) < 26)
    res = env.step(hit)
    assert res.done and not res.success and res.invalid_reason and "overlaps" in res.invalid_reason
    res = env.step(PhyreAction(cell=1, radius=5))  # radius 32 at (25.6, 230.4) sticks out
    assert res.done and not res.success and "inside the scene" in res.invalid_reason
    assert S.placement_problem(scene, green.x + green.size[0] + 5.1, green.y, 5) is None  # near but clear


DETERMINISM = """
import json, sys
from deepphy.envs.phyre import scene as S
from deepphy.envs.phyre.templates import templates, variant_scene
out = []
for t in sorted(templates()):
    sc = variant_scene(t, 7)
    o = S.simulate(sc, (128.0, 240.0, 9.5), snapshot_every=100)
    out.append([repr(sc), o.success, o.steps, [[round(v, 9) for v in st] for _, s in o.snapshots for st in s]])
print(json.dumps(out))
"""


def test_determinism_across_processes():
    runs = []
    for seed in ("0", "12345"):
        proc = subprocess.run([sys.executable, "-c", DETERMINISM], capture_output=True, text=True, check=True,
                              env={"PYTHONHASHSEED": seed, "PATH": ""})
        runs.append(json.loads(proc.stdout))
    assert runs[0] == runs[1]


def test_episode_speed():
    t0 = time.time()
    n = 0
    for t in sorted(templates()):
        sc = variant_scene(t, 0)
        S.simulate(sc, max_steps=1000)
        n += 1
    assert (time.time() - t0) / n < 0.1
