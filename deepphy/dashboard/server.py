"""The dashboard's web server (aiohttp): static page, JSON API, live updates over
Server-Sent Events.

Every run directory is polled by a loop and a thread of its own (stat, then only the new
whole lines of its log), so a huge or broken run does not hold up the others; when a run
changed, its view (card, curve, report table) is recomputed, throttled for large runs, and
pushed to every open page with the grid cells that changed. With a Ray address, the runs
live on that cluster are found by their metrics actors and their run directories added.
A directory of runs given (a suite root) also has a leaderboard, made by the code of
`deepphy leaderboard` from the reports the runs' views already hold (and the manifest's
cells not started), and pushed again whenever one of its runs changed.
Who may read it: `deepphy.webguard` (a loopback Host without a token; the token beyond loopback).
"""

from __future__ import annotations

import asyncio
import logging
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from aiohttp import web

from deepphy import webguard
from deepphy.config import RuntimeOptions
from deepphy.dashboard.source import RunSource
from deepphy.metrics import registry
from deepphy.metrics.leaderboard import LeaderboardError, as_dict, leaderboard, not_started
from deepphy.metrics.report import Report, setting_label
from deepphy.play import replay
from deepphy.ray_connect import ensure_ray
from deepphy.runs.discovery import dir_id, is_run_dir, live_snapshots, runs_in
from deepphy.runs.store import IMAGES, RunDirError
from deepphy.webserve import HEARTBEAT, HEARTBEAT_S, event_stream, listen, sse

log = logging.getLogger(__name__)

STATIC = Path(__file__).parent / "static"
POLL_S = 0.25  # how often each run directory is checked for new records (a stat, usually)
REFRESH_S = 2.0  # a view is re-sent at least this often while its run is live (rate, ETA)
LIVE_POLL_S = 2.0  # how often the Ray cluster is asked for its live runs
SCAN_S = 1.0  # how often watched directories are looked through for new run directories
BOARD_S = 1.0  # a directory's leaderboard is made again at most this often while its runs change
MAX_CELL_DELTA = 5000  # beyond this many changed cells, pages re-fetch their grid page
CLIENT_BACKLOG = 200  # messages queued for a page that does not read; then it is dropped


