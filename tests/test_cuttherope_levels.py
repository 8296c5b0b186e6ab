"""Every Cut the Rope level: its stored plan wins when replayed through the environment
(parsed and stepped like a model's replies), with the stars the file records, and its first
observation labels every element inside the picture."""

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
