"""Pooltool: single-player nine-ball on the real `pooltool-billiards` package.

Each shot the cue is aimed automatically at the centre of the lowest-numbered ball on
the table (a full-ball hit, `pooltool.ai.aim.at_ball`, no cut); the agent chooses only
the cue speed and where the tip strikes the cue ball. The physics and the nine-ball rules
are pooltool's own (`pt.simulate` with an explicit engine, pooltool's NINEBALL ruleset);
the rack, the ball-in-hand placement and the rendering are ours.

Decisions (documented in the README):
- Actions: `Speed: Low|Medium|High` = cue speed 2 / 5 / 8 m/s, and `Strikespot:` one of
  nine spots on the cue ball as the shooter sees it. Edge spots sit half a ball radius
  from the centre on an axis, corner spots at +-0.35 on both axes (radius 0.495, the
  same distance from the centre), in pooltool's units of the ball radius:
      top-left (+0.35, +0.35)   top-centre (0, +0.5)    top-right (-0.35, +0.35)
      middle-left (+0.5, 0)     middle-centre (0, 0)    middle-right (-0.5, 0)
      bottom-left (+0.35,-0.35) bottom-centre (0, -0.5) bottom-right (-0.35, -0.35)
  as (a, b); pooltool's a = +1 is the LEFT edge of the ball, b = +1 the top. Top = follow,
  bottom = draw, left / right = side spin. 3 x 9 = 27 actions.
- Racks: pooltool's nine-ball diamond (1 at the apex on the foot spot, 9 in the middle,
  2-8 in the other places, each ball jittered inside (1 + 1e-3) R as `get_rack` does) and
  pooltool's break position of the cue ball (0.85 w, 0.23 l). We draw the permutation and
  the jitter from `seeded_rng("pooltool", "rack", k)`, name the balls ourselves and insert
  them in a fixed order (cue, 1..9): pooltool's `get_rack` has no seed and takes ball ids
  from a Python set, and dict order changes collision order, so its racks differ between
  processes.
- Physics engine: `PhysicsEngine(resolver=default_resolver())`, passed explicitly, so a
  user's ~/.config/pooltool/physics/resolver.yaml cannot change the physics.
- Rules: pooltool's nine-ball (legal break: a pot or 4 balls to a cushion; afterwards the
  lowest ball must be hit first and then a ball must be potted or a ball must reach a
  cushion; the cue ball must stay on the table). One player: the turn never passes.
  Success = the 9-ball potted on a legal shot (on the break too).
- Ball in hand: after any foul the cue ball is placed on the head spot (w/2, l/4), where
  pooltool's ruleset puts it; if a ball lies there, on the nearest free point of a fixed
  grid (2 mm steps, ties broken by position), see `_free_spot`.
- A 9-ball potted on a foul is respotted on the foot spot (w/2, 3l/4) or the nearest free
  point (standard nine-ball rule; pooltool only respots it when it was the last ball).
- Attempts: one game per task (max_attempts 1), at most 15 shots (max_steps 15).
- Numba: pooltool compiles its kernels on the first shot (~25-30 s of CPU). We point
  NUMBA_CACHE_DIR at $DEEPPHY_CACHE_DIR/numba (default ~/.cache/deepphy/numba) before
  numba is imported, so every process and worker on a machine shares one cache, and the
  first step of each process simulates a warm-up break under a file lock (`warm_up`), so
  concurrent workers on a cold machine compile once, not once each.

This module imports pooltool lazily: the action space must be importable (and rebuilt
from JSON by the MOCK model) without pulling in panda3d and numba.
"""

from __future__ import annotations

import functools
import math
import os
import re
from pathlib import Path
from typing import Any, Literal, Sequence

import cv2
import numpy as np

from deepphy.envs.base import (
    Action,
    ActionSpace,
    Environment,
    InvalidAction,
    Observation,
    Planning,
    StepResult,
    Task,
    seeded_rng,
)
from deepphy.envs.images import FONT, Image

NUM_RACKS = 100
MAX_SHOTS = 15
MAX_EVENTS = 5000  # bounds rare, very long shots (balls set stationary after that many events)

