"""Pooltool nine-ball on the real pooltool-billiards package (no mocks).

pooltool writes ~/.config/pooltool at import, so HOME points at a temporary directory
while it is imported here and in the subprocesses. The numba cache stays the machine's
(DEEPPHY_CACHE_DIR, pinned by tests/conftest.py), so kernels compile once per machine.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import textwrap
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from deepphy.envs import ActionSpace, InvalidAction, Planning, Task, get_env_class
from deepphy.envs.pooltool.env import PooltoolEnv, PooltoolOptions
from deepphy.envs.pooltool.space import ACTIONS, SPOT_OFFSETS, SPOTS, PoolShot, PoolSpace

REPO = Path(__file__).resolve().parents[1]

# Recorded once by an offline search over all 27 actions per shot (docs/environments.md). The
# assertions are on what pooltool simulates for them, not on the search.
WIN_IN_7 = (0, [  # rack_000: every shot pots, the 7th pots the 9-ball
    "Speed: Medium, Strikespot: top-right",
    "Speed: High, Strikespot: top-left",
    "Speed: Medium, Strikespot: middle-right",
    "Speed: Low, Strikespot: bottom-centre",
    "Speed: Low, Strikespot: middle-left",
    "Speed: Low, Strikespot: top-right",
    "Speed: Low, Strikespot: top-left",
])
GOLDEN_BREAK = (4, "Speed: High, Strikespot: middle-right")  # rack_004: the 9 drops on the break
SCRATCH_WITH_NINE = (6, "Speed: High, Strikespot: bottom-right")  # rack_006: 9, 6 and the cue ball drop
FIFTEEN = [  # 15 uniformly random actions (numpy default_rng(0)); on rack_000 they foul and scratch
    "Speed: High, Strikespot: middle-centre", "Speed: Medium, Strikespot: bottom-right",
    "Speed: Medium, Strikespot: middle-centre", "Speed: Low, Strikespot: bottom-centre",
    "Speed: Low, Strikespot: bottom-right", "Speed: Low, Strikespot: top-centre",
    "Speed: Low, Strikespot: top-right", "Speed: Low, Strikespot: top-left",
    "Speed: Low, Strikespot: middle-centre", "Speed: High, Strikespot: middle-left",
    "Speed: Medium, Strikespot: bottom-right", "Speed: High, Strikespot: bottom-left",
    "Speed: Medium, Strikespot: middle-centre", "Speed: Medium, Strikespot: bottom-centre",
    "Speed: High, Strikespot: bottom-right",
]


@pytest.fixture(scope="module")
def home(tmp_path_factory):
    """A throwaway HOME for pooltool's config files; pooltool imported under it."""
    path = tmp_path_factory.mktemp("home")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HOME", str(path))
        from deepphy.envs.pooltool.sim import _engine

        _engine()  # imports pooltool (reads HOME once, at import) and builds the engine
    yield path


# Most tests play pooltool's nine-ball rules with the text that describes them (both opt-in
# departures from the paper's set-up, which plays the reference rules and shows the table only)
NINEBALL = PooltoolOptions(rules="nineball", state_text=True)


@pytest.fixture(scope="module")
def env(home):
    yield PooltoolEnv(NINEBALL)


def task(k: int) -> Task:
    return Task(env="pooltool", id=f"rack_{k:03d}", params={"rack": k})


def play(env: PooltoolEnv, k: int, actions: list[str]):
    space = PoolSpace()
    obs = env.reset(task(k))
    results = []
    for text in actions:
        r = env.step(space.parse(text))
        results.append(r)
        if r.done:
            break
        obs = r.observation
    return obs, results


# -- the action space (no pooltool needed) --------------------------------------------


def test_space_has_27_actions_and_formats_round_trip():
    space = PoolSpace()
    actions = space.all_actions()
    assert len(actions) == len(set(actions)) == 27 == len(ACTIONS)
    for a in actions:
        assert space.parse(space.format(a)) == a
    assert len(SPOTS) == 9 and set(SPOT_OFFSETS) == set(SPOTS)
    # edge spots on the axes at 0.5 R, corners at +-0.35 on both; left = +a in pooltool
    assert SPOT_OFFSETS["top-centre"] == (0.0, 0.5) and SPOT_OFFSETS["bottom-centre"] == (0.0, -0.5)
    assert SPOT_OFFSETS["middle-left"] == (0.5, 0.0) and SPOT_OFFSETS["middle-right"] == (-0.5, 0.0)
    assert SPOT_OFFSETS["top-left"] == (0.35, 0.35) and SPOT_OFFSETS["bottom-right"] == (-0.35, -0.35)
    assert PoolShot(speed="High", spot="middle-centre").velocity == 8.0


