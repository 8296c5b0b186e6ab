"""The level format: one JSON file per level under `levels/`, validated by these models.

A level lists its elements; each element kind is numbered from 1 in the order of its list,
and those numbers are the ids the model sees on the image and names in actions (pin 1 is
labelled P1 and cut with `cut_pin(1)`). Positions are screen units (see constants.py: the
480 x 720 screenshot, y down). Every level states its idea (what it teaches or tests) and
stores one 3-star plan found by the oracle (solve.py make); a test replays all of them.

Light module (pydantic only): the action space and the prompt read levels without pymunk.
"""

from __future__ import annotations

import functools
import json
import math
import re
from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, model_validator

from deepphy.envs.cuttherope.constants import HEIGHT, MAX_ACTIONS, WIDTH

LEVELS_DIR = Path(__file__).parent / "levels"
_NUMBER_LIST = re.compile(r"\[\s*(-?[0-9.]+(?:,\s*-?[0-9.]+)*)\s*\]")
BOXES = {1: 24, 2: 23, 3: 7, 4: 15, 5: 19}  # levels per box: the reference set's sizes (88 in all)
BOX_THEMES = {  # season 1's boxes: Cardboard, Fabric, Foil, Magic, Valentine
    1: "ropes, bubbles, automatic ropes, stretched ropes, spikes",
    2: "air cushions and spiders",
    3: "hooks on tracks, electric sparks, walls",
    4: "magic hats",
    5: "two candy halves",
}

