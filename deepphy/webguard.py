"""Who may use deepphy's web pages: one guard for both servers, the dashboard and `deepphy play`.

A server listening on loopback (127.0.0.0/8, ::1, localhost) has no token and answers only
requests whose Host is a loopback name, so a web page elsewhere whose name resolves to this
machine (DNS rebinding) reads and changes nothing. A server listening beyond loopback has a
token (`token_for`, printed with its URL) and every request must carry it: as `?token=` (the
printed URL; the page is then redirected to itself with the token in a cookie, for its own
requests), the cookie, or `Authorization: Bearer`. A request that changes something (an
answer in `deepphy play`) must come from the page itself as well (`from_page`).
"""

from __future__ import annotations

import os
import secrets
from urllib.parse import urlsplit

from aiohttp import web

from deepphy.loopback import is_loopback


def token_for(listen_host: str, env_var: str) -> str | None:
    """The access token of a server listening on `listen_host`: None on loopback; beyond it,
    `$env_var` if set (a token that survives restarts), else a new random one."""
    if is_loopback(listen_host):
        return None
    return os.environ.get(env_var) or secrets.token_urlsafe(18)


def _host_name(host: str) -> str:
    """The name in a Host header or an Origin's netloc, without its port."""
    return urlsplit(f"//{host}").hostname or ""


def middleware(token: str | None, cookie: str, what: str):
    """The aiohttp middleware that lets a request in, or answers 403 (a Host that is not a
    loopback name, without a token) or 401 (no token, or the wrong one). `cookie`: the
    cookie that keeps the token (one name per server: cookies do not tell ports apart);
    `what`: the server, for the refusals' words."""

    @web.middleware
    async def check(request: web.Request, handler):
        if token is None:
            if not is_loopback(_host_name(request.host)):
                raise web.HTTPForbidden(text=f"{what} answers only to a loopback Host (127.0.0.1 or localhost)")
            return await handler(request)
        bearer = request.headers.get("Authorization", "").removeprefix("Bearer ").strip()
        given = request.query.get("token") or request.cookies.get(cookie) or bearer
        if not secrets.compare_digest(given.encode(), token.encode()):
            raise web.HTTPUnauthorized(text=f"{what} needs its access token: open the URL it printed")
        if "token" in request.query and request.method == "GET" and request.path == "/":
            response = web.HTTPFound("/")  # the token leaves the address bar for a cookie
            response.set_cookie(cookie, token, httponly=True, samesite="Strict", path="/")
            raise response
        return await handler(request)

    return check


def from_page(origin: str | None, host: str, token: str | None) -> bool:
    """Whether a request that changes something comes from the server's own page: no Origin
    (not a browser's cross-site request), or an Origin naming the server as the request
    reached it (`host`, the Host header), by a loopback name when the server has no token
    (a page of another site whose name resolves here is not ours)."""
    if origin is None:
        return True
    parts = urlsplit(origin)
    if parts.netloc.lower() != host.lower():
        return False
    return token is not None or is_loopback(parts.hostname or "")
