"""`deepphy play`: one person plays an environment's tasks; the result is a run directory.

The episodes are driven by the scheduler of `deepphy run` (the one episode loop: resume
from the stored records, attempts in order, each one `protocol.run_attempt`), one episode
at a time, with the person as the model (`HumanModel`) and the environment in this very
process. No Ray: a person needs no parallelism (the physics of a decision takes
milliseconds to seconds, the person seconds to minutes), and a page that is ready as soon
as the environment is beats waiting for a cluster to start.
"""

from __future__ import annotations

import asyncio
from collections import OrderedDict
from pathlib import Path
from typing import Any, Callable

from deepphy.config import RunConfig, RuntimeOptions
from deepphy.envs import Action, Environment, Observation, StepResult, Task
from deepphy.play.background import off_loop
from deepphy.play.human import Desk, HumanModel, Journal, remember
from deepphy.runs.records import AttemptRecord, AttemptSummary, episode_finished
from deepphy.runs.store import RunStore, read_records

DECISION_TIMEOUT_S = 30 * 24 * 3600.0  # a person may leave a decision open for days (the page can be closed)
RECENT_SHOWN = 30  # attempts listed on the page (newest first), each with its replay


class PlayStore(RunStore):
    """The run store, telling the session of each record it keeps."""

    on_record: Callable[[AttemptRecord], None] = staticmethod(lambda record: None)

    def append(self, record: AttemptRecord) -> None:
        super().append(record)
        self.on_record(record)


class PlayEnv:
    """The protocol's `EnvHandle` over an environment in this process. The physics runs in a
    thread, so the pages are served meanwhile; each step's result is kept for the page (what
    the decision did, its key frames)."""

    def __init__(self, env: Environment, session: "PlaySession") -> None:
        self.env, self.session = env, session

    async def reset(self, task: Task) -> Observation:
        observation = await off_loop(self.env.reset, task)
        self.session.warm_up()  # while the person thinks about the first decision
        return observation

    async def step(self, action: Action) -> StepResult:
        self.session.set_busy(True)
        try:
            await self.session.warm_up()
            result = await off_loop(self.env.step, action)
        finally:
            self.session.set_busy(False)
        self.session.stepped(result)
        return result


class PlaySession:
    """A person's play of a run directory: the desk the pages talk to, the progress and
    the latest outcome they show."""

    def __init__(self, config: RunConfig, out: str | Path) -> None:
        from deepphy.runner import resolve

        self.config = config
        self.spec, self.tasks, self.k_max = resolve(config)
        self.store = PlayStore.create_or_resume(out, config)
        self.path = self.store.path.resolve()
        try:
            self.journal = Journal(self.path)
            self.existing = read_records(self.path)
        except BaseException:
            self.store.close()
            raise
        self.desk = Desk()
        self.summaries: list[AttemptSummary] = [r.summary() for r in self.existing]
        self.decision_s: list[float] = [s for r in self.existing for s in r.timing.decision_s]
        self.last: dict[str, Any] | None = None  # what the latest decision did
        self.frames: OrderedDict[int, list[bytes]] = OrderedDict()  # the latest decisions' key frames (PNG), by id
        self.busy = False  # the world is being simulated
        self.warming: asyncio.Future | None = None  # the environment's warm-up, under way
        self.finished = False
        self.error: str | None = None
        self.store.on_record = self.recorded

    # -- what the protocol tells ---------------------------------------------------------

    def warm_up(self) -> asyncio.Future:
        """The environment's one-time preparation (compiling kernels), started once: after
        the first observation, so that it runs while the person decides; steps wait for it."""
        if self.warming is None:
            env_cls = self.spec.load()
            options = env_cls.Options(**self.config.env_options)
            self.warming = asyncio.ensure_future(off_loop(env_cls.warm_up, options, self.tasks))
        return self.warming

    def set_busy(self, busy: bool) -> None:
        self.busy = busy
        self.desk.changed()

    def stepped(self, result: StepResult) -> None:
        """A decision's consequence, for the page (the record comes when the attempt ends)."""
        answered = self.desk.answered
        remember(self.frames, self.desk.version, [frame.png for frame in result.key_frames])
        self.last = {
            "id": self.desk.version, **(answered or {}), "feedback": result.feedback, "done": result.done,
            "success": result.success, "invalid_reason": result.invalid_reason, "stars": result.stars,
            "frames": [{"caption": f.caption, "width": f.size[0], "height": f.size[1]} for f in result.key_frames],
        }
        self.desk.changed()

    def recorded(self, record: AttemptRecord) -> None:
        self.summaries.append(record.summary())
        self.decision_s += record.timing.decision_s
        last = self.last
        if last is None or (last.get("task"), last.get("run"), last.get("attempt")) != record.key:
            # the attempt ended on an answer the parser refused: no step was taken
            last = self.last = {"id": self.desk.version, "task": record.task, "run": record.run,
                                "attempt": record.attempt, "feedback": record.feedback, "done": True,
                                "success": False, "invalid_reason": record.invalid_reason, "frames": []}
        last["record"] = {"success": record.success, "stars": record.stars, "outcome": record.feedback}
        self.desk.changed()

    # -- what the pages see --------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        episodes: dict[tuple[str, int], list[AttemptSummary]] = {}
        for s in self.summaries:
            episodes.setdefault((s.task, s.run), []).append(s)
        done = sum(1 for attempts in episodes.values() if episode_finished(attempts, self.k_max))
        pending = self.desk.pending
        return {
            "env": self.config.env, "title": self.spec.title, "player": self.config.model.partition(":")[2],
            "model": self.config.model, "run_dir": str(self.path), "planning": self.spec.planning.value,
            "max_attempts": self.k_max, "max_steps": self.spec.max_steps, "step_noun": self.spec.report.step_noun,
            "version": self.desk.version,
            "progress": {
                "episodes_total": len(self.tasks) * self.config.runs, "episodes_done": done,
                "solved": sum(1 for attempts in episodes.values() if any(a.success for a in attempts)),
                "attempts": len(self.summaries), "decisions": len(self.decision_s),
                "seconds_per_decision": sum(self.decision_s) / len(self.decision_s) if self.decision_s else None,
            },
            "decision": pending.view(lambda i: f"/api/prompt/{pending.digest}/{i}.png") if pending else None,
            "last": self.last,
            "busy": self.busy,
            "recent": [s.model_dump(include={"task", "run", "attempt", "success", "stars", "decisions", "invalid"})
                       for s in self.summaries[::-1][:RECENT_SHOWN]],
            "finished": self.finished,
            "error": self.error,
        }

    # -- the play ------------------------------------------------------------------------

    async def play(self) -> None:
        """Every unfinished episode, one at a time, until all are done."""
        from deepphy.scheduler import Scheduler

        try:
            env_cls = self.spec.load()
            env = await off_loop(env_cls, env_cls.Options(**self.config.env_options))
            runtime = RuntimeOptions(max_in_flight=1, progress=False, model_timeout_s=DECISION_TIMEOUT_S)
            scheduler = Scheduler(self.config, runtime, self.spec, self.tasks, self.store, [],
                                  HumanModel(self.desk, self.journal), None, self.k_max,
                                  local_env=PlayEnv(env, self))
            await scheduler.run(self.existing)
            self.existing = []
            if scheduler.errored:
                self.error = (f"{len(scheduler.errored)} attempt(s) failed with an error (see "
                              f"{self.path / 'errors.jsonl'}); first: {scheduler.errored[0]}")
        finally:
            self.finished = True
            self.desk.changed()

    def close(self) -> None:
        self.store.close()

