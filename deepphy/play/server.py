"""The play page's web server (aiohttp): the page, the session's state as JSON and
Server-Sent Events, the images of the waiting prompt, the person's answers, replays.

Bound to 127.0.0.1 by default. Who may use it: `deepphy.webguard`, as for the dashboard (on
loopback, requests whose Host names this machine; beyond it, those that carry the token printed
with the URL). Requests that change something (an answer) must come from the page itself: a
JSON body, and an Origin (when the browser sends one) that is this server as the request
reached it, so another web site open in the same browser cannot answer for the person.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any, Callable

from aiohttp import web

from deepphy import webguard
from deepphy.envs import InvalidAction
from deepphy.play import replay
from deepphy.play.human import MAX_ANSWER_CHARS, StaleDecision
from deepphy.play.session import PlaySession
from deepphy.runs.discovery import dir_id
from deepphy.webserve import HEARTBEAT, HEARTBEAT_S, event_stream, listen, sse

STATIC = Path(__file__).parent / "static"
TOKEN_COOKIE = "deepphy_play_token"
TOKEN_ENV = "DEEPPHY_PLAY_TOKEN"  # a fixed token, instead of a new one at every start


class PlayServer:
    def __init__(self, session: PlaySession, token: str | None = None) -> None:
        """`token`: required of every request (`webguard.token_for`: None on loopback)."""
        self.session = session
        self.desk = session.desk
        self.token = token
        self.run_id = dir_id(session.path)

    # -- pages and state ------------------------------------------------------------------

    async def index(self, request: web.Request) -> web.StreamResponse:
        return web.FileResponse(STATIC / "play.html", headers={"Cache-Control": "no-cache"})

    def state(self) -> dict[str, Any]:
        return {**self.session.state(), "run_id": self.run_id}

    async def api_state(self, request: web.Request) -> web.Response:
        return web.json_response(self.state())

    async def events(self, request: web.Request) -> web.StreamResponse:
        """The state, again whenever it changes (a burst of changes sends it once)."""
        response = await event_stream(request)
        queue = self.desk.listen()
        try:
            await response.write(sse("state", self.state()))
            while True:
                try:
                    version = await asyncio.wait_for(queue.get(), HEARTBEAT_S)
                except asyncio.TimeoutError:
                    await response.write(HEARTBEAT)
                    continue
                await asyncio.sleep(0.02)  # a burst of changes: one state
                while version is not None and not queue.empty():
                    version = queue.get_nowait()
                if version is None:  # the server is stopping
                    break
                await response.write(sse("state", self.state()))
        except (ConnectionResetError, asyncio.CancelledError):
            pass
        finally:
            self.desk.unlisten(queue)
        return response

    async def prompt_image(self, request: web.Request) -> web.Response:
        """An image of the waiting prompt, or of one of the latest (the observation's are in
        memory only; a page may still be loading a decision's pictures once it is answered)."""
        images = self.desk.images.get(request.match_info["digest"], [])
        try:
            image = images[_index(request.match_info["index"])]
        except (ValueError, IndexError):
            raise web.HTTPNotFound(text="no such picture (that decision is long past: reload the page)") from None
        png = await asyncio.to_thread(image.load)
        return web.Response(body=png, content_type="image/png", headers={"Cache-Control": "max-age=3600"})

    # -- answers --------------------------------------------------------------------------

    async def _body(self, request: web.Request) -> tuple[str, str]:
        if not webguard.from_page(request.headers.get("Origin"), request.host, self.token):
            raise web.HTTPForbidden(text="answers come from the play page only")
        if request.content_type != "application/json":
            raise web.HTTPUnsupportedMediaType(text="send JSON")
        try:
            body = await request.json()
            key, text = body["key"], body["text"]
        except (ValueError, KeyError, TypeError):
            raise web.HTTPBadRequest(text='expected {"key": ..., "text": ...}') from None
        if not isinstance(key, str) or not isinstance(text, str):
            raise web.HTTPBadRequest(text="key and text must be strings")
        if len(text) > MAX_ANSWER_CHARS:
            raise web.HTTPBadRequest(text=f"an answer has at most {MAX_ANSWER_CHARS} characters")
        return key, text

    async def check(self, request: web.Request) -> web.Response:
        """Whether text is an action of the waiting decision: its canonical text, or the reason."""
        key, text = await self._body(request)
        pending = self.desk.pending
        if pending is None or pending.key != key:
            return web.json_response({"ok": False, "stale": True, "error": "this decision is no longer waiting"})
        try:
            return web.json_response({"ok": True, "action": pending.check(text)})
        except InvalidAction as e:
            return web.json_response({"ok": False, "error": str(e)})

    async def answer(self, request: web.Request) -> web.Response:
        key, text = await self._body(request)
        try:
            action = self.desk.answer(key, text)
        except StaleDecision as e:
            raise web.HTTPConflict(text=str(e)) from None
        except InvalidAction as e:
            raise web.HTTPBadRequest(text=f"not an action: {e}") from None
        return web.json_response({"ok": True, "action": action})

    def replay_run_dir(self, rid: str) -> Path | None:
        return self.session.path if rid == self.run_id else None

    def may_replay(self, task: str, run: int) -> str | None:
        """Why an attempt may not be replayed yet (None: it may): a task's replays open once
        its episode is over, as a model sees no replay before its next decision."""
        if self.session.episode_over(task, run):
            return None
        return ("this task is still being played: its replays open once it is over (a model sees none before its "
                "next decision)")


def _index(text: str) -> int:
    """A picture's index in a URL: a whole number from 0 (ValueError otherwise)."""
    if not text.isdigit():
        raise ValueError(text)
    return int(text)


def make_app(server: PlayServer) -> web.Application:
    app = web.Application(client_max_size=64 * 1024,
                          middlewares=[webguard.middleware(server.token, TOKEN_COOKIE, "this page")])
    app.add_routes([
        web.get("/", server.index),
        web.get("/api/state", server.api_state),
        web.get("/api/events", server.events),
        web.get("/api/prompt/{digest}/{index}.png", server.prompt_image),
        web.post("/api/check", server.check),
        web.post("/api/answer", server.answer),
    ])
    replay.add_routes(app, server.replay_run_dir, server.may_replay)

    async def end_streams(app: web.Application) -> None:  # open event streams end now, not at their next heartbeat
        server.desk.close()

    app.on_shutdown.append(end_streams)
    return app


async def serve(session: PlaySession, host: str, port: int, announce: Callable[[str], None],
                done: Callable[[dict[str, Any]], None], token: str | None = None) -> None:
    """Serve the page while the session plays, and after (replays) until cancelled.
    `announce(url)` is called once the socket listens, before the environment loads (the URL
    carries `token`, required of every request beyond loopback); `done(progress)` once every
    episode is played."""
    runner, url = await listen(make_app(PlayServer(session, token)), host, port, token)
    announce(url)
    try:
        await session.play()
        done(session.state()["progress"])
        await asyncio.Event().wait()
    finally:
        await runner.cleanup()