class Dashboard:
    def __init__(self, sources: list[RunSource], roots: list[Path] = (), address: str | None = None,
                 poll_s: float = POLL_S) -> None:
        self.sources: dict[str, RunSource] = {}
        # Directories that are not (yet) run directories: a run started into one, or a run
        # directory created inside one, joins the page when it appears.
        self.roots = [Path(r).resolve() for r in roots]
        self._unreadable: set[Path] = set()
        self.address = address
        self.poll_s = poll_s
        self.views: dict[str, dict[str, Any]] = {}  # latest view per run
        # Runs load side by side, so their first views arrive in any order; each view carries
        # the place of its run (as given, then as found) and the page keeps that order.
        self._order: dict[str, int] = {}
        self.live_only: dict[str, dict[str, Any]] = {}  # Ray run id -> view, when its directory is not readable
        self.boards: dict[str, dict[str, Any]] = {}  # root's id -> its leaderboard view
        self._boards_dirty = True
        self._not_started: dict[str, dict[str, Any]] = {}  # reports of manifest cells with no run yet
        self.clients: set[asyncio.Queue] = set()
        # Each run has a thread of its own (RunSource is not thread-safe, and a huge or broken
        # run must not hold up the others' polls and API calls); finding runs has another.
        self.executor = ThreadPoolExecutor(1, thread_name_prefix="dashboard-find")
        self._threads: dict[str, ThreadPoolExecutor] = {}
        self._pending: dict[str, set | None] = {}  # run id -> changed cells not yet sent (None: all)
        self._sent_at: dict[str, float] = {}
        self._cost: dict[str, float] = {}  # seconds the last view took: throttles large runs
        self._tasks: list[asyncio.Task] = []
        self._started = False
        for source in sources:
            self._add(source)

    def _place(self, view: dict[str, Any]) -> dict[str, Any]:
        view["order"] = self._order.setdefault(view["id"], len(self._order))
        self.views[view["id"]] = view
        return view

    def _add(self, source: RunSource) -> None:
        self._order.setdefault(source.id, len(self._order))
        self.sources[source.id] = source
        self._threads[source.id] = ThreadPoolExecutor(1, thread_name_prefix=f"dashboard-{source.id}")
        if self._started:
            self._tasks.append(asyncio.create_task(self._run_loop(source)))

    async def _call(self, source: RunSource | None, fn, *args):
        """`fn(*args)` on `source`'s thread (None: the thread that finds runs)."""
        executor = self.executor if source is None else self._threads[source.id]
        return await asyncio.get_running_loop().run_in_executor(executor, fn, *args)

    # -- lifecycle ----------------------------------------------------------------------

    async def start(self, app: web.Application) -> None:
        self._started = True
        self._tasks += [asyncio.create_task(self._run_loop(s)) for s in self.sources.values()]
        if self.roots:
            self._tasks.append(asyncio.create_task(self._scan_loop()))
            self._tasks.append(asyncio.create_task(self._board_loop()))
        if self.address:
            self._tasks.append(asyncio.create_task(self._live_loop()))

    async def stop(self, app: web.Application) -> None:
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        for q in list(self.clients):
            q.put_nowait(None)
        for executor in [self.executor, *self._threads.values()]:
            executor.shutdown(wait=False, cancel_futures=True)

    # -- updates ------------------------------------------------------------------------

    async def _scan_loop(self) -> None:
        while True:
            await self._scan_roots()
            await asyncio.sleep(SCAN_S)

    async def _run_loop(self, source: RunSource) -> None:
        """Poll one run, at its own pace."""
        while True:
            started = time.monotonic()
            try:
                await self._poll(source)
            except Exception:  # noqa: BLE001 - a bad moment of one run; try again
                log.exception("polling %s", source.path)
            await asyncio.sleep(max(0.05, self.poll_s - (time.monotonic() - started)))

    async def _poll(self, source: RunSource) -> None:
        changed = await self._call(source, source.poll)
        pending = self._pending.setdefault(source.id, set())
        if changed is None or pending is None:
            self._pending[source.id] = None
        else:
            pending |= changed
        now = time.monotonic()
        since = now - self._sent_at.get(source.id, 0.0)
        shown = self.views.get(source.id)
        # New records, a refused line (the version), or a load that ended (the page said "loading")
        dirty = (self._pending[source.id] is None or bool(self._pending[source.id]) or shown is None
                 or shown["version"] != source.version or shown["progress"]["loading"] != source.loading)
        live = (shown or {}).get("progress", {}).get("status") == "running"
        # A large run's report takes a while: wait twice its cost between views, so that the
        # worker thread is never busy more than a third of the time.
        if not (dirty and since >= 2 * self._cost.get(source.id, 0.0)) and not (live and since >= REFRESH_S):
            return
        t0 = time.monotonic()
        view = await self._call(source, source.view)
        self._cost[source.id] = time.monotonic() - t0
        keys = self._pending[source.id]
        reset = keys is None or len(keys) > MAX_CELL_DELTA
        cells = [] if reset else await self._call(source, source.cells, keys)
        self._pending[source.id] = set()
        self._sent_at[source.id] = time.monotonic()
        self._place(view)
        self._broadcast({"type": "run", "run": view, "cells": cells, "grid_reset": reset})
        self._boards_dirty |= any(source.path.is_relative_to(root) for root in self.roots)

    async def _scan_roots(self) -> None:
        known = {s.path for s in self.sources.values()}
        removed = False
        for root in self.roots:
            found = await self._call(None, runs_in, root)
            for path in found:
                if path in known or path in self._unreadable:
                    continue
                try:
                    source = await self._call(None, RunSource, path)
                except Exception as e:  # noqa: BLE001 - say so once, keep the others going
                    log.warning("cannot show %s: %s", path, e)
                    self._unreadable.add(path)
                    continue
                self._add(source)  # its first view goes out with its first poll
                known.add(path)
            waiting = f"wait-{dir_id(root)}"
            if found and waiting in self.views:
                del self.views[waiting]
                removed = True
            elif not found and waiting not in self.views:
                self._place(waiting_view(waiting, root))
                self._broadcast({"type": "run", "run": self.views[waiting], "cells": [], "grid_reset": False})
        if removed:  # pages drop the placeholder by taking the whole state again
            data = sse("state", self.state())
            for q in list(self.clients):
                q.put_nowait(data)

    async def _board_loop(self) -> None:
        while True:
            if self._boards_dirty:
                self._boards_dirty = False
                for root in self.roots:
                    try:
                        await self._update_board(root)
                    except Exception:  # noqa: BLE001 - a bad moment of one root; try again
                        log.exception("leaderboard of %s", root)
                        self._boards_dirty = True
            await asyncio.sleep(BOARD_S)

    async def _update_board(self, root: Path) -> None:
        mine = [s for s in self.sources.values() if s.path.is_relative_to(root)]
        reports = {s.path: await self._call(s, s.report) for s in mine if self.views.get(s.id, {}).get("report")}
        view = await self._call(None, self._board_view, root, {s.path for s in mine}, reports)
        if view is None or self.boards.get(view["id"]) == view:
            return
        self.boards[view["id"]] = view
        self._broadcast({"type": "leaderboard", "board": view})

    def _board_view(self, root: Path, started: set[Path], reports: dict[Path, Report]) -> dict[str, Any] | None:
        """The leaderboard of the runs below `root` (None while there is nothing to show)."""
        view = {"id": f"board-{dir_id(root)}", "path": str(root), "name": root.name, "board": None, "error": None}
        try:
            reports = {**reports, **not_started(root, started, self._not_started)}
            if not reports:
                return None
            view["board"] = as_dict(leaderboard(list(reports.values()), [str(p) for p in reports]))
        except (LeaderboardError, RunDirError) as e:
            view["error"] = str(e)
        return view

    async def _live_loop(self) -> None:
        await asyncio.to_thread(ensure_ray, RuntimeOptions(address=self.address))
        while True:
            try:
                snapshots = await asyncio.to_thread(live_snapshots)
                await self._merge_live(snapshots)
            except Exception:  # noqa: BLE001 - a cluster hiccup: try again
                log.exception("asking %s for live runs", self.address)
            await asyncio.sleep(LIVE_POLL_S)

    async def _merge_live(self, snapshots: dict[str, dict[str, Any]]) -> None:
        by_path = {str(s.path): s for s in self.sources.values()}
        found = set()
        for ray_id, snap in snapshots.items():
            run_dir = snap.get("run_dir")
            path = str(Path(run_dir).resolve()) if run_dir else None
            if path and path not in by_path and is_run_dir(Path(path)):
                try:
                    source = await self._call(None, RunSource, path)
                except Exception:  # noqa: BLE001 - unreadable here: show the snapshot only
                    log.warning("cannot read the run directory %s of live run %s", path, ray_id)
                else:
                    self._add(source)
                    by_path[path] = source
            if path in by_path:
                by_path[path].snapshot = snap
                found.add(by_path[path].id)
                self.live_only.pop(ray_id, None)
            else:
                view = live_only_view(ray_id, snap)
                self.live_only[ray_id] = self._place(view)
                self._broadcast({"type": "run", "run": view, "cells": [], "grid_reset": False})
        for source in self.sources.values():
            if source.id not in found:
                source.snapshot = None
        for ray_id, view in self.live_only.items():
            if ray_id not in snapshots and view["progress"]["status"] == "running":
                view["progress"]["status"] = "ended"
                self._broadcast({"type": "run", "run": view, "cells": [], "grid_reset": False})

    def _broadcast(self, message: dict[str, Any]) -> None:
        data = sse("message", message)
        for q in list(self.clients):
            if q.qsize() > CLIENT_BACKLOG:
                self.clients.discard(q)
                q.put_nowait(None)  # the page reconnects and gets the whole state again
            else:
                q.put_nowait(data)

    # -- HTTP ---------------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        return {"runs": sorted(self.views.values(), key=lambda v: v["order"]), "address": self.address,
                "boards": list(self.boards.values())}

    async def index(self, request: web.Request) -> web.StreamResponse:
        return web.FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-cache"})

    async def api_state(self, request: web.Request) -> web.Response:
        return web.json_response(self.state())

    def _source(self, request: web.Request) -> RunSource:
        source = self.sources.get(request.match_info["run"])
        if source is None:
            raise web.HTTPNotFound(text="no such run")
        return source

    async def api_report(self, request: web.Request) -> web.Response:
        source = self._source(request)
        return web.json_response(await self._call(source, source.report_json))

    async def api_grid(self, request: web.Request) -> web.Response:
        source = self._source(request)
        try:
            page = int(request.query.get("page", "0"))
        except ValueError:
            raise web.HTTPBadRequest(text="page must be an integer") from None
        group = request.query.get("group") or None
        return web.json_response(await self._call(source, source.grid, page, group))

    async def api_samples(self, request: web.Request) -> web.Response:
        source = self._source(request)
        return web.json_response(await self._call(source, source.samples))

    async def api_episode(self, request: web.Request) -> web.Response:
        source = self._source(request)
        try:
            task, run = request.query["task"], int(request.query["run"])
            return web.json_response(await self._call(source, source.episode, task, run))
        except (KeyError, ValueError) as e:
            raise web.HTTPNotFound(text=f"no such episode: {e}") from None

    async def frame(self, request: web.Request) -> web.StreamResponse:
        """A key frame (frames/...) or a prompt image (images/<sha256>.png, served only if its
        bytes hash to its name)."""
        source = self._source(request)
        rel = request.match_info["path"]
        if rel.startswith(f"{IMAGES}/"):
            try:
                png = await self._call(source, source.image, rel)
            except RunDirError as e:
                raise web.HTTPConflict(text=str(e)) from None
            if png is None:
                raise web.HTTPNotFound(text="no such image")
            return web.Response(body=png, content_type="image/png", headers={"Cache-Control": "max-age=3600"})
        path = source.frame_path(rel)
        if path is None:
            raise web.HTTPNotFound(text="no such frame")
        return web.FileResponse(path, headers={"Cache-Control": "max-age=3600"})  # frames never change

    async def events(self, request: web.Request) -> web.StreamResponse:
        response = await event_stream(request)
        queue: asyncio.Queue = asyncio.Queue()
        self.clients.add(queue)
        try:
            await response.write(sse("state", self.state()))
            while True:
                try:
                    data = await asyncio.wait_for(queue.get(), HEARTBEAT_S)
                except asyncio.TimeoutError:
                    data = HEARTBEAT
                if data is None:
                    break
                await response.write(data)
        except (ConnectionResetError, asyncio.CancelledError):
            pass
        finally:
            self.clients.discard(queue)
        return response


