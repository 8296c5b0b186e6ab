"""PHYRE action space: parsing, sampling, grid geometry (no physics)."""

import numpy as np
import pytest

from deepphy.envs import ActionSpace, InvalidAction
from deepphy.envs.phyre.space import PhyreAction, PhyreSpace

SPACE = PhyreSpace()


@pytest.mark.parametrize(
    "text, cell, radius",
    [
        ("Cell: 7, Radius: 3", 7, 3),
        ("cell:7 radius:3", 7, 3),
        ("CELL = 25, RADIUS = 5", 25, 5),
        ("```\nCell: 1, Radius: 1\n```", 1, 1),
        ("I think the ball should go left.\n**Cell:** 12\n**Radius:** 2", 12, 2),
        ("Action: Cell: 13, Radius: 4.", 13, 4),
        ("Cell 9, radius level 2", 9, 2),
        ("Cell: 3, Radius: 2 ... on second thought Cell: 4, Radius: 5", 4, 5),
        ("Cell: 10.0, Radius: 2", 10, 2),
    ],
)
def test_parse_accepts(text, cell, radius):
    assert SPACE.parse(text) == PhyreAction(cell=cell, radius=radius)


@pytest.mark.parametrize(
    "text",
    ["", "I don't know", "Cell: 26, Radius: 1", "Cell: 0, Radius: 1", "Cell: 5, Radius: 6",
     "Cell: 5", "Radius: 3", "Cell: 2.5, Radius: 1", "Cell: -3, Radius: 2", "x=0.5 y=0.5 r=0.1"],
)
def test_parse_rejects(text):
    with pytest.raises(InvalidAction):
        SPACE.parse(text)


def test_format_round_trip_and_json():
    for a in SPACE.all_actions():
        assert SPACE.parse(SPACE.format(a)) == a
    assert len(SPACE.all_actions()) == 125
    assert ActionSpace.from_json(SPACE.model_dump()) == SPACE


def test_grid_numbering_from_top_left():
    x, y, r = SPACE.to_scene(PhyreAction(cell=1, radius=1))
    assert (round(x, 1), round(y, 1), r) == (25.6, 230.4, 2.0)  # top-left; y grows upward
    x, y, r = SPACE.to_scene(PhyreAction(cell=5, radius=5))
    assert (round(x, 1), round(y, 1), r) == (230.4, 230.4, 32.0)  # top-right
    x, y, _ = SPACE.to_scene(PhyreAction(cell=25, radius=3))
    assert (round(x, 1), round(y, 1)) == (230.4, 25.6)  # bottom-right
    assert [SPACE.radius_px(k) for k in range(1, 6)] == [2.0, 9.5, 17.0, 24.5, 32.0]


def test_configurable_grid():
    space = PhyreSpace(grid=8, radius_levels=3)
    assert len(space.all_actions()) == 192
    assert space.parse("Cell: 64, Radius: 3") == PhyreAction(cell=64, radius=3)
    with pytest.raises(InvalidAction):
        space.parse("Cell: 65, Radius: 1")


def test_sample_uniform_and_excludes():
    rng = np.random.default_rng(0)
    seen = {}
    for _ in range(12500):
        a = SPACE.sample(rng)
        seen[(a.cell, a.radius)] = seen.get((a.cell, a.radius), 0) + 1
    assert len(seen) == 125 and max(seen.values()) < 160 and min(seen.values()) > 50
    tried = []
    for _ in range(125):
        a = SPACE.sample(rng, exclude=tried)
        assert a not in tried
        tried.append(a)
    assert SPACE.sample(rng, exclude=tried) in tried  # all used: repeats are unavoidable
