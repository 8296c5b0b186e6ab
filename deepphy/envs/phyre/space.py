"""PHYRE action spaces and PHYRE's own ball action mapper. Light: no Box2D, no OpenCV.

PHYRE's action is (x, y, r) in [0, 1]^3 (`phyre.action_mappers.SingleBallActionMapper`):
the ball's centre at x * 255, y * 255 px (y UP, 0 = bottom), radius r * 30 + 2 px; the ball
must lie inside the scene (checked before rounding); then x, y are truncated to integers
and the radius rounded with Python's round. `ball_from_action` reproduces it.

Spaces (the model's syntax):
- `PhyreSpace`, `Cell: N, Radius: R`: a grid x grid overlay numbered 1..grid^2 row by row
  from the TOP-LEFT cell; the ball's centre at the cell's centre; radius levels linear from
  `r_min` to `r_max` px. A grid action is PHYRE's (x / 255, y / 255, (r - 2) / 30) for the
  cell centre (x, y) in px (y up) and the level's radius r. The paper's grid: 5 x 5 cells,
  5 levels 2..32 px; the reference code's: 8 x 8 cells, 8 levels 3.875..32 px (phyre
  r = 0.0625 .. 1).
- `PhyreContinuousSpace`, `X: 0.31, Y: 0.72, R: 0.4`: PHYRE's action itself.
"""

from __future__ import annotations

import re
from typing import Literal, NamedTuple, Sequence

import numpy as np
from pydantic import Field

from deepphy.envs.base import Action, ActionSpace, InvalidAction

SCENE = 256  # px, width and height
MIN_RADIUS = 2  # px at r = 0
MAX_RADIUS = SCENE // 8  # px at r = 1
_POSITION_SCALE = SCENE - 1  # PHYRE scales x, y by 255, not 256


class InvalidPlacement(ValueError):
    """The ball cannot be placed. The message says why (it is shown to the agent)."""


class Ball(NamedTuple):
    """The placed ball as PHYRE simulates it: integer px, y up."""

    x: int
    y: int
    r: int


def ball_from_action(ax: float, ay: float, ar: float) -> Ball:
    """PHYRE's SingleBallActionMapper: (x, y, r) in [0, 1]^3 -> the ball in px."""
    if not all(0 <= v <= 1 for v in (ax, ay, ar)):
        raise InvalidPlacement(f"x, y and r must lie in [0, 1], got ({ax}, {ay}, {ar})")
    x, y = ax * _POSITION_SCALE, ay * _POSITION_SCALE
    r = ar * (MAX_RADIUS - MIN_RADIUS) + MIN_RADIUS
    if not (r <= x <= SCENE - r and r <= y <= SCENE - r):
        raise InvalidPlacement(f"the ball (centre x={x:.1f}, y={y:.1f} px from the bottom-left, radius "
                               f"{r:.1f} px) does not lie inside the scene")
    return Ball(int(x), int(y), round(r))


def phyre_r(radius_px: float) -> float:
    """PHYRE's r in [0, 1] for a radius in px."""
    return (radius_px - MIN_RADIUS) / (MAX_RADIUS - MIN_RADIUS)


# -- the grid ---------------------------------------------------------------------------------


# The reference implementation's random baseline answers a refusal this often.
REFERENCE_REFUSALS = 0.1
REFERENCE_REFUSAL = "I am not able to determine where to place the ball from this image."


class PhyreAction(Action):
    cell: int
    radius: int


# Possessive quantifiers (*+, ++): no backtracking, linear in the reply's length.
_CELL = re.compile(r"\bcell\**+\s*+(?:number|no\.?|#)?+\s*+[:=]?+\s*+\**+\s*+(-?[0-9]++(?:\.[0-9]++)?+)", re.I | re.ASCII)
_RADIUS = re.compile(r"\bradius\**+\s*+(?:level)?+\s*+[:=]?+\s*+\**+\s*+(-?[0-9]++(?:\.[0-9]++)?+)", re.I | re.ASCII)
MAX_DIGITS = 6