@pytest.mark.parametrize(
    "text, speed, spot",
    [
        ("Speed: Low, Strikespot: top-left", "Low", "top-left"),
        ("speed: HIGH\nstrikespot: Bottom-Right", "High", "bottom-right"),
        ("```\nSpeed: Medium\nStrikespot: middle-centre\n```", "Medium", "middle-centre"),
        ("I will play softly with follow.\n**Speed:** Low\n**Strike spot:** top center", "Low", "top-centre"),
        ("Speed: medium; Strike_spot: centre", "Medium", "middle-centre"),
        ("Speed: Medium, Strikespot: center", "Medium", "middle-centre"),
        ("Speed: High, Strikespot: left", "High", "middle-left"),
        ("Speed: High, Strikespot: top", "High", "top-centre"),
        ('{"speed": "low", "strikespot": "bottom_left"}', "Low", "bottom-left"),
        ("Speed: 5 m/s, Strike-spot: upper right (for follow)", "Medium", "top-right"),
        ("Speed = 8, Strikespot = lower left of the cue ball.", "High", "bottom-left"),
        ("Maybe Speed: Low... no. Final answer: Speed: High, Strikespot: middle-right", "High", "middle-right"),
        ("Action: Speed: Low, Strikespot: Middle Left", "Low", "middle-left"),
    ],
)
def test_parse_accepts_the_syntax_robustly(text, speed, spot):
    assert PoolSpace().parse(text) == PoolShot(speed=speed, spot=spot)


@pytest.mark.parametrize(
    "text",
    [
        "",
        "hit it hard with topspin",
        "Speed: High",
        "Strikespot: top-left",
        "Speed: Extreme, Strikespot: top-left",
        "Speed: 3, Strikespot: top-left",
        "Speed: Low, Strikespot: sideways",
        "Speed: Low, Strikespot: top-bottom",
        "Speed: Low, Strikespot: left-right",
    ],
)
def test_parse_rejects_anything_else_with_a_reason(text):
    with pytest.raises(InvalidAction) as e:
        PoolSpace().parse(text)
    assert str(e.value)


def test_sample_is_uniform_over_the_27_and_space_rebuilds_from_json():
    space = PoolSpace()
    rng = np.random.default_rng(1)
    counts = Counter(space.sample(rng) for _ in range(27 * 400))
    assert len(counts) == 27
    assert min(counts.values()) > 300 and max(counts.values()) < 500
    rebuilt = ActionSpace.from_json(json.loads(space.model_dump_json()))
    assert isinstance(rebuilt, PoolSpace)


