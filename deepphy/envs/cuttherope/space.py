"""The Cut the Rope action syntax (the reference benchmark's vocabulary):

    cut_pin(id, ...)               cut the rope of pin P<id>; several ids: those ropes at the same moment
    cut_active_pin(id, ...)        cut the rope of active pin A<id> (or remove it before it catches the candy)
    pop_bubble(id)                 pop bubble B<id>
    tap_air_cushion(id, times=n)   n puffs of air cushion C<id>, n in {1, 3, 5}
    sleep(seconds)                 let the world run, 0.1 <= seconds <= 10
    success()                      declare the level won: the world runs on to decide it
    fail()                         stop acting: the world runs on and the game decides

The space carries what can be named now (pins with a rope, active pins not yet cut,
bubbles not popped, all cushions, and which cushions were tapped): it travels in every
observation, so MOCK and the model server can sample and parse without the simulator.
An id that is not on the screen (or no longer there), a value out of range, or text
with no action is invalid. When a reply names several actions the last one counts; one
cut action may name several ropes, cut at the same moment (the game's long swipe).

Light module (no pymunk).
"""

from __future__ import annotations

import re
from itertools import combinations
from typing import Literal, Sequence

import numpy as np
from pydantic import Field

from deepphy.envs.base import Action, ActionSpace, InvalidAction
from deepphy.envs.cuttherope.constants import SAMPLE_SLEEPS, SLEEP_DECIMALS, SLEEP_MAX, SLEEP_MIN, TAP_TIMES

ActionName = Literal["cut_pin", "cut_active_pin", "pop_bubble", "tap_air_cushion", "sleep", "success", "fail"]
ELEMENT_ACTIONS = {  # action -> (label letter on the image, element noun, space field)
    "cut_pin": ("P", "pin", "pins"),
    "cut_active_pin": ("A", "active pin", "active_pins"),
    "pop_bubble": ("B", "bubble", "bubbles"),
    "tap_air_cushion": ("C", "air cushion", "cushions"),
}
LABEL_NOUNS = {"P": "pin", "A": "active pin", "B": "bubble", "C": "air cushion"}


MULTI_CUTS = ("cut_pin", "cut_active_pin")  # the actions that may name several elements (one long swipe)


class CutAction(Action):
    name: ActionName
    ids: tuple[int, ...] = ()  # the elements' numbers (P<id>, A<id>, B<id>, C<id>): one, or several cuts at once
    times: int | None = None  # tap_air_cushion
    seconds: float | None = None  # sleep


# A call: a known name after a word boundary (ASCII: no letter, digit or _ before it; also
# quick to scan for), up to 20 blanks, then "(" arguments ")". Bounded quantifiers only, so
# a scan is linear in the text's length.
_SEP = r"[ _\-]?"
_NAME = (rf"\b(cut{_SEP}active{_SEP}pin|cut{_SEP}pin|pop{_SEP}bubble|tap{_SEP}(?:air{_SEP})?cushion"
         r"|sleep|wait|success|fail)[ \t]{0,20}\(")
_CALL = re.compile(_NAME + r"([^()]{0,200})\)", re.I | re.ASCII)
_OPEN = re.compile(_NAME, re.I | re.ASCII)  # a call whose ")" never comes
_KEY = re.compile(r"^[\"'`]?([a-z_]{1,20})[\"'`]?[ \t]{0,10}[:=][ \t]{0,10}(.*)$", re.I | re.ASCII | re.S)
_ID = re.compile(r"^([pabc])?[ \t]{0,3}#?[ \t]{0,3}([0-9]{1,4})$", re.I | re.ASCII)
_INT = re.compile(r"^([0-9]{1,4})(?:\.0{1,6})?$", re.ASCII)
_SECONDS = re.compile(r"^([0-9]{1,4}(?:\.[0-9]{1,6})?|\.[0-9]{1,6})[ \t]{0,3}(?:s|sec|secs|seconds?)?$", re.I | re.ASCII)
_ID_KEYS = {"id", "pin", "active_pin", "bubble", "cushion", "air_cushion", "index", "idx", "number", "element"}
_TIMES_KEYS = {"times", "n", "count", "taps", "puffs", "repeat"}
_SECONDS_KEYS = {"seconds", "second", "secs", "sec", "s", "duration", "time", "t"}


def _canonical_name(raw: str) -> str:
    name = re.sub(r"[ _\-]", "", raw.lower())
    return {"cutpin": "cut_pin", "cutactivepin": "cut_active_pin", "popbubble": "pop_bubble",
            "tapaircushion": "tap_air_cushion", "tapcushion": "tap_air_cushion", "sleep": "sleep",
            "wait": "sleep", "success": "success", "fail": "fail"}[name]


