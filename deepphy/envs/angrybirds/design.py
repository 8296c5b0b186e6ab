"""Angry Birds' 34 levels as designed (the third edition, issue 42): each one built here from a
few structures whose pigs a bird cannot reach along an open line, with its title, its idea and
the designer's winning plan. `deepphy solve --env angrybirds make` turns a design into its
level file under levels/ (the plan, measured; solve.py); the files are what the game reads,
and a test checks that they match these designs.

The structures (each a `Parts`), in world units (the ground at y = 0, x to the right):
- `slab_trap`: a pig in a rock niche under a heavy stone slab on two legs (ice, wood or
  stone: the blue, yellow or black bird's material), the left leg showing above the rock in
  front; a bird has to break a leg or knock the slab so that it falls on the pig.
- `boulder_hill`: a hill with a stone boulder on its top and a hut at the foot of its far
  slope: the hut is sheltered from a direct shot, the boulder rolls down onto it.
- `tnt_ledge`: TNT on a rock ledge, a house with its pigs at the ledge's foot, within the
  blast.
- `tower_pig`: a pig on the top floor of a tower of wooden frames (a lob or a topple).
- decor that takes shots (forts, keeps, fences), so that a stray bird has something to hit.
Blocks are placed resting on what is below them (`post` stands a bar up, `bar` lays it
flat); the level settles before the first shot (sim.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from deepphy.envs.angrybirds import constants as C
from deepphy.envs.angrybirds.levels import Block, Level, Pig, Terrain, Tnt

SIZE = C.BLOCK_SIZES
Point = tuple[float, float]


@dataclass
class Parts:
    blocks: list[Block] = field(default_factory=list)
    pigs: list[Pig] = field(default_factory=list)
    tnt: list[Tnt] = field(default_factory=list)
    terrain: list[list[Point]] = field(default_factory=list)

    def __add__(self, other: "Parts") -> "Parts":
        return Parts(self.blocks + other.blocks, self.pigs + other.pigs, self.tnt + other.tnt,
                     self.terrain + other.terrain)


# -- blocks -----------------------------------------------------------------------------------------


def post(x: float, y0: float, shape: str = "rect_small", material: str = "wood") -> Block:
    """A bar standing up, its foot at height y0."""
    w, _ = SIZE[shape]
    return Block(shape=shape, material=material, x=round(x, 3), y=round(y0 + w / 2, 3), angle=90.0)


def bar(x: float, y0: float, shape: str = "rect_medium", material: str = "wood") -> Block:
    """A bar (or square) lying flat on height y0."""
    _, h = SIZE[shape]
    return Block(shape=shape, material=material, x=round(x, 3), y=round(y0 + h / 2, 3))


def pig(x: float, y0: float, size: str = "small") -> Pig:
    return Pig(size=size, x=round(x, 3), y=round(y0 + C.PIG_RADIUS[size], 3))


def hill(x0: float, x1: float, h: float, ls: float = 0.6, rs: float = 0.6, y0: float = 0.0) -> list[Point]:
    """A rock: its bottom from x0 to x1, its top inset by ls (left) and rs (right)."""
    return [(x0, y0), (x1, y0), (x1 - rs, y0 + h), (x0 + ls, y0 + h)]


def frame(x: float, y0: float, lintel: str = "rect_medium", post_shape: str = "rect_small", material: str = "wood",
          inset: float = 0.11) -> tuple[list[Block], float]:
    """Two posts and a lintel centred on x: the blocks and the height of the lintel's top."""
    span, tall = SIZE[lintel][0], SIZE[post_shape][0]
    return ([post(x - span / 2 + inset, y0, post_shape, material), post(x + span / 2 - inset, y0, post_shape, material),
             bar(x, y0 + tall, lintel, material)], y0 + tall + SIZE[lintel][1])


def roof(x: float, y0: float, material: str = "wood") -> list[Block]:
    """A gable: two triangles meeting over x."""
    w = SIZE["triangle"][0]
    return [Block(shape="triangle", material=material, x=round(x - w / 2, 3), y=round(y0 + w / 2, 3), angle=90.0),
            Block(shape="triangle", material=material, x=round(x + w / 2, 3), y=round(y0 + w / 2, 3))]


