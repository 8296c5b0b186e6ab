"""Watching a recorded attempt (a model's or a person's) as an animation of the world.

The environments are deterministic, so an attempt is replayed by simulating its recorded
actions again from the task's initial state, through `Environment.film`: `step` with
pictures of the world while it runs (FILM_FPS per simulated second where the environment
films; its key frames where it does not). Each decision's result is compared with the
record: a replay that does not reproduce the record (the environment's code changed since)
says so rather than show something else as what happened.

The film is served to a page (`replay.html`) as JPEG pictures; the play server serves the
replays of its run and the dashboard those of every run it shows (`add_routes`).
"""

from __future__ import annotations

import asyncio
import hashlib
from collections import OrderedDict
from pathlib import Path
from typing import Any, Callable

import cv2
import numpy as np
from aiohttp import web

from deepphy.envs import InvalidAction
from deepphy.envs.base import FILM_FPS, Environment
from deepphy.plan import plan
from deepphy.play.background import off_loop
from deepphy.play.human import remember
from deepphy.runs.records import AttemptRecord, StepRecord
from deepphy.runs.store import RunDirError, read_config, read_records

STATIC = Path(__file__).parent / "static"
JPEG_QUALITY = 85
FILMS_KEPT = 4  # films held in memory (each a few MB of JPEG)


