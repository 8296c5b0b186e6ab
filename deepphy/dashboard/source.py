"""One run directory as the dashboard sees it: the attempt log tailed by byte offset, the
report built by the same code as `deepphy report`, the task grid and the episodes.

The run directory is the source of truth; a live metrics actor only adds its own progress
figures. Not thread-safe: the server calls every method from one worker thread.
"""

from __future__ import annotations

import bisect
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from deepphy.metrics import figures as F
from deepphy.config import is_human
from deepphy.metrics import registry
from deepphy.metrics.report import Report, build_report, setting_label, table, table_key
from deepphy.plan import plan
from deepphy.runs.discovery import dir_id
from deepphy.runs.records import AttemptRecord
from deepphy.runs.status import read_status, writer_holds_lock
from deepphy.runs.store import (
    ATTEMPTS, FRAMES, IMAGE_DIGEST, IMAGES, OLD_IMAGE_PLACEHOLDER, RunDirError, episode_prompts, inside,
    read_config, read_image, stored_image, stored_prompt_json,
)

# Bytes of the log consumed per poll: a huge log loads in slices, so the page shows
# progress and other requests get a turn between them.
READ_CHUNK = 8 * 1024 * 1024
SCAN_CHUNK = 1024 * 1024  # looking for the end of a line
MAX_LINE = 16 * 1024 * 1024  # a record is at most ~1 MB (replies are cut at 32,768 characters)
RATE_WINDOW_S = 60.0  # attempts/s and ETA of a live run: over the records of the last minute
GRID_PAGE = 200  # tasks per grid page