def fort(x: float, y0: float, storeys: int = 2, lintel: str = "rect_medium", post_shape: str = "rect_small",
         materials: tuple[str, ...] = ("wood",), top: str | None = "roof") -> tuple[list[Block], float]:
    """Frames stacked on x (no pig), the storeys' materials from the bottom, then a roof or a
    block of the top storey's material."""
    blocks, y = [], y0
    for k in range(storeys):
        b, y = frame(x, y, lintel, post_shape, materials[min(k, len(materials) - 1)])
        blocks += b
    if top == "roof":
        blocks += roof(x, y, materials[-1])
    elif top:
        blocks.append(bar(x, y, top, materials[-1]))
    return blocks, y


def keep(x0: float, y0: float, storeys: int = 2,
         materials: tuple[str, ...] = ("stone", "wood")) -> tuple[list[Block], float]:
    """A fort of medium frames whose left edge is x0 (no pig), roofed."""
    return fort(x0 + SIZE["rect_medium"][0] / 2, y0, storeys, "rect_medium", "rect_small", materials)


def fence(x0: float, y0: float, n: int, shape: str = "square_small", material: str = "stone") -> list[Block]:
    step = SIZE[shape][0] + 0.02
    return [bar(x0 + k * step, y0, shape, material) for k in range(n)]


# -- structures with a pig ----------------------------------------------------------------------------


def slab_trap(x: float, niche: float = 2.06, lh: float = 0.95, rh: float = 2.35, lw: float = 1.0, rw: float = 1.0,
              legs: str = "ice", ground: float = 0.0, crown: bool = True) -> Parts:
    """A small pig in a rock niche centred on x (the rock in front lh high and lw wide, the
    rock behind rh high and rw wide; the niche's floor at `ground`) under a stone slab on
    two big legs of `legs`; `crown`: a little stone shrine on the slab (more weight)."""
    a, b, g = x - niche / 2, x + niche / 2, ground
    rocks = [[(a - lw, g), (a, g), (a, g + lh), (a - lw + 0.25, g + lh)],
             [(b, g), (b + rw, g), (b + rw, g + rh), (b, g + rh)]]
    if g > 0:  # a raised niche: one rock under both
        rocks.append([(a, 0.0), (b, 0.0), (b, g), (a, g)])
        rocks[0][0], rocks[0][1] = (a - lw, 0.0), (a, 0.0)
        rocks[1][0], rocks[1][1] = (b, 0.0), (b + rw, 0.0)
    tall = SIZE["rect_big"][0]
    blocks = [post(a + 0.11, g, "rect_big", legs), post(b - 0.11, g, "rect_big", legs),
              bar(x, g + tall, "rect_big", "stone")]
    if crown:
        yt = g + tall + SIZE["rect_big"][1]
        blocks += [bar(x - 0.55, yt, "square_small", "stone"), bar(x + 0.55, yt, "square_small", "stone"),
                   bar(x, yt + 0.43, "rect_medium", "wood"), bar(x, yt + 0.65, "triangle", "stone")]
    return Parts(blocks, [pig(x, g)], terrain=rocks)


def hut(x: float, legs: str = "wood", lid: str = "wood", gable: bool = True) -> list[Block]:
    """A one-storey hut on the ground centred on x (a pig goes inside): legs, a lid, a gable."""
    span, tall = SIZE["rect_medium"][0], SIZE["rect_small"][0]
    blocks = [post(x - span / 2 + 0.11, 0.0, "rect_small", legs), post(x + span / 2 - 0.11, 0.0, "rect_small", legs),
              bar(x, tall, "rect_medium", lid)]
    return blocks + (roof(x, tall + SIZE["rect_medium"][1], lid) if gable else [])