def test_env_module_imports_without_pooltool():
    code = (
        "import sys; from deepphy.envs import get_env_class, ActionSpace; "
        "get_env_class('pooltool'); s = ActionSpace.from_json({'kind': 'pooltool_shot'}); "
        "print(s.format(s.parse('Speed: Low, Strikespot: top-left'))); "
        "assert 'pooltool' not in sys.modules and 'numba' not in sys.modules, 'imported eagerly'"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "Speed: Low, Strikespot: top-left"


def test_registration_and_task_set():
    cls = get_env_class("pooltool")
    assert cls is PooltoolEnv
    assert cls.spec.planning is Planning.ON_THE_FLY and cls.spec.max_steps == 15 and cls.spec.max_attempts == 1
    tasks = cls.tasks(cls.Options())
    assert [t.id for t in tasks] == [f"rack_{k:03d}" for k in range(100)]
    assert type(cls.spec.load_prompt()).__name__ == "PooltoolPrompt"


# -- the game on real pooltool ---------------------------------------------------------


def test_racks_are_nine_ball_diamonds_and_differ(env):
    from deepphy.envs.pooltool.sim import _ball_params, rack_layout

    R = _ball_params().R
    layouts = [rack_layout(k) for k in range(100)]
    for lay in layouts[:10]:
        assert list(lay) == ["cue"] + [str(i) for i in range(1, 10)]
        pts = np.array(list(lay.values()))
        d = np.linalg.norm(pts[:, None] - pts[None], axis=2) + np.eye(10)
        assert d.min() > 2 * R  # no overlap
        # the 1 on the foot spot (within the jitter), the 9 two rows behind it in the middle
        assert np.allclose(lay["1"], (0.9906 / 2, 0.75 * 1.9812), atol=2 * R * 1e-3)
        assert abs(d[1, 9] - 2 * np.sqrt(3) * R * (1 + 1e-3)) < 4 * R * 1e-3
        assert abs(lay["9"][0] - lay["1"][0]) < 4 * R * 1e-3
    orders = {tuple(sorted(lay, key=lambda b: (round(lay[b][1], 3), round(lay[b][0], 3)))) for lay in layouts}
    assert len(orders) > 90  # seeded permutations of balls 2-8


def test_reset_observation_and_render(env):
    obs = env.reset(task(0))
    assert [i.name for i in obs.images] == ["table"]
    img = obs.images[0].to_array()
    assert max(img.shape[:2]) in range(700, 900) and img.shape[1] > img.shape[0]  # landscape, readable
    assert "Balls on the table: 1, 2, 3, 4, 5, 6, 7, 8, 9" in obs.text and "Target (lowest-numbered) ball: 1" in obs.text
    assert obs.action_space == PoolSpace()
    from deepphy.prompts import PromptFormat, build_messages

    for fmt in PromptFormat:
        msgs = build_messages(PooltoolEnv.spec.load_prompt(), fmt, task(0), obs, [])
        assert "Strikespot" in msgs[0].text and len(msgs[1].images) == 1


def test_by_default_the_observation_is_the_papers_the_table_alone(home):
    """The paper's Pooltool prompt: the table from above, no text, nothing drawn on it, and no
    history of shots; the reference rules."""
    plain = PooltoolEnv()
    assert plain.options.rules == "reference" and plain.options.departures_from_paper({}) == []
    tasks = PooltoolEnv.tasks(plain.options)
    obs = plain.reset(tasks[0])
    assert obs.text == "" and [i.name for i in obs.images] == ["table"]
    rich = PooltoolEnv(PooltoolOptions(state_text=True))
    annotated = rich.reset(PooltoolEnv.tasks(rich.options)[0])
    assert "Balls on the table" in annotated.text
    # the same table; the richer image circles the target and draws the cue's line to it
    assert obs.images[0].to_array().shape == annotated.images[0].to_array().shape
    assert (obs.images[0].to_array() != annotated.images[0].to_array()).any()
    from deepphy.prompts import PromptFormat, build_messages

    first = plain.step(PoolSpace().parse("Speed: Low, Strikespot: middle-centre"))
    from deepphy.prompts.base import PastStep

    earlier = [PastStep(step=1, action="Speed: Low, Strikespot: middle-centre", feedback=first.feedback,
                        frame=obs.images[0])]
    msgs = build_messages(PooltoolEnv.spec.load_prompt(), PromptFormat.VLA, tasks[0], first.observation, [], earlier)
    assert "earlier decisions" not in msgs[1].text and len(msgs[1].images) == 1  # no history of shots
    assert "m/s" not in msgs[0].text and "15" not in msgs[0].text and "aimed" not in msgs[0].text


def test_known_sequence_pots_the_nine_legally(env):
    k, actions = WIN_IN_7
    _, results = play(env, k, actions)
    assert len(results) == 7
    assert not any(r.done for r in results[:-1])
    assert all(r.info["legal"] for r in results)
    last = results[-1]
    assert last.done and last.success and last.observation is None
    assert last.info["shots"] == 7 and "9" in last.info["potted"]
    assert "game won" in last.feedback
    assert last.key_frames and last.key_frames[0].to_array().ndim == 3


def test_golden_break_wins_in_one_shot(env):
    k, action = GOLDEN_BREAK
    _, results = play(env, k, [action])
    assert results[0].done and results[0].success and results[0].info["shots"] == 1


def test_scratch_gives_ball_in_hand_not_a_lost_game(env):
    k, action = SCRATCH_WITH_NINE
    obs, results = play(env, k, [action, "Speed: Low, Strikespot: middle-centre"])
    scratch = results[0]
    assert not scratch.done and not scratch.success
    assert "cue" in scratch.info["potted"] and not scratch.info["legal"]
    assert "scratch" in scratch.feedback and "ball in hand" in scratch.feedback
    assert "9-ball was potted on a foul" in scratch.feedback
    # the cue ball is back on the table at the head spot; the 9 is back on the foot spot
    text = scratch.observation.text
    assert text.startswith("Shot 2 of at most 15.") and "Ball in hand" in text
    assert "9" in scratch.info["balls_left"]
    table = env._system.table
    assert "cue ball: X=0.50, Y=0.50" in text  # head spot: l/4 = 0.50 along, w/2 = 0.50 across
    assert f"9-ball: X={3 * table.l / 4:.2f}, Y={table.w / 2:.2f}" in text
    # and the game goes on
    assert len(results) == 2 and results[1].info["shots"] == 2


def _summary(env: PooltoolEnv, k: int, actions: list[str]) -> dict:
    obs, results = play(env, k, actions)
    balls = env._system.balls
    return {
        "feedback": [r.feedback for r in results],
        "info": [r.info for r in results],
        "positions": {b: [float(v).hex() for v in balls[b].state.rvw[0]] for b in balls},
        "frames": [hashlib.sha256(r.key_frames[0].png).hexdigest() for r in results],
        "obs": hashlib.sha256(obs.images[0].png).hexdigest(),
    }


def test_same_rack_and_actions_identical_across_processes(env, home):
    here = _summary(env, 0, FIFTEEN)
    assert len(here["feedback"]) == 15
    assert any("FOUL" in f for f in here["feedback"]) and any("scratch" in f for f in here["feedback"])
    script = textwrap.dedent(
        f"""
        import json, sys
        sys.path.insert(0, {str(REPO / 'tests')!r})
        from test_pooltool import PooltoolEnv, _summary, FIFTEEN
        from test_pooltool import NINEBALL
        print(json.dumps(_summary(PooltoolEnv(NINEBALL), 0, FIFTEEN)))
        """
    )
    outs = []
    for hashseed in ("1", "4242"):
        run_env = dict(os.environ, PYTHONHASHSEED=hashseed, HOME=str(home))
        out = subprocess.run([sys.executable, "-c", script], cwd=REPO, env=run_env, capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr[-3000:]
        outs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    assert outs[0] == outs[1] == json.loads(json.dumps(here))


def test_a_fresh_process_after_the_warm_up_compiles_nothing(env, home):
    """Issue 40: once the kernels a shot uses are in numba's cache, a new process (a Ray
    worker) loads them all: its warm-up and a shot write no cache entry (an entry written
    is a kernel compiled again, e.g. for a signature that differs from process to process)."""
    from deepphy.envs.pooltool.sim import configure_numba_cache, warm_up

    warm_up()
    play(env, 0, FIFTEEN[:1])  # whatever these need is compiled and cached by now
    cache = configure_numba_cache()

    def entries() -> set[tuple[str, int]]:
        return {(str(p.relative_to(cache)), p.stat().st_mtime_ns) for p in cache.rglob("*.nb[ic]")}

    before = entries()
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(REPO / 'tests')!r})
        from test_pooltool import PooltoolEnv, NINEBALL, FIFTEEN, play
        from deepphy.envs.pooltool.sim import warm_up
        warm_up()
        play(PooltoolEnv(NINEBALL), 0, FIFTEEN[:1])
        """
    )
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, env=dict(os.environ, HOME=str(home)),
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert sorted(entries() - before) == []


@pytest.mark.slow
def test_random_games_keep_the_table_consistent(env):
    """MOCK-like games on 10 racks: after every shot no two balls overlap on the table."""
    from deepphy.envs.pooltool.sim import _ball_params

    R = _ball_params().R
    space = PoolSpace()
    for k in range(10):
        env.reset(task(k))
        rng = np.random.default_rng(k)
        for _ in range(15):
            r = env.step(space.sample(rng))
            on = [b for b in env._system.balls.values() if b.state.s != 4]
            pts = np.array([b.state.rvw[0][:2] for b in on])
            d = np.linalg.norm(pts[:, None] - pts[None], axis=2) + np.eye(len(pts))
            assert d.min() > 2 * R - 1e-9
            if r.done:
                break


def test_warm_up_waits_for_a_compiling_worker_only_until_the_cache_is_filled(tmp_path, monkeypatch):
    """A cold cache: warm-ups take turns under the lock (one compiles, the others load what it
    wrote). Once a warm-up has filled the cache, the others load at once (no lock held)."""
    import fcntl
    import threading

    from deepphy.envs.pooltool import sim

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    breaks = []
    monkeypatch.setattr(sim, "_break", lambda pt: breaks.append(1))

    def warm_up_while_another_holds_the_lock() -> bool:
        """Whether a warm-up finished while another process's warm-up held the lock."""
        with open(tmp_path / "pooltool-warm-up.lock", "w") as held:
            fcntl.flock(held, fcntl.LOCK_EX)
            worker = threading.Thread(target=sim.warm_up.__wrapped__, daemon=True)
            worker.start()
            worker.join(timeout=1.0)
            finished = not worker.is_alive()
        worker.join(timeout=30)
        assert not worker.is_alive()
        return finished

    assert not warm_up_while_another_holds_the_lock()  # cold: it waited for the lock
    assert len(breaks) == 1 and [p.name for p in tmp_path.glob("*.done")]
    assert warm_up_while_another_holds_the_lock()  # filled: no waiting
    assert len(breaks) == 2
