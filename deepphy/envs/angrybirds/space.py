"""The Angry Birds action syntax: `shoot(angle=A, power=P)` for the bird in the slingshot.

A in [0, 90] degrees above the horizontal (0 = straight right, 90 = straight up), P in
[0, 1] (launch speed = P x MAX_LAUNCH_SPEED). Both are used to two decimal places.
Light (no pymunk import): MOCK and the model server rebuild the space from JSON.

Parsing accepts what models write around the stated syntax: prose, code fences, list
brackets, `angle=` / `angle:` keys in either order or positional values, integers or
decimals, a degree sign. When no `shoot(...)` call is found, `angle: A` and `power: P`
written anywhere are accepted. When a reply states several shots, the last one counts.
Everything runs in time linear in the length of the reply: the patterns have bounded
repetitions, numbers are at most 12 digits before and after the point.
"""

from __future__ import annotations

import math
import re
from typing import Literal, Sequence

import numpy as np

from deepphy.envs.angrybirds.constants import ACTION_DECIMALS, ANGLE_MAX, ANGLE_MIN, POWER_MAX, POWER_MIN
from deepphy.envs.base import Action, ActionSpace, InvalidAction

# The reference implementation's random baseline: shoot(angle=U(0,90), power=U(0.5,1.0)).
REFERENCE_POWER_MIN = 0.5


class Shoot(Action):
    angle: float  # degrees above the horizontal, towards the structures
    power: float  # 0..1 of the full pull


_NUM = r"(?<![\w.])([+-]?(?:\d{1,12}(?:\.\d{0,12})?|\.\d{1,12}))(?![\w.]*\d)"
_UNIT = r"(?:\s{0,3}(?:°|deg(?:rees?)?\b|%))?"
_CALL = re.compile(r"shoot\s{0,20}\(([^()]{0,200})\)", re.I | re.A)
_ARG = re.compile(
    r"^[\s\"'`*]{0,10}(?:(angle|power|a|p|theta|speed|force|strength)[\"'`*]{0,3}\s{0,10}[:=]\s{0,10})?"
    r"[\"'`*]{0,3}" + _NUM + r"(" + _UNIT + r")[\"'`*]{0,3}\s{0,10}$",
    re.I | re.A,
)
_KEYED = {
    "angle": re.compile(r"\bangle[\"'`*]{0,3}\s{0,10}[:=]\s{0,10}[\"'`*]{0,3}" + _NUM, re.I | re.A),
    "power": re.compile(r"\bpower[\"'`*]{0,3}\s{0,10}[:=]\s{0,10}[\"'`*]{0,3}" + _NUM, re.I | re.A),
}
_KEY_NAMES = {"angle": "angle", "a": "angle", "theta": "angle",
              "power": "power", "p": "power", "speed": "power", "force": "power", "strength": "power"}


def _number(text: str) -> float:
    value = float(text)  # the pattern guarantees a plain decimal of bounded length
    if not math.isfinite(value):
        raise InvalidAction(f"{text!r} is not a number")
    return value


def _call_args(inner: str) -> tuple[float, float]:
    """The (angle, power) of the text between a call's parentheses; InvalidAction if it is not two numbers."""
    parts = re.split(r"[,;]", inner)
    if len(parts) != 2:
        raise InvalidAction(f"shoot({inner.strip()[:80]}) does not have exactly two arguments (angle and power)")
    named: dict[str, tuple[float, str]] = {}
    positional: list[tuple[float, str]] = []
    for part in parts:
        m = _ARG.match(part)
        if not m:
            raise InvalidAction(f"argument {part.strip()[:40]!r} of shoot(...) is not a number")
        key, value = m.group(1), (_number(m.group(2)), m.group(3).strip().lower())
        if key:
            name = _KEY_NAMES[key.lower()]
            if name in named:
                raise InvalidAction(f"shoot(...) gives {name} twice")
            named[name] = value
        else:
            positional.append(value)
    for name in ("angle", "power"):
        if name not in named:
            named[name] = positional.pop(0)
    (angle, angle_unit), (power, power_unit) = named["angle"], named["power"]
    if angle_unit == "%" or (power_unit and power_unit != "%"):
        raise InvalidAction("the angle is in degrees and the power a fraction from 0 to 1")
    return angle, power / 100.0 if power_unit == "%" else power


class ShootSpace(ActionSpace):
    """One launch of the bird in the slingshot: angle x power, continuous."""

    kind: Literal["angrybirds_shoot"] = "angrybirds_shoot"

    def parse(self, text: str) -> Shoot:
        text = text.replace("```", " ")
        calls = list(_CALL.finditer(text))
        if calls:
            angle, power = _call_args(calls[-1].group(1))  # the last shot stated counts
        else:
            angles = _KEYED["angle"].findall(text)
            powers = _KEYED["power"].findall(text)
            if not angles or not powers:
                raise InvalidAction("no `shoot(angle=A, power=P)` found")
            angle, power = _number(angles[-1]), _number(powers[-1])
        return self.make(angle, power)

    def make(self, angle: float, power: float) -> Shoot:
        """A validated action (InvalidAction when out of range), rounded to the used precision."""
        if not ANGLE_MIN <= angle <= ANGLE_MAX:
            raise InvalidAction(f"angle {angle:g} is outside {ANGLE_MIN:g}..{ANGLE_MAX:g} degrees")
        if not POWER_MIN <= power <= POWER_MAX:
            raise InvalidAction(f"power {power:g} is outside {POWER_MIN:g}..{POWER_MAX:g}")
        return Shoot(angle=round(angle, ACTION_DECIMALS) + 0.0, power=round(power, ACTION_DECIMALS) + 0.0)

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> Shoot:
        # Uniform over the valid range. `exclude` is ignored: the space is continuous (a repeat
        # is nearly impossible) and the same launch means something else in another state.
        return self.make(float(rng.uniform(ANGLE_MIN, ANGLE_MAX)), float(rng.uniform(POWER_MIN, POWER_MAX)))

    def reference_reply(self, rng: np.random.Generator, earlier: Sequence[str] = ()) -> str:
        """The reference code's baseline: angle U(0, 90), power U(0.5, 1.0), two decimals."""
        angle = round(float(rng.uniform(ANGLE_MIN, ANGLE_MAX)), 2)
        power = round(float(rng.uniform(REFERENCE_POWER_MIN, POWER_MAX)), 2)
        return f"shoot(angle={angle}, power={power})"

    def format(self, action: Action) -> str:
        assert isinstance(action, Shoot)
        return f"shoot(angle={_fmt(action.angle)}, power={_fmt(action.power)})"


def _fmt(value: float) -> str:
    text = f"{value:.{ACTION_DECIMALS}f}".rstrip("0").rstrip(".")
    return text if text not in ("-0", "") else "0"
