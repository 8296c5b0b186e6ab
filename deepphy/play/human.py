"""A person as an agent: the `ModelHandle` whose replies come from a web page.

The protocol asks `HumanModel.complete` for a reply, as it asks a model. The request (the
very prompt a model gets: rules, history of failed attempts, earlier decisions, the
current observation) waits on the `Desk` until a page answers it; the answer is text in
the environment's own syntax, which the protocol parses like a model's.

Every answer is also appended to the run directory's journal (`human.jsonl`) the moment
it is given. A play stopped in the middle of an attempt (the page closed, the server
stopped) loses nothing: the attempt is re-run from its start when play resumes, and each
decision whose prompt is the one the person already answered gets that answer again, with
the time the person took; the person is asked from the first decision not yet answered.
"""

from __future__ import annotations

import asyncio
import os
import re
import time
from collections import OrderedDict
from pathlib import Path
from typing import Any, Callable

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from deepphy.chat import Image, ImagePart, TextPart
from deepphy.config import HUMAN_PREFIX
from deepphy.envs import ActionSpace, InvalidAction
from deepphy.models.base import ModelRequest, ModelResponse, RequestContext
from deepphy.prompts import prompt_digest
from deepphy.prompts.base import CURRENT_OBSERVATION
from deepphy.runs.store import RunDirError

PLAYER_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,39}$")
JOURNAL = "human.jsonl"
JOURNAL_MAX_BYTES = 64 * 1024**2  # a person's answers are a few hundred bytes each
MAX_ANSWER_CHARS = 4096  # the controls write a few dozen characters; a typed answer is bounded too
# Decisions whose pictures stay served once answered: a page may still be loading the pictures
# of a decision the person (or a test) has already answered, and a missing picture is an error.
RECENT_SERVED = 8


def player_model(name: str) -> str:
    """The run's model name for a player (ValueError for a name that is not plain)."""
    if not PLAYER_NAME.match(name):
        raise ValueError(f"player name {name!r}: use 1-40 letters, digits, '.', '_' or '-', starting with a letter "
                         "or digit")
    return HUMAN_PREFIX + name


class Answer(BaseModel):
    """One decision of a person, as the journal keeps it."""

    model_config = ConfigDict(extra="forbid")

    task: str
    run: int = Field(ge=0)
    attempt: int = Field(ge=1)
    step: int = Field(ge=1)
    prompt: str  # digest of the prompt answered: an answer is replayed only for the same prompt
    text: str = Field(max_length=MAX_ANSWER_CHARS)
    seconds: float = Field(ge=0)  # how long the person took to decide


class Journal:
    """A person's answers, one JSON line each, written (and flushed to disk) as given. Opened
    only by the play holding the run directory's lock."""

    def __init__(self, run_dir: str | Path) -> None:
        self.path = Path(run_dir) / JOURNAL
        self._answers: dict[tuple[str, int, int, int], list[Answer]] = {}
        for answer in self._read():
            self._answers.setdefault((answer.task, answer.run, answer.attempt, answer.step), []).append(answer)

    def _read(self) -> list[Answer]:
        try:
            if self.path.is_symlink() or self.path.stat().st_size > JOURNAL_MAX_BYTES:
                raise RunDirError(f"{self.path} is not a journal of answers (a link, or over "
                                  f"{JOURNAL_MAX_BYTES // 1024**2} MB)")
            data = self.path.read_bytes()
        except FileNotFoundError:
            return []
        except PermissionError:
            raise RunDirError(f"cannot read {self.path}: permission denied") from None
        if data and not data.endswith(b"\n"):  # a line torn by a crash: dropped, as the run store does
            with open(self.path, "r+b") as f:
                f.truncate(data.rfind(b"\n") + 1)
        answers = []
        for n, line in enumerate(data.split(b"\n")[:-1], 1):  # after the last newline: empty, or torn by a crash
            if not line.strip():
                continue
            try:
                answers.append(Answer.model_validate_json(line))
            except ValidationError:
                raise RunDirError(f"{self.path}:{n} is not a valid answer") from None
        return answers

    def find(self, ctx: RequestContext, digest: str) -> Answer | None:
        """The answer given to this very prompt at this decision, if any."""
        found = [a for a in self._answers.get((ctx.task_id, ctx.run, ctx.attempt, ctx.step), []) if a.prompt == digest]
        return found[-1] if found else None

    def append(self, answer: Answer) -> None:
        line = (answer.model_dump_json() + "\n").encode()
        with open(self.path, "ab") as f:
            f.write(line)
            f.flush()
            os.fsync(f.fileno())
        self._answers.setdefault((answer.task, answer.run, answer.attempt, answer.step), []).append(answer)


class StaleDecision(ValueError):
    """An answer to a decision that is no longer waiting (answered in another tab, say)."""


