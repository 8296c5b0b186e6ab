"""Everything that touches pooltool (imported lazily: panda3d and numba are heavy): the
numba cache, the physics engine, the warm-up break, racks, ball placement."""

from __future__ import annotations

import fcntl
import functools
import hashlib
import math
import os
import sys
from importlib.metadata import version
from pathlib import Path

import numpy as np

from deepphy.cache import cache_root
from deepphy.envs.pooltool.space import SPEEDS
from deepphy.seeding import seeded_rng

MAX_EVENTS = 5000  # bounds rare, very long shots (balls set stationary after that many events)
BREAK_POSITION = (0.85, 0.23)  # pooltool's nine-ball break position of the cue ball, as (x/w, y/l)
HEAD_SPOT = (0.5, 0.25)  # ball in hand goes here (pooltool's ruleset does the same)
FOOT_SPOT = (0.5, 0.75)  # a 9-ball potted on a foul is respotted here

# -- pooltool, lazily -----------------------------------------------------------------


def configure_numba_cache() -> Path:
    """Point numba's cache at the shared per-machine directory (before numba is imported).

    An explicit NUMBA_CACHE_DIR is respected. If numba is already imported, its config is
    re-read so the directory still takes effect for kernels compiled from now on.
    """
    if not os.environ.get("NUMBA_CACHE_DIR"):
        path = cache_root() / "numba"
        path.mkdir(parents=True, exist_ok=True)
        os.environ["NUMBA_CACHE_DIR"] = str(path)
        if "numba" in sys.modules:
            sys.modules["numba"].core.config.reload_config()
    return Path(os.environ["NUMBA_CACHE_DIR"])


@functools.lru_cache(maxsize=None)
def _pt():
    configure_numba_cache()
    import pooltool  # after the numba cache is configured (and heavy: panda3d, numba)

    return pooltool


@functools.lru_cache(maxsize=None)
def _engine():
    _pt()  # first: every pooltool import must come after the numba cache is configured
    from pooltool.physics.engine import PhysicsEngine
    from pooltool.physics.resolve.resolver import default_resolver

    return PhysicsEngine(resolver=default_resolver())