SPEEDS: dict[str, float] = {"Low": 2.0, "Medium": 5.0, "High": 8.0}  # cue speed, m/s
ROWS = ("top", "middle", "bottom")
COLS = ("left", "centre", "right")
SPOTS: tuple[str, ...] = tuple(f"{r}-{c}" for r in ROWS for c in COLS)
# (a, b) in pooltool's units of the ball radius: a = +1 is the ball's LEFT edge, b = +1 its top.
SPOT_OFFSETS: dict[str, tuple[float, float]] = {
    "top-left": (0.35, 0.35),
    "top-centre": (0.0, 0.5),
    "top-right": (-0.35, 0.35),
    "middle-left": (0.5, 0.0),
    "middle-centre": (0.0, 0.0),
    "middle-right": (-0.5, 0.0),
    "bottom-left": (0.35, -0.35),
    "bottom-centre": (0.0, -0.5),
    "bottom-right": (-0.35, -0.35),
}
ACTIONS: tuple[tuple[str, str], ...] = tuple((s, p) for s in SPEEDS for p in SPOTS)  # the 27, in order


# -- action space ---------------------------------------------------------------------


class PoolShot(Action):
    speed: Literal["Low", "Medium", "High"]
    spot: Literal[
        "top-left", "top-centre", "top-right",
        "middle-left", "middle-centre", "middle-right",
        "bottom-left", "bottom-centre", "bottom-right",
    ]

    @property
    def velocity(self) -> float:
        return SPEEDS[self.speed]

    @property
    def offsets(self) -> tuple[float, float]:
        return SPOT_OFFSETS[self.spot]


_SPEED_WORDS = {
    "low": "Low", "slow": "Low", "soft": "Low", "2": "Low",
    "medium": "Medium", "med": "Medium", "mid": "Medium", "moderate": "Medium", "5": "Medium",
    "high": "High", "fast": "High", "hard": "High", "strong": "High", "8": "High",
}
_VERTICAL = {"top": "top", "upper": "top", "up": "top", "high": "top",
             "bottom": "bottom", "lower": "bottom", "low": "bottom", "down": "bottom"}
_HORIZONTAL = {"left": "left", "right": "right"}
_NEUTRAL = {"middle", "centre", "center", "central", "mid", "centered", "centred"}
_FILLER = {"of", "the", "ball", "cue", "spot", "side", "edge", "hit", "strike", "at", "on", "and", "a"}

_KEY_TAIL = r"[\s*_`\"']*[:=][\s*_`\"']*"  # `Speed:`, `**Speed:**`, `"speed": "`, `speed = `
_SPEED_RE = re.compile(r"\bspeed" + _KEY_TAIL + r"([a-z0-9.]+)(\s*m\s*/\s*s)?", re.I)
_SPOT_RE = re.compile(r"(?:\bstrike[\s_\-]*|\b)spot" + _KEY_TAIL + r"([a-z][a-z \t\-_]*)", re.I)


def _parse_speed(value: str) -> str:
    v = value.strip().lower().rstrip(".")
    if v.endswith(".0"):
        v = v[:-2]
    if v in _SPEED_WORDS:
        return _SPEED_WORDS[v]
    raise InvalidAction(f"speed {value!r} is not Low, Medium or High")


def _parse_spot(value: str) -> str:
    words = [w for w in re.split(r"[\s\-_]+", value.strip().lower()) if w]
    rows, cols, known = set(), set(), 0
    for w in words:
        if w in _VERTICAL:
            rows.add(_VERTICAL[w])
        elif w in _HORIZONTAL:
            cols.add(_HORIZONTAL[w])
        elif w not in _NEUTRAL:
            if w in _FILLER:
                continue
            break  # the spot name has ended (prose follows)
        known += 1
    if not known:
        raise InvalidAction(f"strike spot {value.strip()!r} is not one of {', '.join(SPOTS)}")
    if len(rows) > 1 or len(cols) > 1:
        raise InvalidAction(f"strike spot {value.strip()!r} names two different spots")
    row = rows.pop() if rows else "middle"
    col = cols.pop() if cols else "centre"
    return f"{row}-{col}"


