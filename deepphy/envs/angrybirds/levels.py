"""Level data: one JSON file per level under `levels/`, validated by these models.

A level lists its birds (in launch order) and its objects, each by centre position in
world units (x right, y up, the ground's surface at y = 0) and rotation in degrees
(counter-clockwise); fixed terrain is boxes (`platforms`) or convex polygons (`terrain`:
slopes, hills). Its `idea` says what the level teaches or tests; its `title` is shown
only with the `physics_hints` option. The oracle (solve.py) adds its winning plan, what
that plan measured; the stars of a win follow from its bird count (`stars_for`). Files
are written one object per line, so they read and diff well. The levels are designed in
design.py: after editing a design, `deepphy solve --env angrybirds make --levels <id>`
writes its file with the plan and its measurements (`search` searches a plan anew).
"""

from __future__ import annotations

import functools
import json
import re
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from deepphy.envs.angrybirds.constants import (
    ANGLE_MAX,
    ANGLE_MIN,
    BLOCK_SIZES,
    MAX_BIRDS,
    POWER_MAX,
    POWER_MIN,
    SCENE_LEVELS,
    SCORE_PIG,
    STARS_MAX,
)

LEVEL_DIR = Path(__file__).parent / "levels"
LEVEL_ID = re.compile(r"^s([12])_l(\d\d)$")

Bird = Literal["red", "yellow", "blue", "black"]
Material = Literal["wood", "ice", "stone"]
Shape = Literal[
    "rect_big", "rect_fat", "rect_medium", "rect_small", "rect_tiny", "square_hole",
    "square_small", "square_tiny", "triangle", "triangle_hole", "circle", "circle_small",
]


class _Item(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Block(_Item):
    shape: Shape
    material: Material
    x: float
    y: float
    angle: float = 0.0  # degrees, counter-clockwise

    @property
    def size(self) -> tuple[float, float]:
        return BLOCK_SIZES[self.shape]


class Pig(_Item):
    size: Literal["small", "medium", "big"] = "small"
    x: float
    y: float


class Tnt(_Item):
    x: float
    y: float


class Platform(_Item):
    """A static, unbreakable box (a ledge or a hill)."""

    x: float
    y: float
    w: float = Field(gt=0)
    h: float = Field(gt=0)
    angle: float = 0.0


class Terrain(_Item):
    """A static, unbreakable convex polygon (a slope or a hill), corners in world units."""

    points: list[tuple[float, float]] = Field(min_length=3, max_length=12)


class Shot(_Item):
    angle: float = Field(ge=ANGLE_MIN, le=ANGLE_MAX)
    power: float = Field(ge=POWER_MIN, le=POWER_MAX)


class Oracle(_Item):
    """What the oracle found (solve.py): a winning plan with the fewest birds it needs,
    chosen for robustness, and what that plan and the level measured (oracle.py defines
    the nudge set and the one-shot grid)."""

    plan: list[Shot]
    score: int
    blocks_destroyed: int
    robustness: float = Field(ge=0, le=1)  # its weakest shot: share of that shot's nudges that still win
    robustness_all: float = Field(ge=0, le=1)  # share of the nudges applied to every shot at once that win
    one_shot_wins: int = Field(ge=0)  # one-shot wins on the one-shot grid (from the start)
    one_shot_isolated: int = Field(ge=0)  # of those, wins with no winning grid neighbour
    searched: int  # plans simulated by the search
    shorter_tried: int  # of those, plans with fewer shots than `plan`: none won


class Level(_Item):
    id: str = Field(pattern=LEVEL_ID.pattern)
    title: str  # shown to the model only with the physics_hints option
    idea: str = Field(min_length=1)  # what the level teaches or tests (for designers and the docs)
    birds: list[Bird] = Field(min_length=1, max_length=MAX_BIRDS)
    blocks: list[Block] = Field(default_factory=list)
    pigs: list[Pig] = Field(min_length=1)
    tnt: list[Tnt] = Field(default_factory=list)
    platforms: list[Platform] = Field(default_factory=list)
    terrain: list[Terrain] = Field(default_factory=list)
    oracle: Oracle | None = None

    @model_validator(mode="after")
    def _consistent(self) -> "Level":
        if self.oracle is not None and len(self.oracle.plan) > len(self.birds):
            raise ValueError(f"{self.id}: the oracle's plan has more shots than the level has birds")
        return self

    @property
    def scene(self) -> int:
        return int(self.id[1])

    @property
    def group(self) -> str:
        return self.id[:2]

    @property
    def least_win_score(self) -> int:
        """What any win scores at least: every pig, no block, no bird to spare."""
        return SCORE_PIG * len(self.pigs)

    def stars(self, won: bool, shots: int) -> int:
        """The stars of an attempt on this level (`stars_for`, with the stored plan's birds;
        a level without a plan: 1 for any win)."""
        if self.oracle is None:
            return int(won)
        return stars_for(won, shots, len(self.oracle.plan))


def stars_for(won: bool, shots: int, needed: int) -> int:
    """The stars of an attempt that used `shots` birds, on a level whose oracle needs
    `needed` (constants.py): 0 when lost; 3 with at most `needed` birds, one less for each
    bird more, at least 1."""
    if not won:
        return 0
    return max(1, STARS_MAX - max(0, shots - needed))


def level_ids() -> list[str]:
    return [f"s{scene}_l{k:02d}" for scene, n in SCENE_LEVELS.items() for k in range(1, n + 1)]


@functools.lru_cache(maxsize=None)
def load_level(level_id: str) -> Level:
    if not LEVEL_ID.match(level_id):
        raise ValueError(f"not an angrybirds level id: {level_id!r}")
    path = LEVEL_DIR / f"{level_id}.json"
    level = Level.model_validate_json(path.read_text())
    if level.id != level_id:
        raise ValueError(f"{path.name} holds level {level.id!r}")
    return level


def level_json(level: Level) -> str:
    """The level as JSON, one object per line (stable, hand-editable, diff-friendly)."""
    data = level.model_dump(mode="json", exclude_none=True)
    lines = ["{"]
    keys = list(data)
    for i, key in enumerate(keys):
        value = data[key]
        comma = "," if i < len(keys) - 1 else ""
        if isinstance(value, list) and value and isinstance(value[0], dict):
            lines.append(f"  {json.dumps(key)}: [")
            lines += [f"    {json.dumps(v)}" + ("," if j < len(value) - 1 else "") for j, v in enumerate(value)]
            lines.append(f"  ]{comma}")
        elif isinstance(value, dict) and "plan" in value:
            inner = ", ".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in value.items())
            lines.append(f"  {json.dumps(key)}: {{{inner}}}{comma}")
        else:
            lines.append(f"  {json.dumps(key)}: {json.dumps(value)}{comma}")
    lines.append("}")
    return "\n".join(lines) + "\n"


def save_level(level: Level) -> Path:
    path = LEVEL_DIR / f"{level.id}.json"
    path.write_text(level_json(level))
    load_level.cache_clear()
    return path