def live_only_view(ray_id: str, snap: dict[str, Any]) -> dict[str, Any]:
    """A live run whose directory this machine cannot read: the metrics actor's figures."""
    config = snap.get("config") or {}
    label = setting_label(config.get("model", "?"), config.get("format", "?"), config.get("env_options", {}),
                          config.get("prompts", "before-parity"))
    done, total = snap.get("episodes_done", 0), snap.get("episodes_total", 0)
    return {
        "id": f"ray-{ray_id}", "path": snap.get("run_dir", ""), "name": ray_id, "label": label,
        "env": config.get("env", "?"), "model": config.get("model", "?"), "format": config.get("format", "?"),
        "live_only": True, "live": True,
        "progress": {"status": "running", "phase": snap.get("phase"), "episodes_done": done, "episodes_total": total,
                     "attempts": snap.get("attempts", 0), "attempts_per_s": snap.get("attempts_per_s"),
                     "eta_s": snap.get("eta_s"), "loading": False},
        "totals": {m.key: snap.get(m.key, 0) for m in registry.metrics("run") if m.total},
        "curve": None, "stars": None, "table": None, "report": None, "errors": [],
        "note": "the run directory is not readable from here: the live snapshot of its metrics actor",
    }


def waiting_view(view_id: str, root: Path) -> dict[str, Any]:
    """A directory given on the command line that holds no run yet."""
    return {
        "id": view_id, "path": str(root), "name": root.name, "label": "no run yet", "env": "waiting",
        "model": "", "format": "", "waiting": True, "live": False,
        "progress": {"status": "waiting", "episodes_done": 0, "episodes_total": 0, "attempts": 0,
                     "attempts_per_s": None, "eta_s": None, "loading": False},
        "totals": dict.fromkeys(("solved", "attempts", "invalid_attempts", "model_errors", "retries",
                                 "input_tokens", "output_tokens", "cost_usd"), 0),
        "curve": None, "stars": None, "table": None, "report": None, "errors": [],
        "note": "waiting for a run directory here (a `deepphy run --out` into it, or one created inside it)",
    }


