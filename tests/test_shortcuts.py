"""Shortcut baselines (deepphy/envs/shortcuts.py): declared per environment, evaluated as the
agent `shortcut-<name>` through the same attempt protocol as any model, deterministic."""

from __future__ import annotations

import asyncio
import json
import subprocess

import numpy as np
import pytest

from deepphy.agents import endpoint_config, is_baseline, make_agent
from deepphy.config import RunConfig
from deepphy.envs import get_spec
from deepphy.envs.kinetix.space import KinetixSpace
from deepphy.envs.shortcuts import ShortcutContext, UnknownShortcut, shortcut_for, shortcuts
from deepphy.protocol import LocalEnv, MemoryArtifacts, run_episode

# The cheap environments, played for real (Kinetix compiles JAX: its policy is checked on its space).
PLAYED = ["phyre", "iphyre", "pooltool", "angrybirds", "cuttherope"]


def play(env: str, agent: str, n_tasks: int = 2, attempts: int = 3):
    spec = get_spec(env)
    cls = spec.load()
    options = cls.Options()
    config = RunConfig(env=env, model=agent)
    model = make_agent(agent, env=env)
    out = []
    for task in cls.tasks(options)[:n_tasks]:
        records = asyncio.run(run_episode(spec, spec.load_prompt(), config, task, 0, min(attempts, spec.max_attempts),
                                          LocalEnv(cls(options)), model, MemoryArtifacts()))
        out.append(records)
    return out


def test_every_environment_declares_shortcuts_that_are_baselines_without_an_endpoint():
    for name in ["phyre", "iphyre", "kinetix", "pooltool", "angrybirds", "cuttherope"]:
        declared = shortcuts(get_spec(name))
        assert declared, f"{name} declares no shortcut baseline"
        for short in declared:
            agent = f"shortcut-{short}"
            assert is_baseline(agent) and endpoint_config(agent) is None
            assert declared[short].exploits


@pytest.mark.parametrize("env", PLAYED)
def test_a_shortcut_plays_through_the_protocol_with_valid_actions_and_the_same_records_twice(env):
    for short in shortcuts(get_spec(env)):
        agent = f"shortcut-{short}"
        first, second = play(env, agent), play(env, agent)
        for records in first:
            assert all(s.invalid_reason is None for r in records for s in r.steps), records[0].steps[0].raw_output
        dump = lambda eps: [[(r.success, [s.raw_output for s in r.steps]) for r in rs] for rs in eps]  # noqa: E731
        assert dump(first) == dump(second)


def test_iphyre_all_at_once_removes_every_block_at_time_zero():
    records = play("iphyre", "shortcut-all-at-once", n_tasks=3, attempts=1)
    for (record,) in records:
        plan = json.loads(record.steps[0].raw_output)
        space = record.steps[0].action
        assert [c["time"] for c in plan] == [0.0] * len(plan)
        assert sorted(c["index"] for c in plan) == list(range(len(plan)))
        assert [c["index"] for c in space["clicks"]] == list(range(len(plan)))


def test_phyre_drop_on_green_never_repeats_a_failed_action_and_drops_above_the_green_object():
    from deepphy.envs.phyre import data
    from deepphy.envs.phyre.env import phyre_id
    from deepphy.envs.phyre.space import PhyreSpace

    space = PhyreSpace()
    spec = get_spec("phyre")
    cls = spec.load()
    for records in play("phyre", "shortcut-drop-on-green", n_tasks=3, attempts=4):
        texts = [r.steps[0].action_text for r in records]
        assert len(set(texts)) == len(texts)
        task = data.load_task(phyre_id(next(t for t in cls.tasks(cls.Options()) if t.id == records[0].task)))
        green = task.bodies[task.body1]
        for r in records:
            cell = r.steps[0].action["cell"]
            assert space.cell_centre(cell)[1] > green.y  # above it (y up)


