"""Helpers shared by action parsers: finding the action inside a model's free-form reply."""

from __future__ import annotations

import json
import re
from typing import Any

_FENCE = re.compile(r"```[a-z]*", re.I)


def first_json_array(text: str) -> list[Any] | None:
    """The first balanced [...] in `text` (code fences and prose around it allowed) that is
    a valid JSON array, or None if there is none."""
    text = _FENCE.sub(" ", text)
    start = text.find("[")
    while start != -1:
        depth = 0
        for end in range(start, len(text)):
            if text[end] == "[":
                depth += 1
            elif text[end] == "]":
                depth -= 1
                if depth == 0:
                    try:
                        value = json.loads(text[start : end + 1])
                    except json.JSONDecodeError:
                        break
                    if isinstance(value, list):
                        return value
                    break
        start = text.find("[", start + 1)
    return None