class LogTail:
    """The attempt log read by byte offset, whole lines only, in time linear in its size: each
    byte is looked at a bounded number of times, however long its line. A line longer than
    MAX_LINE (no record comes near it) comes back as None, skipped without being held; a
    line still being written stays unread."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.offset = 0  # everything before it has been returned
        self._scanned = 0  # no newline in [offset, _scanned)

    def read(self, limit: int = READ_CHUNK) -> list[bytes | None]:
        """The next complete lines (about `limit` bytes, more to finish one long line)."""
        with open(self.path, "rb") as f:
            f.seek(self._scanned)
            while True:  # the end of the next line
                chunk = f.read(SCAN_CHUNK)
                if not chunk:
                    return []  # being written
                newline = chunk.find(b"\n")
                if newline >= 0:
                    break
                self._scanned += len(chunk)
            line_end = self._scanned + newline
            if line_end - self.offset > MAX_LINE:
                self.offset = self._scanned = line_end + 1
                return [None]
            f.seek(self.offset)
            data = f.read(max(limit, line_end + 1 - self.offset))
        end = data.rfind(b"\n")
        self.offset += end + 1
        self._scanned = self.offset
        return data[:end].split(b"\n")


@dataclass
class Cell:
    state: str  # solved | failed | progress (started, not finished) | pending (no attempt yet)
    attempts: int = 0
    solved_at: int | None = None
    invalid: int = 0
    stars: int | None = None
    steps_to_solve: int | None = None

    def as_json(self) -> list[Any]:  # compact: grids of thousands of cells travel often
        return [self.state, self.attempts, self.solved_at, self.invalid, self.stars, self.steps_to_solve]


class RunSource:
    def __init__(self, path: str | Path) -> None:
        self.path = Path(path).resolve()
        self.id = dir_id(self.path)
        self.plan = plan(read_config(self.path))
        self.config, self.tasks, self.k_max = self.plan.config, self.plan.tasks, self.plan.k_max
        self.max_steps = self.plan.spec.max_steps
        self.task_index = {t.id: i for i, t in enumerate(self.tasks)}
        self.records: list[AttemptRecord] = []
        self.episodes: dict[tuple[str, int], dict[int, AttemptRecord]] = {}
        self.tail = LogTail(self.path / ATTEMPTS)
        self.inode: int | None = None
        self.log_size = 0
        self.errors: list[str] = []
        self.version = 0  # bumps whenever what the view shows changes: records arrive, a line is refused
        self.snapshot: dict[str, Any] | None = None  # the live metrics actor's, if one was found
        self._report: tuple[int, dict[str, Any]] | None = None
        self._cells: dict[tuple[str, int], Cell] = {}  # cache; poll() drops what changed
        # timing facts kept up to date by poll(), for attempts/s and ETA without rescanning
        self._finished: list[float] = []  # sorted finish times of all attempts
        self._first_started: float | None = None
        self._episode_ends: dict[tuple[str, int], float] = {}  # finished episodes -> their last finish time

    # -- reading ------------------------------------------------------------------------

    def poll(self) -> set[tuple[str, int]] | None:
        """Read what was appended since the last call. Returns the (task, run) episodes that
        changed, or None if the log was replaced (everything changed). A line refused (in
        `errors`) changes no episode but bumps `version`: the view shows it."""
        log = self.path / ATTEMPTS
        try:
            st = log.stat()
        except FileNotFoundError:
            return set()
        reset = self.inode is not None and (st.st_ino != self.inode or st.st_size < self.offset)
        if reset:  # a different log (the directory was recreated): start over
            self.records, self.episodes, self.errors, self._cells = [], {}, [], {}
            self.tail = LogTail(log)
            self._finished, self._first_started, self._episode_ends = [], None, {}
            self.version += 1
        self.inode, self.log_size = st.st_ino, st.st_size
        if st.st_size == self.offset:
            return None if reset else set()
        at = self.offset
        lines = self.tail.read()
        errors = len(self.errors)
        changed: set[tuple[str, int]] = set()
        for line in lines:
            if line is None:
                at = self.offset  # the skipped line's end
                self.errors.append(f"{log}: the line ending at byte {at} is longer than {MAX_LINE >> 20} MiB, "
                                   "larger than any record (skipped)")
                continue
            at += len(line) + 1
            if not line.strip():
                continue
            try:
                record = AttemptRecord.model_validate_json(line)
            except ValidationError:
                self.errors.append(f"{log}: the line ending at byte {at} is not a valid attempt record (skipped)")
                continue
            attempts = self.episodes.setdefault((record.task, record.run), {})
            if record.attempt in attempts:  # shown once; `deepphy report` refuses the directory
                self.errors.append(f"{log}: attempt {record.attempt} of task {record.task} run {record.run} is "
                                   f"recorded twice (the line ending at byte {at}); see `deepphy repair`")
                continue
            self.records.append(record)
            attempts[record.attempt] = record
            changed.add((record.task, record.run))
            if record.timing.finished:
                bisect.insort(self._finished, record.timing.finished)
            if record.timing.started:
                self._first_started = min(self._first_started or record.timing.started, record.timing.started)
        for key in changed:
            self._cells.pop(key, None)
            if self._cell(key).state in ("solved", "failed"):
                self._episode_ends[key] = max(r.timing.finished for r in self.episodes[key].values())
        if changed or len(self.errors) != errors:
            self.version += 1
        return None if reset else changed

    @property
    def label(self) -> str:
        c = self.config
        return setting_label(c.model, c.format.value, c.env_options, c.prompts)

    @property
    def offset(self) -> int:
        return self.tail.offset

    @property
    def loading(self) -> bool:
        return self.offset < self.log_size

    # -- figures (all from the report code) ---------------------------------------------

    def report(self) -> Report:
        """Exactly what `deepphy report` makes of the records read so far."""
        if self._report is None or self._report[0] != self.version:
            self._report = (self.version, build_report(self.config, self.tasks, self.records, self.k_max))
        return self._report[1]

    def report_json(self) -> dict[str, Any]:
        """What `deepphy report --json` prints for the records read so far."""
        return self.report().to_json()

    def partial_report(self, report: Report) -> Report | None:
        """While episodes are unfinished: the report over the finished ones alone (what the
        page's rates show, marked partial with the finished count); None once all are done."""
        done, total = report.episodes_done()
        if done == total:
            return None
        return build_report(self.config, self.tasks, self.records, self.k_max, finished_only=True)

    def curve(self, report: Report) -> dict[str, Any]:
        """The success curve the report implies, mean and std over runs: within k attempts
        (K > 1), else within k decisions, k = 1..max (one attempt of many decisions)."""
        m, s = report.overall.mean, report.overall.std
        if report.max_attempts > 1 or m.success_by_step is None:
            return {"kind": "attempts", "x": list(range(1, report.max_attempts + 1)),
                    "mean": m.success_at, "std": s.success_at}
        return {"kind": "decisions", "noun": report.step_noun, "x": list(range(1, len(m.success_by_step) + 1)),
                "mean": m.success_by_step, "std": s.success_by_step,
                "checkpoints": [int(k) for k in m.success_within_steps or {}]}

    def progress(self, report: Report, now: float | None = None) -> dict[str, Any]:
        now = time.time() if now is None else now
        per_run = report.overall.per_run
        done = sum(r.tasks - r.unfinished for r in per_run)
        total = report.overall.tasks * report.runs
        attempts = sum(r.attempts for r in per_run)
        writing = writer_holds_lock(self.path)
        if writing is None:  # no /proc/locks: a log that grew in the last half minute is live
            writing = now - (self.path / ATTEMPTS).stat().st_mtime < 30 if self.log_size else False
        rate = eta = phase = None
        if writing:
            # the driver's phase (starting, compiling, running): its live snapshot, else its status file
            status_file = read_status(self.path)
            phase = (self.snapshot or {}).get("phase") or (status_file.phase if status_file else None)
            cutoff = now - RATE_WINDOW_S
            span = min(RATE_WINDOW_S, now - (self._first_started or now))
            if span > 1:
                rate = (len(self._finished) - bisect.bisect_left(self._finished, cutoff)) / span
                ended = sum(1 for t in self._episode_ends.values() if t >= cutoff)
                eta = (total - done) / (ended / span) if ended else None
            if self.snapshot and self.snapshot.get("attempts_per_s") is not None:  # the live run's own figure
                rate = self.snapshot["attempts_per_s"]
        elif len(self._finished) > 1 and self._first_started:
            rate = len(self._finished) / max(self._finished[-1] - self._first_started, 1e-9)
        status = "running" if writing else "complete" if done == total else "incomplete"
        return {"status": status, "phase": phase, "episodes_done": done, "episodes_total": total, "attempts": attempts,
                "attempts_per_s": rate, "eta_s": eta, "loading": self.loading,
                "bytes_read": self.offset, "bytes_total": self.log_size}

    def view(self) -> dict[str, Any]:
        """Everything a run's card, curve and table show. Every rate is over finished
        episodes: while some are not, from the partial report (`partial` says how many are
        done); `report` is always the whole one, as `deepphy report --json` prints it."""
        report = self.report()
        partial = self.partial_report(report)
        shown = partial or report
        totals = totals_of(report)
        header, rows = table([shown])
        done, total = report.episodes_done()
        stars, human_time = shown.overall.mean.stars, report.human_time
        return {
            "id": self.id, "path": str(self.path), "name": self.path.name, "label": report.setting,
            "env": report.env, "title": report.title, "model": report.model, "format": report.format,
            "env_options": report.env_options, "runs": report.runs, "k_max": report.max_attempts,
            "groups": sorted({t.group for t in self.tasks if t.group}), "tasks": len(self.tasks),
            "n": report.sample_size(), "human": is_human(report.model),
            "human_time": None if human_time is None else human_time.model_dump(),
            "partial": None if partial is None else {"finished": done, "total": total},
            "solved_rate": shown.overall.mean.success_at[shown.max_attempts - 1],
            "version": self.version, "progress": self.progress(report), "totals": totals,
            "curve": self.curve(shown), "stars": None if stars is None else stars.model_dump(),
            "table": {"header": header, "rows": rows, "key": table_key([shown])}, "report": report.to_json(),
            "errors": self.errors[-5:], "live": self.snapshot is not None,
        }

    # -- grid ---------------------------------------------------------------------------

    def _cell(self, key: tuple[str, int]) -> Cell:
        if key in self._cells:
            return self._cells[key]
        attempts = self.episodes.get(key)
        if not attempts:
            return Cell("pending")
        e = F.episodes(attempts.values(), self.k_max)[0]
        state = "solved" if e.solved else "failed" if e.finished else "progress"
        self._cells[key] = cell = Cell(state, e.attempts, e.solved_at, e.invalid, e.stars, e.steps_to_solve)
        return cell

    def cells(self, keys: set[tuple[str, int]]) -> list[list[Any]]:
        """[task, run, *cell] for each episode, in task order."""
        keys = [k for k in keys if k[0] in self.task_index and k[1] < self.config.runs]
        keys.sort(key=lambda k: (self.task_index[k[0]], k[1]))
        return [[task, run, *self._cell((task, run)).as_json()] for task, run in keys]

    def grid(self, page: int = 0, group: str | None = None, page_size: int = GRID_PAGE) -> dict[str, Any]:
        tasks = [t for t in self.tasks if not group or t.group == group]
        pages = max(1, -(-len(tasks) // page_size))
        page = min(max(page, 0), pages - 1)
        shown = tasks[page * page_size : (page + 1) * page_size]
        return {
            "run": self.id, "page": page, "pages": pages, "page_size": page_size, "group": group or "",
            "runs": self.config.runs, "k_max": self.k_max, "max_steps": self.max_steps, "tasks_total": len(tasks),
            "tasks": [[t.id, t.group] for t in shown],
            "cells": [[self._cell((t.id, r)).as_json() for r in range(self.config.runs)] for t in shown],
        }

    # -- the episode browser's list -----------------------------------------------------

    def samples(self) -> dict[str, Any]:
        """Every episode recorded so far, one row each, for the page's filterable list (in
        task order, then run): its outcome, attempts, decisions, invalid attempts and the kind
        of the last one's reason (numbers made N, so that alike reasons filter together),
        stars, the agent's time to decide (a person's or the model's), tokens, and words to
        search (the outcome, the actions)."""
        rows = []
        for (task, run) in sorted(self.episodes, key=lambda k: (self.task_index.get(k[0], 0), k[1])):
            if task not in self.task_index or run >= self.config.runs:
                continue
            attempts = sorted(self.episodes[(task, run)].values(), key=lambda r: r.attempt)
            cell = self._cell((task, run))
            reasons = [r.invalid_reason for r in attempts if r.invalid_reason]
            actions = "; ".join(s.action_text or s.raw_output[:60] for r in attempts for s in r.steps)
            rows.append([
                task, self.tasks[self.task_index[task]].group, run, cell.state, cell.attempts, cell.solved_at,
                sum(len(r.steps) for r in attempts), cell.invalid, reason_kind(reasons[-1]) if reasons else None,
                cell.stars, round(sum(sum(r.timing.decision_s) for r in attempts), 3),
                sum(r.model_stats.usage.input_tokens + r.model_stats.usage.output_tokens for r in attempts),
                f"{attempts[-1].feedback} {actions}"[:SEARCH_CHARS],
            ])
        return {"run": self.id, "human": is_human(self.config.model), "k_max": self.k_max, "runs": self.config.runs,
                "columns": SAMPLE_COLUMNS, "rows": rows}

    # -- one episode --------------------------------------------------------------------

    def episode(self, task: str, run: int) -> dict[str, Any]:
        if task not in self.task_index:
            raise KeyError(f"no task {task!r} in this run")
        records = sorted(self.episodes.get((task, run), {}).values(), key=lambda r: r.attempt)
        prompts: dict[str, Any] = {}
        attempts = []
        try:
            logged = episode_prompts(self.path, task, run)  # read once for the whole episode
        except RunDirError:
            logged = {}  # its prompts are shown as missing
        images: dict[str, str | None] = {}  # what is wrong with each image, checked once for the episode
        for r in records:
            for s in r.steps:
                if s.prompt not in prompts:
                    prompts[s.prompt] = self._prompt(task, run, s.prompt, logged, images)
            attempts.append(r.model_dump(mode="json"))
        return {
            "run_id": self.id, "task": task, "run": run, "group": self.tasks[self.task_index[task]].group,
            "label": self.label, "env": self.config.env, "k_max": self.k_max,
            "max_steps": self.max_steps, "cell": self._cell((task, run)).as_json(),
            "attempts": attempts, "prompts": prompts,
        }

    def _prompt(self, task: str, run: int, digest: str, logged: dict[str, list],
                images: dict[str, str | None]) -> list[dict[str, Any]] | None:
        """The prompt's messages (`logged`: the episode's prompt log), each image resolved to
        its stored file: images/<sha256>.png (runs before images/ kept only history key
        frames, under frames/<task>/ by name), or what is wrong with it (`images`: found so
        far, by digest; "" when it is fine). None if the prompt is missing or malformed."""
        try:
            messages = stored_prompt_json(self.path, task, run, digest, logged)
        except RunDirError:
            return None
        out = []
        for m in messages:
            parts = []
            for text in m["content"]:
                ref = stored_image(text)
                if ref is not None:
                    digest, name, caption = ref
                    if digest not in images:
                        try:
                            images[digest] = "" if read_image(self.path, digest) is not None else None
                        except RunDirError as e:
                            images[digest] = str(e)
                    problem = images[digest]
                    parts.append({"type": "image", "name": name, "caption": caption,
                                  "file": f"{IMAGES}/{digest}.png" if problem == "" else None,
                                  **({"problem": problem} if problem else {})})
                    continue
                image = OLD_IMAGE_PLACEHOLDER.match(text)
                if image is None:
                    parts.append({"type": "text", "text": text})
                    continue
                name, caption = image.groups()
                frame = inside(self.path, f"{FRAMES}/{task}/{name}") if "/" not in name else None
                stored = frame is not None and frame.parent == self.path / FRAMES / task and frame.is_file()
                parts.append({"type": "image", "name": name, "caption": caption,
                              "file": f"frames/{task}/{name}" if stored else None})
            out.append({"role": m.get("role"), "content": parts})
        return out

    def frame_path(self, rel: str) -> Path | None:
        """A key frame under frames/ of this run directory (resolved inside it: symlinks out of
        the directory are not followed), or None. (Prompt images: `image`.)"""
        target = inside(self.path, rel)
        if target is None or target.suffix != ".png" or not target.is_relative_to(self.path / FRAMES):
            return None
        return target if target.is_file() else None

    def image(self, rel: str) -> bytes | None:
        """The bytes of a prompt image, images/<sha256>.png, checked against its name
        (`read_image`: RunDirError if damaged); None if `rel` names no stored image."""
        name = rel.removeprefix(f"{IMAGES}/").removesuffix(".png")
        if f"{IMAGES}/{name}.png" != rel or not IMAGE_DIGEST.match(name):
            return None
        return read_image(self.path, name)



def totals_of(report: Report) -> dict[str, Any]:
    """The counts a run's card shows, summed over its runs (the registry's totals)."""
    return {m.key: sum(getattr(r, m.key) for r in report.overall.per_run) for m in registry.metrics("run") if m.total}


SAMPLE_COLUMNS = ["task", "group", "run", "state", "attempts", "solved_at", "decisions", "invalid", "reason", "stars",
                  "seconds", "tokens", "words"]
SEARCH_CHARS = 400  # of an episode's outcome and actions, searched by the page


def reason_kind(reason: str) -> str:
    """An invalid reason with its numbers made N: alike reasons filter together."""
    return re.sub(r"-?\d+(?:\.\d+)?", "N", reason)[:120]
