"""Nothing left behind: a watchdog that stops the local Ray instance a driver started once
that driver is gone, however it ended (a crash, Ctrl-C, `kill -9`, during Ray's start
included).

The driver starts it just before it starts Ray. It waits for the driver's exit without
polling (a pidfd where the OS has one) and then looks through the processes once: every
process with a file open in one of the driver's Ray sessions (`<Ray temp dir>/session_*_<driver
pid>`: Ray names a local session after the process that starts it, and every Ray process
of that session, the agents and workers that rename themselves included, holds its log
files open) is terminated, and killed if it is still there a moment later (Ray's agents
ignore SIGTERM). It never touches a process without a file in those sessions.

    python -m deepphy.reaper DRIVER_PID RAY_TEMP_DIR
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys

import psutil

GRACE_S = 2.0  # between SIGTERM and SIGKILL
WAIT_S = 0.5  # how often the driver is checked where there is no pidfd


def start(temp_dir: str) -> subprocess.Popen:
    """Watch this process; after it ends, stop the processes of the Ray sessions it started
    under `temp_dir`."""
    return subprocess.Popen(
        [sys.executable, "-m", "deepphy.reaper", str(os.getpid()), temp_dir],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True,  # not in the driver's process group: Ctrl-C does not stop it
    )


def wait_for_exit(pid: int) -> None:
    """Return once process `pid` has exited."""
    try:
        fd = os.pidfd_open(pid)
    except (AttributeError, OSError):  # no pidfd (not Linux), or already gone
        try:
            psutil.Process(pid).wait()
        except psutil.Error:
            pass
        return
    try:
        select.select([fd], [], [])
    finally:
        os.close(fd)


def session_processes(driver: int, temp_dir: str) -> list[psutil.Process]:
    """Every process with a file open in one of `driver`'s Ray sessions under `temp_dir`."""
    prefix = os.path.join(os.path.realpath(temp_dir), "session_")
    suffix = f"_{driver}"
    me = os.getpid()
    found = []
    for proc in psutil.process_iter():
        if proc.pid == me:
            continue
        try:
            files = proc.open_files()
        except psutil.Error:
            continue
        for f in files:
            if f.path.startswith(prefix) and f.path[len(prefix):].split("/", 1)[0].endswith(suffix):
                found.append(proc)
                break
    return found


def reap(driver: int, temp_dir: str) -> None:
    wait_for_exit(driver)
    left = session_processes(driver, temp_dir)
    for p in left:
        try:
            p.terminate()
        except psutil.Error:
            pass
    psutil.wait_procs(left, timeout=GRACE_S)
    for p in session_processes(driver, temp_dir):  # what ignored SIGTERM, and what was being started
        try:
            p.kill()
        except psutil.Error:
            pass


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    reap(int(sys.argv[1]), sys.argv[2])
