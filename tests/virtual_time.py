"""An asyncio event loop whose clock jumps ahead whenever it would otherwise sleep with
nothing to do: a test of minutes-long deadlines (a model endpoint's default timeouts, a rate
limiter's minute windows) runs in moments, with real sockets between a client and a server
that both run on this loop.

Time jumps only when no socket of the loop is ready (loopback traffic between two ends of
one loop is ready at once; while an exchange is under way, after a short real wait too), so
nothing in it may wait on another thread's work (a name lookup in an executor, a worker
thread): there the clock would run ahead of it. Timers, deadlines and `loop.time()` are
virtual; `time.time()` is not.
"""

from __future__ import annotations

import asyncio
import contextlib

GRACE_S = 0.02  # real seconds a socket is given to become ready before the clock jumps (more on a loaded machine)


class VirtualTimeLoop(asyncio.SelectorEventLoop):
    def __init__(self) -> None:
        super().__init__()
        self.skipped = 0.0  # virtual seconds added to the real clock
        real_select = self._selector.select
        busy = [False]  # the last select found a socket ready: an exchange is under way

        def select(timeout: float | None = None):
            ready = real_select(0)
            if not ready and timeout != 0:
                if timeout is None:  # no timer at all: only a socket can wake the loop
                    ready = real_select(None)
                else:
                    started = super(VirtualTimeLoop, self).time()
                    ready = real_select(min(timeout, GRACE_S)) if busy[0] else []
                    if not ready:
                        self.skipped += max(0.0, timeout - (super(VirtualTimeLoop, self).time() - started))
            busy[0] = bool(ready)
            return ready

        self._selector.select = select  # type: ignore[method-assign]

    def time(self) -> float:
        return super().time() + self.skipped


@contextlib.contextmanager
def virtual_time():
    """A VirtualTimeLoop for the `with` block: `loop.run_until_complete(...)`."""
    loop = VirtualTimeLoop()
    try:
        yield loop
    finally:  # as asyncio.run ends: what is left (a limiter's pump, say) is cancelled
        left = asyncio.all_tasks(loop)
        for task in left:
            task.cancel()

        async def cancelled() -> None:
            await asyncio.gather(*left, return_exceptions=True)

        loop.run_until_complete(cancelled())
        loop.run_until_complete(loop.shutdown_asyncgens())
        loop.close()
