"""Prompt construction shared by all environments: message types, formats, history.

An environment's prompt (deepphy/envs/<name>/prompt.py, named by its EnvSpec) supplies the words: the legend
of the scene, the goal, the action syntax with its ranges and the validity rules. This
module assembles them with the observation and the history of failed attempts into chat
messages, and splits a reply into the WM prediction and the action text.
Prompts know nothing of Ray or of model providers.
"""

from __future__ import annotations

import hashlib
import json
import re
from abc import ABC, abstractmethod
from functools import cached_property
from typing import ClassVar, NamedTuple, Sequence

from pydantic import BaseModel, Field

from deepphy.chat import Image, ImagePart, Message, PromptFormat, TextPart, image_digest  # noqa: F401 (re-exported)
from deepphy.envs.base import Observation, Task


class PastAttempt(BaseModel):
    """A failed attempt, as shown to the agent before its next one."""

    attempt: int
    actions: list[str]  # the actions as submitted (canonical text, or the raw text if invalid)
    outcome: str  # what happened, in words
    key_frames: list[Image] = Field(default_factory=list)

    @cached_property
    def parts(self) -> list["TextPart | ImagePart"]:
        """This attempt as a prompt shows it. Made once: every later attempt of the episode
        shows it again (`deepphy.protocol` reuses an episode's PastAttempts). Not a field:
        kept out of dumps and equality."""
        acts = "; ".join(self.actions) if self.actions else "(none)"
        parts: list[TextPart | ImagePart] = [_text(f"Attempt {self.attempt}: action(s) {acts}. Outcome: {self.outcome}")]
        for frame in self.key_frames:
            parts.append(_text(f"Attempt {self.attempt}, {frame.caption}:"))
            parts.append(_image(frame))
        return parts


class PastStep(BaseModel):
    """An earlier decision within the current attempt (on-the-fly environments)."""

    step: int
    action: str
    feedback: str = ""
    frame: Image | None = None


class EnvPrompt(ABC):
    """The words for one environment. Numbers (sizes, time limits, speeds, step counts)
    come from the environment's constants or its action space, never retyped."""

    recent_steps_shown: ClassVar[int] = 5  # on-the-fly: how many earlier decisions to show

    @abstractmethod
    def rules(self, task: Task, observation: Observation) -> str:
        """Legend of the scene, goal, action syntax with ranges, validity rules."""

    @abstractmethod
    def example(self, observation: Observation) -> str:
        """An example action in the exact syntax (shown in the reply instructions)."""

    @abstractmethod
    def prediction_hint(self) -> str:
        """WM only: what the prediction should describe (e.g. where the ball will land)."""

    def recent_steps(self, task: Task) -> int:
        """On the fly: how many of this attempt's earlier decisions a prompt shows."""
        return self.recent_steps_shown

    def retry(self, task: Task, observation: Observation) -> str:
        """After failed attempts: the paper's retry instructions, in our words (analyse what
        went wrong, propose a new action, never repeat one that failed). An environment
        whose paper prompt says more (PHYRE's grid, I-PHYRE's checklist) adds it."""
        return RETRY


CURRENT_OBSERVATION = "Current observation:"  # the text part after which a prompt shows the observation
RETRY = ("Before you answer, analyse why your earlier attempts failed (their pictures, where the history has them, "
         "show what happened). Then propose a new, better action: do not repeat an action that already failed.")


def _vla_instructions(example: str) -> str:
    return (
        "Reply with the action only, in exactly this syntax, and nothing else:\n"
        f"{example}"
    )


def _wm_instructions(example: str, hint: str) -> str:
    return (
        "First predict what your action will cause, then give the action. Reply in exactly "
        "this form:\n"
        f"Prediction: <{hint}>\n"
        f"Outcome: <one word, {' or '.join(OUTCOMES)}: whether this attempt will reach the goal>\n"
        f"Action: {example}"
    )


def build_messages(
    prompt: EnvPrompt,
    fmt: PromptFormat,
    task: Task,
    observation: Observation,
    history: list[PastAttempt],
    recent: Sequence[PastStep] = (),
) -> list[Message]:
    """The chat messages for one decision."""
    example = prompt.example(observation)
    instructions = (
        _vla_instructions(example)
        if fmt is PromptFormat.VLA
        else _wm_instructions(example, prompt.prediction_hint())
    )
    system = _message("system", [_text(prompt.rules(task, observation) + "\n\n" + instructions)])

    parts: list[TextPart | ImagePart] = []
    if history:
        parts.append(_text(f"Your previous {len(history)} attempt(s) at this task failed:"))
        for past in history:
            parts.extend(past.parts)
        parts.append(_text("Every attempt starts again from the same initial state. " + prompt.retry(task, observation)))
    keep = prompt.recent_steps(task)
    shown = list(recent)[-keep:] if keep else []
    if shown:
        parts.append(_text("Your earlier decisions in this attempt, oldest first:"))
        for past in shown:
            line = f"Step {past.step}: {past.action}"
            parts.append(_text(line + (f" -> {past.feedback}" if past.feedback else "")))
            if past.frame is not None:
                parts.append(_image(past.frame))
    parts.append(_text(CURRENT_OBSERVATION))
    for image in observation.images:
        parts.append(_text(image.caption))
        parts.append(_image(image))
    if observation.text:
        parts.append(_text(observation.text))
    parts.append(_text("Your action:" if fmt is PromptFormat.VLA else "Your prediction and action:"))
    return [system, _message("user", parts)]