def boulder_hill(x0: float = 6.8, top: float = 3.0, flat: float = 1.6, run: float = 2.6, lw: float = 1.2,
                 edge: float = 0.35, hut_legs: str = "wood", hut_lid: str = "wood", gable: bool = True,
                 chock: float = 0.0) -> Parts:
    """A hill (left slope lw wide, a flat top, a right slope `run` wide down to the ground) with
    a stone boulder on its top `edge` from the right edge, and a hut with a small pig 0.9 beyond
    the right slope's foot. `chock`: a low rock lip just right of the boulder (it takes a real
    push to roll it over)."""
    c = x0 + lw + flat
    d = c + run
    rocks = [[(x0, 0.0), (d, 0.0), (c, top), (x0 + 0.6, top)]]
    r = SIZE["circle"][0] / 2
    bx = c - r - edge
    blocks = [Block(shape="circle", material="stone", x=round(bx, 3), y=round(top + r, 3))]
    if chock:
        rocks.append([(bx + r * 0.55, top), (bx + r * 0.55 + 0.25, top), (bx + r * 0.55 + 0.25, top + chock),
                      (bx + r * 0.55, top + chock)])
    hx = d + 0.9
    blocks += hut(hx, legs=hut_legs, lid=hut_lid, gable=gable)
    return Parts(blocks, [pig(hx, 0.0)], terrain=rocks)


def tnt_ledge(x0: float = 7.0, h: float = 1.3, w: float = 2.4, pigs: int = 1, lip: float = 0.0,
              storeys: int = 2) -> Parts:
    """A flat-topped rock (x0 to x0 + w, h high) with TNT near its right edge, and a house of
    `storeys` medium frames (roofed when more than one) at the rock's right foot with one or
    two small pigs inside, within the blast. `lip`: a rock lip that high in front of the TNT."""
    rocks = [[(x0, 0.0), (x0 + w, 0.0), (x0 + w, h), (x0 + 0.6, h)]]
    tx = x0 + w - 0.25 - 0.05  # the crate's half width and a margin from the edge
    if lip:
        rocks.append([(tx - 0.55, h), (tx - 0.27, h), (tx - 0.27, h + lip), (tx - 0.55, h + lip)])
    hx = x0 + w + 0.05 + SIZE["rect_medium"][0] / 2
    blocks, y = frame(hx, 0.0)
    for _ in range(storeys - 1):
        b, y = frame(hx, y)
        blocks += b
    if storeys > 1:
        blocks += roof(hx, y)
    inside = [pig(hx - 0.33, 0.0), pig(hx + 0.2, 0.0)] if pigs == 2 else [pig(hx - 0.2, 0.0)]
    return Parts(blocks, inside, [Tnt(x=round(tx, 3), y=round(h + 0.25, 3))], rocks)


def tower_pig(x: float, storeys: int = 3, lintel: str = "rect_medium", material: str = "wood") -> Parts:
    """A tower of frames on the ground with a small pig on its top floor, roofed."""
    blocks, y = [], 0.0
    for _ in range(storeys):
        b, y = frame(x, y, lintel, "rect_small", material)
        blocks += b
    floor = y
    b, y = frame(x, y, lintel, "rect_small", material)
    return Parts(blocks + b + roof(x, y, material), [pig(x, floor)])


# -- the book -----------------------------------------------------------------------------------------

LEVELS: list[Level] = []
PLANS: dict[str, list[tuple[float, float]]] = {}  # the designer's winning plan (centred), per level


def level(level_id: str, title: str, birds: str, plan: list[tuple[float, float]], idea: str) -> Callable:
    """Register the decorated function's Parts as a level: `birds` in BIRD_LETTERS, `plan`
    the designer's winning shots (angle, power)."""

    def register(build: Callable[[], Parts]) -> Callable[[], Parts]:
        parts = build()
        LEVELS.append(Level(id=level_id, title=title, idea=idea, birds=[C.BIRD_LETTERS[b] for b in birds],
                            blocks=parts.blocks, pigs=parts.pigs, tnt=parts.tnt,
                            terrain=[Terrain(points=p) for p in parts.terrain]))
        PLANS[level_id] = [(float(a), float(p)) for a, p in plan]
        return build

    return register


@level("s1_l01", "Lookout", "RRR", [(15, 0.91)],
       "opener: a small pig on the first floor of a two-storey wooden lookout on a low rock mound; any solid hit "
       "topples it (the scene's forgiving first level)")
def _():
    blocks, y = frame(8.8, 0.7)
    b, y2 = frame(8.8, y)
    return Parts(blocks + b + roof(8.8, y2) + [bar(7.75, 0.7, "square_small"), bar(9.85, 0.7, "square_small")],
                 [pig(8.8, y)], terrain=[hill(7.0, 10.6, 0.7, 0.5, 0.5)])


