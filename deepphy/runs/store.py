"""The run directory: resolved config, an append-only attempt log, prompts and key frames.

Layout:
    config.json      the RunConfig, written once; a resume must present the same one
    attempts.jsonl   one AttemptRecord per line, appended by the single driver
    prompts/<digest>.json   each distinct prompt text once (images as placeholders)
    frames/<task>/r<run>_a<attempt>_<name>.png   key frames, referenced by records
    errors.jsonl     attempts that failed with an unexpected error (type, message, traceback);
                     they have no record, so a resume runs them again
    logs/            output of the run's worker processes (library warnings and the like)
    .lock            held (flock) while a run writes, so two runs cannot interleave

Crash safety: a record is one `write` of one line on an O_APPEND descriptor, made after
its frames are on disk. A run killed mid-write leaves at most a torn last line; opening
the store drops it (it has no newline) before appending again, so every (task, run,
attempt) appears exactly once.
"""

from __future__ import annotations

import fcntl
import json
import os
from pathlib import Path

from pydantic import ValidationError

from deepphy.chat import Image
from deepphy.config import RunConfig
from deepphy.runs.records import AttemptRecord

PROMPTS_REMEMBERED = 10_000  # digests known to be on disk without asking the file system
CONFIG = "config.json"
ATTEMPTS = "attempts.jsonl"
ERRORS = "errors.jsonl"
LOGS = "logs"


class RunDirError(RuntimeError):
    """A run directory that cannot be used as asked. The message is for the user."""


class RunStore:
    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._root = self.path.resolve()  # resolved once, not for every key frame handed out
        self._fd: int | None = None
        self._lock_fd: int | None = None
        self._prompts: set[str] = set()

    # -- opening ----------------------------------------------------------------------

    @classmethod
    @staticmethod
    def check(path: str | Path, config: RunConfig) -> None:
        """RunDirError unless `path` can hold this run (new, or the same config): creates nothing."""
        path = Path(path)
        if path.exists() and not path.is_dir():
            raise RunDirError(f"{path} exists and is not a directory")
        if (path / CONFIG).exists():
            previous = read_config(path)
            if previous != config:
                diff = _diff(previous.model_dump(mode="json"), config.model_dump(mode="json"))
                raise RunDirError(
                    f"{path} holds a run with a different config ({diff}); "
                    "resume it with the same options or choose another --out"
                )

    @classmethod
    def create_or_resume(cls, path: str | Path, config: RunConfig) -> "RunStore":
        """Open for writing: a new directory, or the resume of a run with the same config."""
        store = cls(Path(path))
        cls.check(store.path, config)
        existing = store.path / CONFIG
        try:
            store.path.mkdir(parents=True, exist_ok=True)
            (store.path / "frames").mkdir(exist_ok=True)
            (store.path / "prompts").mkdir(exist_ok=True)
            (store.path / LOGS).mkdir(exist_ok=True)
        except OSError as e:
            raise RunDirError(f"cannot create run directory {store.path}: {e.strerror}") from None
        store._lock()
        if not existing.exists():
            _atomic_write(existing, config.model_dump_json(indent=2).encode())
        store._repair_tail()
        store._fd = os.open(store.path / ATTEMPTS, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        return store

    def _lock(self) -> None:
        self._lock_fd = os.open(self.path / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self._lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self._lock_fd)
            self._lock_fd = None
            raise RunDirError(f"{self.path} is in use by another deepphy run") from None

    def _repair_tail(self) -> None:
        """Drop a torn last line left by a run killed in the middle of a write."""
        log = self.path / ATTEMPTS
        if not log.exists():
            return
        data = log.read_bytes()
        if data and not data.endswith(b"\n"):
            with open(log, "r+b") as f:
                f.truncate(data.rfind(b"\n") + 1)

    def close(self) -> None:
        for fd in (self._fd, self._lock_fd):
            if fd is not None:
                os.close(fd)
        self._fd = self._lock_fd = None

    def __enter__(self) -> "RunStore":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- writing ----------------------------------------------------------------------

    def append(self, record: AttemptRecord) -> None:
        assert self._fd is not None, "store not open for writing"
        line = (record.model_dump_json() + "\n").encode()
        written = os.write(self._fd, line)
        if written != len(line):  # never seen on a local disk; fail loudly rather than tear
            raise OSError(f"short write to {ATTEMPTS}: {written} of {len(line)} bytes")

    def append_error(self, error: dict) -> None:
        """One attempt that ended in an unexpected error (not a record: a resume retries it)."""
        with open(self.path / ERRORS, "a") as f:
            f.write(json.dumps(error) + "\n")

    def log_path(self, name: str) -> str:
        return str((self.path / LOGS / f"{name}.log").resolve())

    def write_frame(self, task: str, run: int, attempt: int, name: str, png: bytes) -> str:
        rel = f"frames/{task}/r{run}_a{attempt}_{name}.png"
        target = self.path / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        _atomic_write(target, png)
        return rel

    def write_prompt(self, digest: str, text: str) -> None:
        if digest in self._prompts:
            return
        target = self.path / "prompts" / f"{digest}.json"
        if not target.exists():
            _atomic_write(target, text.encode())
        if len(self._prompts) >= PROMPTS_REMEMBERED:  # bounded: a long run's memory stays flat
            self._prompts.clear()
        self._prompts.add(digest)

    def frame_image(self, rel: str, caption: str) -> Image:
        # By file: a waiting prompt holds the path, not the bytes (read where it is encoded).
        return Image(name=rel.rsplit("/", 1)[-1], caption=caption, file=str(self._root / rel))


# -- reading (no lock needed: the log only grows by whole lines) ---------------------


def read_config(path: str | Path) -> RunConfig:
    path = Path(path)
    if not path.is_dir():
        why = "it is a file" if path.exists() else "it does not exist"
        raise RunDirError(f"{path} is not a run directory ({why})")
    try:
        return RunConfig.model_validate_json((path / CONFIG).read_bytes())
    except FileNotFoundError:
        raise RunDirError(f"{path} is not a run directory (no {CONFIG})") from None
    except PermissionError:
        raise RunDirError(f"cannot read {path / CONFIG}: permission denied") from None
    except ValidationError as e:
        raise RunDirError(f"{path / CONFIG} is not a valid run config: {e.errors()[0]['msg']}") from None


def read_records(path: str | Path) -> list[AttemptRecord]:
    """All complete records, in the order they were written. A torn last line is ignored."""
    log = Path(path) / ATTEMPTS
    try:
        data = log.read_bytes()
    except FileNotFoundError:
        return []
    except PermissionError:
        raise RunDirError(f"cannot read {log}: permission denied") from None
    records = []
    lines = data.split(b"\n")
    complete = lines[:-1]  # the part after the last newline is empty or torn
    for n, line in enumerate(complete, 1):
        if not line.strip():
            continue
        try:
            records.append(AttemptRecord.model_validate_json(line))
        except ValidationError:
            raise RunDirError(f"{log}:{n} is not a valid attempt record") from None
    return records


def _atomic_write(target: Path, data: bytes) -> None:
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, target)


def _diff(old: dict, new: dict) -> str:
    keys = sorted(k for k in old.keys() | new.keys() if old.get(k) != new.get(k))
    return ", ".join(f"{k}: {json.dumps(old.get(k))} -> {json.dumps(new.get(k))}" for k in keys)