class PhyreSpace(ActionSpace):
    kind: Literal["phyre_grid"] = "phyre_grid"
    grid: int = 5
    radius_levels: int = 5
    r_min: float = 2.0  # px, level 1
    r_max: float = 32.0  # px, the last level

    @property
    def num_cells(self) -> int:
        return self.grid * self.grid

    def parse(self, text: str) -> PhyreAction:
        cells = _CELL.findall(text)
        radii = _RADIUS.findall(text)
        if not cells or not radii:
            raise InvalidAction(f"expected 'Cell: <1..{self.num_cells}>, Radius: <1..{self.radius_levels}>'")
        # The last stated pair wins: models often restate their final answer at the end.
        cell_s, radius_s = cells[-1], radii[-1]
        for name, value, hi in (("cell", cell_s, self.num_cells), ("radius", radius_s, self.radius_levels)):
            if len(value) > MAX_DIGITS:
                raise InvalidAction(f"{name} {value[:12]}... is outside 1..{hi}")
            if not float(value).is_integer():
                raise InvalidAction(f"{name} must be a whole number, got {value}")
            if not 1 <= int(float(value)) <= hi:
                raise InvalidAction(f"{name} {int(float(value))} is outside 1..{hi}")
        return PhyreAction(cell=int(float(cell_s)), radius=int(float(radius_s)))

    def all_actions(self) -> list[PhyreAction]:
        return [PhyreAction(cell=c, radius=r) for c in range(1, self.num_cells + 1)
                for r in range(1, self.radius_levels + 1)]

    def reference_reply(self, rng: np.random.Generator, earlier: Sequence[str] = ()) -> str:
        """The reference baseline: a uniform cell and radius level, but one reply in ten is a
        refusal that no parser reads (an invalid attempt). No memory of earlier attempts."""
        if rng.random() < REFERENCE_REFUSALS:
            return REFERENCE_REFUSAL
        return f"Cell: {int(rng.integers(1, self.num_cells + 1))}, Radius: {int(rng.integers(1, self.radius_levels + 1))}"

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> PhyreAction:
        excluded = {(a.cell, a.radius) for a in exclude if isinstance(a, PhyreAction)}
        choices = [a for a in self.all_actions() if (a.cell, a.radius) not in excluded]
        if not choices:  # every action tried: repeating is unavoidable
            choices = self.all_actions()
        return choices[int(rng.integers(len(choices)))]

    def format(self, action: Action) -> str:
        assert isinstance(action, PhyreAction)
        return f"Cell: {action.cell}, Radius: {action.radius}"

    # -- geometry ---------------------------------------------------------------------------

    def cell_centre(self, cell: int) -> tuple[float, float]:
        """(x, y) px of a cell's centre, y up."""
        row, col = divmod(cell - 1, self.grid)
        # this exact float expression: the triple's x * 255 is truncated, so ulps matter
        return (col + 0.5) * SCENE / self.grid, SCENE - (row + 0.5) * SCENE / self.grid

    def radius_px(self, level: int) -> float:
        """The level's nominal radius (linear from r_min to r_max)."""
        if self.radius_levels == 1:
            return self.r_max
        return self.r_min + (self.r_max - self.r_min) * (level - 1) / (self.radius_levels - 1)

    def simulated_radius(self, level: int) -> int:
        """The radius PHYRE simulates for the level (its action mapper rounds to whole px)."""
        return round(phyre_r(self.radius_px(level)) * (MAX_RADIUS - MIN_RADIUS) + MIN_RADIUS)

    def to_phyre(self, action: Action) -> tuple[float, float, float]:
        """PHYRE's action (x, y, r) in [0, 1]^3."""
        assert isinstance(action, PhyreAction)
        x, y = self.cell_centre(action.cell)
        return x / _POSITION_SCALE, y / _POSITION_SCALE, phyre_r(self.radius_px(action.radius))


# -- continuous -------------------------------------------------------------------------------


class PhyreContinuousAction(Action):
    x: float = Field(ge=0.0, le=1.0)
    y: float = Field(ge=0.0, le=1.0)
    r: float = Field(ge=0.0, le=1.0)


_NUMBER = r"\**+\s*+[:=]\s*+\**+\s*+(-?[0-9]++(?:\.[0-9]*+)?+(?:e-?[0-9]++)?+|-?\.[0-9]++)"
_KEYS = {k: re.compile(rf"(?<![a-z]){k}{_NUMBER}", re.I | re.ASCII) for k in ("x", "y", "r")}


class PhyreContinuousSpace(ActionSpace):
    """PHYRE's own action: `X: <0..1>, Y: <0..1>, R: <0..1>` (y from the BOTTOM edge)."""

    kind: Literal["phyre_continuous"] = "phyre_continuous"
    decimals: int = 3  # MOCK's samples are rounded to this many decimals

    def parse(self, text: str) -> PhyreContinuousAction:
        values = {}
        for key, pattern in _KEYS.items():
            found = pattern.findall(text)
            if not found:
                raise InvalidAction("expected 'X: <0..1>, Y: <0..1>, R: <0..1>'")
            values[key] = float(found[-1])  # the last stated value wins
            if not 0.0 <= values[key] <= 1.0:
                raise InvalidAction(f"{key.upper()} {found[-1]} is outside 0..1")
        return PhyreContinuousAction(**values)

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> PhyreContinuousAction:
        while True:
            x, y, r = (round(float(v), self.decimals) for v in rng.random(3))
            action = PhyreContinuousAction(x=x, y=y, r=r)
            if action not in exclude:
                return action

    def format(self, action: Action) -> str:
        assert isinstance(action, PhyreContinuousAction)
        return f"X: {action.x!r}, Y: {action.y!r}, R: {action.r!r}"

    def to_phyre(self, action: Action) -> tuple[float, float, float]:
        assert isinstance(action, PhyreContinuousAction)
        return action.x, action.y, action.r
