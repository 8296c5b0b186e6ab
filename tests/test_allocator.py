"""deepphy.allocator: an environment process keeps freed memory for its next arrays."""

from __future__ import annotations

import subprocess
import sys

import pytest

from deepphy.allocator import keep_freed_memory

# Arrays alive together then freed, as an attempt's canvases and PNG buffers are: glibc's
# defaults hand them back to the kernel, so each round faults its pages in again.
ROUNDS = """
import resource, sys
import numpy as np
if sys.argv[1] == "keep":
    from deepphy.allocator import keep_freed_memory
    assert keep_freed_memory()
faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(50):
    arrays = [np.ones(2 << 20, np.uint8) for _ in range(4)]
    del arrays
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults)
"""


def faults(mode: str) -> int:
    out = subprocess.run([sys.executable, "-c", ROUNDS, mode], capture_output=True, text=True, timeout=60, check=True)
    return int(out.stdout)


@pytest.mark.skipif(not sys.platform.startswith("linux") or not keep_freed_memory(), reason="glibc's mallopt only")
def test_freed_arrays_are_reused_not_faulted_in_again():
    default, kept = faults("default"), faults("keep")
    # 50 rounds of 8 MiB: ~100,000 faults by default; with the thresholds the first round's only
    assert default > 20 * kept, (default, kept)
    assert kept < 10_000, kept
