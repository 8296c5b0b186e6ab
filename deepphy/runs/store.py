"""The run directory: resolved config, an append-only attempt log, prompts and key frames.

Layout:
    config.json      the RunConfig, written once; a resume must present the same one
    attempts.jsonl   one AttemptRecord per line, appended by the single driver
    prompts/<task>/r<run>.jsonl   the episode's prompt log: each distinct prompt of the
                     episode once, a line {"digest", "messages"} (its images by content address),
                     appended before the record that names it (runs before these logs hold
                     prompts/<digest>.json files instead; readers take both)
    images/<sha256>.png     every image of every prompt, once (named by the sha256 of its bytes;
                     a history key frame is a hard link to its file under frames/)
    frames/<task>/r<run>_a<attempt>_<name>.png   key frames, referenced by records
    errors.jsonl     attempts that failed with an unexpected error (type, message, traceback);
                     they have no record, so a resume runs them again
    logs/            output of the run's worker processes (library warnings and the like)
    .lock            held (flock) while a run writes, so two runs cannot interleave

Crash safety: a record is one `write` of one line on an O_APPEND descriptor, made after
its frames are on disk. A run killed mid-write leaves at most a torn last line; opening
the store drops it (it has no newline) before appending again, so every (task, run,
attempt) appears exactly once. An episode's prompt log is appended to the same way; its
torn tail is cut the first time a resume appends to it (that prompt belongs to an attempt
with no record, which the resume runs again), and readers skip it. A write that fails
(disk full, read-only file system, no permission) stops the run with `RunWriteError`: a
short record or prompt line is cut off again and a frame or image is written to a
temporary file renamed into place, so what is on disk stays whole and the next resume
goes on from it.

A run directory is untrusted input (someone may hand you one): everything read from it is
confined to it (`inside`: the resolved path, symlinks followed, must stay in the
directory), records are validated (`AttemptRecord`, then `problems`: each episode holds
attempts 1..n once each, and the key frames an unfinished episode's next attempt will be
shown are files in the directory), and `repair` is the documented way out of a broken log.
"""

from __future__ import annotations

import errno
import fcntl
import json
import logging
import os
import re
import shutil
import time
from collections import Counter, defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence

from pydantic import ValidationError

from deepphy.chat import Image, ImagePart, Message, TextPart
from deepphy.config import RunConfig
from deepphy.envs.base import SAFE_ID
from deepphy.messages import one_line, validation_message
from deepphy.prompts import image_digest, prompt_as_json
from deepphy.runs.records import DIGEST, AttemptRecord, episode_finished

log = logging.getLogger(__name__)

PROMPTS_REMEMBERED = 10_000  # prompts and images known to be on disk without asking the file system
# A prompt is KBs (the replies its history repeats are cut at 32,768 characters each): a
# longer line of a prompt log, or a longer prompts/<digest>.json, is not ours and is not read.
MAX_PROMPT_BYTES = 16 * 1024 * 1024
MAX_IMAGE_BYTES = 64 * 1024 * 1024  # a prompt image is KBs (a few MB at most): a larger file is not ours
TAIL_BLOCK = 64 * 1024  # read backwards in blocks of this size to find a torn line's start
CONFIG = "config.json"
ATTEMPTS = "attempts.jsonl"
ERRORS = "errors.jsonl"
LOGS = "logs"
FRAMES = "frames"
PROMPTS = "prompts"
IMAGES = "images"
LOCK = ".lock"
OWN_ENTRIES = {CONFIG, ATTEMPTS, ERRORS, LOGS, FRAMES, PROMPTS, IMAGES, LOCK}  # what a run directory holds
IMAGE_DIGEST = re.compile(r"^[0-9a-f]{64}$")  # images/<digest>.png (deepphy.prompts.image_digest)
PROMPT_DIGEST = re.compile(DIGEST)  # deepphy.prompts.prompt_digest
OLD_IMAGE_PLACEHOLDER = re.compile(r"^<image ([^:>]*): (.*)>$", re.S)  # an image in prompts of runs before images/


class RunDirError(RuntimeError):
    """A run directory that cannot be used as asked. The message is for the user."""


