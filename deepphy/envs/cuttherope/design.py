"""The seeded procedures the 88 level files were made with (`python -m
deepphy.envs.cuttherope.solve generate`). The files are the source of truth: this module
only explains and reproduces how they came to be.

Each box is a list of stages; a stage introduces or mixes mechanics and proposes layouts
from a seeded generator (`propose`). A proposal becomes a level when:
0. its elements do not overlap on the screen (`layout_problem`);
1. doing nothing does not win it (the world run on for RUN_ON_CAP seconds);
2. the oracle (oracle.search) finds a winning plan within the decision limit that uses the
   stage's mechanic (the candy rides a bubble, a cushion is tapped, the candy goes through a
   hat, an active pin catches it, the halves join; spider stages: left alone, a spider takes
   the candy);
3. three stars are placed on that plan's path, preferring points away from the straight
   line to Om Nom (the plan then collects all three; other plans may not);
4. the plan, replayed through the environment, wins with 3 stars.
Within a stage the levels are ordered from easy to hard: by how often the reference random
agent wins (oracle.reference_win_rate), then by the plan's length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from deepphy.envs.cuttherope import constants as C
from deepphy.envs.cuttherope.level import (
    ActivePinSpec,
    BubbleSpec,
    CandySpec,
    CushionSpec,
    ElectricSpec,
    HatPairSpec,
    HatSpec,
    Level,
    PinSpec,
    SpiderSpec,
    SpikeSpec,
)

Point = tuple[float, float]
PLACEHOLDER_STARS = [(1.0, 1.0), (2.0, 1.0), (3.0, 1.0)]  # replaced once a plan's path is known


@dataclass(frozen=True)
class Stage:
    name: str
    count: int  # levels of the box made by this stage
    propose: Callable[[np.random.Generator], dict]  # level fields without id and stars
    mechanic: str | None  # event the winning plan must show (see `uses_mechanic`)
    min_reference_rate: float = 0.0  # the reference random agent must win at least this often (first levels)


# -- geometry helpers ------------------------------------------------------------------------------


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(round(rng.uniform(lo, hi)))


def _clamp(p: Point, margin: float = 24.0) -> Point:
    return (float(round(min(max(p[0], margin), C.WIDTH - margin))),
            float(round(min(max(p[1], margin), C.HEIGHT - margin))))


def _pins_above(rng, candy: Point, n: int, *, spread: float = 70.0, dist=(90.0, 190.0), candy_index: int = 0,
                slack=(1.0, 1.06), spiders: int = 0) -> list[PinSpec]:
    """`n` pins above the candy at angles within +-spread degrees of vertical, spread apart."""
    for _ in range(20):  # pins at least MIN_PIN_GAP apart
        angles = sorted(rng.uniform(-spread, spread, size=n))
        if all(b - a >= 2 * spread / (n + 2) for a, b in zip(angles, angles[1:])):
            break
    pins = []
    spider_pins = set(rng.choice(n, size=min(spiders, n), replace=False).tolist()) if spiders else set()
    for k, a in enumerate(angles):
        d = rng.uniform(*dist)
        p = _clamp((candy[0] + d * math.sin(math.radians(a)), candy[1] - d * math.cos(math.radians(a))))
        length = round(math.dist(p, candy) * rng.uniform(*slack), 1)
        spider = SpiderSpec(delay=round(float(rng.uniform(0.0, 1.0)), 1)) if k in spider_pins else None
        pins.append(PinSpec(pos=p, candy=candy_index, length=length, spider=spider))
    return pins


def _spike_across(rng, p: Point, q: Point, *, at=(0.35, 0.65), length=(80.0, 170.0), tilt=25.0) -> SpikeSpec:
    """A row of spikes across the segment p-q, roughly perpendicular to it."""
    t = rng.uniform(*at)
    c = (p[0] + (q[0] - p[0]) * t, p[1] + (q[1] - p[1]) * t)
    heading = math.degrees(math.atan2(q[1] - p[1], q[0] - p[0])) + 90 + rng.uniform(-tilt, tilt)
    half = rng.uniform(*length) / 2
    dx, dy = half * math.cos(math.radians(heading)), half * math.sin(math.radians(heading))
    return SpikeSpec(a=_clamp((c[0] - dx, c[1] - dy), 8), b=_clamp((c[0] + dx, c[1] + dy), 8))


def _angle_to(p: Point, q: Point) -> float:
    """Screen angle (degrees counter-clockwise from right) from p toward q."""
    return math.degrees(math.atan2(-(q[1] - p[1]), q[0] - p[0]))


def _side_x(rng, x: float, away=(100.0, 260.0)) -> float:
    """An x some distance from `x`, on whichever side has room."""
    d = rng.uniform(*away)
    left, right = x - d, x + d
    options = [v for v in (left, right) if 50 <= v <= C.WIDTH - 50]
    return float(round(options[int(rng.integers(len(options)))] if options else min(max(left, 50), C.WIDTH - 50)))


# -- box 1: ropes, stars, bubbles, spikes ------------------------------------------------------------


def _ropes_first(rng) -> dict:
    """One rope (sometimes two) right above Om Nom: one cut drops it in within a second."""
    candy = (_u(rng, 150, 330), _u(rng, 180, 320))
    n = 1 if rng.random() < 0.7 else 2
    return dict(candies=[CandySpec(pos=candy)], pins=_pins_above(rng, candy, n, spread=30),
                om_nom=(_u(rng, candy[0] - 20, candy[0] + 20), _u(rng, candy[1] + 250, candy[1] + 370)))


def _ropes(rng) -> dict:
    candy = (_u(rng, 110, 370), _u(rng, 140, 290))
    return dict(candies=[CandySpec(pos=candy)], pins=_pins_above(rng, candy, int(rng.integers(2, 4)), spread=75),
                om_nom=(_side_x(rng, candy[0], (70, 230)), _u(rng, 520, 650)))


def _spikes(rng) -> dict:
    level = _ropes(rng)
    candy, mouth = level["candies"][0].pos, level["om_nom"]
    below = (candy[0], mouth[1])
    spikes = [_spike_across(rng, candy, below, at=(0.45, 0.8))]
    if rng.random() < 0.6:
        spikes.append(_spike_across(rng, candy, mouth, at=(0.4, 0.7), length=(60, 120)))
    level["spikes"] = spikes
    return level


def _bubble_lift(rng, *, cushion: bool = False) -> dict:
    """The candy hangs low; a bubble waits on its way; Om Nom sits higher up."""
    candy = (_u(rng, 110, 370), _u(rng, 430, 580))
    pins = _pins_above(rng, candy, int(rng.integers(1, 3)), spread=60, dist=(100, 200))
    bubble = _clamp((candy[0] + rng.uniform(-90, 90), candy[1] + rng.uniform(70, 120)), 40)
    if cushion:
        mouth = (_side_x(rng, bubble[0], (110, 260)), _u(rng, 130, 400))
    else:
        mouth = (_u(rng, bubble[0] - 90, bubble[0] + 90), _u(rng, 120, 380))
    level = dict(candies=[CandySpec(pos=candy)], pins=pins, bubbles=[BubbleSpec(pos=bubble)], om_nom=_clamp(mouth, 50))
    if rng.random() < 0.5:  # spikes overhead punish a late pop
        y = _u(rng, 30, max(40, mouth[1] - 90))
        x0 = _u(rng, 30, 200)
        level["spikes"] = [SpikeSpec(a=(x0, y), b=(min(x0 + rng.uniform(150, 300), C.WIDTH - 20), y))]
    if cushion:
        side = -1 if mouth[0] > bubble[0] else 1  # the cushion sits on the far side and puffs toward Om Nom
        pos = _clamp((bubble[0] + side * rng.uniform(50, 140), rng.uniform(mouth[1] + 30, bubble[1] - 40)), 30)
        level["cushions"] = [CushionSpec(pos=pos, angle=round(_angle_to(pos, (mouth[0], pos[1])) + rng.uniform(-15, 15)))]
    return level


# -- box 2: air cushions, spiders -------------------------------------------------------------------


def _swing_cushion(rng) -> dict:
    """No bubble: a cushion under or beside the hanging candy pushes it while it swings or falls."""
    level = _ropes(rng)
    candy, mouth = level["candies"][0].pos, level["om_nom"]
    pos = _clamp((candy[0] + rng.uniform(-60, 60), candy[1] + rng.uniform(80, 200)), 30)
    level["cushions"] = [CushionSpec(pos=pos, angle=round(_angle_to(pos, mouth) + rng.uniform(-30, 30)))]
    level["spikes"] = [_spike_across(rng, candy, (candy[0], mouth[1]), at=(0.6, 0.85), length=(80, 140))]
    return level


def _spiders(rng) -> dict:
    candy = (_u(rng, 110, 370), _u(rng, 180, 330))
    n = int(rng.integers(2, 4))
    pins = _pins_above(rng, candy, n, spread=75, dist=(110, 220), spiders=int(rng.integers(1, n)))
    level = dict(candies=[CandySpec(pos=candy)], pins=pins, om_nom=(_side_x(rng, candy[0], (60, 220)), _u(rng, 520, 650)))
    if rng.random() < 0.5:
        level["spikes"] = [_spike_across(rng, candy, (candy[0], level["om_nom"][1]), at=(0.5, 0.8), length=(60, 130))]
    return level


def _mixed2(rng) -> dict:
    kind = rng.random()
    if kind < 0.5:
        level = _bubble_lift(rng, cushion=True)
        if rng.random() < 0.6:  # a spider on the first rope
            level["pins"] = [p.model_copy(update={"spider": SpiderSpec(delay=round(float(rng.uniform(0, 1.5)), 1))})
                             if k == 0 else p for k, p in enumerate(level["pins"])]
        return level
    level = _spiders(rng)
    candy, mouth = level["candies"][0].pos, level["om_nom"]
    pos = _clamp((candy[0] + rng.uniform(-80, 80), candy[1] + rng.uniform(90, 220)), 30)
    level["cushions"] = [CushionSpec(pos=pos, angle=round(_angle_to(pos, mouth) + rng.uniform(-30, 30)))]
    return level


# -- box 3: active pins ------------------------------------------------------------------------------


def _active(rng) -> dict:
    candy = (_u(rng, 90, 390), _u(rng, 110, 230))
    pins = _pins_above(rng, candy, int(rng.integers(1, 3)), spread=50, dist=(80, 150))
    n = int(rng.integers(1, 3))
    actives, last = [], candy
    for _ in range(n):
        pos = _clamp((last[0] + rng.choice([-1, 1]) * rng.uniform(40, 160), last[1] + rng.uniform(110, 230)), 50)
        actives.append(ActivePinSpec(pos=pos, radius=_u(rng, 60, 105)))
        last = pos
    mouth = (_side_x(rng, last[0], (120, 280)), _u(rng, min(last[1] + 60, 640), 660))
    level = dict(candies=[CandySpec(pos=candy)], pins=pins, active_pins=actives, om_nom=_clamp(mouth, 50))
    if rng.random() < 0.7:  # spikes under the active pins: just dropping does not do
        y = _u(rng, last[1] + 120, 700)
        x = last[0]
        level["spikes"] = [SpikeSpec(a=_clamp((x - rng.uniform(60, 120), y), 8), b=_clamp((x + rng.uniform(60, 120), y), 8))]
    return level


# -- box 4: magic hats -------------------------------------------------------------------------------


def _hats(rng, *, extra: bool = False) -> dict:
    candy = (_u(rng, 90, 390), _u(rng, 110, 260))
    pins = _pins_above(rng, candy, int(rng.integers(1, 3)), spread=45, dist=(80, 160))
    entry = _clamp((candy[0] + rng.uniform(-40, 40), candy[1] + rng.uniform(140, 280)), 40)
    mouth = _clamp((_side_x(rng, entry[0], (130, 300)), _u(rng, 420, 660)), 50)
    exit_pos = _clamp((rng.uniform(40, 440), rng.uniform(120, mouth[1] - 60)), 40)
    exit_angle = round(_angle_to(exit_pos, mouth) + rng.uniform(-35, 35))
    hats = [HatPairSpec(hats=(HatSpec(pos=entry, angle=round(90 + rng.uniform(-25, 25))),
                              HatSpec(pos=exit_pos, angle=exit_angle)))]
    level = dict(candies=[CandySpec(pos=candy)], pins=pins, hats=hats, om_nom=mouth)
    if extra:
        roll = rng.random()
        if roll < 0.35:  # spikes between the entry hat and Om Nom
            level["spikes"] = [_spike_across(rng, entry, mouth, at=(0.35, 0.65), length=(80, 150))]
        elif roll < 0.6:  # a live barrier on the way out
            a = _spike_across(rng, exit_pos, mouth, at=(0.4, 0.6), length=(90, 150))
            period = round(float(rng.uniform(1.5, 3.0)), 1)
            level["electrics"] = [ElectricSpec(a=a.a, b=a.b, period=period, on=round(period * float(rng.uniform(0.4, 0.6)), 1),
                                               phase=round(float(rng.uniform(0, period)), 1))]
        elif roll < 0.8:  # an active pin catches the candy on its way
            level["active_pins"] = [ActivePinSpec(pos=_clamp(((exit_pos[0] + mouth[0]) / 2, (exit_pos[1] + mouth[1]) / 2 - 40), 40),
                                                  radius=_u(rng, 55, 90))]
        else:  # the candy rides a bubble into the entry hat
            level["bubbles"] = [BubbleSpec(pos=entry)]
            level["hats"] = [HatPairSpec(hats=(HatSpec(pos=_clamp((entry[0], candy[1] - rng.uniform(40, 90)), 40), angle=270),
                                               HatSpec(pos=exit_pos, angle=exit_angle)))]
            level["candies"] = [CandySpec(pos=(candy[0], candy[1] + 60))]
            level["pins"] = _pins_above(rng, (candy[0], candy[1] + 60), 1, spread=60, dist=(120, 160))
    return level


# -- box 5: two candy halves -------------------------------------------------------------------------


def _halves(rng, *, extra: bool = False) -> dict:
    left = (_u(rng, 70, 200), _u(rng, 130, 300))
    right = (_u(rng, 280, 410), _u(rng, max(110, left[1] - 70), min(330, left[1] + 70)))
    pins = (_pins_above(rng, left, int(rng.integers(1, 3)), spread=60, dist=(80, 170), candy_index=0)
            + _pins_above(rng, right, int(rng.integers(1, 3)), spread=60, dist=(80, 170), candy_index=1))
    order = rng.permutation(len(pins))  # ids do not tell which half a pin holds
    pins = [pins[i] for i in order]
    mouth = (_u(rng, 90, 390), _u(rng, 500, 650))
    level = dict(candies=[CandySpec(pos=left), CandySpec(pos=right)], pins=pins, om_nom=mouth)
    if extra:
        roll = rng.random()
        mid = ((left[0] + right[0]) / 2, (left[1] + right[1]) / 2)
        if roll < 0.3:
            level["spikes"] = [_spike_across(rng, (mid[0], mid[1] + 120), mouth, at=(0.3, 0.6), length=(70, 140))]
        elif roll < 0.5:
            level["bubbles"] = [BubbleSpec(pos=_clamp((mid[0] + rng.uniform(-60, 60), mid[1] + rng.uniform(120, 220)), 40))]
            level["om_nom"] = (_u(rng, 90, 390), _u(rng, 120, 330))
        elif roll < 0.7:
            pos = _clamp((mid[0] + rng.uniform(-120, 120), mid[1] + rng.uniform(160, 280)), 30)
            level["cushions"] = [CushionSpec(pos=pos, angle=round(_angle_to(pos, mouth) + rng.uniform(-30, 30)))]
            level["om_nom"] = (_side_x(rng, mid[0], (120, 220)), mouth[1])
        elif roll < 0.85:
            level["pins"] = [p.model_copy(update={"spider": SpiderSpec(delay=round(float(rng.uniform(0.5, 1.5)), 1))})
                             if k == 0 else p for k, p in enumerate(pins)]
        else:
            entry = _clamp((mid[0] + rng.uniform(-40, 40), mid[1] + rng.uniform(170, 260)), 40)
            exit_pos = _clamp((_side_x(rng, entry[0], (150, 250)), rng.uniform(150, 350)), 40)
            level["hats"] = [HatPairSpec(hats=(HatSpec(pos=entry, angle=90), HatSpec(pos=exit_pos, angle=270)))]
            level["om_nom"] = (exit_pos[0] + rng.uniform(-40, 40), _u(rng, 520, 650))
    return level


# -- the boxes ---------------------------------------------------------------------------------------

BOX_STAGES: dict[int, list[Stage]] = {
    1: [Stage("first ropes", 3, _ropes_first, None, min_reference_rate=0.5),
        Stage("ropes and swings", 6, _ropes, None),
        Stage("spikes", 6, _spikes, None),
        Stage("bubbles", 9, lambda rng: _bubble_lift(rng), "bubble")],
    2: [Stage("air cushions", 8, lambda rng: _bubble_lift(rng, cushion=True), "cushion"),
        Stage("cushions without bubbles", 4, _swing_cushion, "cushion"),
        Stage("spiders", 6, _spiders, "spider"),
        Stage("cushions, spiders, bubbles", 5, _mixed2, "cushion")],
    3: [Stage("active pins", 7, _active, "active")],
    4: [Stage("magic hats", 6, lambda rng: _hats(rng), "hat"),
        Stage("hats with hazards, active pins, bubbles", 9, lambda rng: _hats(rng, extra=True), "hat")],
    5: [Stage("two halves", 7, lambda rng: _halves(rng), "join"),
        Stage("halves with everything", 12, lambda rng: _halves(rng, extra=True), "join")],
}


def proposal(box: int, stage: Stage, rng: np.random.Generator) -> Level:
    """A layout of the stage; ValueError when its elements would overlap on the screen."""
    fields = stage.propose(rng)
    level = Level(id=f"b{box}_l01", title=stage.name, stars=PLACEHOLDER_STARS, **fields)
    problem = layout_problem(level)
    if problem:
        raise ValueError(problem)
    return level


def _points(level: Level) -> list[tuple[str, Point]]:
    return ([("candy", c.pos) for c in level.candies] + [("pin", p.pos) for p in level.pins]
            + [("active pin", a.pos) for a in level.active_pins] + [("bubble", b.pos) for b in level.bubbles]
            + [("cushion", c.pos) for c in level.cushions] + [("hat", h.pos) for pair in level.hats for h in pair.hats])


def layout_problem(level: Level) -> str | None:
    """Why the layout would look cluttered (None when it is clear): elements on top of each
    other, or on Om Nom, or spikes on an element."""
    points = _points(level)
    for i, (a, p) in enumerate(points):
        if math.dist(p, level.om_nom) < 85:
            return f"{a} on Om Nom"
        for b, q in points[i + 1:]:
            if math.dist(p, q) < 45:
                return f"{a} on {b}"
    for s in level.spikes + level.electrics:
        for a, p in points:
            if _point_segment(p, s.a, s.b) < 45:
                return f"spikes on {a}"
        if _point_segment(level.om_nom, s.a, s.b) < 75:
            return "spikes on Om Nom"
    return None


def _point_segment(p: Point, a: Point, b: Point) -> float:
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = dx * dx + dy * dy
    t = 0.0 if n == 0 else max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / n))
    return math.hypot(p[0] - a[0] - t * dx, p[1] - a[1] - t * dy)


def uses_mechanic(mechanic: str | None, events: list[str], plan_texts: list[str], no_action_loss: str) -> bool:
    """Does the winning plan use the stage's mechanic? (events: what happened while it played)."""
    if mechanic is None:
        return True
    if mechanic == "bubble":
        return any("bubble" in e and "captured" in e for e in events)
    if mechanic == "cushion":
        return any(t.startswith("tap_air_cushion") for t in plan_texts)
    if mechanic == "hat":
        return any("magic hat" in e for e in events)
    if mechanic == "active":
        return any("active pin" in e and "attached" in e for e in events)
    if mechanic == "join":
        return any("joined" in e for e in events)
    if mechanic == "spider":
        return "spider" in no_action_loss
    raise ValueError(mechanic)