class PoolSpace(ActionSpace):
    """Speed (3 levels) x strike spot on the cue ball (9 spots) = 27 shots."""

    kind: Literal["pooltool_shot"] = "pooltool_shot"

    def parse(self, text: str) -> PoolShot:
        text = text.replace("```", " ")
        speeds = _SPEED_RE.findall(text)
        spots = _SPOT_RE.findall(text)
        if not speeds:
            raise InvalidAction("no `Speed: Low|Medium|High` found")
        if not spots:
            raise InvalidAction("no `Strikespot: <spot>` found")
        # The last well-formed value of each counts: replies often restate the answer at the end.
        speed = _last_valid(_parse_speed, [s for s, _ in speeds])
        spot = _last_valid(_parse_spot, spots)
        return PoolShot(speed=speed, spot=spot)

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> PoolShot:
        # Uniform over all 27 shots. `exclude` (actions of earlier failed games) is ignored:
        # a shot's effect depends on the table, so an action from another game is no repeat.
        speed, spot = ACTIONS[int(rng.integers(len(ACTIONS)))]
        return PoolShot(speed=speed, spot=spot)

    def format(self, action: Action) -> str:
        assert isinstance(action, PoolShot)
        return f"Speed: {action.speed}, Strikespot: {action.spot}"

    def all_actions(self) -> list[PoolShot]:
        return [PoolShot(speed=s, spot=p) for s, p in ACTIONS]


def _last_valid(parse, values: list[str]) -> str:
    error: InvalidAction | None = None
    for value in reversed(values):
        try:
            return parse(value)
        except InvalidAction as e:
            error = error or e
    assert error is not None
    raise error


# -- pooltool, lazily -----------------------------------------------------------------


def cache_root() -> Path:
    return Path(os.environ.get("DEEPPHY_CACHE_DIR") or "~/.cache/deepphy").expanduser()