MIN_STRETCHED = 0.5  # a stretched rope's rest length is at least this share of its pin-candy distance
Coord = Annotated[float, Field(ge=-200, le=1000, allow_inf_nan=False)]
Point = tuple[Coord, Coord]
Angle = Annotated[float, Field(ge=-360, le=360, allow_inf_nan=False)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CandySpec(_Model):
    pos: Point
    velocity: tuple[float, float] = (0.0, 0.0)  # px/s at t = 0: at rest unless the level's idea says otherwise


class SpiderSpec(_Model):
    delay: float = Field(0.0, ge=0, le=60)  # s after the level starts before it crawls


class TrackSpec(_Model):
    """A hook on a track: the pin slides back and forth between its `pos` and `to` by itself,
    a smooth (sinusoidal) motion, one round trip every `period` seconds."""

    to: Point
    period: float = Field(gt=0.5, le=30)
    phase: float = Field(0.0, ge=0, lt=1)  # share of a round trip done at t = 0 (0: at `pos`, 0.5: at `to`)


class PinSpec(_Model):
    pos: Point
    candy: int = Field(0, ge=0, le=1)  # index into Level.candies of the candy its rope holds
    length: float | None = Field(None, gt=0, le=2000)  # rest length; None = the initial pin-candy distance;
    #                                                    shorter than that distance: a stretched rope
    spider: SpiderSpec | None = None  # a spider starting at this pin, crawling down the rope
    track: TrackSpec | None = None  # a moving hook: the pin slides along this track

    def at(self, t: float) -> tuple[float, float]:
        """Where the pin is at time t (s): its `pos`, or on its track."""
        if self.track is None:
            return self.pos
        f = (1.0 - math.cos(2.0 * math.pi * (t / self.track.period + self.track.phase))) / 2.0
        (x0, y0), (x1, y1) = self.pos, self.track.to
        return x0 + (x1 - x0) * f, y0 + (y1 - y0) * f

    def velocity(self, t: float) -> tuple[float, float]:
        """The pin's velocity at time t (px/s)."""
        if self.track is None:
            return 0.0, 0.0
        w = 2.0 * math.pi / self.track.period
        df = w * math.sin(2.0 * math.pi * (t / self.track.period + self.track.phase)) / 2.0
        (x0, y0), (x1, y1) = self.pos, self.track.to
        return (x1 - x0) * df, (y1 - y0) * df


class ActivePinSpec(_Model):
    pos: Point
    radius: float = Field(gt=0, le=400)  # a rope attaches when the candy enters this circle


class BubbleSpec(_Model):
    pos: Point


class CushionSpec(_Model):
    pos: Point
    angle: Angle  # direction of the puff (degrees, 0 right, 90 up)


class HatSpec(_Model):
    pos: Point  # the opening
    angle: Angle  # direction the opening faces: the candy enters against it and leaves along it


class HatPairSpec(_Model):
    hats: tuple[HatSpec, HatSpec]


class SpikeSpec(_Model):
    a: Point
    b: Point


class WallSpec(_Model):
    a: Point
    b: Point


class ElectricSpec(_Model):
    a: Point
    b: Point
    period: float = Field(gt=0, le=60)  # s of one on/off cycle
    on: float = Field(gt=0, le=60)  # s live at the start of each cycle
    phase: float = Field(0.0, ge=0, le=60)  # s into its cycle at t = 0


class Solution(_Model):
    """One winning plan from the oracle, replayed by a test."""

    actions: list[str] = Field(min_length=1, max_length=MAX_ACTIONS)
    stars: int = Field(ge=0, le=3)  # stars this plan collects
    best_stars: int = Field(ge=0, le=3)  # best star count the search found (this plan's, or more)


class Level(_Model):
    id: str = Field(pattern=r"^b[1-5]_l[0-9]{2}$")
    title: str = ""
    idea: str = ""  # what the level teaches or tests, in a sentence
    candies: list[CandySpec] = Field(min_length=1, max_length=2)  # one candy, or two halves
    pins: list[PinSpec] = Field(default_factory=list, max_length=9)
    active_pins: list[ActivePinSpec] = Field(default_factory=list, max_length=9)
    bubbles: list[BubbleSpec] = Field(default_factory=list, max_length=9)
    cushions: list[CushionSpec] = Field(default_factory=list, max_length=9)
    hats: list[HatPairSpec] = Field(default_factory=list, max_length=4)
    spikes: list[SpikeSpec] = Field(default_factory=list, max_length=20)
    electrics: list[ElectricSpec] = Field(default_factory=list, max_length=9)
    walls: list[WallSpec] = Field(default_factory=list, max_length=12)
    stars: list[Point] = Field(min_length=3, max_length=3)
    om_nom: Point  # the centre of Om Nom (his mouth)
    solution: Solution | None = None

    @property
    def box(self) -> int:
        return int(self.id[1])

    @property
    def halves(self) -> bool:
        return len(self.candies) == 2

    @model_validator(mode="after")
    def _consistent(self) -> "Level":
        for i, pin in enumerate(self.pins, 1):
            if pin.candy >= len(self.candies):
                raise ValueError(f"pin {i} holds candy {pin.candy}, but the level has {len(self.candies)}")
            d = math.dist(pin.at(0.0), self.candies[pin.candy].pos)
            if pin.length is not None and pin.length < MIN_STRETCHED * d:
                raise ValueError(f"pin {i}: rope length {pin.length} is less than {MIN_STRETCHED:g} x the distance "
                                 f"{d:.1f} to its candy")
        for name, p in [("Om Nom", self.om_nom), *(("star", s) for s in self.stars),
                        *(("candy", c.pos) for c in self.candies)]:
            if not (0 <= p[0] <= WIDTH and 0 <= p[1] <= HEIGHT):
                raise ValueError(f"{name} at {p} is outside the {WIDTH} x {HEIGHT} screen")
        return self

    def rope_length(self, pin: int) -> float:
        """Length of pin `pin`'s rope (0-based index)."""
        spec = self.pins[pin]
        return spec.length if spec.length is not None else math.dist(spec.at(0.0), self.candies[spec.candy].pos)


def level_path(level_id: str) -> Path:
    return LEVELS_DIR / f"{level_id}.json"


def level_ids() -> list[str]:
    """All 88 ids in order: b1_l01 .. b5_l19."""
    return [f"b{box}_l{n:02d}" for box, count in BOXES.items() for n in range(1, count + 1)]


@functools.lru_cache(maxsize=None)
def load_level(level_id: str) -> Level:
    path = level_path(level_id)
    level = Level.model_validate_json(path.read_text())
    if level.id != level_id:
        raise ValueError(f"{path} holds level {level.id!r}")
    return level


def save_level(level: Level, path: Path | None = None) -> Path:
    path = path or level_path(level.id)
    data = {k: v for k, v in level.model_dump(mode="json", exclude_none=True).items() if v != []}
    text = json.dumps(data, indent=1)
    # Points on one line: [240.0, 120.0] rather than three lines each.
    text = _NUMBER_LIST.sub(lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]", text)
    path.write_text(text + "\n")
    load_level.cache_clear()
    return path
