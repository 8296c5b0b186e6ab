"""No model reply can crash or stall a parser: every registered action space, fuzzed.

For any string, `parse` returns a valid action or raises InvalidAction, in bounded time;
a reply with several answers is read by the one shared rule (the last one counts); only
ASCII digits are digits. The action spaces come from each environment's own first
observation, so a new environment is fuzzed without being named here.
"""

from __future__ import annotations

import functools
import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deepphy.envs import Action, ActionSpace, InvalidAction, specs
from deepphy.envs.parsing import MAX_REPLY_CHARS, cut_reply
from deepphy.testing.replies import adversarial_replies, valid_replies

NAMES = sorted(specs())
FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)


@functools.lru_cache(maxsize=None)
def space_of(name: str) -> ActionSpace:
    env_cls = specs()[name].load()
    options = env_cls.Options()
    return env_cls(options).reset(env_cls.tasks(options)[0]).action_space


def check_total(space: ActionSpace, text: str) -> Action | None:
    """parse(text) is an action that round-trips, or InvalidAction; anything else fails."""
    try:
        action = space.parse(text)
    except InvalidAction:
        return None
    assert space.parse(space.format(action)) == action
    return action


# -- property-based -----------------------------------------------------------------------

NOISE = st.sampled_from(["", " ", "\n", "```json\n", "```", "**", "Action: ", "Final answer: ", "[", "]", "{",
                         "}", '"', ",", ":", "=", "(", ")", "-", ".", "1e999", "NaN", "-0", "9" * 40, "٣", "\u200b"])


@st.composite
def mutated(draw, base: list[str]):
    """A valid answer, then damaged: characters inserted, deleted, duplicated, digits swapped."""
    text = draw(st.sampled_from(base))
    for _ in range(draw(st.integers(0, 6))):
        i = draw(st.integers(0, len(text)))
        op = draw(st.sampled_from(["insert", "delete", "repeat", "digit"]))
        if op == "insert":
            text = text[:i] + draw(NOISE | st.text(max_size=4)) + text[i:]
        elif op == "delete":
            text = text[:i] + text[i + draw(st.integers(1, 3)):]
        elif op == "repeat":
            text = text[:i] + text[i:i + 5] * draw(st.integers(2, 50)) + text[i:]
        else:
            text = text[:i] + str(draw(st.integers(-10**30, 10**30))) + text[i:]
    return text


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=True) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=20,
)


@pytest.mark.parametrize("name", NAMES)
@FUZZ
@given(text=st.text(max_size=3000))
def test_any_text(name, text):
    check_total(space_of(name), text)


@pytest.mark.parametrize("name", NAMES)
@FUZZ
@given(data=st.data())
def test_damaged_answers(name, data):
    space = space_of(name)
    check_total(space, data.draw(mutated(valid_replies(space))))


@pytest.mark.parametrize("name", NAMES)
@FUZZ
@given(value=JSON_VALUES, prose=st.text(max_size=40))
def test_json_shaped_replies(name, value, prose):
    check_total(space_of(name), f"{prose} {json.dumps(value)} {prose}")


# -- the cases that crashed or stalled runs ---------------------------------------------


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.timeout(300)  # a hang guard: backtracking takes hours; the speed is benchmarks/parsers.py's
def test_adversarial_replies_are_invalid_or_valid(name):
    space = space_of(name)
    for label, text in adversarial_replies(space).items():
        action = check_total(space, text)
        if label.startswith("1 MB reply ending"):
            assert action is not None, "the answer at the end of a long reply is read"


@pytest.mark.parametrize("name", NAMES)
def test_the_last_answer_counts(name):
    space = space_of(name)
    texts = valid_replies(space, 30)
    first, last = next((a, b) for a, b in zip(texts, texts[1:]) if space.parse(a) != space.parse(b))
    assert space.parse(f"I considered {first}, but my final answer is:\n{last}") == space.parse(last)


@pytest.mark.parametrize("name", NAMES)
def test_only_ascii_digits_are_digits(name):
    space = space_of(name)
    arabic = str.maketrans("0123456789", "٠١٢٣٤٥٦٧٨٩")
    for text in valid_replies(space):
        if any(c.isdigit() for c in text):
            with pytest.raises(InvalidAction):
                space.parse(text.translate(arabic))


def test_over_long_replies_are_cut_to_their_end():
    text = "a" * (MAX_REPLY_CHARS + 10) + "[1, 0]"
    kept, cut = cut_reply(text)
    assert len(kept) == MAX_REPLY_CHARS and cut == 16 and kept.endswith("[1, 0]")
    assert cut_reply("short") == ("short", 0)
