"""PHYRE action spaces: parsing, sampling, grid geometry and PHYRE's action triples (no physics)."""

import numpy as np
import pytest

from deepphy.envs import ActionSpace, InvalidAction
from deepphy.envs.phyre.env import SPACES
from deepphy.envs.phyre.space import PhyreAction, PhyreContinuousAction, PhyreContinuousSpace, PhyreSpace

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
    assert SPACE.cell_centre(1) == pytest.approx((25.6, 230.4))  # top-left; y grows upward
    assert SPACE.cell_centre(5) == pytest.approx((230.4, 230.4))  # top-right
    assert SPACE.cell_centre(25) == pytest.approx((230.4, 25.6))  # bottom-right
    assert [SPACE.radius_px(k) for k in range(1, 6)] == [2.0, 9.5, 17.0, 24.5, 32.0]


def test_grid_actions_are_the_ground_truths_phyre_triples():
    # phyre_real_grid_outcomes.json: x=(col+0.5)*256/5, y=256-(row+0.5)*256/5, triple (x/255, y/255, (r-2)/30)
    for a in SPACE.all_actions():
        row, col = divmod(a.cell - 1, 5)
        x, y, r = (col + 0.5) * 256 / 5, 256 - (row + 0.5) * 256 / 5, [2, 9.5, 17, 24.5, 32][a.radius - 1]
        assert SPACE.to_phyre(a) == (x / 255, y / 255, (r - 2) / 30)


def test_reference_grid_has_8x8_cells_and_8_radius_levels():
    space = SPACES["grid8"]
    assert len(space.all_actions()) == 512
    radii = [space.to_phyre(PhyreAction(cell=1, radius=k))[2] for k in range(1, 9)]
    assert radii == pytest.approx([0.0625 + (k - 1) / 7 * 0.9375 for k in range(1, 9)])
    assert space.cell_centre(64) == (240.0, 16.0)


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


CONTINUOUS = PhyreContinuousSpace()


@pytest.mark.parametrize(
    "text, xyr",
    [
        ("X: 0.31, Y: 0.72, R: 0.4", (0.31, 0.72, 0.4)),
        ("x=0.5 y=0.25 r=1", (0.5, 0.25, 1.0)),
        ("**X:** 0.1\n**Y:** 0.9\n**R:** 0", (0.1, 0.9, 0.0)),
        ("X: .5, Y: 0.5, R: 0.5 -- no wait, X: 0.6, Y: 0.4, R: 0.2", (0.6, 0.4, 0.2)),
        ("The box: 0.9 is left. Max: 3. X: 0.2, Y: 0.3, R: 0.1", (0.2, 0.3, 0.1)),
    ],
)
def test_continuous_parse_accepts(text, xyr):
    assert CONTINUOUS.parse(text) == PhyreContinuousAction(x=xyr[0], y=xyr[1], r=xyr[2])


@pytest.mark.parametrize("text", ["", "X: 0.5, Y: 0.5", "X: 1.5, Y: 0.5, R: 0.5", "X: 0.5, Y: -0.1, R: 0.5",
                                  "Cell: 3, Radius: 2", "X: a, Y: b, R: c"])
def test_continuous_parse_rejects(text):
    with pytest.raises(InvalidAction):
        CONTINUOUS.parse(text)


def test_continuous_round_trip_sample_and_triple():
    rng = np.random.default_rng(1)
    seen = set()
    for _ in range(200):
        a = CONTINUOUS.sample(rng)
        assert CONTINUOUS.parse(CONTINUOUS.format(a)) == a
        assert CONTINUOUS.to_phyre(a) == (a.x, a.y, a.r)
        seen.add((a.x, a.y, a.r))
    assert len(seen) == 200
    assert ActionSpace.from_json(CONTINUOUS.model_dump()) == CONTINUOUS