@functools.lru_cache(maxsize=None)
def warm_up() -> None:
    """Compile (or load from the shared cache) pooltool's kernels by simulating one break.

    On a cold cache, under an exclusive file lock in the cache directory: when several
    workers start on a cold machine, one compiles and writes the cache while the others
    wait and then load it, so the compile cost is paid once per machine. A marker left by
    that first warm-up says the cache is filled: from then on the workers load the kernels
    at once rather than one after another (about a second each). The marker is named by
    pooltool's and numba's versions and by where pooltool is installed, as numba files its
    kernels by their source's directory: each virtual environment fills its own. Later
    shots that reach a kernel the break did not use compile it once and add it to the
    same cache.
    """
    pt = _pt()
    cache = configure_numba_cache()
    cache.mkdir(parents=True, exist_ok=True)
    where = hashlib.sha1(os.path.dirname(os.path.abspath(pt.__file__)).encode()).hexdigest()[:12]
    filled = cache / f"pooltool-warm-up-{version('pooltool-billiards')}-{version('numba')}-{where}.done"
    if filled.exists():
        _break(pt)
        return
    with open(cache / "pooltool-warm-up.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            _break(pt)
            filled.touch()
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _break(pt) -> None:
    system = build_system(0)
    system.strike(V0=SPEEDS["High"], phi=aim_at(system, "1"), theta=0.0, a=0.0, b=0.0)
    pt.simulate(system, engine=_engine(), inplace=True, max_events=MAX_EVENTS)


_UNIT_X = np.array([1.0, 0.0])  # the x axis, from which pooltool measures the cue's angle phi


def aim_at(system, ball_id: str) -> float:
    """The cue angle phi (degrees) of a full-ball hit on `ball_id`: pooltool's
    `aim.at_ball(system, ball_id)`, to the bit, but with `ptmath.angle`'s reference axis
    passed rather than left to its default. That default is a numpy array, which numba keys
    by its id(): in every new process the signature was new, so each one compiled `angle`
    again and added a cache entry no other process could use. Passed, it loads from cache.
    """
    pt = _pt()
    cue = system.balls[system.cue.cue_ball_id].state.rvw[0]
    target = system.balls[ball_id].state.rvw[0]
    direction = pt.ptmath.angle(pt.ptmath.unit_vector(target - cue), _UNIT_X)
    return direction * 180 / np.pi


# -- racks ----------------------------------------------------------------------------

_SPACING = 1e-3  # pooltool's default spacing_factor
# pooltool's nine-ball blueprint: (translation from the previous place, which balls may go there)
_S3 = math.sqrt(3.0)
_JUMPS = [(-1.0, _S3), (2.0, 0.0), (1.0, _S3), (-2.0, 0.0), (-2.0, 0.0), (1.0, _S3), (2.0, 0.0), (-1.0, _S3)]
_NINE_PLACE = 4  # index (after the apex) of the middle of the diamond


def rack_layout(k: int | str, cue: tuple[float, float] | None = None) -> dict[str, tuple[float, float]]:
    """Ball id -> (x, y) in metres for rack `k`, in the insertion order used (cue, 1..9).
    `cue`: the cue ball's place as fractions (of w, of l); default pooltool's break position."""
    pt = _pt()
    table = pt.Table.default()
    R = _ball_params().R
    rng = seeded_rng("pooltool", "rack", k)
    others = [str(i) for i in rng.permutation(np.arange(2, 9))]
    radius = R * (1 + _SPACING)
    x, y = 0.5 * table.w, 0.75 * table.l
    places = [(x, y)]
    for dx, dy in _JUMPS:
        x, y = x + dx * radius, y + dy * radius
        places.append((x, y))
    ids = ["1"] + others[:_NINE_PLACE - 1] + ["9"] + others[_NINE_PLACE - 1 :]
    where: dict[str, tuple[float, float]] = {}
    for ball_id, (px, py) in zip(ids, places):
        ang = 2 * math.pi * float(rng.random())
        rad = R * _SPACING * float(rng.random())
        where[ball_id] = (px + rad * math.cos(ang), py + rad * math.sin(ang))
    cx, cy = cue or BREAK_POSITION
    out = {"cue": (cx * table.w, cy * table.l)}
    out.update({str(i): where[str(i)] for i in range(1, 10)})
    return out


@functools.lru_cache(maxsize=None)
def _ball_params():
    pt = _pt()
    return pt.BallParams.default(game_type=pt.GameType.NINEBALL)


def build_system(k: int | str, cue: tuple[float, float] | None = None):
    """A fresh pooltool System for rack `k` (balls inserted in the fixed order cue, 1..9)."""
    import attrs  # pooltool's own dependency: loaded with it

    pt = _pt()  # before any other pooltool import
    from pooltool.objects.ball.sets import get_ballset  # after _pt(): numba's cache configured

    table = pt.Table.default()
    params = attrs.asdict(_ball_params())
    ballset = get_ballset("pooltool_pocket")
    balls = {
        ball_id: pt.Ball.create(ball_id, xy=xy, ballset=ballset, **params)
        for ball_id, xy in rack_layout(k, cue).items()
    }
    return pt.System(cue=pt.Cue(cue_ball_id="cue"), table=table, balls=balls)


def _on_table(system) -> list[str]:
    """Numbered balls on the table, lowest first."""
    return sorted(
        (b.id for b in system.balls.values() if b.id != "cue" and b.state.s != 4),
        key=int,
    )


def _free_spot(system, centre: tuple[float, float], ignore: str) -> tuple[float, float]:
    """`centre` if no ball (other than `ignore`) is within 2R + 1 mm, else the nearest free
    point of a 2 mm grid inside the cushions (ties by x then y): deterministic."""
    R = _ball_params().R
    table = system.table
    others = np.array(
        [b.state.rvw[0][:2] for b in system.balls.values() if b.id != ignore and b.state.s != 4]
    ).reshape(-1, 2)
    clear = 2 * R + 1e-3

    def free(p: np.ndarray) -> np.ndarray:
        if not len(others):
            return np.ones(len(p), bool)
        d = np.linalg.norm(p[:, None, :] - others[None, :, :], axis=2)
        return (d > clear).all(axis=1)

    c = np.array(centre, float)
    if free(c[None])[0]:
        return centre
    step = 2e-3
    xs = np.arange(R + step, table.w - R, step)
    ys = np.arange(R + step, table.l - R, step)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
    dist = np.round(np.linalg.norm(pts - c, axis=1), 9)
    order = np.lexsort((pts[:, 1], pts[:, 0], dist))
    for start in range(0, len(order), 2000):
        chunk = pts[order[start : start + 2000]]
        ok = free(chunk)
        if ok.any():
            p = chunk[int(np.argmax(ok))]
            return float(p[0]), float(p[1])
    raise RuntimeError("no free spot on the table")  # cannot happen with ten balls


def _place(system, ball_id: str, xy: tuple[float, float]) -> None:
    from pooltool.ruleset.utils import respot  # pooltool: loaded by _pt() with numba's cache configured

    respot(system, ball_id, xy[0], xy[1])
    ball = system.balls[ball_id]
    ball.state.rvw[1] = np.zeros(3)
    ball.state.rvw[2] = np.zeros(3)
