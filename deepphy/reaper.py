"""Nothing left behind: a watchdog that stops the local Ray instance a driver started once
that driver is gone, however it ended (a crash, Ctrl-C, `kill -9`).

Ray's own processes (GCS, raylet, log monitor, ...) are the roots; the reaper follows
their descendants (workers, and the agents that rename themselves and ignore SIGTERM)
while the driver lives, and when it dies, terminates every process it saw that is still
the same process (same pid and start time), then kills what is left. It never touches a
process it cannot trace to those roots.

    python -m deepphy.reaper DRIVER_PID PID:START_TIME ...

The driver takes the first snapshot itself, so a driver killed a moment after starting
Ray still leaves nothing behind.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import psutil

POLL_S = 0.5
GRACE_S = 2.0  # between SIGTERM and SIGKILL


def start(root_pids: list[int]) -> subprocess.Popen:
    """Watch this process; reap `root_pids` and their descendants after it ends."""
    roots = {}
    for pid in root_pids:
        try:
            roots[pid] = psutil.Process(pid).create_time()
        except psutil.Error:
            pass
    family = _family(roots)
    return subprocess.Popen(
        [sys.executable, "-m", "deepphy.reaper", str(os.getpid()),
         *(f"{pid}:{started!r}" for pid, started in family.items())],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True,  # not in the driver's process group: Ctrl-C does not stop it
    )


def ray_roots() -> list[int]:
    """The processes of the local Ray node this driver started."""
    import ray._private.worker as worker

    node = worker._global_node
    if node is None:
        return []
    return [info.process.pid for infos in node.all_processes.values() for info in infos if info.process]


def _family(roots: dict[int, float]) -> dict[int, float]:
    """pid -> start time of the roots still alive and all their descendants."""
    seen: dict[int, float] = {}
    for pid, started in roots.items():
        try:
            proc = psutil.Process(pid)
            if proc.create_time() != started:
                continue
            for p in [proc, *proc.children(recursive=True)]:
                seen[p.pid] = p.create_time()
        except psutil.Error:
            continue
    return seen


def _alive(procs: dict[int, float]) -> list[psutil.Process]:
    out = []
    for pid, started in procs.items():
        try:
            p = psutil.Process(pid)
            if p.create_time() == started and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
        except psutil.Error:
            pass
    return out


def _running(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def reap(driver: int, family: dict[int, float]) -> None:
    """Follow `family` (pid -> start time) while `driver` runs; then stop what is left."""
    me = os.getpid()
    while _running(driver):
        family.update(_family(family))
        time.sleep(POLL_S)
    family.update(_family(family))  # what they started last
    family.pop(me, None)
    left = _alive(family)
    for p in left:
        try:
            p.terminate()
        except psutil.Error:
            pass
    _, left = psutil.wait_procs(left, timeout=GRACE_S)
    for p in left:  # the agents ignore SIGTERM
        try:
            p.kill()
        except psutil.Error:
            pass


if __name__ == "__main__":
    try:
        reap(int(sys.argv[1]), {int(p): float(t) for p, _, t in (a.partition(":") for a in sys.argv[2:])})
    except psutil.Error:
        pass