def configure_numba_cache() -> Path:
    """Point numba's cache at the shared per-machine directory (before numba is imported).

    An explicit NUMBA_CACHE_DIR is respected. If numba is already imported, its config is
    re-read so the directory still takes effect for kernels compiled from now on.
    """
    import sys

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
    import pooltool

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

    Under an exclusive file lock in the cache directory: when several workers start on a
    cold machine, one compiles and writes the cache while the others wait and then load
    it, so the compile cost is paid once per machine. Later shots that reach a kernel the
    break did not use compile it once and add it to the same cache.
    """
    import fcntl

    pt = _pt()
    lock_path = configure_numba_cache() / "pooltool-warm-up.lock"
    lock_path.parent.mkdir(parents=True, exist_ok=True)
    with open(lock_path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            system = build_system(0)
            system.strike(V0=SPEEDS["High"], phi=pt.aim.at_ball(system, "1"), theta=0.0, a=0.0, b=0.0)
            pt.simulate(system, engine=_engine(), inplace=True, max_events=MAX_EVENTS)
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


# -- racks ----------------------------------------------------------------------------

_SPACING = 1e-3  # pooltool's default spacing_factor
# pooltool's nine-ball blueprint: (translation from the previous place, which balls may go there)
_S3 = math.sqrt(3.0)
_JUMPS = [(-1.0, _S3), (2.0, 0.0), (1.0, _S3), (-2.0, 0.0), (-2.0, 0.0), (1.0, _S3), (2.0, 0.0), (-1.0, _S3)]
_NINE_PLACE = 4  # index (after the apex) of the middle of the diamond


def rack_layout(k: int) -> dict[str, tuple[float, float]]:
    """Ball id -> (x, y) in metres for rack `k`, in the insertion order used (cue, 1..9)."""
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
    out = {"cue": (0.85 * table.w, 0.23 * table.l)}
    out.update({str(i): where[str(i)] for i in range(1, 10)})
    return out


@functools.lru_cache(maxsize=None)
def _ball_params():
    pt = _pt()
    return pt.BallParams.default(game_type=pt.GameType.NINEBALL)


def build_system(k: int):
    """A fresh pooltool System for rack `k` (balls inserted in the fixed order cue, 1..9)."""
    import attrs

    pt = _pt()  # before any other pooltool import
    from pooltool.objects.ball.sets import get_ballset

    table = pt.Table.default()
    params = attrs.asdict(_ball_params())
    ballset = get_ballset("pooltool_pocket")
    balls = {
        ball_id: pt.Ball.create(ball_id, xy=xy, ballset=ballset, **params)
        for ball_id, xy in rack_layout(k).items()
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
    from pooltool.ruleset.utils import respot

    respot(system, ball_id, xy[0], xy[1])
    ball = system.balls[ball_id]
    ball.state.rvw[1] = np.zeros(3)
    ball.state.rvw[2] = np.zeros(3)


# -- rendering ------------------------------------------------------------------------

SCALE = 380.0  # pixels per metre: the table (1.98 m x 0.99 m) renders at 825 x 449 px
MARGIN = 0.11  # metres of rail drawn around the playing surface
RAIL, CUSHION, CLOTH, NOSE, POCKET = (92, 58, 30), (18, 92, 52), (28, 128, 72), (12, 70, 38), (8, 8, 8)
BALL_COLOURS: dict[str, tuple[int, int, int]] = {
    "cue": (250, 250, 245),
    "1": (245, 200, 0), "2": (20, 70, 200), "3": (215, 35, 35), "4": (110, 45, 150),
    "5": (250, 120, 10), "6": (0, 120, 55), "7": (125, 25, 35), "8": (15, 15, 15),
    "9": (245, 200, 0),  # a stripe: drawn as a yellow band on white
}
DARK_BALLS = {"2", "3", "4", "6", "7", "8"}  # numbers written in white on these
TARGET_RING = (255, 40, 200)
AIM_LINE = (235, 235, 235)
TRACE = (255, 255, 255)


def _to_px(x: float, y: float) -> tuple[int, int]:
    """Table (x across, y along) -> image (u right, v down): the long axis is horizontal,
    the head rail (where the break starts) on the left, the rack on the right."""
    return int(round((y + MARGIN) * SCALE)), int(round((x + MARGIN) * SCALE))


def render_table(system, *, target: str | None = None, traces: dict[str, np.ndarray] | None = None) -> np.ndarray:
    table = system.table
    R = _ball_params().R
    width = int(round((table.l + 2 * MARGIN) * SCALE))
    height = int(round((table.w + 2 * MARGIN) * SCALE))
    img = np.empty((height, width, 3), np.uint8)
    img[:] = RAIL
    cw = 0.045
    cv2.rectangle(img, _to_px(-cw, -cw), _to_px(table.w + cw, table.l + cw), CUSHION, -1)
    cv2.rectangle(img, _to_px(0, 0), _to_px(table.w, table.l), CLOTH, -1)
    # head string and the head / foot spots, faintly (ball in hand and respot places)
    cv2.line(img, _to_px(0, table.l / 4), _to_px(table.w, table.l / 4), (60, 150, 95), 1, cv2.LINE_AA)
    for spot in ((table.w / 2, table.l / 4), (table.w / 2, 3 * table.l / 4)):
        cv2.circle(img, _to_px(*spot), 3, (60, 150, 95), -1, cv2.LINE_AA)
    for seg in table.cushion_segments.linear.values():
        cv2.line(img, _to_px(seg.p1[0], seg.p1[1]), _to_px(seg.p2[0], seg.p2[1]), NOSE, 2, cv2.LINE_AA)
    for seg in table.cushion_segments.circular.values():
        cv2.circle(img, _to_px(seg.center[0], seg.center[1]), max(1, int(round(seg.radius * SCALE))), NOSE, -1, cv2.LINE_AA)
    for pocket in table.pockets.values():
        cv2.circle(img, _to_px(pocket.center[0], pocket.center[1]), int(round(pocket.radius * SCALE)), POCKET, -1, cv2.LINE_AA)

    balls = {b.id: b for b in system.balls.values() if b.state.s != 4}
    if traces:
        for ball_id, path in traces.items():
            pts = np.array([_to_px(x, y) for x, y in path], np.int32)
            if len(pts) > 1:
                colour = TRACE if ball_id == "cue" else BALL_COLOURS[ball_id]
                cv2.polylines(img, [pts], False, colour, 1, cv2.LINE_AA)
    if target is not None and target in balls and "cue" in balls:
        a = balls["cue"].state.rvw[0][:2]
        b = balls[target].state.rvw[0][:2]
        _dashed(img, _to_px(*a), _to_px(*b), AIM_LINE)
    r = R * SCALE
    for ball_id, ball in balls.items():
        x, y = ball.state.rvw[0][:2]
        c = _to_px(x, y)
        ri = int(round(r))
        if ball_id == "9":
            cv2.circle(img, c, ri, BALL_COLOURS["cue"], -1, cv2.LINE_AA)
            band = np.zeros_like(img[..., 0])
            cv2.circle(band, c, ri, 255, -1, cv2.LINE_AA)
            stripe = np.zeros_like(band)
            h = max(2, int(round(r * 0.55)))
            cv2.rectangle(stripe, (c[0] - ri - 1, c[1] - h), (c[0] + ri + 1, c[1] + h), 255, -1)
            mask = (band > 127) & (stripe > 0)
            img[mask] = BALL_COLOURS["9"]
        else:
            cv2.circle(img, c, ri, BALL_COLOURS[ball_id], -1, cv2.LINE_AA)
        cv2.circle(img, c, ri, (0, 0, 0), 1, cv2.LINE_AA)
        if ball_id != "cue":
            text_colour = (255, 255, 255) if ball_id in DARK_BALLS else (0, 0, 0)
            (tw, th), _ = cv2.getTextSize(ball_id, FONT, 0.45, 1)
            cv2.putText(img, ball_id, (c[0] - tw // 2, c[1] + th // 2), FONT, 0.45, text_colour, 1, cv2.LINE_AA)
        if ball_id == target:
            cv2.circle(img, c, ri + 4, TARGET_RING, 2, cv2.LINE_AA)
    return img


def _dashed(img: np.ndarray, p: tuple[int, int], q: tuple[int, int], colour, dash: int = 8) -> None:
    length = math.hypot(q[0] - p[0], q[1] - p[1])
    n = int(length // dash)
    for i in range(0, n, 2):
        a = (int(p[0] + (q[0] - p[0]) * i / n), int(p[1] + (q[1] - p[1]) * i / n))
        b = (int(p[0] + (q[0] - p[0]) * (i + 1) / n), int(p[1] + (q[1] - p[1]) * (i + 1) / n))
        cv2.line(img, a, b, colour, 1, cv2.LINE_AA)


def _traces(system, moved: set[str]) -> dict[str, np.ndarray]:
    """Ball paths during the last shot, from the event history (straight between events,
    which is exact for rolling balls and close for the short sliding phases)."""
    out = {}
    for ball_id in sorted(moved):  # a fixed drawing order: set order varies with PYTHONHASHSEED
        hist = system.balls[ball_id].history
        out[ball_id] = np.array([s.rvw[0][:2] for s in hist.states])
    return out


# -- the environment ------------------------------------------------------------------


class PooltoolEnv(Environment):
    name = "pooltool"
    title = "Pooltool"
    planning = Planning.ON_THE_FLY
    max_attempts = 1
    max_steps = MAX_SHOTS

    def __init__(self, options=None) -> None:
        super().__init__(options)
        self._system: Any = None
        self._game: Any = None
        self._task: Task | None = None
        self._shots = 0
        self._note = ""

    @classmethod
    def tasks(cls, options) -> list[Task]:
        return [Task(env=cls.name, id=f"rack_{k:03d}", params={"rack": k}) for k in range(NUM_RACKS)]

    @staticmethod
    def rack_index(task: Task) -> int:
        if "rack" in task.params:
            return int(task.params["rack"])
        m = re.fullmatch(r"(?:rack_)?(\d+)", task.id)
        if not m:
            raise ValueError(f"not a pooltool task id: {task.id!r}")
        return int(m.group(1))

    # -- the contract ---------------------------------------------------------------

    def reset(self, task: Task) -> Observation:
        pt = _pt()
        self._task = task
        self._system = build_system(self.rack_index(task))
        self._game = pt.get_ruleset(pt.GameType.NINEBALL)(players=[pt.Player("agent")])
        self._shots = 0
        self._note = "Break shot: the cue ball starts behind the head string."
        return self._observation()

    def step(self, action: Action) -> StepResult:
        assert isinstance(action, PoolShot) and self._system is not None
        pt = _pt()
        warm_up()
        system, game = self._system, self._game
        target = _on_table(system)[0]
        a, b = action.offsets
        system.reset_history()
        system.strike(V0=action.velocity, phi=pt.aim.at_ball(system, target), theta=0.0, a=a, b=b)
        pt.simulate(system, engine=_engine(), inplace=True, max_events=MAX_EVENTS)
        self._shots += 1
        events = system.events
        potted = [e.agents[0].id for e in pt.events.filter_type(events, pt.EventType.BALL_POCKET)]
        first_hit = _first_hit(system)
        moved = {bid for bid, ball in system.balls.items() if _moved(ball)}
        traces = _traces(system, moved)
        truncated = len(events) >= MAX_EVENTS

        game.process_and_advance(system)
        info_obj = game.shot_info
        legal, game_over = bool(info_obj.legal), bool(info_obj.game_over)
        success = game_over and "9" in potted and legal

        notes: list[str] = []
        if not legal and not game_over:
            if "9" in potted:
                if system.balls["9"].state.s == 4:  # pooltool respots it only when it was the last ball
                    _place(system, "9", _free_spot(system, (system.table.w / 2, 3 * system.table.l / 4), "9"))
                notes.append("the 9-ball was potted on a foul, so it is respotted on the foot spot")
            spot = (system.table.w / 2, system.table.l / 4)
            where = _free_spot(system, spot, "cue")
            _place(system, "cue", where)
            notes.append(
                "ball in hand: the cue ball is placed on the head spot"
                if where == spot
                else "ball in hand: the cue ball is placed next to the head spot (it was occupied)"
            )

        outcome = self._describe_shot(action, target, first_hit, potted, legal, info_obj.reason, notes, truncated)
        frame = render_table(system, traces=traces)
        key = Image.from_array(
            f"shot_{self._shots}",
            f"the table after shot {self._shots}, with the paths the balls took (cue ball in white)",
            frame,
        )
        done = success or self._shots >= MAX_SHOTS
        info = {
            "shots": self._shots,
            "target": target,
            "first_hit": first_hit,
            "potted": potted,
            "legal": legal,
            "foul": None if legal else info_obj.reason,
            "balls_left": _on_table(system),
            "events": len(events),
        }
        if not done:
            self._note = " ".join(n[0].upper() + n[1:] + "." for n in notes)
        if done and not success:
            outcome += f" The game is over: the 9-ball was not potted legally within {MAX_SHOTS} shots."
        return StepResult(
            done=done,
            success=success,
            observation=None if done else self._observation(),
            feedback=outcome,
            key_frames=[key],
            info=info,
        )

    # -- text -----------------------------------------------------------------------

    def _describe_shot(self, action, target, first_hit, potted, legal, reason, notes, truncated) -> str:
        parts = [f"Shot {self._shots} ({action.speed}, {action.spot}) aimed at the {target}-ball"]
        parts.append(f"first hit: {'the ' + first_hit + '-ball' if first_hit else 'nothing'}")
        numbered = [p for p in potted if p != "cue"]
        parts.append("potted: " + (", ".join(numbered) if numbered else "none"))
        if "cue" in potted:
            parts.append("the cue ball was potted (scratch)")
        if legal:
            parts.append("legal shot")
            if "9" in numbered:
                parts.append("the 9-ball is down: game won")
        else:
            parts.append(f"FOUL: {reason.rstrip('!.')}")
        parts += notes
        if truncated:
            parts.append(f"(simulation stopped after {MAX_EVENTS} events)")
        return "; ".join(parts) + "."

    def _observation(self) -> Observation:
        system = self._system
        balls = _on_table(system)
        target = balls[0]
        img = render_table(system, target=target)
        cue = system.balls["cue"].state.rvw[0]
        lines = [
            f"Shot {self._shots + 1} of at most {MAX_SHOTS}.",
        ]
        if self._note:
            lines.append(self._note)
        lines.append(f"Balls on the table: {', '.join(balls)}. Target (lowest-numbered) ball: {target}.")
        lines.append(
            "Positions in metres, measured in the image: X from the left end of the playing "
            "surface to the right (0 to {:.2f}), Y from the top edge down (0 to {:.2f}):".format(
                system.table.l, system.table.w
            )
        )
        lines.append(f"  cue ball: X={cue[1]:.2f}, Y={cue[0]:.2f}")
        for bid in balls:
            p = system.balls[bid].state.rvw[0]
            lines.append(f"  {bid}-ball: X={p[1]:.2f}, Y={p[0]:.2f}")
        return Observation(
            images=[
                Image.from_array(
                    "table",
                    "Top-down view of the table. The dashed line shows where the cue will send the "
                    f"cue ball (at the {target}-ball, circled in magenta).",
                    img,
                )
            ],
            text="\n".join(lines),
            action_space=PoolSpace(),
        )


def _first_hit(system) -> str | None:
    from pooltool.ruleset.utils import get_id_of_first_ball_hit

    return get_id_of_first_ball_hit(system, cue="cue")


def _moved(ball) -> bool:
    hist = ball.history
    if len(hist.states) < 2:
        return False
    return not np.allclose(hist.states[0].rvw[0], hist.states[-1].rvw[0]) or hist.states[-1].s == 4