def _split_args(text: str) -> tuple[list[str], dict[str, str]]:
    positional: list[str] = []
    keyword: dict[str, str] = {}
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        m = _KEY.match(part)
        if m:
            key = m.group(1).lower()
            if key in keyword:
                raise InvalidAction(f"argument {key!r} given twice")
            keyword[key] = m.group(2).strip()
        elif keyword:
            raise InvalidAction("a positional argument follows a keyword argument")
        else:
            positional.append(part)
    return positional, {k: v.strip().strip("\"'`").strip() for k, v in keyword.items()}


def _unquote(value: str) -> str:
    return value.strip().strip("\"'`").strip()


class CutSpace(ActionSpace):
    """The actions of one decision; the availability lists change as the level plays."""

    kind: Literal["cuttherope"] = "cuttherope"
    num_pins: int = Field(0, ge=0)  # element counts of the level (ids 1..n)
    num_active_pins: int = Field(0, ge=0)
    num_bubbles: int = Field(0, ge=0)
    num_cushions: int = Field(0, ge=0)
    pins: list[int] = Field(default_factory=list)  # pins whose rope is still attached
    active_pins: list[int] = Field(default_factory=list)  # active pins not yet cut
    bubbles: list[int] = Field(default_factory=list)  # bubbles not yet popped
    cushions_tapped: list[int] = Field(default_factory=list)  # cushions tapped before (MOCK taps each once)

    # -- parse ----------------------------------------------------------------------------

    def parse(self, text: str) -> CutAction:
        calls = list(_CALL.finditer(text))
        if not calls:
            if _OPEN.search(text):
                raise InvalidAction("an action's arguments are not closed by ')' within 200 characters")
            raise InvalidAction("no action found: expected one of cut_pin(id), cut_active_pin(id), pop_bubble(id), "
                                "tap_air_cushion(id, times=n), sleep(seconds), success(), fail()")
        last = calls[-1]  # the project's rule: the last stated answer counts
        name = _canonical_name(last.group(1))
        positional, keyword = _split_args(last.group(2))
        if name in ("success", "fail"):
            if positional or keyword:
                raise InvalidAction(f"{name}() takes no arguments")
            return CutAction(name=name)
        if name == "sleep":
            value = self._one_arg(name, positional, keyword, _SECONDS_KEYS, "seconds")
            return CutAction(name=name, seconds=self._seconds(value))
        if name == "tap_air_cushion":
            extra = [k for k in keyword if k not in _ID_KEYS | _TIMES_KEYS]
            if extra or len(positional) > 2:
                raise InvalidAction("tap_air_cushion takes an id and times, e.g. tap_air_cushion(1, times=3)")
            ids = [keyword[k] for k in keyword if k in _ID_KEYS]
            times = [keyword[k] for k in keyword if k in _TIMES_KEYS]
            args = positional + ids
            if len(args) < 1 or len(ids) > 1 or len(times) > 1:
                raise InvalidAction("tap_air_cushion takes one id and one number of times, e.g. tap_air_cushion(1, times=3)")
            if len(args) == 2 and not times:
                times = [args[1]]
            elif len(args) == 2:
                raise InvalidAction("times given twice")
            ident = self._id(name, _unquote(args[0]))
            n = self._times(_unquote(times[0])) if times else 1
            return CutAction(name=name, ids=(ident,), times=n)
        if name in MULTI_CUTS:
            extra = [k for k in keyword if k not in _ID_KEYS]
            values = positional + [keyword[k] for k in keyword if k in _ID_KEYS]
            if extra or not values or len(values) > 9:
                raise InvalidAction(f"{name} takes one or more ids, e.g. {name}(1) or {name}(1, 3)")
            ids = [self._id(name, _unquote(v)) for v in values]
            if len(set(ids)) != len(ids):
                raise InvalidAction(f"{name}: an id is named twice")
            return CutAction(name=name, ids=tuple(sorted(ids)))
        value = self._one_arg(name, positional, keyword, _ID_KEYS, "id")
        return CutAction(name=name, ids=(self._id(name, value),))

    @staticmethod
    def _one_arg(name: str, positional: list[str], keyword: dict[str, str], keys: set[str], what: str) -> str:
        extra = [k for k in keyword if k not in keys]
        values = positional + [keyword[k] for k in keyword if k in keys]
        if extra or len(values) != 1:
            raise InvalidAction(f"{name} takes exactly one argument ({what})")
        return _unquote(values[0])

    def _id(self, name: str, value: str) -> int:
        letter, noun, field = ELEMENT_ACTIONS[name]
        m = _ID.match(value)
        if not m:
            raise InvalidAction(f"{name}: {value[:40]!r} is not an id like {letter}1 or 1")
        if m.group(1) and m.group(1).upper() != letter:
            raise InvalidAction(f"{name}: {m.group(1).upper()}{m.group(2)} is a {LABEL_NOUNS[m.group(1).upper()]}, "
                                f"not a {noun}")
        ident = int(m.group(2))
        count = getattr(self, f"num_{field}")
        if not 1 <= ident <= count:
            have = f"{letter}1..{letter}{count}" if count else "none in this level"
            raise InvalidAction(f"{name}: there is no {noun} {letter}{ident} ({noun}s: {have})")
        if field != "cushions" and ident not in getattr(self, field):
            gone = {"cut_pin": "its rope is already cut or gone", "cut_active_pin": "it was already cut",
                    "pop_bubble": "it has already popped"}[name]
            raise InvalidAction(f"{name}: {noun} {letter}{ident} cannot be used: {gone}")
        return ident

    @staticmethod
    def _times(value: str) -> int:
        m = _INT.match(value)
        if not m or int(m.group(1)) not in TAP_TIMES:
            raise InvalidAction(f"times must be one of {', '.join(map(str, TAP_TIMES))}, got {value[:40]!r}")
        return int(m.group(1))

    @staticmethod
    def _seconds(value: str) -> float:
        m = _SECONDS.match(value)
        if not m:
            raise InvalidAction(f"sleep: {value[:40]!r} is not a number of seconds")
        seconds = round(float(m.group(1)), SLEEP_DECIMALS)
        if not SLEEP_MIN <= seconds <= SLEEP_MAX:
            raise InvalidAction(f"sleep: {seconds:g} s is outside [{SLEEP_MIN:g}, {SLEEP_MAX:g}]")
        return seconds

    # -- sample / reference baseline -------------------------------------------------------

    def element_actions(self, tap_times: Sequence[int] = TAP_TIMES) -> list[CutAction]:
        """Every action on elements that can be named now, in a fixed order: each rope cut
        alone, then each pair of ropes cut together, bubbles, cushion taps."""
        cuts = [(name, ids) for name, ids in (("cut_pin", self.pins), ("cut_active_pin", self.active_pins))]
        return ([CutAction(name=name, ids=(i,)) for name, ids in cuts for i in ids]
                + [CutAction(name=name, ids=pair) for name, ids in cuts for pair in combinations(ids, 2)]
                + [CutAction(name="pop_bubble", ids=(i,)) for i in self.bubbles]
                + [CutAction(name="tap_air_cushion", ids=(i,), times=n)
                   for i in range(1, self.num_cushions + 1) for n in tap_times])

    def valid_actions(self) -> list[CutAction]:
        """The finite set `sample` draws from: every element action, sleeps of SAMPLE_SLEEPS
        seconds, success() and fail()."""
        return (self.element_actions()
                + [CutAction(name="sleep", seconds=float(s)) for s in SAMPLE_SLEEPS]
                + [CutAction(name="success"), CutAction(name="fail")])

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> CutAction:
        # Uniform over the valid actions now. `exclude` (actions of earlier attempts) is
        # ignored: an action's effect depends on the moment, so an earlier one is no repeat.
        actions = self.valid_actions()
        return actions[int(rng.integers(len(actions)))]

    def reference_reply(self, rng: np.random.Generator, earlier: Sequence[str] = ()) -> str:
        """The reference benchmark's random agent: uniform among `reference_choices`; fail()
        when there is none (the world then runs on and the game decides); never sleep() or
        success()."""
        choices = self.reference_choices()
        if not choices:
            return self.format(CutAction(name="fail"))
        return self.format(choices[int(rng.integers(len(choices)))])

    def reference_choices(self) -> list[CutAction]:
        """What the reference random agent chooses among now: cutting each pin and active pin
        not used yet (one at a time), popping each bubble present, and one tap of each cushion
        not tapped yet."""
        return ([CutAction(name="cut_pin", ids=(i,)) for i in self.pins]
                + [CutAction(name="cut_active_pin", ids=(i,)) for i in self.active_pins]
                + [CutAction(name="pop_bubble", ids=(i,)) for i in self.bubbles]
                + [CutAction(name="tap_air_cushion", ids=(i,), times=1)
                   for i in range(1, self.num_cushions + 1) if i not in self.cushions_tapped])

    # -- format ----------------------------------------------------------------------------

    def format(self, action: Action) -> str:
        assert isinstance(action, CutAction)
        if action.name in ("success", "fail"):
            return f"{action.name}()"
        if action.name == "sleep":
            return f"sleep({format_seconds(action.seconds)})"
        if action.name == "tap_air_cushion":
            return f"tap_air_cushion({action.ids[0]}, times={action.times})"
        return f"{action.name}({', '.join(map(str, action.ids))})"


def format_seconds(seconds: float | None) -> str:
    return f"{seconds:.{SLEEP_DECIMALS}f}".rstrip("0").rstrip(".")
