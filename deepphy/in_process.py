"""`deepphy run --in-process`: a run's workers in this process, without Ray, for smoke tests
of a prompt or an endpoint (a Ray run spends half a minute starting Ray on a busy machine).

The scheduler, the attempt protocol and the records are those of a Ray run; only the
handles the scheduler holds differ (deepphy.runner.evaluate picks them):
- each environment worker is the actor's own class (`EnvWorkerImpl`) on an event loop in a
  thread of its own, so physics and compiling never stall the model's requests or the
  progress line, as in the worker's own process;
- the metrics actor's class (`MetricsImpl`) on the run's own event loop;
- the model is its client itself (an endpoint's rate limits kept by its in-process limiter).
`Actor` answers `handle.method.remote(...)` with an awaitable, as a Ray actor handle answers
with an ObjectRef, so the scheduler's code is the same for both.
"""

from __future__ import annotations

import asyncio
import inspect
import threading
from typing import Any, Callable


class ThreadLoop:
    """An event loop running in a daemon thread of its own: an in-process worker's."""

    def __init__(self, name: str) -> None:
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, name=name, daemon=True)
        self._thread.start()

    def close(self, timeout_s: float = 10.0) -> None:
        """Let the calls still on their way finish (`timeout_s` at most, then they are
        cancelled), and stop the loop and its thread."""
        try:
            asyncio.run_coroutine_threadsafe(self._finish(timeout_s), self.loop).result(timeout_s + 5)
        except Exception:  # noqa: BLE001 - a call that will not end: the thread is a daemon
            pass
        self.loop.call_soon_threadsafe(self.loop.stop)
        self._thread.join(timeout_s)
        if not self._thread.is_alive():
            self.loop.close()

    @staticmethod
    async def _finish(timeout_s: float) -> None:
        await asyncio.sleep(0)  # the calls handed over just before start first
        others = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        if others:
            _, late = await asyncio.wait(others, timeout=timeout_s)
            for task in late:
                task.cancel()
            await asyncio.gather(*late, return_exceptions=True)


class Actor:
    """An actor's implementation, called as a Ray actor handle is: `handle.method.remote(...)`
    runs the method on the actor's loop and returns an awaitable of its result.

    `make()` builds the implementation; on another thread's loop it is built there, first,
    without waiting (calls queue behind it, as calls to a Ray actor wait for its
    constructor; one that raises fails every call). Without a loop it is built here, now,
    and its calls run on the caller's loop (at once, for a synchronous method called
    outside any loop: the run's first summaries)."""

    def __init__(self, make: Callable[[], Any], loop: asyncio.AbstractEventLoop | None = None) -> None:
        self._loop = loop
        self._impl: Any = None
        self._failed: BaseException | None = None
        if loop is None:
            self._impl = make()
        else:
            def build() -> None:
                try:
                    self._impl = make()
                except BaseException as e:  # noqa: BLE001 - raised by every call, as Ray's init failure is
                    self._failed = e

            loop.call_soon_threadsafe(build)

    def __getattr__(self, name: str) -> "_Method":
        return _Method(self, name)

    async def _call(self, name: str, args: tuple, kwargs: dict) -> Any:
        if self._failed is not None:
            raise self._failed
        result = getattr(self._impl, name)(*args, **kwargs)
        return await result if inspect.isawaitable(result) else result


class _Method:
    def __init__(self, actor: Actor, name: str) -> None:
        self.actor, self.name = actor, name

    def remote(self, *args: Any, **kwargs: Any) -> Any:
        if self.actor._loop is not None:  # on the actor's own thread
            call = self.actor._call(self.name, args, kwargs)
            return asyncio.wrap_future(asyncio.run_coroutine_threadsafe(call, self.actor._loop))
        try:
            asyncio.get_running_loop()
        except RuntimeError:  # no loop running here: a synchronous method, called now
            return _done(getattr(self.actor._impl, self.name)(*args, **kwargs))
        return asyncio.ensure_future(self.actor._call(self.name, args, kwargs))


async def _done(value: Any) -> Any:
    """The result of a call made outside any loop, to await later."""
    return value