class RunWriteError(RunDirError):
    """Writing to the run directory failed (disk full, read-only, no permission). The run
    stops; everything recorded so far is whole, and a resume goes on from it."""


def inside(root: Path, rel: str | Path) -> Path | None:
    """`root / rel` resolved (symlinks followed) if it stays inside `root` (itself resolved),
    else None: `..`, absolute paths, NUL bytes and symlinks out of the directory."""
    try:
        target = (root / rel).resolve()
    except (OSError, ValueError):  # a symlink loop; an embedded NUL byte
        return None
    return target if target == root or target.is_relative_to(root) else None


def prompt_log(task: str, run: int) -> str:
    """The prompt log of episode (task, run), relative to the run directory."""
    return f"{PROMPTS}/{task}/r{run}.jsonl"


def _write_failed(path: Path, what: str, e: OSError) -> RunWriteError:
    return RunWriteError(f"cannot write {what} in {path}: {e.strerror or e}; what is recorded is whole: "
                         "fix that and run the same command again to resume")


class RunStore:
    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._root = self.path.resolve()  # resolved once, not for every key frame handed out
        self._fd: int | None = None
        self._lock_fd: int | None = None
        self._prompts: set[tuple[str, int, str]] = set()  # (task, run, digest) in the episode's log
        self._logs: set[tuple[str, int]] = set()  # episodes whose prompt log this store has checked for a torn tail
        self._images: set[str] = set()  # image digests known to be on disk
        self._digests: dict[str, str] = {}  # image digest of each key frame this store wrote, by file
        self._task_dirs: set[str] = set()  # frames/<task>, prompts/<task>: known to be inside the run
        self._images_dir = str(self.path / IMAGES)  # joined once
        self.created = False  # this store made the directory (discard() may remove it)
        self.appended = 0  # records and errors written

    # -- opening ----------------------------------------------------------------------

    @staticmethod
    def check(path: str | Path, config: RunConfig) -> None:
        """RunDirError unless `path` can hold this run (new, or the same config): creates nothing."""
        path = Path(path)
        if path.exists() and not path.is_dir():
            raise RunDirError(f"{path} exists and is not a directory")
        if not path.exists():
            return
        try:
            entries = {p.name for p in path.iterdir()}
        except OSError as e:
            raise RunDirError(f"cannot read {path}: {e.strerror or e}") from None
        foreign = sorted(entries - OWN_ENTRIES)
        if CONFIG not in entries and foreign:
            raise RunDirError(f"{path} is not empty and holds no run (it has {', '.join(foreign[:3])}"
                              f"{', ...' if len(foreign) > 3 else ''}); choose another --out")
        check_confined(path, entries)
        if CONFIG in entries:
            previous = read_config(path)
            if previous.prompts != config.prompts:
                raise RunDirError(
                    f"{path} was made with deepphy's prompts from {previous.prompts} and cannot be resumed with "
                    f"the {config.prompts} prompts (docs/comparability.md); report, leaderboard and export still "
                    "read it: choose another --out for a new run")
            if previous != config:
                diff = _diff(previous.model_dump(mode="json"), config.model_dump(mode="json"))
                raise RunDirError(
                    f"{path} holds a run with a different config ({diff}); "
                    "resume it with the same options or choose another --out"
                )

    @classmethod
    def claim(cls, path: str | Path, config: RunConfig) -> "RunStore":
        """Lock `path` for this run, making it (and writing its config) if it is new. Fails
        before anything else starts; nothing is appended until `start_writing`."""
        cls.check(path, config)
        store = cls(Path(path))
        store.created = not store.path.exists()
        try:
            store.path.mkdir(parents=True, exist_ok=True)
            for sub in (FRAMES, PROMPTS, IMAGES, LOGS):
                (store.path / sub).mkdir(exist_ok=True)
        except OSError as e:
            store.discard()
            raise RunDirError(f"cannot create run directory {store.path}: {e.strerror or e}") from None
        store._root = store.path.resolve()
        if inside(store._root, IMAGES) != store._root / IMAGES:
            store.discard()
            raise RunDirError(f"{store.path}/{IMAGES} leads out of the run directory; refusing to write there")
        try:
            store._lock()
            if not (store.path / CONFIG).exists():
                try:
                    atomic_write(store.path / CONFIG, config.model_dump_json(indent=2).encode())
                except OSError as e:
                    raise _write_failed(store.path, CONFIG, e) from None
        except BaseException:
            store.discard()
            raise
        return store

    def start_writing(self) -> None:
        """Open the attempt log for appending (after dropping a torn last line)."""
        try:
            self._fd = os.open(self.path / ATTEMPTS, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
            _cut_torn_tail(self._fd)
        except OSError as e:
            raise _write_failed(self.path, ATTEMPTS, e) from None

    @classmethod
    def create_or_resume(cls, path: str | Path, config: RunConfig) -> "RunStore":
        """Open for writing: a new directory, or the resume of a run with the same config."""
        store = cls.claim(path, config)
        try:
            store.start_writing()
        except BaseException:
            store.discard()
            raise
        return store

    def _lock(self) -> None:
        lock = self.path / LOCK
        try:
            self._lock_fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            try:  # a read-only directory: its existing lock can still be taken, to read
                self._lock_fd = os.open(lock, os.O_RDONLY)
            except OSError:
                raise RunDirError(f"cannot lock {self.path}: {e.strerror or e}") from None
        try:
            fcntl.flock(self._lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self._lock_fd)
            self._lock_fd = None
            raise RunDirError(f"{self.path} is in use by another deepphy run") from None

    def close(self) -> None:
        for fd in (self._fd, self._lock_fd):
            if fd is not None:
                os.close(fd)
        self._fd = self._lock_fd = None

    def discard(self) -> None:
        """Close; and if this store made the directory and recorded nothing, remove it, so
        that a run that fails before its first attempt leaves nothing behind."""
        self.close()
        if self.created and not self.appended:
            shutil.rmtree(self.path, ignore_errors=True)

    def __enter__(self) -> "RunStore":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- writing ----------------------------------------------------------------------

    def append(self, record: AttemptRecord) -> None:
        assert self._fd is not None, "store not open for writing"
        try:
            _append_line(self._fd, (record.model_dump_json() + "\n").encode())
        except OSError as e:
            raise _write_failed(self.path, ATTEMPTS, e) from None
        self.appended += 1

    def append_error(self, error: dict) -> None:
        """One attempt that ended in an unexpected error (not a record: a resume retries it)."""
        try:
            with open(self.path / ERRORS, "a") as f:
                f.write(json.dumps(error) + "\n")
        except OSError as e:
            raise _write_failed(self.path, ERRORS, e) from None
        self.appended += 1

    def log_path(self, name: str) -> str:
        return str(self._root / LOGS / f"{name}.log")

    def _task_dir(self, kind: str, task: str) -> None:
        """Make <kind>/<task> (frames/, prompts/) once, checked to stay inside the run."""
        rel = f"{kind}/{task}"
        if rel not in self._task_dirs:
            (self.path / rel).mkdir(exist_ok=True)
            if inside(self._root, rel) is None:
                raise RunDirError(f"{self.path}/{rel} leads out of the run directory; refusing to write there")
            self._task_dirs.add(rel)

    def write_frame(self, task: str, run: int, attempt: int, name: str, png: bytes) -> str:
        rel = f"{FRAMES}/{task}/r{run}_a{attempt}_{name}.png"
        try:
            self._task_dir(FRAMES, task)
            atomic_write(f"{self.path}/{rel}", png)
        except OSError as e:
            raise _write_failed(self.path, rel, e) from None
        if len(self._digests) >= PROMPTS_REMEMBERED:
            self._digests.clear()
        self._digests[f"{self._root}/{rel}"] = image_digest(png)  # while the bytes are here: later prompts show it
        return rel

    def write_prompt(self, task: str, run: int, digest: str, messages: list[Message]) -> None:
        """The prompt as a line of the episode's prompt log, once per episode, and each of its
        images once (images first: a stored prompt's images are on disk). Appending to an
        existing file creates no inode: a run makes a file per episode, not per decision."""
        if (task, run, digest) in self._prompts:
            return
        rel = prompt_log(task, run)
        try:
            for image in (image for m in messages for image in m.images):
                self._write_image(image)
            self._task_dir(PROMPTS, task)
            # read as well: the first append of this store checks the tail
            fd = os.open(f"{self.path}/{rel}", os.O_RDWR | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o644)
            try:
                if (task, run) not in self._logs:  # a run killed mid-line left a torn one
                    _cut_torn_tail(fd)
                    _remember(self._logs, (task, run))
                _append_line(fd, f'{{"digest":"{digest}","messages":{prompt_as_json(messages)}}}\n'.encode())
            finally:
                os.close(fd)
        except OSError as e:
            if e.errno == errno.ELOOP:  # O_NOFOLLOW: the log is a symlink
                raise RunDirError(f"{self.path}/{rel} is a symbolic link; refusing to write there") from None
            raise _write_failed(self.path, rel, e) from None
        _remember(self._prompts, (task, run, digest))

    def _write_image(self, image: Image) -> None:
        digest = image.digest
        if digest in self._images:
            return
        target = f"{self._images_dir}/{digest}.png"
        try:  # a key frame already in the run directory: a second name, not a second copy
            if image.file is None:
                raise OSError("no file to link")
            os.link(image.file, target)  # atomic by itself: the name comes with the whole (written) file
        except OSError:
            if not os.path.lexists(target):
                atomic_write(target, image.load())
            elif not self._image_intact(digest):  # stored before, and damaged since: these are its bytes
                log.warning("%s/%s/%s.png did not hash to its name; written again", self.path, IMAGES, digest)
                atomic_write(target, image.load())
        _remember(self._images, digest)

    def _image_intact(self, digest: str) -> bool:
        try:
            return read_image(self._root, digest) is not None
        except RunDirError:  # damaged, or a link out of the run: replaced (the rename replaces a link, not its target)
            return False

    def frame_image(self, rel: str, caption: str) -> Image:
        # By file: a waiting prompt holds the path, not the bytes (read where it is encoded).
        # `rel` is a validated record's (see `problems`: checked inside the run on resume).
        # Its digest, if this store wrote it: the run directory is ours (locked) and a
        # recorded key frame is never rewritten.
        file = f"{self._root}/{rel}"  # a string join: pathlib's is 3 us, for every key frame of every prompt
        return Image.stored(name=rel.rsplit("/", 1)[-1], caption=caption, file=file, digest=self._digests.get(file))


def _remember(known: set, key: object) -> None:
    if len(known) >= PROMPTS_REMEMBERED:  # bounded: a long run's memory stays flat
        known.clear()
    known.add(key)


def _append_line(fd: int, line: bytes) -> None:
    """One `write` of a whole line on an O_APPEND descriptor. A short write (the disk filled
    up mid-line) is cut off again, so the file stays whole lines."""
    written = os.write(fd, line)
    if written != len(line):
        try:
            os.ftruncate(fd, os.lseek(fd, 0, os.SEEK_END) - written)
        except OSError:
            pass  # the next resume drops the torn line
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _cut_torn_tail(fd: int) -> None:
    """Truncate a log (open for reading and writing) after its last newline: a run killed
    in the middle of a write leaves a last line without one."""
    end = os.fstat(fd).st_size
    if end == 0 or os.pread(fd, 1, end - 1) == b"\n":
        return
    keep = 0
    while end > 0:
        start = max(0, end - TAIL_BLOCK)
        cut = os.pread(fd, end - start, start).rfind(b"\n")
        if cut >= 0:
            keep = start + cut + 1
            break
        end = start
    os.ftruncate(fd, keep)


# -- reading (no lock needed: the log only grows by whole lines) ---------------------


def read_config(path: str | Path) -> RunConfig:
    path = Path(path)
    if not path.is_dir():
        why = "it is a file" if path.exists() else "it does not exist"
        raise RunDirError(f"{path} is not a run directory ({why})")
    if (path / CONFIG).exists() and inside(path.resolve(), CONFIG) is None:
        raise RunDirError(f"{path / CONFIG} leads out of the run directory (a symlink?); refusing to read it")
    try:
        raw = json.loads((path / CONFIG).read_bytes())
        if isinstance(raw, dict) and "prompts" not in raw:
            raw["prompts"] = "before-parity"  # written before the config named its prompts
        return RunConfig.model_validate(raw)
    except FileNotFoundError:
        raise RunDirError(f"{path} is not a run directory (no {CONFIG})") from None
    except OSError as e:
        raise RunDirError(f"cannot read {path / CONFIG}: {e.strerror or e}") from None
    except ValidationError as e:
        raise RunDirError(f"{path / CONFIG} is not a valid run config: {_first_error(e)}") from None
    except (ValueError, RecursionError) as e:  # not JSON (JSONDecodeError, UnicodeDecodeError), or nested too deep
        raise RunDirError(f"{path / CONFIG} is not a valid run config: not JSON ({one_line(str(e))[:200]})") from None


def read_lines(path: str | Path) -> list[tuple[int, bytes]]:
    """(line number, bytes) of every complete, non-blank line of the attempt log. A torn
    last line is left out."""
    path = Path(path)
    log = path / ATTEMPTS
    if log.exists() and inside(path.resolve(), ATTEMPTS) is None:
        raise RunDirError(f"{log} leads out of the run directory (a symlink?); refusing to read it")
    try:
        data = log.read_bytes()
    except FileNotFoundError:
        return []
    except OSError as e:
        raise RunDirError(f"cannot read {log}: {e.strerror or e}") from None
    complete = data.split(b"\n")[:-1]  # the part after the last newline is empty or torn
    return [(n, line) for n, line in enumerate(complete, 1) if line.strip()]


def parse_line(log: Path, n: int, line: bytes) -> AttemptRecord:
    try:
        return AttemptRecord.model_validate_json(line)
    except ValidationError as e:
        raise RunDirError(f"{log}:{n} is not a valid attempt record ({_first_error(e)}); "
                          f"`deepphy repair {log.parent}` sets the line aside") from None


def read_records(path: str | Path) -> list[AttemptRecord]:
    """All complete records, in the order they were written. A torn last line is ignored."""
    log = Path(path) / ATTEMPTS
    return [parse_line(log, n, line) for n, line in read_lines(path)]


# -- integrity ------------------------------------------------------------------------


@dataclass(frozen=True)
class Problem:
    """The first broken attempt of an episode: it and every later one cannot be used."""

    task: str
    run: int
    attempt: int
    what: str
    fix: str = ""  # said before the repair, when there is a better one


def problems(path: str | Path, records: Sequence[AttemptRecord], k_max: int, frames: bool = True) -> list[Problem]:
    """What a resume cannot go on from, one per broken episode: attempt numbers that are not
    1..n each once (a line deleted, a record duplicated), and (`frames`) for an episode the
    resume will continue, a key frame of its history that is missing or leads out of the
    directory."""
    root = Path(path).resolve()
    episodes: dict[tuple[str, int], list[AttemptRecord]] = defaultdict(list)
    for r in records:
        episodes[(r.task, r.run)].append(r)
    found = []
    for (task, run), recs in episodes.items():
        counts = Counter(r.attempt for r in recs)
        first_bad = 1
        while counts.get(first_bad) == 1:
            first_bad += 1
        problem = None
        if counts.get(first_bad, 0) > 1:
            problem = Problem(task, run, first_bad, f"attempt {first_bad} of task {task} run {run} is recorded "
                                                    f"{counts[first_bad]} times")
        elif max(counts) >= first_bad:
            shown = ", ".join(map(str, sorted(counts)[:12]))
            problem = Problem(task, run, first_bad, f"task {task} run {run} has attempts {shown}: "
                                                    f"attempt {first_bad} is missing")
        kept = sorted((r for r in recs if r.attempt < first_bad), key=lambda r: r.attempt)
        if frames and not episode_finished(kept, k_max):  # the next attempt is shown these frames
            for r in kept:
                bad = next((f.path for f in r.key_frames if not _frame_ok(root, f.path)), None)
                if bad is not None:
                    where = "is missing" if inside(root, bad) is not None else "leads out of the run directory"
                    problem = Problem(task, run, r.attempt, f"the key frame {bad} of task {task} run {run} attempt "
                                                            f"{r.attempt} {where}",
                                      fix="restore it, or" if where == "is missing" else "")
                    break
        if problem is not None:
            found.append(problem)
    return found


def _frame_ok(root: Path, rel: str) -> bool:
    target = inside(root, rel)
    return target is not None and target.is_file()


def check_records(path: str | Path, records: Sequence[AttemptRecord], k_max: int, frames: bool = True) -> None:
    """RunDirError naming the first broken episode (see `problems`) and the way out."""
    found = problems(path, records, k_max, frames)
    if not found:
        return
    p = found[0]
    more = f" (and {len(found) - 1} more episode(s))" if len(found) > 1 else ""
    raise RunDirError(f"{path}: {p.what}{more}; {p.fix + ' ' if p.fix else ''}run `deepphy repair {path}` to keep "
                      f"each broken episode's attempts before the first broken one (the next resume runs the rest)")


@dataclass
class Repair:
    dropped_lines: int
    episodes: list[Problem]
    unreadable: int  # lines that were not valid records
    backup: Path | None


def repair(path: str | Path, k_max: int) -> Repair:
    """Set aside what a resume cannot go on from: lines that are not valid records, and each
    broken episode's attempts from its first broken one on (see `problems`). The old log is
    kept beside the new one (attempts.jsonl.<time>.bak); the next resume runs the dropped
    attempts again. Takes the run's lock."""
    path = Path(path)
    read_config(path)  # a run directory, or a clear error
    store = RunStore(path)
    store._lock()
    try:
        lines = read_lines(path)
        records, unreadable = [], 0
        for n, line in lines:
            try:
                records.append((n, line, AttemptRecord.model_validate_json(line)))
            except ValidationError:
                unreadable += 1
        found = problems(path, [r for _, _, r in records], k_max)
        first_bad = {(p.task, p.run): p.attempt for p in found}
        kept = [line for _, line, r in records if r.attempt < first_bad.get((r.task, r.run), r.attempt + 1)]
        dropped = len(lines) - len(kept)
        if not dropped:
            return Repair(0, [], 0, None)
        log = path / ATTEMPTS
        backup = path / f"{ATTEMPTS}.{time.strftime('%Y%m%d-%H%M%S')}.bak"
        tmp = path / f".{ATTEMPTS}.{os.getpid()}.tmp"
        try:
            tmp.write_bytes(b"".join(line + b"\n" for line in kept))
            os.link(log, backup)  # the old log stays, under its backup name
            os.replace(tmp, log)
        except OSError as e:
            tmp.unlink(missing_ok=True)
            raise _write_failed(path, ATTEMPTS, e) from None
        return Repair(dropped, found, unreadable, backup)
    finally:
        store.close()


def is_stored_prompt(messages: object) -> bool:
    """The shape of a stored prompt (deepphy.prompts.prompt_as_json): a list of
    {"role": str, "content": [part, ...]}, a part a text or an image reference (see
    `stored_image`; older runs hold "<image NAME: CAPTION>" strings). Readers check it: the
    file may have been edited."""
    return isinstance(messages, list) and all(
        isinstance(m, dict) and isinstance(m.get("role"), str) and isinstance(m.get("content"), list)
        and all(isinstance(t, str) or stored_image(t) is not None for t in m["content"]) for m in messages)


def stored_image(part: object) -> tuple[str, str, str] | None:
    """(digest, name, caption) of a stored prompt's image reference, or None if `part` is not one."""
    if not isinstance(part, dict) or set(part) != {"image", "name", "caption"}:
        return None
    digest, name, caption = part["image"], part["name"], part["caption"]
    if not (isinstance(digest, str) and IMAGE_DIGEST.match(digest) and isinstance(name, str) and isinstance(caption, str)):
        return None
    return digest, name, caption


def read_image(path: str | Path, digest: str) -> bytes | None:
    """The bytes of images/<digest>.png of a run directory, checked to hash to `digest`: the
    one reader of stored images (`read_prompt`, the dashboard, the export, a resume that finds
    one already there). None if the run did not store it; RunDirError in one line if it, or
    images/, leads out of the run directory, or its bytes hash to something else."""
    path = Path(path)
    rel = f"{IMAGES}/{digest}.png"
    if not IMAGE_DIGEST.match(digest):
        raise RunDirError(f"{path}: {digest[:80]!r} is not an image digest")
    root = path.resolve()
    target = inside(root, rel)
    if target is None or target.parent != root / IMAGES:
        raise RunDirError(f"{path}/{rel} leads out of the run directory (a symlink?); refusing to read it")
    try:
        with open(target, "rb") as f:
            png = f.read(MAX_IMAGE_BYTES + 1)
    except (FileNotFoundError, IsADirectoryError):
        return None
    except OSError as e:
        raise RunDirError(f"{path}/{rel} cannot be read ({e.strerror or type(e).__name__})") from None
    if len(png) > MAX_IMAGE_BYTES or image_digest(png) != digest:
        raise RunDirError(f"{path}/{rel} is damaged: its bytes do not hash to its name")
    return png


def check_confined(path: str | Path, entries: set[str] | None = None) -> None:
    """RunDirError unless each of a run directory's own entries (attempts.jsonl, images/,
    frames/, ...) stays inside it: what resumes, exports and plays check before reading."""
    path = Path(path)
    root = path.resolve()
    if entries is None:
        entries = {name for name in OWN_ENTRIES if os.path.lexists(path / name)}
    escaped = sorted(name for name in entries & OWN_ENTRIES if inside(root, name) is None)
    if escaped:
        raise RunDirError(f"{path}/{escaped[0]} leads out of the run directory (a symlink?); refusing to use it")


def episode_prompts(path: str | Path, task: str, run: int) -> dict[str, list[dict]]:
    """Every prompt in the log of episode (task, run), by digest, read once: for callers that
    walk an episode (give it to `stored_prompt_json`). The first line of a digest counts (a
    resume may append one again); a line that is torn, too long or not a stored prompt is
    skipped. Empty for a run from before these logs."""
    return _read_log(Path(path), task, run)[0]


def stored_prompt_json(path: str | Path, task: str, run: int, digest: str,
                       logged: dict[str, list[dict]] | None = None) -> list[dict]:
    """The JSON of prompt `digest` of episode (task, run), checked to be a stored prompt:
    from the episode's log (`logged`: that log as `episode_prompts` read it), else, in a run
    from before these logs, from prompts/<digest>.json. RunDirError in one line otherwise."""
    path = Path(path)
    if not PROMPT_DIGEST.fullmatch(digest):
        raise RunDirError(f"{path}: {digest[:80]!r} is not a prompt digest")
    if logged is None:
        logged = _read_log(path, task, run, digest)[0]
    if digest in logged:
        return logged[digest]
    old = f"{PROMPTS}/{digest}.json"
    target = inside(path.resolve(), old)
    if target is None:
        raise RunDirError(f"{path}: {old} leads out of the run directory; refusing to read it")
    try:
        with open(target, "rb") as f:
            data = f.read(MAX_PROMPT_BYTES + 1)
    except FileNotFoundError:
        rejected = _read_log(path, task, run, digest)[1]  # on the way to an error: say why
        why = "is not a stored prompt (a list of messages)" if rejected else "is missing"
        raise RunDirError(f"{path}: prompt {digest} {why} (in {prompt_log(task, run)})") from None
    except OSError as e:
        raise RunDirError(f"{path}: {old} cannot be read ({e.strerror or type(e).__name__})") from None
    try:
        stored = json.loads(data) if len(data) <= MAX_PROMPT_BYTES else None
    except (ValueError, RecursionError) as e:
        raise RunDirError(f"{path}: {old} cannot be read ({type(e).__name__})") from None
    if not is_stored_prompt(stored):
        raise RunDirError(f"{path}: {old} is not a stored prompt (a list of messages)")
    return stored


def _read_log(path: Path, task: str, run: int, digest: str | None = None) -> tuple[dict[str, list[dict]], int]:
    """The stored prompts of an episode's log by digest (only `digest`'s, if given: other
    lines are not parsed), and how many of the lines looked at were skipped as not a stored
    prompt."""
    rel = prompt_log(task, run)
    target = inside(path.resolve(), rel) if SAFE_ID.fullmatch(task) and run >= 0 else None
    if target is None:
        raise RunDirError(f"{path}: {rel} leads out of the run directory; refusing to read it")
    found: dict[str, list[dict]] = {}
    rejected = 0
    try:
        with open(target, "rb") as f:
            for line in _complete_lines(f):
                if digest is not None and digest.encode() not in line:
                    continue
                entry = _logged_prompt(line)
                if entry is None:
                    rejected += 1
                elif entry[0] not in found and digest in (None, entry[0]):
                    found[entry[0]] = entry[1]
                    if digest is not None:
                        break
    except FileNotFoundError:
        pass  # nothing logged: a run from before these logs, or an episode not begun
    except OSError as e:
        raise RunDirError(f"{path}: {rel} cannot be read ({e.strerror or type(e).__name__})") from None
    return found, rejected


def _complete_lines(f) -> Iterator[bytes]:
    """The lines of a log that end in a newline (a torn last line has none), without it; a
    line longer than MAX_PROMPT_BYTES comes back empty, skipped without being held."""
    while True:
        line = f.readline(MAX_PROMPT_BYTES + 1)
        if line.endswith(b"\n"):
            yield line[:-1]
        elif len(line) <= MAX_PROMPT_BYTES:
            return  # the end of the log
        else:
            while line and not line.endswith(b"\n"):  # the rest of the over-long line
                line = f.readline(TAIL_BLOCK)
            yield b""


def _logged_prompt(line: bytes) -> tuple[str, list[dict]] | None:
    """(digest, messages) of a prompt log's line, or None if it is not one."""
    try:
        entry = json.loads(line)
    except (ValueError, RecursionError):
        return None
    if not (isinstance(entry, dict) and set(entry) == {"digest", "messages"} and isinstance(entry["digest"], str)
            and PROMPT_DIGEST.fullmatch(entry["digest"]) and is_stored_prompt(entry["messages"])):
        return None
    return entry["digest"], entry["messages"]


def read_prompt(path: str | Path, task: str, run: int, digest: str) -> list[Message]:
    """The exact messages of prompt `digest` of episode (task, run), images included (read
    from images/ and checked against their digests, `read_image`): the request a model
    received, rebuilt from the run directory. RunDirError if the prompt or an image is missing,
    malformed or damaged, or from a run that did not store its images."""
    root = Path(path).resolve()
    stored = stored_prompt_json(path, task, run, digest)
    rel = f"prompt {digest}"
    if any(m["role"] not in ("system", "user", "assistant") for m in stored):
        raise RunDirError(f"{path}: {rel} is not a stored prompt (a list of messages)")
    messages = []
    for m in stored:
        content: list[TextPart | ImagePart] = []
        for part in m["content"]:
            ref = stored_image(part)
            if ref is None:
                if OLD_IMAGE_PLACEHOLDER.match(part):
                    raise RunDirError(f"{path}: {rel} names an image it did not store (a run from before images/)")
                content.append(TextPart(text=part))
                continue
            image_digest_, name, caption = ref
            png = read_image(root, image_digest_)
            if png is None:
                raise RunDirError(f"{path}: image {image_digest_[:12]}... of {rel} is missing")
            content.append(ImagePart(image=Image(name=name, caption=caption, png=png)))
        messages.append(Message(role=m["role"], content=content))
    return messages


def atomic_write(target: str | Path, data: bytes) -> None:
    """Write to a temporary file renamed into place; the temporary file never stays behind.
    (os-level calls: a run writes several files per decision.)"""
    head, name = os.path.split(target)
    tmp = os.path.join(head, f".{name}.{os.getpid()}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _first_error(e: ValidationError) -> str:
    return validation_message(e)[:200]  # bounded: the data it quotes came from disk


def _diff(old: dict, new: dict) -> str:
    keys = sorted(k for k in old.keys() | new.keys() if old.get(k) != new.get(k))
    return ", ".join(f"{k}: {json.dumps(old.get(k))} -> {json.dumps(new.get(k))}" for k in keys)
