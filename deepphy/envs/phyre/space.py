"""The PHYRE action space: `Cell: N, Radius: R`. Light: no pymunk, no OpenCV.

The scene is overlaid with a `grid` x `grid` grid of cells numbered 1..grid^2 row by row
from the TOP-LEFT cell (1 = top-left, `grid` = top-right, grid^2 = bottom-right). The
red ball's centre goes to the centre of the chosen cell. Radius levels 1..`radius_levels`
map linearly from `r_min` to `r_max` px (defaults 2 and 32 px in a 256 px scene: 1/128
and 1/8 of the width, the same linear map as PHYRE's continuous radius in [0, 1]).
"""

from __future__ import annotations

import re
from typing import Literal, Sequence

import numpy as np

from deepphy.envs.base import Action, ActionSpace, InvalidAction

SCENE = 256.0


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
    r_min: float = 2.0
    r_max: float = 32.0

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

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> PhyreAction:
        excluded = {(a.cell, a.radius) for a in exclude if isinstance(a, PhyreAction)}
        choices = [a for a in self.all_actions() if (a.cell, a.radius) not in excluded]
        if not choices:  # every action tried: repeating is unavoidable
            choices = self.all_actions()
        return choices[int(rng.integers(len(choices)))]

    def format(self, action: Action) -> str:
        assert isinstance(action, PhyreAction)
        return f"Cell: {action.cell}, Radius: {action.radius}"

    # -- geometry -------------------------------------------------------------------

    def to_scene(self, action: PhyreAction) -> tuple[float, float, float]:
        """(x, y, r) in scene px, y up."""
        row, col = divmod(action.cell - 1, self.grid)
        size = SCENE / self.grid
        x = (col + 0.5) * size
        y = SCENE - (row + 0.5) * size
        return x, y, self.radius_px(action.radius)

    def radius_px(self, level: int) -> float:
        if self.radius_levels == 1:
            return self.r_max
        return self.r_min + (self.r_max - self.r_min) * (level - 1) / (self.radius_levels - 1)