def test_kinetix_full_throttle_drives_every_motor_forward_and_every_thruster_on():
    policy = shortcut_for(get_spec("kinetix"), "shortcut-full-throttle").policy
    space = KinetixSpace(num_motors=3, num_thrusters=2)
    ctx = ShortcutContext(spec=get_spec("kinetix"), options=None, task=None, action_space=space,  # type: ignore[arg-type]
                          earlier=[], tried=[], rng=np.random.default_rng(0))
    assert space.parse(policy(ctx)).motors == (1, 1, 1) and space.parse(policy(ctx)).thrusters == (1, 1)


def _ab_level(blocks=(), pigs=(), birds=("red", "red")):
    from deepphy.envs.angrybirds.levels import Level

    return Level(id="s1_l01", title="test", idea="a test scene", birds=list(birds), blocks=list(blocks),
                 pigs=list(pigs))


def test_angrybirds_aim_hits_the_nearest_pig_then_lobs_at_it():
    """The closed-form aim goes through the pig's centre (obstacles ignored): with nothing
    in the way its flat arc hits the nearest pig; a pig that survived that very shot gets the
    steep arc next."""
    from deepphy.envs.angrybirds.levels import Pig
    from deepphy.envs.angrybirds.shortcuts import aim_at_pig, arcs, flat_shot
    from deepphy.envs.angrybirds.sim import World

    for x, y in ((6.0, 0.215), (9.0, 0.215), (13.0, 0.215), (14.5, 3.0)):
        world = World(_ab_level(pigs=[Pig(x=x, y=y), Pig(size="medium", x=15.0, y=5.0)]))
        angle, power = aim_at_pig(world, [])
        shot = world.shoot("red", angle, power)
        assert shot.first_hit == "small pig", (x, y, angle, power)  # the nearer one
    far = World(_ab_level(pigs=[Pig(size="big", x=12.0, y=0.465)]))
    first = aim_at_pig(far, [])
    second = aim_at_pig(far, [first])
    low, high = arcs(12.0, 0.465)
    assert first == (round(low, 2), 1.0) and second == (round(high, 2), 1.0) and second[0] > 60
    assert aim_at_pig(far, [first, second]) == first
    assert flat_shot(3.5, 0.2)[0] == 0.0 and flat_shot(3.5, 0.2)[1] < 1.0  # below and near: level, less power


def test_angrybirds_base_aims_at_the_foot_of_the_biggest_structure():
    from deepphy.envs.angrybirds.levels import Block, Pig
    from deepphy.envs.angrybirds.shortcuts import aim_at_base, structures
    from deepphy.envs.angrybirds.sim import World

    hut = [Block(shape="rect_small", material="wood", x=6.0 + dx, y=0.425, angle=90) for dx in (-0.4, 0.4)]
    hut.append(Block(shape="rect_small", material="wood", x=6.0, y=0.96))
    tower = [Block(shape="rect_small", material="stone", x=11.0 + dx, y=0.425 + 0.96 * k, angle=90)
             for k in range(3) for dx in (-0.6, 0.6)]
    tower += [Block(shape="rect_medium", material="stone", x=11.0, y=0.96 + 0.96 * k) for k in range(3)]
    world = World(_ab_level(blocks=hut + tower, pigs=[Pig(x=6.0, y=0.215), Pig(x=11.0, y=3.1)]))
    groups = structures(world)
    assert [len(g) for g in groups] == [9, 3]
    shot = world.shoot("red", *aim_at_base(world, []))
    assert shot.first_hit == "stone rect small", shot.first_hit  # the tower's first leg, over the hut


def test_angrybirds_shortcuts_through_the_protocol_play_what_the_calibration_plays():
    from deepphy.envs.angrybirds.levels import load_level
    from deepphy.envs.angrybirds.space import ShootSpace
    from deepphy.envs.angrybirds.shortcuts import POLICIES, play as play_world

    space = ShootSpace()
    for name, choose in POLICIES.items():
        for (record,) in play("angrybirds", f"shortcut-{name}", n_tasks=2, attempts=1):
            _, shots = play_world(load_level(record.task), choose)
            assert [(s.action["angle"], s.action["power"]) for s in record.steps] == shots, name
            assert all(space.parse(s.raw_output) == space.make(*shot) for s, shot in zip(record.steps, shots))