@level("s1_l02", "Two pigs apart", "RRRRR", [(30, 0.73), (27, 0.9)],
       "planning across shots: a small pig in a wooden hut sheltered by a hill with a stone boulder on its top (roll "
       "the boulder down), and a small pig on the top floor of a far wooden tower")
def _():
    return boulder_hill(x0=5.6, top=2.6, flat=1.4, run=2.2, lw=1.0) + tower_pig(15.0, storeys=2)


@level("s1_l03", "Quarry", "RRRR", [(28, 1.0)],
       "rolling: a small pig in a wooden hut at the foot of a high hill, out of reach of a direct shot; a stone "
       "boulder rests on the hilltop behind a low lip; a stone-and-wood storehouse stands beyond")
def _():
    blocks, _ = fort(14.6, 0.0, 2, materials=("stone", "wood"))
    return boulder_hill(x0=6.4, top=3.0, flat=1.4, run=2.3, lw=1.1, chock=0.12, gable=False) + Parts(blocks)


@level("s1_l04", "The crypt", "RRRR", [(11, 0.9)],
       "structural support: a small pig in a rock niche under a heavy stone slab on two glass (ice) legs; the left "
       "leg shows above the rock in front; a wooden watchtower stands on the rock behind")
def _():
    blocks, _ = fort(12.75, 2.35, 2, "rect_small", top="square_small")
    return slab_trap(10.4, lh=0.95, rh=2.35, rw=2.4) + Parts(blocks)


@level("s1_l05", "Storehouse", "RRRR", [(45, 0.6)],
       "explosions: a small pig in a wooden house at the foot of a ledge, TNT on the ledge behind a low stone lip; "
       "a wooden fort beyond")
def _():
    blocks, _ = keep(13.2, 0.0, 2, ("wood",))
    return tnt_ledge(x0=7.6, h=1.2, w=2.6, lip=0.3, storeys=1) + Parts(blocks)


@level("s1_l06", "Crypt and hill", "RRRR", [(0, 1.0), (24, 0.95)],
       "planning across shots: a small pig under a stone slab on glass (ice) legs in a rock niche, and a small pig "
       "in a wooden hut below a hill with a stone boulder on top")
def _():
    return (slab_trap(8.4, lh=0.95, rh=2.0, lw=1.0, rw=0.6)
            + boulder_hill(x0=10.2, top=2.6, flat=1.0, run=1.9, lw=0.9))


@level("s1_l07", "Storehouse II", "RRRR", [(40, 0.6)],
       "explosions: two small pigs in a two-storey wooden house at the foot of a ledge with TNT on its edge behind a "
       "stone lip almost as high as the crate; a wooden fort beyond")
def _():
    blocks, _ = keep(13.0, 0.0, 2, ("wood",))
    return tnt_ledge(x0=7.6, h=1.1, w=2.6, pigs=2, lip=0.45) + Parts(blocks)


@level("s1_l08", "Hill and tower", "RRRR", [(31, 0.74), (40, 0.82)],
       "rolling and toppling: a small pig in a wooden hut below a hill with a stone boulder on top, a small pig on "
       "the top floor of a far stone tower, a little stone pile between")
def _():
    return (boulder_hill(x0=5.8, top=2.6, flat=1.1, run=2.2, lw=1.0, gable=False)
            + tower_pig(14.6, storeys=3, material="stone")
            + Parts(fence(12.6, 0.0, 2) + fence(12.815, 0.43, 1)))


@level("s1_l09", "Three ways", "RRRR", [(33, 0.62), (48, 0.68)],
       "planning across shots: three small pigs, each reached its own way: a wooden hut below a hill with a stone "
       "boulder, a two-storey wooden house below a ledge with TNT, the top of a slim wooden tower")
def _():
    return (boulder_hill(x0=5.4, top=2.4, flat=0.9, run=1.6, lw=0.9) + tnt_ledge(x0=10.8, h=1.2, w=1.6)
            + tower_pig(15.15, storeys=2, lintel="rect_small"))


@level("s1_l10", "Outpost", "BBBBB", [(16, 0.9), (48, 0.68), (44, 0.8)],
       "the blue bird against ice: a small pig under a stone slab on glass (ice) legs behind a high rock, a small "
       "pig in a one-storey wooden house below a ledge with TNT, a small pig on a far stone tower out of the blast")