def place_stars(rng, level: Level, path: list[Point], count: int = 3) -> list[Point] | None:
    """Three points on the plan's path: away from its start and from Om Nom, apart from each
    other and from the level's elements, preferring points off the straight line to Om Nom."""
    if len(path) < 10:
        return None
    start, mouth = path[0], level.om_nom
    blocked = [p for name, p in _points(level) if name != "candy"]
    candies = [c.pos for c in level.candies]
    candidates = []
    for k, p in enumerate(path):
        if not (30 <= p[0] <= C.WIDTH - 30 and 30 <= p[1] <= C.HEIGHT - 30):
            continue
        if any(math.dist(p, c) < 60 for c in candies) or math.dist(p, mouth) < 80:
            continue
        if any(math.dist(p, b) < 50 for b in blocked):
            continue
        if any(_point_segment(p, s.a, s.b) < 40 for s in level.spikes + level.electrics):
            continue
        off_line = _distance_to_line(p, start, mouth)
        candidates.append((off_line + rng.uniform(0, 60), k, p))
    candidates.sort(reverse=True)
    chosen: list[tuple[int, Point]] = []
    for _, k, p in candidates:
        if all(math.dist(p, q) >= 70 for _, q in chosen):
            chosen.append((k, p))
        if len(chosen) == count:
            break
    if len(chosen) < count:
        return None
    return [(float(round(p[0])), float(round(p[1]))) for _, p in sorted(chosen)]


def _distance_to_line(p: Point, a: Point, b: Point) -> float:
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy)
    if n == 0:
        return math.dist(p, a)
    return abs((p[0] - a[0]) * dy - (p[1] - a[1]) * dx) / n
