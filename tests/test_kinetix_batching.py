"""Kinetix batching is invisible: an episode's record never depends on which episodes shared
its batch (real kinetix-env; see deepphy/envs/kinetix/sim.py for why this needs care).

An episode is a level plus a seeded random 6-vector action per decision. It is stepped
alone, in batches of copies of itself, and in mixed batches (other levels, the same level
in another state, batch counts from 1 to many, so padded chunks and several chunks per
call); every decision's state, reward, done, goal, env steps and timestep must be
bit-identical. The levels of the fast test are ones where a batch of one used to round
differently from a batch of eight from the first decision on.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pytest

from deepphy.envs.kinetix.env import KinetixEnv, KinetixOptions
from deepphy.envs.kinetix.levels import level_names

FAST_LEVELS = ("l/gears", "l/grasp_easy", "l/h0_angrybirds", "l/h6_lorry")
MAX_DECISIONS = 16


@dataclass(frozen=True)
class Episode:
    level: str
    actions: np.ndarray  # (decisions, 6) kinetix MultiDiscrete vectors


def episode(level: str, seed: int, decisions: int) -> Episode:
    rng = np.random.default_rng([seed, *level.encode()])
    return Episode(level, rng.integers(0, [3, 3, 3, 3, 2, 2], size=(decisions, 6)).astype(np.int32))


def record(out) -> tuple:
    """Everything a decision yields, exactly: state leaves as raw bytes, the reward as hex."""
    import jax

    leaves = tuple(np.asarray(x).tobytes() for x in jax.tree.leaves(out.state))
    return (out.done, out.goal, float.hex(out.reward), out.steps, out.timestep, leaves)


Grouping = Callable[[list[int], int], list[list[int]]]  # (live slots, decision) -> batches


def run(episodes: list[Episode], slots: list[int], grouping: Grouping) -> list[list[tuple]]:
    """Step each slot (an index into `episodes`; repeats are copies) until its episode ends or
    runs out of actions, passing the live slots to `Sim.decide` in the batches `grouping`
    cuts; returns every slot's records."""
    from deepphy.envs.kinetix import sim

    states = [sim.load_level(episodes[e].level).state for e in slots]
    records: list[list[tuple]] = [[] for _ in slots]
    live = list(range(len(slots)))
    for d in range(len(episodes[0].actions)):
        for batch in grouping(live, d):
            s = sim.get_sim(sim.load_level(episodes[slots[batch[0]]].level))
            actions = np.stack([episodes[slots[i]].actions[d] for i in batch])
            for i, out in zip(batch, s.decide([states[i] for i in batch], actions)):
                records[i].append(record(out))
                states[i] = out.state
        live = [i for i in live if not records[i][-1][0]]
        if not live:
            break
    return records


def alone(live: list[int], d: int) -> list[list[int]]:
    return [[i] for i in live]


def together(live: list[int], d: int) -> list[list[int]]:
    return [live]


def shuffled(live: list[int], d: int) -> list[list[int]]:
    """Other partners, lane positions and batch counts (1, 3, 8, 13, rest) each decision."""
    order = list(np.random.default_rng(d).permutation(live))
    batches, counts = [], [1, 3, 8, 13]
    while order:
        n = counts[(d + len(batches)) % len(counts)] if len(batches) < len(counts) else len(order)
        batches.append([int(i) for i in order[:n]])
        order = order[n:]
    return batches


def assert_same(reference: list[tuple], other: list[tuple], level: str, what: str) -> None:
    import jax

    from deepphy.envs.kinetix import sim

    assert len(other) == len(reference), f"{what}: {len(other)} decisions, alone {len(reference)}"
    for d, (a, b) in enumerate(zip(reference, other)):
        if a != b:
            state = sim.load_level(level).state
            paths = [jax.tree_util.keystr(p) for p, _ in jax.tree_util.tree_flatten_with_path(state)[0]]
            fields = [p for p, x, y in zip(paths, a[-1], b[-1]) if x != y]
            raise AssertionError(f"{what}: decision {d + 1} differs from stepping alone: {a[:5]} vs {b[:5]}, fields {fields[:5]}")


def check_batching_is_invisible(levels: list[str], seeds: tuple[int, ...], decisions: int, copies: int) -> None:
    """With two seeds, the same level in two different states also shares batches."""
    episodes = [episode(lv, seed, decisions) for seed in seeds for lv in levels]
    names = [f"{e.level} seed {seeds[k // len(levels)]}" for k, e in enumerate(episodes)]
    reference = run(episodes, list(range(len(episodes))), alone)
    assert any(len(r) > 1 for r in reference)  # episodes do run for several decisions

    # Copies: each episode `copies` times in one batch (padded if fewer than a chunk).
    for e in range(len(episodes)):
        got = run(episodes, [e] * copies, together)
        for k in range(copies):
            assert_same(reference[e], got[k], episodes[e].level, f"{names[e]}, copy {k} of {copies}")

    # Mixed: everything together, regrouped every decision; and all in one call.
    slots = list(range(len(episodes)))
    for grouping in (shuffled, together):
        got = run(episodes, slots, grouping)
        for e in slots:
            assert_same(reference[e], got[e], episodes[e].level, f"{names[e]}, mixed ({grouping.__name__})")


def test_batching_is_invisible_on_levels_where_it_used_to_matter():
    from deepphy.envs.kinetix import sim

    check_batching_is_invisible(list(FAST_LEVELS), seeds=(0, 1), decisions=4, copies=3)
    # One compiled program for every batch count above (1 to 8 episodes per call).
    assert sim.get_sim(sim.load_level(FAST_LEVELS[0]))._fn._cache_size() == 1


def test_step_many_records_equal_stepping_alone():
    """Through the environment: the StepResult of each episode (feedback, reward, goal
    distance, timestep, key frame) is the same alone as in one mixed `step_many` call."""
    tasks = {t.params["level"]: t for t in KinetixEnv.tasks(KinetixOptions(sizes=("L",)))}
    levels = list(FAST_LEVELS[:3])
    solo = [KinetixEnv(KinetixOptions(annotate=False)) for _ in levels]
    mixed = [KinetixEnv(KinetixOptions(annotate=False)) for _ in levels]
    obs = [env.reset(tasks[lv]) for env, lv in zip(solo, levels)]
    for env, lv in zip(mixed, levels):
        env.reset(tasks[lv])
    rng = np.random.default_rng(7)
    live = list(range(len(levels)))
    for _ in range(3):
        actions = [obs[i].action_space.sample(rng) for i in live]
        one = [solo[i].step(a) for i, a in zip(live, actions)]
        many = KinetixEnv.step_many([mixed[i] for i in live], actions)
        for a, b in zip(one, many):
            assert json.dumps(a.info) == json.dumps(b.info) and a.feedback == b.feedback and a.done == b.done
            assert a.key_frames[0].png == b.key_frames[0].png
        for i, r in zip(live, one):
            obs[i] = r.observation
        live = [i for i, r in zip(live, one) if not r.done]


@pytest.mark.slow
def test_batching_is_invisible_on_all_large_levels():
    levels = level_names("L")
    assert len(levels) == 40
    check_batching_is_invisible(levels, seeds=(0,), decisions=MAX_DECISIONS, copies=8)
