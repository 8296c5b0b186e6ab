"""Every Cut the Rope level: its stored plan wins when replayed through the environment
(parsed and stepped like a model's replies), with the stars the file records, its first
observation labels every element inside the picture, and the reference random agent wins it
less than a third of the time unless it opens its box."""

from __future__ import annotations

import pytest

from deepphy.envs.cuttherope.level import level_ids, load_level


@pytest.mark.parametrize("level_id", level_ids())
def test_stored_plan_wins(level_id):
    from deepphy.envs.cuttherope.oracle import replay

    level = load_level(level_id)
    out = replay(level, level.solution.actions)
    assert out["success"], out
    assert out["stars"] == level.solution.stars <= level.solution.best_stars
    assert out["actions"] == len(level.solution.actions)  # no action left over after the win


def test_no_level_but_an_opener_is_won_by_random_a_third_of_the_time():
    # DEVELOPERS.md: a level a random agent wins a third of the time measures luck. The exact
    # rate (every order of random's choices played out) for all 88 levels takes about a second.
    from deepphy.envs.cuttherope.calibrate import random_orders
    from deepphy.envs.calibration import wins_by_luck
    from deepphy.envs.cuttherope.solve import BASELINE_TARGET

    rates = {level_id: random_orders(load_level(level_id))["rate"] for level_id in level_ids()}
    assert [k for k, r in rates.items() if wins_by_luck(k, r)] == []
    low, high = BASELINE_TARGET  # 6-16 %: the reference's "one in nine", roughly
    assert low <= sum(rates.values()) / len(rates) <= high


def _pin_cuts(level) -> list[tuple[int, ...]]:
    """The stored plan's cuts of pins' ropes, in order (each the ids cut at one moment)."""
    from deepphy.envs.cuttherope.oracle import ANY

    return [a.ids for a in map(ANY.parse, level.solution.actions) if a.name == "cut_pin"]


def test_ids_tell_nothing_of_the_solution():
    # Pins are numbered in an order drawn from the level's id, so over the levels with two pins or
    # more the stored plans' first cuts name P1 about as often as chance would (k of n ids: k/n),
    # and their cuts come in ascending id order about as often as a random numbering gives (the
    # share of the n! numberings that put them in order). Numbered in the designs' order, 50 of 56
    # first cuts named P1 (about 33 expected) and 34 of 48 plans cut in ascending order.
    import itertools
    import math

    first_p1, ascending = [], []  # (observed, its chance) per level
    for level_id in level_ids():
        level = load_level(level_id)
        n, cuts = len(level.pins), _pin_cuts(load_level(level_id))
        if n < 2 or not cuts:
            continue
        first_p1.append((1 in cuts[0], len(cuts[0]) / n))
        if len(cuts) >= 2:
            def in_order(label) -> bool:
                keys = [min(label[i - 1] for i in cut) for cut in cuts]
                return keys == sorted(keys)
            numberings = list(itertools.permutations(range(1, n + 1)))
            chance = sum(map(in_order, numberings)) / len(numberings)
            ascending.append((in_order(tuple(range(1, n + 1))), chance))
    for name, pairs in (("first cut names P1", first_p1), ("cuts in ascending order", ascending)):
        observed = sum(o for o, _ in pairs)
        expected = sum(p for _, p in pairs)
        sd = math.sqrt(sum(p * (1 - p) for _, p in pairs))
        assert len(pairs) >= 30 and abs(observed - expected) <= 2.5 * sd, (name, observed, expected, sd, len(pairs))