def _():
    return (slab_trap(8.4, lh=1.5, rh=2.0, lw=1.1, rw=0.5) + tnt_ledge(x0=10.4, h=1.3, w=1.8, storeys=1)
            + tower_pig(15.15, storeys=2, material="stone"))


@level("s1_l11", "Crypt and quarry", "RBBB", [(12, 0.8), (50, 0.72)],
       "bird order: a red bird for the small pig under a stone slab on glass (ice) legs, blue birds for the stone "
       "boulder on the hill above the wooden hut")
def _():
    return (slab_trap(8.6, lh=0.95, rh=2.1, lw=1.1, rw=0.5)
            + boulder_hill(x0=10.3, top=2.6, flat=0.8, run=1.8, lw=0.7))


@level("s1_l12", "Crypt and quarry II", "BBBR", [(16, 0.9), (16, 0.99)],
       "bird order: blue birds against the glass (ice) legs of a stone slab over a small pig, a red bird for the "
       "stone boulder above a wooden hut")
def _():
    return (slab_trap(8.4, lh=1.3, rh=2.0, lw=1.1, rw=0.5)
            + boulder_hill(x0=10.0, top=2.6, flat=0.9, run=1.9, lw=0.9))


@level("s1_l13", "Ledge and hill", "BBRR", [(32, 0.6), (16, 0.99)],
       "bird order: blue birds for the TNT on a ledge above a wooden house with a small pig, red birds for the stone "
       "boulder above a wooden hut")
def _():
    return tnt_ledge(x0=6.6, h=1.1, w=2.0) + boulder_hill(x0=11.0, top=2.6, flat=0.8, run=1.6, lw=0.6)


@level("s1_l14", "The wall", "RRRR", [(36, 0.9), (59, 0.8)],
       "relative height: a tall rock wall with a stone boulder on top shelters a small pig in a stone hut; a small "
       "pig on the top floor of a wooden tower beyond")
def _():
    return (boulder_hill(x0=6.2, top=3.6, flat=1.0, run=2.2, lw=1.2, hut_legs="stone", hut_lid="stone", gable=False)
            + tower_pig(14.6, storeys=2))


@level("s1_l15", "Two crypts", "BBBB", [(23, 0.68), (47, 0.7)],
       "the blue bird against ice: two small pigs in two rock niches at two heights, each under a stone slab on glass "
       "(ice) legs")
def _():
    return (slab_trap(8.6, lh=1.3, rh=1.6, lw=1.1, rw=0.5)
            + slab_trap(12.3, lh=1.0, rh=2.6, lw=0.9, rw=1.2, ground=1.0))


@level("s1_l16", "Crypt and quarry III", "YYYYY", [(19, 0.48), (30, 0.48)],
       "the yellow bird against wood: a small pig under a stone slab on wooden legs in a rock niche, a small pig in "
       "a wooden hut below a hill with a stone boulder")
def _():
    return (slab_trap(8.6, lh=1.3, rh=2.0, lw=1.1, rw=0.5, legs="wood")
            + boulder_hill(x0=10.3, top=2.6, flat=0.8, run=1.8, lw=0.7))


@level("s1_l17", "The ridge", "YYY", [(35, 0.52)],
       "the yellow bird's dash: a small pig in a wooden hut below a hill with a stone boulder on top, a wooden fort "
       "beyond; three yellow birds")
def _():
    blocks, _ = keep(13.9, 0.0, 2, ("wood",))
    return boulder_hill(x0=6.4, top=3.0, flat=1.2, run=2.4, lw=1.1) + Parts(blocks)


@level("s1_l18", "Staircase", "YYYYY", [(12, 0.7), (20, 0.66)],
       "the yellow bird against wood: two small pigs in two rock niches at two heights, each under a stone slab on "
       "wooden legs; a wooden hut on the top step")
def _():
    blocks, _ = fort(14.0, 3.6, 1, "rect_small")
    return (slab_trap(8.5, lh=1.3, rh=1.8, lw=1.1, rw=0.6, legs="wood", crown=False)
            + slab_trap(12.2, lh=1.0, rh=2.8, lw=1.0, rw=1.3, legs="wood", ground=0.8) + Parts(blocks))


