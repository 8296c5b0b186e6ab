"""`deepphy play` for the tests: a play server in a thread of the test process, and the same
actions given as a model's replies through the attempt protocol, for comparing records."""

from __future__ import annotations

import asyncio
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable

from deepphy.config import RunConfig
from deepphy.models.base import ModelRequest, ModelResponse
from deepphy.play.server import serve
from deepphy.play.session import PlaySession
from deepphy.protocol import LocalEnv, run_episode
from deepphy.plan import plan
from deepphy.runs.records import AttemptRecord
from deepphy.runs.store import RunStore, read_records


class PlayThread:
    """`deepphy play` served from a thread of this process on a free port of 127.0.0.1."""

    def __init__(self, config: RunConfig, out: Path) -> None:
        self.session = PlaySession(config, out)
        self.loop = asyncio.new_event_loop()
        self.url: str | None = None
        self.played = threading.Event()
        listening = threading.Event()

        def announce(url: str) -> None:
            self.url = url
            listening.set()

        async def main() -> None:
            await serve(self.session, "127.0.0.1", 0, announce, lambda progress: self.played.set())

        self.task = self.loop.create_task(main())
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        if not listening.wait(60):
            raise AssertionError("the play server did not start")

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        try:
            self.loop.run_until_complete(self.task)
        except (asyncio.CancelledError, Exception):  # noqa: BLE001 - a failure shows in the test's checks
            pass

    def close(self) -> None:
        self.loop.call_soon_threadsafe(self.task.cancel)
        self.thread.join(60)
        self.session.close()


class ScriptedModel:
    """A model whose replies are given: reply(task, run, attempt, step) -> text."""

    def __init__(self, reply: Callable[[str, int, int, int], str]) -> None:
        self.reply = reply

    async def complete(self, request: ModelRequest) -> ModelResponse:
        c = request.context
        return ModelResponse(text=self.reply(c.task_id, c.run, c.attempt, c.step))


def model_run(config: RunConfig, out: Path, reply: Callable[[str, int, int, int], str]) -> list[AttemptRecord]:
    """The tasks of `config` with `reply`'s texts as a model's replies, through the attempt
    protocol in this process, into a run directory of its own."""
    the_plan = plan(config)
    spec, tasks, k_max = the_plan.spec, the_plan.tasks, the_plan.k_max
    env = LocalEnv(the_plan.make_env())
    prompt, model = the_plan.prompt(), ScriptedModel(reply)

    async def play() -> None:
        with RunStore.create_or_resume(out, config) as store:
            for run in range(config.runs):
                for task in tasks:
                    await run_episode(spec, prompt, config, task, run, k_max, env, model, store, on_record=store.append)

    with ThreadPoolExecutor(1) as pool:  # a thread of its own: Playwright's sync API holds this one's loop
        pool.submit(asyncio.run, play()).result()
    return read_records(out)


def person_run(config: RunConfig, out: Path, reply: Callable[[str, int, int, int], str]) -> list[AttemptRecord]:
    """A person's play of `config` into `out` without a page: each waiting decision answered
    on the desk with `reply`'s text, as the page would."""

    async def play() -> None:
        session = PlaySession(config, out)
        try:
            await answer(session, reply)
        finally:
            session.close()

    with ThreadPoolExecutor(1) as pool:
        pool.submit(asyncio.run, play()).result()
    return read_records(out)


async def answer(session: PlaySession, reply: Callable[[str, int, int, int], str],
                 stop_after: int | None = None) -> list[str]:
    """Play as a page would: answer each waiting decision with `reply`; stop after
    `stop_after` answers (the play left in the middle). Returns the decision keys answered."""
    play = asyncio.ensure_future(session.play())
    answered: list[str] = []
    while not play.done():
        pending = session.desk.pending
        if pending is None or pending.answer.done():
            await asyncio.sleep(0.005)
            continue
        if stop_after is not None and len(answered) == stop_after:
            play.cancel()
            break
        c = pending.request.context
        session.desk.answer(pending.key, reply(c.task_id, c.run, c.attempt, c.step))
        answered.append(pending.key)
    try:
        await play
    except asyncio.CancelledError:
        pass
    return answered


def same_records(person: list[AttemptRecord], model: list[AttemptRecord]) -> None:
    """The records are equal but for the model's name and the clock."""
    assert [r.key for r in person] == [r.key for r in model]
    for a, b in zip(person, model):
        assert a.model.startswith("human:") and a.model != b.model
        assert {**a.deterministic_view(), "model": None} == {**b.deterministic_view(), "model": None}
        assert len(a.timing.decision_s) == len(a.steps)
