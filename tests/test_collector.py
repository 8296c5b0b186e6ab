"""A driver's heap is frozen while its attempts run and thawed when the last run ends."""

from __future__ import annotations

import gc
import weakref

from deepphy.collector import frozen_heap


class Node:
    pass


def test_the_heap_is_frozen_while_runs_overlap_and_collected_after_the_last():
    gc.unfreeze()
    cycle = Node()
    cycle.me = cycle  # garbage only a collection frees
    alive = weakref.ref(cycle)
    with frozen_heap():
        assert gc.get_freeze_count() > 0
        del cycle
        with frozen_heap():  # a second run of the same process (a suite's cells overlap)
            pass
        assert gc.get_freeze_count() > 0  # the first run still runs: still frozen
        gc.collect()
        assert alive() is not None  # frozen: not collected while attempts run
    assert gc.get_freeze_count() == 0
    gc.collect()
    assert alive() is None  # thawed: collected as before


def test_a_run_that_raises_thaws_the_heap():
    try:
        with frozen_heap():
            raise RuntimeError("a run that fails")
    except RuntimeError:
        pass
    assert gc.get_freeze_count() == 0