@level("s1_l19", "Crypt and store", "BYYR", [(50, 0.68), (8, 0.85)],
       "each bird its job: a blue bird for the TNT on a ledge above a wooden house with a small pig, a yellow bird "
       "for the glass (ice) legs of the stone slab over a small pig")
def _():
    return slab_trap(8.2, lh=1.3, rh=1.8, lw=1.0, rw=0.4) + tnt_ledge(x0=10.2, h=1.2, w=1.8)


@level("s1_l20", "Deep crypt", "YYYYY", [(19, 0.5)],
       "the yellow bird against wood: a small pig under a stone slab on wooden legs deep in a rock niche, a "
       "stone-and-wood keep on the rock behind, a wooden tower beyond")
def _():
    behind, _ = keep(11.6, 2.35, 2, ("stone", "wood"))
    beyond, _ = fort(14.9, 0.0, 3, "rect_small")
    return slab_trap(10.5, lh=1.3, rh=2.35, lw=1.2, rw=1.9, legs="wood") + Parts(behind + beyond)


@level("s1_l21", "The castle", "BRYBRYYY", [(23, 0.6), (44, 0.7)],
       "the scene's finale: a stone slab on glass (ice) legs over a small pig, a stone boulder above a wooden hut "
       "with a small pig, and a three-storey wooden tower with TNT on its ground floor and a small pig on its top "
       "floor")
def _():
    return (slab_trap(7.6, lh=1.4, rh=1.6, lw=0.9, rw=0.3) + boulder_hill(x0=9.0, top=2.4, flat=0.8, run=1.6, lw=0.6)
            + tower_pig(15.05, storeys=2) + Parts(tnt=[Tnt(x=15.05, y=0.25)]))


@level("s2_l01", "Twin lookouts", "RYYB", [(14, 0.87)],
       "opener: two wooden lookouts on a wide rock mound, a small pig on the first floor of each; red, yellow and "
       "blue birds")
def _():
    blocks, pigs = [], []
    for x in (8.4, 10.9):
        b, y = frame(x, 0.9)
        b2, y2 = frame(x, y)
        blocks += b + b2 + roof(x, y2)
        pigs.append(pig(x, y))
    return Parts(blocks, pigs, terrain=[hill(6.8, 12.6, 0.9, 0.6, 0.6)])


@level("s2_l02", "Two huts", "BBBB", [(16, 0.9), (48, 0.7)],
       "blue birds: a small pig under a stone slab on glass (ice) legs behind a high rock, a small pig in a wooden "
       "house below a ledge with TNT")
def _():
    return slab_trap(8.4, lh=1.7, rh=1.8, lw=1.1, rw=0.5) + tnt_ledge(x0=10.9, h=1.3, w=2.0)


@level("s2_l03", "Two depots", "RRRYY", [(24, 0.6), (25, 0.82)],
       "explosions: two ledges with TNT far apart, each above a wooden house with a small pig; red and yellow birds")
def _():
    return tnt_ledge(x0=6.6, h=1.1, w=2.0, storeys=1) + tnt_ledge(x0=12.0, h=1.4, w=1.6)


@level("s2_l04", "Three stores", "YBBR", [(18, 0.48), (45, 0.6), (26, 0.83)],
       "each bird its job: a yellow bird for the wooden legs of a stone slab over a small pig, blue birds for the TNT "
       "above a wooden house, a red bird for a small pig on a far wooden tower")
def _():
    return (slab_trap(8.2, lh=1.3, rh=1.8, lw=1.0, rw=0.4, legs="wood") + tnt_ledge(x0=9.8, h=1.3, w=1.8)
            + tower_pig(15.05, storeys=2))


@level("s2_l05", "Stone crypt", "KKKK", [(20, 0.6), (44, 0.7)],
       "the black bird against stone: a small pig under a stone slab on stone legs deep behind a wide rock, a small "
       "pig in a wooden house below a ledge with TNT")
def _():
    return slab_trap(9.0, lh=1.0, rh=2.0, lw=2.0, rw=0.5, legs="stone") + tnt_ledge(x0=10.7, h=1.4, w=2.6)


@level("s2_l06", "Stone crypt and hill", "KKK", [(20, 0.6), (48, 0.71)],
       "black birds: a small pig under a stone slab on stone legs deep behind a wide rock, a small pig in a wooden "
       "hut below a hill with a stone boulder")