class Pending:
    """A decision waiting for the person: the request, and the future its answer resolves."""

    def __init__(self, request: ModelRequest, digest: str) -> None:
        self.request = request
        self.digest = digest
        ctx = request.context
        self.key = f"{ctx.task_id}|{ctx.run}|{ctx.attempt}|{ctx.step}|{digest}"
        self.space = ActionSpace.from_json(ctx.action_space)
        self.asked = time.monotonic()
        self.asked_at = time.time()
        self.answer: asyncio.Future[str] = asyncio.get_running_loop().create_future()
        self.images: list[Image] = [p.image for m in request.messages for p in m.content if isinstance(p, ImagePart)]

    def check(self, text: str) -> str:
        """The action's canonical text; InvalidAction (the parser's reason) if it is none."""
        if len(text) > MAX_ANSWER_CHARS:
            raise InvalidAction(f"an answer has at most {MAX_ANSWER_CHARS} characters")
        return self.space.format(self.space.parse(text))

    def view(self, image_url: Callable[[int], str]) -> dict[str, Any]:
        """The prompt as the page shows it: the system text, then the user message's parts up
        to the current observation (history, earlier decisions), then the observation (from
        its "Current observation:" on), each part with its place in the prompt."""
        ctx = self.request.context
        system = "\n\n".join(m.text for m in self.request.messages if m.role == "system")
        before: list[dict[str, Any]] = []
        observation: list[dict[str, Any]] = []
        parts = before
        index = 0  # of the prompt's images
        place = 0  # of the user message's parts: the page shows every one, in the prompt's order
        for message in self.request.messages:
            if message.role == "system":
                continue
            for part in message.content:
                if isinstance(part, TextPart):
                    if part.text == CURRENT_OBSERVATION:
                        parts = observation
                    parts.append({"text": part.text, "part": place})
                else:
                    width, height = part.image.size
                    parts.append({"image": image_url(index), "name": part.image.name, "caption": part.image.caption,
                                  "width": width, "height": height, "part": place})
                    index += 1
                place += 1
        return {
            "key": self.key, "task": ctx.task_id, "run": ctx.run, "attempt": ctx.attempt, "step": ctx.step,
            "prompt": self.digest, "format": ctx.format.value, "space": ctx.action_space, "earlier": ctx.earlier,
            "system": system, "before": before, "observation": observation, "asked_at": self.asked_at,
        }


class Desk:
    """Where the protocol's requests wait for the person and the pages find them. Every
    change bumps `version` and wakes the pages listening (`listen`)."""

    def __init__(self) -> None:
        self.pending: Pending | None = None
        self.answered: dict[str, Any] | None = None  # the latest decision taken: where, and the action
        self.images: OrderedDict[str, list[Image]] = OrderedDict()  # the latest prompts' images, by digest
        self.version = 0
        self._listeners: set[asyncio.Queue] = set()

    def changed(self) -> None:
        self.version += 1
        for queue in list(self._listeners):
            queue.put_nowait(self.version)

    def listen(self) -> asyncio.Queue:
        queue: asyncio.Queue = asyncio.Queue()
        self._listeners.add(queue)
        return queue

    def unlisten(self, queue: asyncio.Queue) -> None:
        self._listeners.discard(queue)

    def close(self) -> None:
        """Tell every listening page's stream to end (the server is stopping)."""
        for queue in list(self._listeners):
            queue.put_nowait(None)

    async def ask(self, request: ModelRequest, digest: str) -> tuple[str, float]:
        """Wait for the person's answer to `request`: (text, seconds the person took)."""
        pending = self.pending = Pending(request, digest)
        remember(self.images, digest, pending.images)
        self.changed()
        try:
            text = await pending.answer
        finally:
            if self.pending is pending:
                self.pending = None
        return text, time.monotonic() - pending.asked

    def answer(self, key: str, text: str) -> str:
        """Answer the waiting decision `key` with `text`; returns the action's canonical text.
        StaleDecision if that decision is not waiting, InvalidAction if the text is no action."""
        pending = self.pending
        if pending is None or pending.key != key or pending.answer.done():
            raise StaleDecision("this decision is no longer waiting for an answer")
        canonical = pending.check(text)
        pending.answer.set_result(text)
        self.changed()
        return canonical


class HumanModel:
    """The protocol's `ModelHandle` for a person: the journal's answer if this decision was
    answered before, else the desk's."""

    def __init__(self, desk: Desk, journal: Journal) -> None:
        self.desk, self.journal = desk, journal

    async def complete(self, request: ModelRequest) -> ModelResponse:
        ctx = request.context
        digest = prompt_digest(request.messages)
        known = self.journal.find(ctx, digest)
        if known is not None:
            text, seconds = known.text, known.seconds
        else:
            text, seconds = await self.desk.ask(request, digest)
            seconds = round(seconds, 3)
            self.journal.append(Answer(task=ctx.task_id, run=ctx.run, attempt=ctx.attempt, step=ctx.step,
                                       prompt=digest, text=text, seconds=seconds))
        self.desk.answered = {"task": ctx.task_id, "run": ctx.run, "attempt": ctx.attempt, "step": ctx.step,
                              "text": text, "seconds": seconds}
        return ModelResponse(text=text, seconds=seconds)


def remember(recent: OrderedDict, key: Any, value: Any, keep: int = RECENT_SERVED) -> None:
    """Keep `value` under `key` among the `keep` newest."""
    recent[key] = value
    recent.move_to_end(key)
    while len(recent) > keep:
        recent.popitem(last=False)
