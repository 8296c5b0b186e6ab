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
from pathlib import Path
from typing import Any, Callable

from deepphy.config import RunConfig, RuntimeOptions
from deepphy.envs import Action, Environment, Observation, StepResult, Task
from deepphy.plan import plan
from deepphy.play.background import off_loop
from deepphy.play.human import Desk, HumanModel, Journal
from deepphy.runs.records import AttemptRecord, AttemptSummary, episode_finished
from deepphy.runs.store import RunStore, read_records
from deepphy.scheduler import Scheduler

DECISION_TIMEOUT_S = 30 * 24 * 3600.0  # a person may leave a decision open for days (the page can be closed)
RECENT_SHOWN = 30  # attempts listed on the page (newest first), each with its replay once its task is over


class PlayStore(RunStore):
    """The run store, telling the session of each record it keeps."""

    on_record: Callable[[AttemptRecord], None] = staticmethod(lambda record: None)

    def append(self, record: AttemptRecord) -> None:
        super().append(record)
        self.on_record(record)


class PlayEnv:
    """The protocol's `EnvHandle` over an environment in this process. The physics runs in a
    thread, so the pages are served meanwhile."""

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
        self.session.stepped()
        return result


class PlaySession:
    """A person's play of a run directory: the desk the pages talk to, the progress and
    the latest outcome they show.

    What the pages show of a task while it is played is what a model is shown: the prompt
    (rules, failed attempts, earlier decisions, the observation). What a decision did (its
    feedback, its key frames) reaches the page as it reaches a model, through the next
    prompt; the task's id (a name can hint at the solution), the outcome in full and the
    replays only once the task's episode is over."""

    def __init__(self, config: RunConfig, out: str | Path) -> None:
        self.plan = plan(config)
        self.config, self.spec, self.tasks, self.k_max = config, self.plan.spec, self.plan.tasks, self.plan.k_max
        self.task_index = {t.id: i for i, t in enumerate(self.tasks)}
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
        self.episodes: dict[tuple[str, int], list[AttemptSummary]] = {}
        for summary in self.summaries:
            self.episodes.setdefault((summary.task, summary.run), []).append(summary)
        self.decision_s: list[float] = [s for r in self.existing for s in r.timing.decision_s]
        self.last: dict[str, Any] | None = None  # what the page says of the latest decision
        self.busy = False  # the world is being simulated
        self.warming: asyncio.Future | None = None  # the environment's warm-up, under way
        self.finished = False
        self.error: str | None = None
        self.store.on_record = self.recorded

    def episode_over(self, task: str, run: int) -> bool:
        """Whether the episode (task, run) is finished: only then are its replays shown."""
        return episode_finished(self.episodes.get((task, run), []), self.k_max)

    def episode_number(self, task: str, run: int) -> int:
        """The episode's place (1..runs x tasks): how the page names a task in play."""
        return run * len(self.tasks) + self.task_index.get(task, 0) + 1

    # -- what the protocol tells ---------------------------------------------------------

    def warm_up(self) -> asyncio.Future:
        """The environment's one-time preparation (compiling kernels), started once: after
        the first observation, so that it runs while the person decides; steps wait for it."""
        if self.warming is None:
            self.warming = asyncio.ensure_future(off_loop(self.spec.load().warm_up, self.plan.options, self.tasks))
        return self.warming

    def set_busy(self, busy: bool) -> None:
        self.busy = busy
        self.desk.changed()

    def stepped(self) -> None:
        """A decision was taken: the page names it (what it did comes with the next prompt)."""
        answered = self.desk.answered or {}
        self.last = {"id": self.desk.version, **answered}
        self.desk.changed()

    def recorded(self, record: AttemptRecord) -> None:
        summary = record.summary()
        self.summaries.append(summary)
        self.episodes.setdefault((record.task, record.run), []).append(summary)
        self.decision_s += record.timing.decision_s
        last = self.last
        if last is None or (last.get("task"), last.get("run"), last.get("attempt")) != record.key:
            # the attempt ended on an answer the parser refused: no step was taken
            last = self.last = {"id": self.desk.version, "task": record.task, "run": record.run,
                                "attempt": record.attempt, "step": None, "text": None}
        last["attempt_over"] = True
        if self.episode_over(record.task, record.run):
            last["record"] = {"success": record.success, "stars": record.stars, "outcome": record.feedback,
                              "invalid_reason": record.invalid_reason}
        self.desk.changed()

    # -- what the pages see --------------------------------------------------------------

    def _last_view(self) -> dict[str, Any] | None:
        """The latest decision as the page shows it: its action (the person's own), and the
        task's name and outcome once its episode is over (before, the prompt says what a
        model is told of it)."""
        last = self.last
        if last is None:
            return None
        task, run = last.get("task"), last.get("run")
        view = {k: last.get(k) for k in ("id", "attempt", "step", "text", "attempt_over")}
        view["episode"] = self.episode_number(task, run) if task is not None else None
        if "record" in last:
            view.update(task=task, run=run, record=last["record"])
        return view

    def state(self) -> dict[str, Any]:
        done = sum(1 for attempts in self.episodes.values() if episode_finished(attempts, self.k_max))
        pending = self.desk.pending
        decision = None
        if pending:
            decision = pending.view(lambda i: f"/api/prompt/{pending.digest}/{i}.png")
            ctx = pending.request.context
            decision["episode"] = self.episode_number(ctx.task_id, ctx.run)
        return {
            "env": self.config.env, "title": self.spec.title, "player": self.config.model.partition(":")[2],
            "model": self.config.model, "run_dir": str(self.path), "planning": self.spec.planning.value,
            "max_attempts": self.k_max, "max_steps": self.spec.max_steps, "step_noun": self.spec.report.step_noun,
            "runs": self.config.runs, "version": self.desk.version,
            "progress": {
                "episodes_total": len(self.tasks) * self.config.runs, "episodes_done": done,
                "solved": sum(1 for attempts in self.episodes.values() if any(a.success for a in attempts)),
                "attempts": len(self.summaries), "decisions": len(self.decision_s),
                "seconds_per_decision": sum(self.decision_s) / len(self.decision_s) if self.decision_s else None,
            },
            "decision": decision,
            "last": self._last_view(),
            "busy": self.busy,
            "recent": [self._recent(s) for s in self.summaries[::-1][:RECENT_SHOWN]],
            "finished": self.finished,
            "error": self.error,
        }

    def _recent(self, s: AttemptSummary) -> dict[str, Any]:
        """An attempt in the page's list: named, with its outcome and replay, once its episode is over."""
        row = {"episode": self.episode_number(s.task, s.run), "run": s.run, "attempt": s.attempt,
               "decisions": s.decisions, "over": self.episode_over(s.task, s.run)}
        if row["over"]:
            row.update(s.model_dump(include={"task", "success", "stars", "invalid"}))
        return row

    # -- the play ------------------------------------------------------------------------

    async def play(self) -> None:
        """Every unfinished episode, one at a time, until all are done."""
        try:
            env = await off_loop(self.plan.make_env)
            runtime = RuntimeOptions(max_in_flight=1, progress=False, model_timeout_s=DECISION_TIMEOUT_S)
            scheduler = Scheduler(self.plan, runtime, self.store, [], HumanModel(self.desk, self.journal), None,
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