def _():
    return (slab_trap(9.0, lh=1.0, rh=2.0, lw=2.0, rw=0.5, legs="stone")
            + boulder_hill(x0=10.7, top=2.6, flat=0.8, run=1.6, lw=0.6))


@level("s2_l07", "Wooden crypt and hill", "YYKB", [(19, 0.48), (30, 0.48)],
       "yellow birds first: a small pig under a stone slab on wooden legs, a small pig in a wooden hut below a hill "
       "with a stone boulder; a black and a blue bird to spare")
def _():
    return (slab_trap(8.6, lh=1.3, rh=2.0, lw=1.1, rw=0.5, legs="wood")
            + boulder_hill(x0=10.3, top=2.6, flat=0.8, run=1.8, lw=0.7))


@level("s2_l08", "Three birds", "YRK", [(16, 0.5), (37, 0.72)],
       "one bird each: a yellow bird for the wooden legs of a stone slab over a small pig, a red bird for the TNT "
       "above a wooden house, a black bird for a small pig on a far wooden tower")
def _():
    return (slab_trap(8.2, lh=1.3, rh=1.8, lw=1.0, rw=0.4, legs="wood") + tnt_ledge(x0=10.0, h=1.4, w=2.4)
            + tower_pig(15.15, storeys=2, lintel="rect_small"))


@level("s2_l09", "Crypt, store and tower", "KBYK", [(21, 0.61), (56, 0.7), (28, 0.45)],
       "a black bird for the stone legs of a slab over a small pig, a blue bird for the TNT above a wooden house, a "
       "yellow bird for a small pig on a far wooden tower")
def _():
    return (slab_trap(9.0, lh=1.0, rh=2.0, lw=2.0, rw=0.4, legs="stone") + tnt_ledge(x0=10.6, h=1.3, w=1.6, storeys=1)
            + tower_pig(15.05, storeys=2))


@level("s2_l10", "Stone crypt and hill II", "KKKK", [(20, 0.6), (50, 0.71)],
       "black birds: a small pig under a stone slab on stone legs deep behind a wide rock, a small pig in a "
       "stone-legged hut below a hill with a stone boulder")
def _():
    return (slab_trap(8.8, lh=1.0, rh=2.0, lw=1.9, rw=0.5, legs="stone")
            + boulder_hill(x0=10.5, top=2.8, flat=0.8, run=1.6, lw=0.6, hut_legs="stone"))


@level("s2_l11", "The vault", "KKKK", [(21, 0.61), (28, 0.81)],
       "black birds: two small pigs under stone slabs on stone legs deep behind two wide rocks, the second niche "
       "higher")
def _():
    return (slab_trap(9.0, lh=1.0, rh=1.8, lw=2.0, rw=0.4, legs="stone")
            + slab_trap(13.4, lh=1.1, rh=2.6, lw=1.9, rw=0.5, legs="stone", ground=0.7))


@level("s2_l12", "Three houses", "BBYYYK", [(16, 0.9), (48, 0.69), (24, 0.59)],
       "blue birds for the glass (ice) legs of a stone slab over a small pig and for the TNT above a wooden house, a "
       "yellow bird for a small pig on a far stone tower; a black bird to spare")
def _():
    return (slab_trap(8.4, lh=1.3, rh=1.8, lw=1.1, rw=0.5) + tnt_ledge(x0=10.6, h=1.3, w=1.6)
            + tower_pig(15.05, storeys=2, material="stone"))


@level("s2_l13", "The keep", "YKKK", [(27, 0.76), (20, 0.6)],
       "the scene's finale: a yellow bird for the TNT on a ledge above a two-storey wooden house with a small pig, "
       "black birds for the stone legs of a slab over a small pig deep behind a wide rock under a stone keep")
def _():
    blocks, _ = fort(10.9, 2.0, 2, "rect_small", materials=("stone",), top="square_small")
    return (slab_trap(9.0, lh=1.0, rh=2.0, lw=2.0, rw=1.3, legs="stone") + Parts(blocks)
            + tnt_ledge(x0=11.4, h=1.4, w=1.8))


def design(level_id: str) -> Level:
    for lv in LEVELS:
        if lv.id == level_id:
            return lv
    raise KeyError(f"no design for level {level_id!r}")
