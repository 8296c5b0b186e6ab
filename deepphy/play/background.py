"""Slow work (physics, compiling, rendering films) off the event loop that serves the pages."""

from __future__ import annotations

import asyncio
import threading
from typing import Any, Callable

_threads: set[threading.Thread] = set()


def still_working() -> bool:
    """Whether some of this work is still running (a warm-up compiling, a film)."""
    return any(thread.is_alive() for thread in _threads)


def wait(timeout_s: float) -> None:
    """Let the work under way finish (for a process that must exit normally)."""
    for thread in list(_threads):
        thread.join(timeout_s)


async def off_loop(fn: Callable[..., Any], *args: Any) -> Any:
    """`fn(*args)` in a daemon thread of its own: the pages are served meanwhile, and a
    Ctrl-C need not wait for it (a warm-up compiling kernels for half a minute, say)."""
    loop = asyncio.get_running_loop()
    future = loop.create_future()

    def settle(outcome: Any, failed: bool) -> None:
        if future.done():  # the awaiting coroutine was cancelled
            return
        if not failed:
            future.set_result(outcome)
            return
        try:
            future.set_exception(outcome)
        except TypeError:  # StopIteration (a stray `next()`): a Future refuses it, and the awaiting coroutine would wait forever
            error = RuntimeError(f"{getattr(fn, '__name__', 'call')} raised {type(outcome).__name__}")
            error.__cause__ = outcome
            future.set_exception(error)

    def run() -> None:
        try:
            outcome, failed = fn(*args), False
        except BaseException as e:  # noqa: BLE001 - handed to the awaiting coroutine
            outcome, failed = e, True
        try:
            loop.call_soon_threadsafe(settle, outcome, failed)
        except RuntimeError:  # the loop has closed (Ctrl-C): nobody waits any more
            pass

    thread = threading.Thread(target=run, daemon=True, name=f"play-{getattr(fn, '__name__', 'call')}")
    _threads.difference_update([t for t in _threads if not t.is_alive()])
    _threads.add(thread)
    thread.start()
    return await future
