"""Python's cyclic garbage collector while a driver runs attempts.

A driver's heap is mostly long-lived: Ray, gRPC, protobuf, pydantic's schemas and the
environments' modules, ~290,000 objects once a run has started. With CPython's default
thresholds (700, 10, 10) the attempts' allocations (the pydantic models of prompts and
records) set off ~200 young collections per 1,000 PHYRE attempts and, every few seconds, a
full one that scans the whole heap (100-180 ms each, collecting next to nothing): about a
tenth of the driver's CPU per attempt. While attempts run, the heap that was there when they
began is frozen (`gc.freeze`: out of the collector's sight, though still freed by reference
counting). It is thawed when the last run of the process ends, so a long-lived process (a
suite, a notebook) collects all of it again. Measured (PHYRE, the driver's main thread in the
steady state, three interleaved pairs): 0.89 -> 0.78 ms per attempt (medians). Collecting
young objects less often as well (thresholds 10,000 and 50,000 instead of 700) made it dearer
(0.84-0.95 ms): their collections grow with the allocations they wait for.

Environment workers keep CPython's defaults: their heap is smaller (~80,000 objects for
I-PHYRE) and collecting its reference cycles (a physics space's bodies) less often made their
attempts no cheaper.
"""

from __future__ import annotations

import gc
import threading
from contextlib import contextmanager
from typing import Iterator

_lock = threading.Lock()
_runs = 0  # runs of this process inside `frozen_heap` (a suite runs several at once, in threads)


@contextmanager
def frozen_heap() -> Iterator[None]:
    """Freeze the heap while attempts run (once for runs that overlap)."""
    global _runs
    with _lock:
        if _runs == 0:
            gc.freeze()  # no collection first (~150 ms at a run's start): garbage frozen now is collected after
        _runs += 1
    try:
        yield
    finally:
        with _lock:
            _runs -= 1
            if _runs == 0:
                gc.unfreeze()