# A prompt is rebuilt for every decision. The validating constructors, not `model_construct`:
# pydantic-core checks a str or an Image instance faster than `model_construct` fills in a
# model in Python (1.0-1.2 us a part against 2.7 us; the parts of one decision: 10-40).
def _text(text: str) -> TextPart:
    return TextPart(text=text)


def _image(image: Image) -> ImagePart:
    return ImagePart(image=image)


def _message(role: str, content: list[TextPart | ImagePart]) -> Message:
    return Message(role=role, content=content)


OUTCOMES = ("success", "failure")
_OUTCOME_WORDS = {
    **dict.fromkeys(("success", "successful", "succeed", "succeeds", "solved", "solve", "win", "won", "yes"), "success"),
    **dict.fromkeys(("failure", "fail", "fails", "failed", "unsolved", "lose", "lost", "no"), "failure"),
}


class Reply(NamedTuple):
    """A reply split into its parts (WM: prediction, predicted outcome, action)."""

    prediction: str | None
    outcome: str | None  # "success" | "failure"; None when not stated (never an invalid action)
    action_text: str  # handed to the action space's parser as is


# Possessive quantifiers (*+): no backtracking, so a reply of any shape splits in linear time.
_KEY = r"[ \t]*+\**+[ \t]*+{}[ \t]*+\**+[ \t]*+[:\-]"
_NEXT_SECTION = r"\n" + _KEY.format("(?:outcome|action)")
_PREDICTION = re.compile(r"\bprediction[ \t]*+\**+[ \t]*+[:\-]\s*+(.*?)(?=" + _NEXT_SECTION + r"|\Z)", re.I | re.S | re.ASCII)
_OUTCOME = re.compile(r"(?:\A|\n)" + _KEY.format("outcome") + r"[ \t]*+\**+[ \t]*+([a-z]++)", re.I | re.ASCII)
_ACTION = re.compile(r"(?:\A|\n)" + _KEY.format("action") + r"\s*+(.*)\Z", re.I | re.S | re.ASCII)


def split_reply(fmt: PromptFormat, text: str) -> Reply:
    """VLA replies are the action text. WM replies carry `Prediction: ...`, `Outcome:
    success|failure` and `Action: ...`; a WM reply with no `Action:` section is parsed
    whole, so a bare action still counts. The last stated outcome counts."""
    if fmt is PromptFormat.VLA:
        return Reply(None, None, text)
    prediction = _PREDICTION.search(text)
    outcomes = _OUTCOME.findall(text)
    action = _ACTION.search(text)
    return Reply(
        prediction.group(1).strip() if prediction else None,
        _OUTCOME_WORDS.get(outcomes[-1].lower()) if outcomes else None,
        action.group(1).strip().lstrip("*").strip() if action else text,
    )


def mock_reply(fmt: PromptFormat, action_text: str, outcome: str | None = None) -> str:
    """A reply in the requested format carrying `action_text` (a random baseline's answer)."""
    if fmt is PromptFormat.VLA:
        return action_text
    said = f"\nOutcome: {outcome}" if outcome else ""
    return f"Prediction: no prediction (random baseline).{said}\nAction: {action_text}"


def prompt_digest(messages: list[Message]) -> str:
    """A content hash of the prompt, used to store each distinct prompt text once."""
    h = hashlib.sha256()
    for m in messages:
        h.update(m.role.encode())
        for p in m.content:
            h.update(p.text.encode() if isinstance(p, TextPart) else bytes.fromhex(p.image.digest))
    return h.hexdigest()[:20]


def prompt_as_json(messages: list[Message]) -> str:
    """The prompt for the run directory: texts as strings, each image as {"image": its
    digest, "name", "caption"}; the image itself is stored once, at images/<digest>.png.
    (Runs before content-addressed images held a "<image NAME: CAPTION>" string instead.)
    Compact JSON: a run writes a prompt per distinct decision, each naming its history's
    images again, and indentation was a third of what the references added.

    The same bytes as `json.dumps(..., separators=(",", ":"))` of those lists and dicts,
    joined by hand from each string's JSON, remembered: a decision's prompt repeats the
    rules and the history of the ones before it (4 us a prompt against 22 us)."""
    out = []
    for m in messages:
        content = []
        for p in m.content:
            if isinstance(p, TextPart):
                content.append(_json_string(p.text))
            else:
                image = p.image
                content.append(f'{{"image":{_json_string(image.digest)},"name":{_json_string(image.name)},'
                               f'"caption":{_json_string(image.caption)}}}')
        out.append(f'{{"role":{_json_string(m.role)},"content":[{",".join(content)}]}}')
    return f'[{",".join(out)}]'


_JSON_STRINGS: dict[str, str] = {}
JSON_STRINGS_REMEMBERED = 4096  # a few episodes' texts and captions; bounded: a long run's memory stays flat


def _json_string(text: str) -> str:
    encoded = _JSON_STRINGS.get(text)
    if encoded is None:
        if len(_JSON_STRINGS) >= JSON_STRINGS_REMEMBERED:
            _JSON_STRINGS.clear()
        encoded = _JSON_STRINGS[text] = json.dumps(text)
    return encoded

