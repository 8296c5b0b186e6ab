"""What deepphy's two web servers, the dashboard and `deepphy play`, share besides their guard
(deepphy.webguard): how they listen and say their address, and their event streams
(server-sent events: the state, then what changes)."""

from __future__ import annotations

import json
from typing import Any

from aiohttp import web

# An idle event stream gets a comment line this often: the connection does not look dead to a
# proxy, and a page gone away is noticed (the write fails).
HEARTBEAT_S = 15.0
HEARTBEAT = b": heartbeat\n\n"


def sse(event: str, payload: Any) -> bytes:
    """One server-sent event, its data `payload` as compact JSON."""
    return f"event: {event}\ndata: {json.dumps(payload, separators=(',', ':'))}\n\n".encode()


async def event_stream(request: web.Request) -> web.StreamResponse:
    """The response to `request`, opened as an event stream (not cached, not held by a proxy)."""
    response = web.StreamResponse(headers={
        "Content-Type": "text/event-stream", "Cache-Control": "no-cache", "X-Accel-Buffering": "no"})
    await response.prepare(request)
    return response


async def listen(app: web.Application, host: str, port: int, token: str | None) -> tuple[web.AppRunner, str]:
    """Serve `app` on host:port (port 0: one the system picks). Returns the runner, for its
    cleanup, and the address to open, with `token` in it when there is one."""
    runner = web.AppRunner(app, access_log=None)
    await runner.setup()
    site = web.TCPSite(runner, host, port)
    await site.start()
    bound = runner.addresses[0]
    shown = f"[{bound[0]}]" if ":" in bound[0] else bound[0]  # IPv6 in a URL
    return runner, f"http://{shown}:{bound[1]}/" + (f"?token={token}" if token else "")