def test_a_shortcut_another_environment_declares_is_refused_in_one_line():
    with pytest.raises(UnknownShortcut, match=r"kinetix has no shortcut baseline 'shortcut-drop-on-green' \(its shortcuts: shortcut-full-throttle\)"):
        make_agent("shortcut-drop-on-green", env="kinetix")


def test_the_cli_refuses_an_unknown_shortcut_before_ray_starts(deepphy_cmd, tmp_path):
    proc = subprocess.run([*deepphy_cmd, "run", "--env", "iphyre", "--model", "shortcut-nope", "--out", str(tmp_path / "r")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "deepphy: error: iphyre has no shortcut baseline 'shortcut-nope' (its shortcuts: shortcut-all-at-once)"]
    assert not (tmp_path / "r").exists()


# -- Cut the Rope ---------------------------------------------------------------------------------------


def cut_the_rope_records(agent: str, level_ids: list[str], runs: int = 1) -> dict:
    from deepphy.protocol import run_attempt

    spec = get_spec("cuttherope")
    cls = spec.load()
    config = RunConfig(env="cuttherope", model=agent, seed=0)
    model = make_agent(agent, env="cuttherope")
    tasks = {t.id: t for t in cls.tasks(cls.Options())}
    return {(level, run): asyncio.run(run_attempt(spec, spec.load_prompt(), config, tasks[level], run, 1, [],
                                                  LocalEnv(cls()), model, MemoryArtifacts()))
            for level in level_ids for run in range(runs)}


def test_cut_the_rope_first_id_acts_on_element_1_then_claims_success():
    from deepphy.envs.cuttherope.level import load_level

    for (level, _), record in cut_the_rope_records("shortcut-first-id", ["b1_l04", "b2_l03", "b4_l05"]).items():
        texts = [s.action_text for s in record.steps]
        assert texts[0] == ("cut_pin(1)" if load_level(level).pins else "pop_bubble(1)")
        assert texts[1:] in ([], ["success()"])


def test_cut_the_rope_all_at_once_swipes_every_rope_then_claims_success():
    from deepphy.envs.cuttherope.level import load_level

    for (level, _), record in cut_the_rope_records("shortcut-all-at-once", ["b1_l21", "b3_l05", "b5_l07"]).items():
        texts = [s.action_text for s in record.steps]
        n = len(load_level(level).pins)
        assert n >= 3 and texts[0] == f"cut_pin({', '.join(map(str, range(1, n + 1)))})"
        assert texts[1:] in ([], ["success()"])


def test_cut_the_rope_random_pauses_waits_swipes_and_draws_by_the_request():
    # Over a few levels and runs it pauses (0.1-3 s), cuts two or more ropes at once and acts
    # on single elements; the same request gives the same reply, another run another episode;
    # the calibration replays exactly what a run plays.
    from deepphy.envs.cuttherope.calibrate import shortcut_episode
    from deepphy.envs.cuttherope.level import load_level

    levels = ["b1_l21", "b2_l07", "b3_l05"]
    first = cut_the_rope_records("shortcut-random-pauses", levels, runs=4)
    again = cut_the_rope_records("shortcut-random-pauses", levels, runs=4)
    assert {k: r.deterministic_view() for k, r in first.items()} == {k: r.deterministic_view() for k, r in again.items()}
    texts = [s.action_text for r in first.values() for s in r.steps]
    sleeps = [float(t[6:-1]) for t in texts if t.startswith("sleep(")]
    assert sleeps and all(0.1 <= s <= 3.0 for s in sleeps) and len(set(sleeps)) > 3
    assert any(t.startswith("cut_pin(") and "," in t for t in texts)
    assert any(t.startswith(("cut_pin(", "pop_bubble(", "tap_air_cushion(")) and "," not in t.replace(", times", "")
               for t in texts)
    by_level = {}
    for (level, run), record in first.items():
        by_level.setdefault(level, set()).add(tuple(s.action_text for s in record.steps))
        won, stars = shortcut_episode(load_level(level), "random-pauses", 0, run)
        assert (record.success, record.stars if record.success else 0) == (won, stars), (level, run)
    assert all(len(episodes) > 1 for episodes in by_level.values())
