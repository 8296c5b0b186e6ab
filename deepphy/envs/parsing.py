"""Finding the action inside a model's free-form reply: the rules every parser shares.

- Total and fast: every parser returns an action or raises InvalidAction, for any string,
  in time linear in its length (no backtracking regexes, no quadratic scans, no unbounded
  integer conversions). The protocol cuts a reply to its last MAX_REPLY_CHARS characters
  before parsing and records the cut.
- One rule for replies that state several answers: the LAST one counts (models often
  reason through candidates and restate their final answer at the end).
- ASCII digits only: numbers written with other scripts' digits are not numbers here.
"""

from __future__ import annotations

import json
import re
from typing import Any

MAX_REPLY_CHARS = 32_768  # longer replies keep their last MAX_REPLY_CHARS characters
MAX_DEPTH = 4  # deepest bracket nesting of any action (I-PHYRE: a list of objects)
MAX_INT_DIGITS = 18  # longer integers are treated as out of range, never converted

_FENCE = re.compile(r"```[A-Za-z]*")
_BRACKET = re.compile(r"[\[\]]")


def cut_reply(text: str) -> tuple[str, int]:
    """(the reply as parsed, characters cut from its start)."""
    if len(text) <= MAX_REPLY_CHARS:
        return text, 0
    return text[-MAX_REPLY_CHARS:], len(text) - MAX_REPLY_CHARS


def _bounded_int(digits: str) -> int | float:
    # An integer longer than any action needs becomes inf, which every range check rejects
    # (and Python's int() is quadratic in the number of digits).
    return int(digits) if len(digits.lstrip("-")) <= MAX_INT_DIGITS else float("inf")


def _loads(candidate: str) -> Any:
    return json.loads(candidate, parse_int=_bounded_int, parse_constant=lambda c: float("nan"))


def last_json_array(text: str) -> list[Any] | None:
    """The last balanced [...] in `text` (code fences and prose around it allowed) that is a
    valid JSON array, or None. Of nested arrays the outermost that parses wins.

    Linear time: one pass matches brackets with a stack; only spans nested at most
    MAX_DEPTH deep are tried (so each character is inside few candidates), latest first."""
    text = _FENCE.sub(" ", text)
    starts: list[int] = []  # open brackets
    inner: list[int] = []  # depth of the deepest array inside each open bracket
    spans: list[tuple[int, int]] = []  # (start, end) of candidates, in order of their end
    for m in _BRACKET.finditer(text):
        if m.group() == "[":
            starts.append(m.start())
            inner.append(0)
        elif starts:
            start, depth = starts.pop(), inner.pop() + 1
            if inner and inner[-1] < depth:
                inner[-1] = depth
            if depth <= MAX_DEPTH:
                spans.append((start, m.end()))
    for start, end in reversed(spans):
        try:
            value = _loads(text[start:end])
        except (ValueError, RecursionError):
            continue
        if isinstance(value, list):
            return value
    return None


def brief(value: Any, limit: int = 60) -> str:
    """A value's repr for an error message, shortened (replies can be absurdly long)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def is_number(value: Any) -> bool:
    """A JSON number (not a boolean)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)
