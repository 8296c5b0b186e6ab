"""Keep freed memory in the heap of a process that hosts environments.

An attempt allocates and frees the same large arrays over and over: canvases, frame
stacks, the buffers of PNG encoding (0.1-10 MB each). With its default settings glibc's
malloc hands such memory back to the kernel when it is freed (blocks above its mmap
threshold are unmapped; the top of the heap is trimmed), so the next attempt's arrays
fault their pages in again, each page zeroed by the kernel. For I-PHYRE that was ~1,000
page faults and ~3 ms of kernel CPU per attempt, about a quarter of the environment's
whole work (benchmarks/cpu_per_attempt.py, `/proc/<pid>/stat`'s minflt). With fixed
thresholds freed blocks stay in the heap and are reused: ~30 faults per attempt. The
price is that a process keeps its peak heap; an environment worker's peak resident
memory measured the same both ways (~220 MB for I-PHYRE).

Only glibc has `mallopt`; elsewhere (macOS, musl) this does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools

# mallopt's parameter numbers (glibc's malloc.h).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
# Blocks up to this size come from the heap, never a fresh mapping: glibc's largest
# allowed value on 64-bit (larger blocks, rare here, are still mapped).
MMAP_THRESHOLD = 32 << 20
# Free memory at the top of the heap is handed back only beyond this much: more than an
# attempt of any environment frees at once.
TRIM_THRESHOLD = 256 << 20


@functools.cache
def keep_freed_memory() -> bool:
    """Set this process's malloc thresholds (once); True where they were set (glibc)."""
    name = ctypes.util.find_library("c")
    if not name:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
