"""The Pooltool action syntax: `Speed: Low|Medium|High, Strikespot: <spot>`, 27 shots.
Light (no pooltool import): MOCK and the model server rebuild it from JSON."""

from __future__ import annotations

import re
from typing import Literal, Sequence

import numpy as np

from deepphy.envs.base import Action, ActionSpace, InvalidAction

NUM_RACKS = 100
MAX_SHOTS = 15

SPEEDS: dict[str, float] = {"Low": 2.0, "Medium": 5.0, "High": 8.0}  # cue speed, m/s
ROWS = ("top", "middle", "bottom")
COLS = ("left", "centre", "right")
SPOTS: tuple[str, ...] = tuple(f"{r}-{c}" for r in ROWS for c in COLS)
# (a, b) in pooltool's units of the ball radius: a = +1 is the ball's LEFT edge, b = +1 its top.
SPOT_OFFSETS: dict[str, tuple[float, float]] = {
    "top-left": (0.35, 0.35),
    "top-centre": (0.0, 0.5),
    "top-right": (-0.35, 0.35),
    "middle-left": (0.5, 0.0),
    "middle-centre": (0.0, 0.0),
    "middle-right": (-0.5, 0.0),
    "bottom-left": (0.35, -0.35),
    "bottom-centre": (0.0, -0.5),
    "bottom-right": (-0.35, -0.35),
}
ACTIONS: tuple[tuple[str, str], ...] = tuple((s, p) for s in SPEEDS for p in SPOTS)  # the 27, in order
REFERENCE_TRIES = 54  # the reference baseline redraws a shot already played this game up to this often


# -- action space ---------------------------------------------------------------------


class PoolShot(Action):
    speed: Literal["Low", "Medium", "High"]
    spot: Literal[
        "top-left", "top-centre", "top-right",
        "middle-left", "middle-centre", "middle-right",
        "bottom-left", "bottom-centre", "bottom-right",
    ]

    @property
    def velocity(self) -> float:
        return SPEEDS[self.speed]

    @property
    def offsets(self) -> tuple[float, float]:
        return SPOT_OFFSETS[self.spot]


_SPEED_WORDS = {
    "low": "Low", "slow": "Low", "soft": "Low", "2": "Low",
    "medium": "Medium", "med": "Medium", "mid": "Medium", "moderate": "Medium", "5": "Medium",
    "high": "High", "fast": "High", "hard": "High", "strong": "High", "8": "High",
}
_VERTICAL = {"top": "top", "upper": "top", "up": "top", "high": "top",
             "bottom": "bottom", "lower": "bottom", "low": "bottom", "down": "bottom"}
_HORIZONTAL = {"left": "left", "right": "right"}
_NEUTRAL = {"middle", "centre", "center", "central", "mid", "centered", "centred"}
_FILLER = {"of", "the", "ball", "cue", "spot", "side", "edge", "hit", "strike", "at", "on", "and", "a"}

_KEY_TAIL = r"[\s*_`\"']*[:=][\s*_`\"']*"  # `Speed:`, `**Speed:**`, `"speed": "`, `speed = `
_SPEED_RE = re.compile(r"\bspeed" + _KEY_TAIL + r"([a-z0-9.]+)(\s*m\s*/\s*s)?", re.I | re.ASCII)
_SPOT_RE = re.compile(r"(?:\bstrike[\s_\-]*|\b)spot" + _KEY_TAIL + r"([a-z][a-z \t\-_]*)", re.I | re.ASCII)


def _parse_speed(value: str) -> str:
    v = value.strip().lower().rstrip(".")
    if v.endswith(".0"):
        v = v[:-2]
    if v in _SPEED_WORDS:
        return _SPEED_WORDS[v]
    raise InvalidAction(f"speed {value!r} is not Low, Medium or High")


def _parse_spot(value: str) -> str:
    words = [w for w in re.split(r"[\s\-_]+", value.strip().lower()) if w]
    rows, cols, known = set(), set(), 0
    for w in words:
        if w in _VERTICAL:
            rows.add(_VERTICAL[w])
        elif w in _HORIZONTAL:
            cols.add(_HORIZONTAL[w])
        elif w not in _NEUTRAL:
            if w in _FILLER:
                continue
            break  # the spot name has ended (prose follows)
        known += 1
    if not known:
        raise InvalidAction(f"strike spot {value.strip()!r} is not one of {', '.join(SPOTS)}")
    if len(rows) > 1 or len(cols) > 1:
        raise InvalidAction(f"strike spot {value.strip()!r} names two different spots")
    row = rows.pop() if rows else "middle"
    col = cols.pop() if cols else "centre"
    return f"{row}-{col}"


class PoolSpace(ActionSpace):
    """Speed (3 levels) x strike spot on the cue ball (9 spots) = 27 shots."""

    kind: Literal["pooltool_shot"] = "pooltool_shot"

    def parse(self, text: str) -> PoolShot:
        text = text.replace("```", " ")
        speeds = _SPEED_RE.findall(text)
        spots = _SPOT_RE.findall(text)
        if not speeds:
            raise InvalidAction("no `Speed: Low|Medium|High` found")
        if not spots:
            raise InvalidAction("no `Strikespot: <spot>` found")
        # The last well-formed value of each counts: replies often restate the answer at the end.
        speed = _last_valid(_parse_speed, [s for s, _ in speeds])
        spot = _last_valid(_parse_spot, spots)
        return PoolShot(speed=speed, spot=spot)

    def reference_reply(self, rng: np.random.Generator, earlier: Sequence[str] = ()) -> str:
        """The reference baseline: a uniform speed and spot, redrawn (up to REFERENCE_TRIES
        times) while it is a shot already played in this game."""
        played = set(earlier)
        for _ in range(REFERENCE_TRIES):
            speed, spot = ACTIONS[int(rng.integers(len(ACTIONS)))]
            text = self.format(PoolShot(speed=speed, spot=spot))
            if text not in played:
                break
        return text

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> PoolShot:
        # Uniform over all 27 shots. `exclude` (actions of earlier failed games) is ignored:
        # a shot's effect depends on the table, so an action from another game is no repeat.
        speed, spot = ACTIONS[int(rng.integers(len(ACTIONS)))]
        return PoolShot(speed=speed, spot=spot)

    def format(self, action: Action) -> str:
        assert isinstance(action, PoolShot)
        return f"Speed: {action.speed}, Strikespot: {action.spot}"

    def all_actions(self) -> list[PoolShot]:
        return [PoolShot(speed=s, spot=p) for s, p in ACTIONS]


def _last_valid(parse, values: list[str]) -> str:
    error: InvalidAction | None = None
    for value in reversed(values):
        try:
            return parse(value)
        except InvalidAction as e:
            error = error or e
    assert error is not None
    raise error
