"""What a running driver says about itself in its run directory (`status.json`): its phase
(starting, compiling, running) and where its Ray cluster is, so that a dashboard shows the
phase of a run it only reads from disk and `deepphy watch RUN_DIR` can join the run's Ray
cluster, a local one included.

The file is written while the driver holds the directory's lock and removed when it ends;
a file left by a killed driver is recognised by the lock no longer being held.
"""

from __future__ import annotations

import os
from pathlib import Path

from pydantic import BaseModel, ValidationError

STATUS = "status.json"
PHASES = ("starting", "compiling", "running")  # workers starting; their warm-up (compiling kernels); attempts
STATUS_MAX_BYTES = 64 * 1024  # a status file is a few hundred bytes; anything bigger is not ours


class RunStatus(BaseModel):
    run_id: str  # the Ray actors' prefix, deepphy/<run_id>/...
    pid: int  # the driver's process
    phase: str  # one of PHASES
    since: float  # unix time the phase began
    ray_address: str | None = None  # the Ray cluster's address (HOST:PORT), local or joined
    ray_auth: str | None = None  # RAY_AUTH_MODE of the driver ("token": the cluster needs Ray's token)


def write_status(run_dir: str | Path, status: RunStatus) -> None:
    """Replace the status file atomically (readers never see half of one)."""
    path = Path(run_dir) / STATUS
    tmp = path.with_name(f".{STATUS}.{os.getpid()}.tmp")
    tmp.write_text(status.model_dump_json())
    os.replace(tmp, path)


def remove_status(run_dir: str | Path) -> None:
    try:
        (Path(run_dir) / STATUS).unlink()
    except FileNotFoundError:
        pass


def read_status(run_dir: str | Path) -> RunStatus | None:
    """The status of the driver writing `run_dir` now, or None: no file, an unreadable or
    invalid one, or one left by a driver that no longer holds the lock."""
    path = Path(run_dir) / STATUS
    try:
        if path.is_symlink() or path.stat().st_size > STATUS_MAX_BYTES:
            return None
        status = RunStatus.model_validate_json(path.read_bytes())
    except (OSError, ValidationError):
        return None
    return status if writer_holds_lock(Path(run_dir)) is not False else None


def writer_holds_lock(path: Path) -> bool | None:
    """Whether a `deepphy run` holds the directory's lock (it is writing now), read from
    /proc/locks so that a reader never takes the lock itself (a run starting at that
    moment would then refuse the directory). None where /proc/locks does not exist."""
    try:
        st = (path / ".lock").stat()
    except FileNotFoundError:
        return False
    try:
        locks = Path("/proc/locks").read_text()
    except OSError:
        return None
    wanted = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    return any(line.split()[5] == wanted for line in locks.splitlines() if len(line.split()) > 5 and "FLOCK" in line)