class Film:
    """The pictures of one replayed attempt, with what each decision did."""

    def __init__(self, run_dir: str | Path, record: AttemptRecord) -> None:
        self.record = record
        self.id = film_key(run_dir, *record.key)
        self.pictures: list[bytes] = []  # JPEG
        self.captions: list[str] = []
        self.decisions: list[dict[str, Any]] = []  # per decision: its first picture, action, what happened
        self.filmed = True  # False: the environment only gave its key frames
        self.matches = True  # every decision's result equals the record's
        self.note = ""

    def add(self, rgb: np.ndarray, caption: str) -> None:
        ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR),
                                [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        assert ok
        self.pictures.append(jpeg.tobytes())
        self.captions.append(caption)

    def view(self, url: Callable[[int], str]) -> dict[str, Any]:
        r = self.record
        return {
            "id": self.id, "env": r.env, "task": r.task, "run": r.run, "attempt": r.attempt, "model": r.model,
            "success": r.success, "stars": r.stars, "outcome": r.feedback, "filmed": self.filmed,
            "matches": self.matches, "note": self.note, "fps": FILM_FPS,
            "pictures": [{"url": url(i), "caption": c} for i, c in enumerate(self.captions)],
            "decisions": self.decisions,
        }


def film_attempt(run_dir: str | Path, task_id: str, run: int, attempt: int) -> Film:
    """Replay attempt `attempt` of `task_id` in repetition `run` of a run directory.
    KeyError if the run directory holds no such attempt, or its task is not the run's;
    RunDirError if the directory cannot be read."""
    config = read_config(run_dir)
    record = next((r for r in read_records(run_dir) if r.key == (task_id, run, attempt)), None)
    if record is None:
        raise KeyError(f"no attempt {attempt} of {task_id} run {run} in {run_dir}")
    the_plan = plan(config)
    task = next((t for t in the_plan.tasks if t.id == task_id), None)
    if task is None:  # a record the run could not have made (edited, or copied from another run)
        raise KeyError(f"the record's task {task_id} is not one of this run's {config.env} tasks")
    env = the_plan.make_env()
    observation = env.reset(task)
    film = Film(run_dir, record)
    film.add(observation.images[0].to_array(), "before the first decision")
    for step in record.steps:
        film.decisions.append({"step": step.step, "picture": len(film.pictures), "action": step.action_text,
                               "feedback": step.feedback, "invalid_reason": step.invalid_reason})
        if step.action_text is None or observation is None:  # the reply did not parse: nothing was done
            break
        try:
            action = observation.action_space.parse(step.action_text)
        except InvalidAction as e:
            film.matches, film.note = False, f"decision {step.step}: the recorded action no longer parses ({e})"
            break
        result, pictures = env.film(action)
        if type(env).film is Environment.film:
            film.filmed = False
        for picture in pictures:
            film.add(picture.rgb, f"decision {step.step} ({step.action_text}): {picture.caption}")
        if not same_result(step, result):
            film.matches = False
            film.note = (f"decision {step.step}: the replay's result differs from the record (the environment "
                         f"changed since?): replayed '{result.feedback}', recorded '{step.feedback}'")
            break
        observation = result.observation
        if observation is not None:
            film.add(observation.images[0].to_array(), f"after decision {step.step}: the next observation")
    if not film.filmed:
        film.note = film.note or f"{the_plan.spec.title} does not film its steps: these are the key frames of each decision"
    return film


def same_result(step: StepRecord, result) -> bool:
    return (step.feedback, step.terminated, step.truncated, step.invalid_reason) == (
        result.feedback, result.terminated, result.truncated, result.invalid_reason)


class Films:
    """Films made on demand (in a thread: physics and encoding take seconds), the latest kept."""

    def __init__(self) -> None:
        self._films: OrderedDict[str, Film] = OrderedDict()  # by film id
        self._making: dict[str, asyncio.Future] = {}

    async def get(self, run_dir: Path, task: str, run: int, attempt: int) -> Film:
        film_id = film_key(run_dir, task, run, attempt)
        if film_id in self._films:
            return self._films[film_id]
        if film_id not in self._making:
            self._making[film_id] = asyncio.ensure_future(off_loop(film_attempt, run_dir, task, run, attempt))
        making = self._making[film_id]
        try:
            film = await asyncio.shield(making)
        finally:
            if making.done():
                self._making.pop(film_id, None)
        remember(self._films, film_id, film, FILMS_KEPT)
        return film

    def picture(self, film_id: str, index: int) -> bytes | None:
        film = self._films.get(film_id)
        if film is None or not 0 <= index < len(film.pictures):
            return None
        return film.pictures[index]


def film_key(run_dir: str | Path, task: str, run: int, attempt: int) -> str:
    return hashlib.sha1(repr((str(run_dir), task, run, attempt)).encode()).hexdigest()[:16]


def add_routes(app: web.Application, run_dir_of: Callable[[str], Path | None],
               may_replay: Callable[[str, int], str | None] = lambda task, run: None) -> None:
    """The replay page and its API on a server: `run_dir_of(run id)` names the run
    directories it may replay (None: not one of them); `may_replay(task, run)` says why an
    episode's attempts may not be replayed yet (None: they may)."""
    films = Films()

    async def page(request: web.Request) -> web.StreamResponse:
        return web.FileResponse(STATIC / "replay.html", headers={"Cache-Control": "no-cache"})

    async def film(request: web.Request) -> web.Response:
        run_dir = run_dir_of(request.match_info["run"])
        if run_dir is None:
            raise web.HTTPNotFound(text="no such run")
        try:
            task, run, attempt = request.query["task"], int(request.query["run"]), int(request.query["attempt"])
            refused = may_replay(task, run)
            if refused:
                raise web.HTTPForbidden(text=refused)
            made = await films.get(run_dir, task, run, attempt)
        except (KeyError, ValueError) as e:
            raise web.HTTPNotFound(text=f"no such attempt: {e.args[0] if e.args else e}") from None
        except RunDirError as e:  # the page shows the line
            raise web.HTTPConflict(text=str(e)) from None
        base = f"/api/runs/{request.match_info['run']}/replay/{made.id}"
        return web.json_response(made.view(lambda i: f"{base}/{i}.jpg"))

    async def picture(request: web.Request) -> web.Response:
        try:
            index = int(request.match_info["index"])
        except ValueError:
            raise web.HTTPNotFound() from None
        data = films.picture(request.match_info["film"], index)
        if data is None:
            raise web.HTTPNotFound(text="no such picture (the film is no longer kept: reload the page)")
        return web.Response(body=data, content_type="image/jpeg", headers={"Cache-Control": "max-age=3600"})

    app.add_routes([
        web.get("/replay", page),
        web.get("/api/runs/{run}/replay", film),
        web.get("/api/runs/{run}/replay/{film}/{index}.jpg", picture),
        web.get("/play-static/{name}", static_file),
    ])


async def static_file(request: web.Request) -> web.StreamResponse:
    """The play and replay pages' scripts and style (one directory, no listing)."""
    name = request.match_info["name"]
    path = STATIC / name
    if "/" in name or name.startswith(".") or not path.is_file():
        raise web.HTTPNotFound()
    return web.FileResponse(path, headers={"Cache-Control": "no-cache"})