TOKEN_COOKIE = "deepphy_dashboard_token"
TOKEN_ENV = "DEEPPHY_DASHBOARD_TOKEN"  # a fixed token, instead of a new one at every start


def make_app(dashboard: Dashboard, token: str | None = None) -> web.Application:
    """`token`: required of every request (deepphy.webguard); None serves loopback Hosts only."""
    app = web.Application(middlewares=[webguard.middleware(token, TOKEN_COOKIE, "this dashboard")])
    app.add_routes([
        web.get("/", dashboard.index),
        web.get("/api/state", dashboard.api_state),
        web.get("/api/events", dashboard.events),
        web.get("/api/runs/{run}/report", dashboard.api_report),
        web.get("/api/runs/{run}/grid", dashboard.api_grid),
        web.get("/api/runs/{run}/episode", dashboard.api_episode),
        web.get("/api/runs/{run}/samples", dashboard.api_samples),
        web.get("/files/{run}/{path:.+}", dashboard.frame),
        web.static("/static", STATIC),
    ])
    replay.add_routes(app, lambda rid: dashboard.sources[rid].path if rid in dashboard.sources else None)
    app.on_startup.append(dashboard.start)
    app.on_shutdown.append(dashboard.stop)
    return app


async def serve(dashboard: Dashboard, host: str, port: int, announce, token: str | None = None) -> None:
    """Serve until cancelled; `announce(url)` is called once the socket listens."""
    runner, url = await listen(make_app(dashboard, token), host, port, token)
    announce(url)
    try:
        await asyncio.Event().wait()
    finally:
        await runner.cleanup()
