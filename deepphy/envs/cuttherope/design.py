"""The 88 levels as designed: each one written by hand here, with its idea (what it teaches
or tests), and turned into its level file under levels/ by `deepphy solve --env cuttherope
make` (the oracle finds the 3-star plan that the file stores; calibrate.py measures it).
The files are what the game reads; a test checks that they match these designs.

The boxes follow season 1 of the game (public wikis, /work/shared/notes/games.md):
Cardboard (ropes, stars, bubbles, automatic ropes, stretched ropes, spikes, several ropes
cut at once), Fabric (air cushions, spiders), Foil (hooks on tracks, electric sparks, and
our walls), Magic (hats), Valentine (two candy halves). Each box starts with tutorials for
its new mechanics and ends with levels that combine them with the earlier ones.

Helpers: `rope` describes a pin and its rope; `make` builds a level, giving every loaded
rope the rest length that holds the candy still (candies start at rest unless a level's
idea says otherwise), slack ropes their slack and stretched ropes their stretch, and
numbering each kind of element the model acts on (pins, active pins, bubbles, cushions) in
an order drawn from the level's id, unrelated to the design's order or the solution. The
ideas therefore speak of elements by place ("the left rope"), never by id.
"""

from __future__ import annotations

import math

from deepphy.envs.cuttherope import constants as C
from deepphy.envs.cuttherope.level import BOXES, Level
from deepphy.seeding import seeded_rng

Point = tuple[float, float]


def rope(x: float, y: float, *, slack: float | None = None, stretch: float | None = None, candy: int = 0,
         spider: float | None = None, track: dict | None = None, balance: bool = False) -> dict:
    """A pin at (x, y) and its rope to candy `candy`: loaded (it carries the candy's weight
    with the other loaded rope), `slack` px longer than the distance (pulling nothing), or
    `stretch` px shorter (a stretched rope: it contracts and throws the candy); a spider
    that starts crawling `spider` s after the start; a hook's `track` (TrackSpec fields).
    `balance`: the candy's only loaded rope, its pin moved (same distance) onto the line
    along which it must pull to hold the candy still against the stretched ropes."""
    return {"pos": (float(x), float(y)), "slack": slack, "stretch": stretch, "candy": candy, "spider": spider,
            "track": track, "balance": balance}


def make(id: str, title: str, idea: str, *, candies: list, ropes: list[dict] = (), om_nom: Point,
         stars: list[Point], **elements) -> Level:
    """A level: `candies` are points (or dicts with "pos" and "velocity"); the ropes' rest
    lengths come from `rope`'s kind; `elements` are the other Level fields."""
    specs = [c if isinstance(c, dict) else {"pos": c} for c in candies]
    halves = len(specs) == 2
    pins = []
    bubbles = [b["pos"] for b in elements.get("bubbles", ())]
    ropes = [dict(r) for r in ropes]
    lengths = _rest_lengths(specs, ropes, halves, bubbles)
    for r, length in zip(ropes, lengths):
        pin = {"pos": r["pos"], "candy": r["candy"], "length": round(length, 3)}
        if r["spider"] is not None:
            pin["spider"] = {"delay": r["spider"]}
        if r["track"] is not None:
            pin["track"] = r["track"]
        pins.append(pin)
    numbered = {kind: _shuffled(id, kind, items) for kind, items in {
        "pins": pins, **{k: list(elements.get(k, ())) for k in ACTED_ON_KINDS[1:]}}.items()}
    return Level.model_validate({"id": id, "title": title, "idea": idea, "candies": specs, "om_nom": om_nom,
                                 "stars": stars, **elements, **numbered})


ACTED_ON_KINDS = ("pins", "active_pins", "bubbles", "cushions")  # the elements an action names by id
FIRST_SWIPE = "b1_l20"  # the level that teaches cutting several ropes at once: no plan before it does


def _shuffled(level_id: str, kind: str, items: list) -> list:
    """The elements of one kind in the order that numbers them (1, 2, ...): a permutation of
    the design's order drawn from the level's id and the kind, so that an id tells nothing
    (the design lists elements in whatever order it thinks of them, often the solution's)."""
    order = seeded_rng("cuttherope-ids", level_id, kind).permutation(len(items))
    return [items[k] for k in order]


def _anchor(r: dict) -> Point:
    """Where a rope's pin is at t = 0 (a hook starts `phase` along its track)."""
    if not r["track"]:
        return r["pos"]
    f = (1.0 - math.cos(2.0 * math.pi * r["track"].get("phase", 0.0))) / 2.0
    (x0, y0), (x1, y1) = r["pos"], r["track"]["to"]
    return x0 + (x1 - x0) * f, y0 + (y1 - y0) * f


def _rest_lengths(candies: list[dict], ropes: list[dict], halves: bool, bubbles: list[Point]) -> list[float]:
    """Each rope's rest length: slack and stretched ropes by their numbers; the loaded ropes
    of a candy (one or two) stretched just enough that, with the stretched ropes' pull, they
    hold it still. A candy that starts inside a bubble is lifted instead of pulled down."""
    lengths = [0.0] * len(ropes)
    for ci, spec in enumerate(candies):
        cx, cy = spec["pos"]
        weight = (C.HALF_MASS if halves else C.CANDY_MASS) / C.CANDY_MASS  # downward, in whole-candy weights
        if any(math.dist(b, (cx, cy)) < C.BUBBLE_CAPTURE for b in bubbles):
            weight *= -C.BUBBLE_DRAG * C.BUBBLE_RISE_SPEED / C.GRAVITY  # the bubble's lift
        need_x, need_y = 0.0, -weight  # what the loaded ropes must pull (in weights)
        loaded = []
        for k, r in enumerate(ropes):
            if r["candy"] != ci:
                continue
            ax, ay = _anchor(r)
            d = math.dist((ax, ay), (cx, cy))
            ux, uy = (ax - cx) / d, (ay - cy) / d
            if r["slack"] is not None:
                lengths[k] = d + r["slack"]
            elif r["stretch"] is not None:
                lengths[k] = d - r["stretch"]
                pull = r["stretch"] * C.ROPE_STIFFNESS
                need_x, need_y = need_x - pull * ux, need_y - pull * uy
            else:
                loaded.append((k, d, ux, uy))
        if len(loaded) == 1 and ropes[loaded[0][0]]["balance"]:
            k, d, _, _ = loaded[0]
            n = math.hypot(need_x, need_y)
            ropes[k]["pos"] = (round(cx + d * need_x / n, 3), round(cy + d * need_y / n, 3))
            loaded = [(k, d, need_x / n, need_y / n)]
        if not loaded:
            continue
        if len(loaded) == 1:
            k, d, ux, uy = loaded[0]
            tension = math.hypot(need_x, need_y)
            if tension > 0 and abs(ux * need_y - uy * need_x) > 1e-6 * tension or ux * need_x + uy * need_y < 0:
                raise ValueError(f"candy {ci}: its only loaded rope must pull straight against the other forces")
            tensions = [tension]
        elif len(loaded) == 2:
            (_, _, ax_, ay_), (_, _, bx, by) = loaded
            det = ax_ * by - bx * ay_
            if abs(det) < 1e-9:
                raise ValueError(f"candy {ci}: its two loaded ropes are parallel")
            tensions = [(need_x * by - bx * need_y) / det, (ax_ * need_y - need_x * ay_) / det]
            if min(tensions) < 0:
                raise ValueError(f"candy {ci}: its two loaded ropes cannot hold it still there")
        else:
            raise ValueError(f"candy {ci}: give all but two of its ropes a slack or a stretch")
        for (k, d, _, _), tension in zip(loaded, tensions):
            lengths[k] = d - tension / C.ROPE_STIFFNESS
    return lengths


def spikes(a: Point, b: Point) -> dict:
    return {"a": a, "b": b}


def wall(a: Point, b: Point) -> dict:
    return {"a": a, "b": b}


# -- box 1: Cardboard ------------------------------------------------------------------------------

BOX1: list[Level] = [
    make("b1_l01", "One rope",
         "Cut the rope and the candy falls straight to Om Nom, through the three stars.",
         candies=[(240, 200)], ropes=[rope(240, 80)], om_nom=(240, 600),
         stars=[(240, 300), (240, 390), (240, 480)]),
    make("b1_l02", "One, then the other",
         "Two ropes hold the candy up; a long slack rope hangs from a pin on the right. Cut the left rope and, at "
         "once after, the right one: the candy, just starting to swing, falls into the slack rope's reach, which "
         "catches it and swings it through the stars into Om Nom. Cut both at the same moment and it drops too "
         "straight; let go later and it swings too far; cut the slack rope and nothing catches it.",
         candies=[(160, 200)], ropes=[rope(50, 120), rope(230, 80), rope(300, 300, slack=120)], om_nom=(360, 520),
         stars=[(218, 351), (235, 466), (254, 604)]),
    make("b1_l03", "The other way round",
         "As in the level before, but mirrored and lower: cut the right rope and, at once after, the left one, and "
         "the slack rope on the left catches the candy and swings it down through the stars into Om Nom. The other "
         "order swings the candy the wrong way; both at once drop it straight past the slack rope's swing.",
         candies=[(320, 180)], ropes=[rope(200, 60), rope(460, 90), rope(120, 300, slack=120)], om_nom=(80, 580),
         stars=[(250, 362), (223, 521), (208, 642)]),
    make("b1_l04", "Three in a row",
         "Three ropes. Cut the right one and the short one below, one after the other, and the left one swings the "
         "candy down; let go of it a moment later and the candy is flung left through the stars into Om Nom. Let "
         "go at once and it drops short; later and it swings past.",
         candies=[(280, 240)], ropes=[rope(140, 130), rope(390, 130), rope(280, 300, slack=100)], om_nom=(73, 548),
         stars=[(203, 303), (145, 380), (110, 451)]),
    make("b1_l05", "Up with a bubble",
         "Cut the rope above the candy: it drops into the bubble, which carries it up until the slack rope on the "
         "right comes taut and swings it round, floating, toward the top of its pin. Let it go under Om Nom and it rises "
         "into him; let it go at once and it floats straight up past him.",
         candies=[(120, 400)], ropes=[rope(120, 280), rope(300, 460, slack=40)], bubbles=[{"pos": (120, 480)}],
         om_nom=(240, 100), stars=[(120, 330), (185, 262), (243, 175)]),
    make("b1_l06", "Steer the bubble",
         "The candy starts in a bubble held down by two ropes. Cut one and the bubble drifts over the other pin; "
         "cut the second when the bubble is under Om Nom and it rises straight to him.",
         candies=[(140, 520)], bubbles=[{"pos": (140, 520)}], ropes=[rope(60, 640), rope(340, 660)],
         om_nom=(330, 100), stars=[(215, 458), (300, 360), (310, 230)]),
    make("b1_l07", "Pop it over Om Nom",
         "The candy rides in a bubble tied down by two ropes, as in the level before. Cut the left one and the "
         "bubble drifts up and over the right pin; pop it once it floats over Om Nom and the candy drops into him. "
         "Pop it too soon and the rope swings the candy past him.",
         candies=[(120, 300)], bubbles=[{"pos": (120, 300)}], ropes=[rope(40, 420), rope(265, 420)],
         om_nom=(265, 520), stars=[(170, 240), (245, 220), (265, 330)]),
    make("b1_l08", "Throw it into the bubble",
         "Cut the rope above the candy and, at once after, the other one: the candy, just starting to swing, drops "
         "into the bubble, which carries it up through the stars into Om Nom. Cut both at the same moment and it "
         "drops straight past the bubble; let go later and the swing throws it past; cut the other rope first and "
         "it swings the wrong way.",
         candies=[(110, 220)], ropes=[rope(110, 140), rope(230, 140, slack=0)], bubbles=[{"pos": (200, 500)}],
         om_nom=(220, 100), stars=[(184, 455), (212, 504), (212, 312)]),
    make("b1_l09", "The rope steers the bubble",
         "Cut the rope above the candy: it drops into the bubble and floats up, until the slack rope on the right "
         "comes taut and swings it round, floating, through the stars and just past Om Nom. Pop the bubble as it "
         "passes over him and the candy drops into him; pop it early and it drops short of him, late and the rope "
         "swings it past him.",
         candies=[(80, 340)], ropes=[rope(80, 250), rope(360, 400, slack=40)], bubbles=[{"pos": (80, 440)}],
         om_nom=(194, 201), stars=[(80, 410), (80, 290), (116, 183)]),
    make("b1_l10", "An automatic rope",
         "Cut the rope: as the falling candy enters the dashed circle, the automatic rope grabs it and swings it "
         "round. Let go of the automatic rope as the swing carries the candy up toward Om Nom and it flies into "
         "him; hold on and the swing carries it back.",
         candies=[(80, 160)], ropes=[rope(80, 60)], active_pins=[{"pos": (140, 360), "radius": 130}],
         om_nom=(313, 456), stars=[(80, 332), (80, 455), (174, 479)]),
    make("b1_l11", "Stop the bubble",
         "The bubble would carry the candy off the top; the automatic rope catches it on the way and holds it "
         "floating. Pop the bubble then, and the rope swings the candy down to Om Nom.",
         candies=[(100, 560)], ropes=[rope(100, 460)], bubbles=[{"pos": (100, 640)}],
         active_pins=[{"pos": (200, 250), "radius": 120}], om_nom=(345, 300), stars=[(100, 380), (130, 172), (250, 390)]),
    make("b1_l12", "A stretched rope",
         "Two ropes pull against each other, the upper one red: stretched. Cut the lower one: the red rope contracts "
         "and throws the candy up past its pin, catches it and swings it back. Let go of it on the swing back and "
         "the candy flies left into Om Nom; let go in the throw and it flies off, hold on and it swings on.",
         candies=[(180, 480)], ropes=[rope(80, 580, balance=True), rope(260, 300, stretch=45)], om_nom=(75, 492),
         stars=[(319, 232), (327, 310), (271, 451)]),
    make("b1_l13", "Slingshot to a rope",
         "Cut the lower rope and at once the red one: the red rope slings the candy up into the automatic rope's "
         "circle, which catches it and swings it round through the stars. Let go as it swings back down toward Om "
         "Nom. Keep the red rope and it pulls the candy back; let go of the automatic rope too soon or too late and "
         "the swing throws the candy past him.",
         candies=[(90, 620)], ropes=[rope(10, 700, balance=True), rope(160, 520, stretch=35)],
         active_pins=[{"pos": (260, 440), "radius": 70}], om_nom=(202, 598), stars=[(222, 480), (325, 437), (234, 503)]),
    make("b1_l14", "Tug of war",
         "Three ropes pull the candy three ways. Cut the two on the right and the left one swings the candy down; "
         "let go of it a moment later and it is flung left through the stars into Om Nom. Let go at once and it "
         "drops short; later and it swings past.",
         candies=[(240, 280)], ropes=[rope(130, 170), rope(320, 200), rope(280, 220, slack=60)], om_nom=(78, 468),
         stars=[(188, 315), (145, 348), (114, 394)]),
    make("b1_l15", "Sling, float, pop",
         "Cut the lower rope and at once the red one: the red rope slings the candy up into the bubble, which carries "
         "it up in a line over Om Nom. Pop it when it has risen through the stars and the candy drops straight into him; "
         "pop it at once and it flies past the stars. Keep the red rope a moment longer and it drags the bubble back, "
         "out of line with him.",
         candies=[(120, 600)], ropes=[rope(60, 660, balance=True), rope(160, 520, stretch=30)],
         bubbles=[{"pos": (210, 470)}], om_nom=(270, 575), stars=[(240, 400), (251, 300), (251, 200)]),
    make("b1_l16", "Swing out, let go",
         "Three ropes, one of them slack. Cut them one after the other, without a pause, in the one order that "
         "swings the candy out to the right and lets it go through the stars into Om Nom. Every rope plays its "
         "part: the wrong order, or a pause, and it falls wide.",
         candies=[(200, 200)], ropes=[rope(120, 120), rope(310, 120), rope(80, 100, slack=60)], om_nom=(369, 388),
         stars=[(255, 245), (291, 269), (327, 312)]),
    make("b1_l17", "Under the spikes",
         "Spikes block the straight drop to Om Nom. Cut the left rope: the right one swings the candy out and back; "
         "let go as it swings back low, and it flies under the spikes into Om Nom.",
         candies=[(200, 250)], ropes=[rope(120, 150), rope(330, 120)], spikes=[spikes((110, 310), (205, 310))],
         om_nom=(180, 440), stars=[(290, 305), (330, 330), (250, 370)]),
    make("b1_l18", "Throw over the spikes",
         "A row of spikes stands between the candy and Om Nom. Cut the lower rope: the red rope throws the candy up "
         "past its pin and swings it back and forth; let go as a swing carries it right, high enough to clear the "
         "spikes, and it falls into Om Nom.",
         candies=[(90, 520)], ropes=[rope(0, 630, balance=True), rope(250, 320, stretch=50)],
         spikes=[spikes((217, 430), (217, 710))], om_nom=(305, 607), stars=[(388, 248), (314, 431), (104, 463)]),
    make("b1_l19", "Not that rope",
         "Cut the left rope and the candy swings out on the right one, toward Om Nom behind a row of spikes; but "
         "the automatic rope lies across the swing: it grabs the candy and, left holding it alone, swings it into "
         "the spikes. Take it away first and let go at the far end of the swing; or let it grab, and let go of "
         "both ropes in turn at the moments that throw the candy over the spikes. Let go early and the candy flies "
         "into them.",
         candies=[(200, 250)], ropes=[rope(100, 130), rope(320, 150)], active_pins=[{"pos": (320, 400), "radius": 100}],
         spikes=[spikes((370, 450), (370, 680))], om_nom=(430, 600), stars=[(260, 300), (380, 300), (430, 420)]),
    make("b1_l20", "Together",
         "Cut the rope above the candy: it falls into the two slack ropes, swings and settles between them, over Om "
         "Nom. Then cut both in one swipe and it drops straight into him; cut the left one alone and the other swings "
         "it into the spikes, cut all three at once and it drops past him.",
         candies=[(190, 240)], ropes=[rope(190, 140), rope(60, 200, slack=170), rope(400, 200, slack=50)],
         spikes=[spikes((440, 420), (440, 620))], om_nom=(300, 640),
         stars=[(190, 330), (260, 400), (300, 540)]),
    make("b1_l21", "Twin slingshot",
         "Two red ropes pull the candy up against the rope below. Cut the lower one and they throw it up between "
         "their pins; let both go in one swipe as it comes back down, and it falls through the stars into Om Nom. "
         "Let go of one alone and the other pulls the candy aside; of both at once, or too late, and it misses him.",
         candies=[(260, 460)], ropes=[rope(120, 300, stretch=15), rope(400, 380, stretch=35), rope(260, 710, balance=True)],
         om_nom=(290, 595), stars=[(320, 316), (304, 334), (282, 456)]),
    make("b1_l22", "Which order?",
         "Three ropes, one of them slack. Cut the right one and the slack one, then at once the left one: the "
         "candy, flung right, flies through the stars into Om Nom. Any other order, or a pause, and it falls short.",
         candies=[(160, 280)], ropes=[rope(50, 170), rope(300, 170), rope(120, 180, slack=100)], om_nom=(325, 481),
         stars=[(214, 326), (249, 354), (283, 401)]),
    make("b1_l23", "Up, across, down",
         "Let the bubble take the candy up into the automatic rope's reach, pop it, and let go of the automatic rope "
         "when its swing points at Om Nom.",
         candies=[(80, 540)], ropes=[rope(80, 440)], bubbles=[{"pos": (80, 630)}],
         active_pins=[{"pos": (200, 260), "radius": 130}],
         om_nom=(400, 400), stars=[(80, 330), (200, 420), (320, 380)]),
    make("b1_l24", "Cardboard finale",
         "A stretched rope, a bubble and an automatic rope: sling the candy into the bubble, let it rise to the "
         "automatic rope, pop it, and let go of the automatic rope toward Om Nom.",
         candies=[(400, 580)], ropes=[rope(470, 660, balance=True), rope(300, 520, stretch=30)],
         bubbles=[{"pos": (190, 520)}], active_pins=[{"pos": (170, 230), "radius": 100}], om_nom=(320, 320),
         stars=[(250, 540), (190, 360), (260, 240)]),
]

# -- box 2: Fabric ----------------------------------------------------------------------------------


def cushion(x: float, y: float, angle: float) -> dict:
    return {"pos": (float(x), float(y)), "angle": float(angle)}


BOX2: list[Level] = [
    make("b2_l01", "A puff of air",
         "Tap the air cushion: its puffs push the hanging candy into a swing. Cut the rope and the candy flies on "
         "toward Om Nom; a tutorial, it reaches him however the two are done, but only three puffs and a cut near "
         "the top of the swing take it through every star.",
         candies=[(140, 360)], ropes=[rope(140, 200)], cushions=[cushion(30, 360, 0)],
         om_nom=(240, 460), stars=[(220, 360), (290, 280), (300, 390)]),
    make("b2_l02", "Puff the swing",
         "Puff the hanging candy: enough puffs and it swings up and round to Om Nom, through the stars; too few and "
         "it swings back.",
         candies=[(200, 330)], ropes=[rope(200, 170)], cushions=[cushion(70, 330, 0)],
         om_nom=(420, 165), stars=[(290, 310), (320, 215), (355, 165)]),
    make("b2_l03", "How many puffs?",
         "The candy starts in a bubble, tied down. Cut it loose: spikes hang over its way up. Push the bubble left "
         "with the cushion, far enough to pass them, to Om Nom.",
         candies=[(330, 560)], bubbles=[{"pos": (330, 560)}], ropes=[rope(330, 660)],
         cushions=[cushion(440, 380, 180)], spikes=[spikes((150, 150), (440, 150))], om_nom=(90, 80),
         stars=[(330, 440), (200, 330), (110, 220)]),
    make("b2_l04", "Puff it to the rope",
         "Puff the hanging candy up into the automatic rope's circle; once that rope has it, cut the first one and "
         "the new rope swings the candy to Om Nom.",
         candies=[(140, 420)], ropes=[rope(140, 300)], cushions=[cushion(40, 420, 0)],
         active_pins=[{"pos": (300, 260), "radius": 90}], om_nom=(380, 500), stars=[(200, 340), (260, 200), (330, 420)]),
    make("b2_l05", "Right, then left",
         "Two cushions on either side of the bubble's way up: the lower one pushes it right, past the spikes, the "
         "upper one back left to Om Nom.",
         candies=[(160, 600)], bubbles=[{"pos": (160, 600)}], ropes=[rope(160, 690)],
         cushions=[cushion(40, 470, 0), cushion(450, 230, 180)], spikes=[spikes((60, 340), (250, 340))],
         om_nom=(200, 70), stars=[(260, 440), (330, 300), (250, 140)]),
    make("b2_l06", "Puff the throw",
         "The red rope throws the candy up past its pin, but not far enough: a puff from below, as the candy passes "
         "over the cushion, carries it the rest of the way to Om Nom. Let it swing once under the pin, through the "
         "stars, and puff it when it comes back over the cushion; puffed on the throw itself it reaches him but "
         "misses every star, and puffed anywhere else it swings on.",
         candies=[(80, 600)], ropes=[rope(20, 690, balance=True), rope(180, 460, stretch=30)],
         cushions=[cushion(240, 640, 90)], om_nom=(330, 340), stars=[(286, 535), (149, 601), (45, 480)]),
    make("b2_l07", "Puff, then pop",
         "The candy rises in a bubble, tied down beside spikes. Cut it loose first (puffed while tied, it swings on "
         "its short rope into the spikes), let it rise through the first star, then puff it over until it floats "
         "above Om Nom and pop it: he is below, and the bubble would carry the candy away. Once it has drifted, one "
         "puff leaves it short of him and five carry it past; puffed and popped at once, it drops to him but misses "
         "the stars.",
         candies=[(100, 560)], bubbles=[{"pos": (100, 560)}], ropes=[rope(100, 620)], cushions=[cushion(20, 500, 0)],
         spikes=[spikes((150, 595), (150, 660))],
         om_nom=(240, 620), stars=[(100, 440), (180, 410), (258, 340)]),
    make("b2_l08", "Puff it into the bubble",
         "Puff the hanging candy so that it swings into the bubble; the bubble lifts it on its rope, and cutting the "
         "rope lets it rise to Om Nom.",
         candies=[(160, 420)], ropes=[rope(160, 260)], cushions=[cushion(30, 420, 0)], bubbles=[{"pos": (300, 360)}],
         om_nom=(330, 80), stars=[(240, 420), (320, 270), (340, 170)]),
    make("b2_l09", "A spider",
         "A spider crawls down the rope that holds the candy. Cut that rope before it arrives: the candy falls, the "
         "slack rope catches it and swings it toward Om Nom; let go of it on the way and the candy flies on through "
         "the stars into him. Hold on and the swing carries it back; let go at once and it falls short.",
         candies=[(150, 200)], ropes=[rope(150, 100, spider=0.5), rope(350, 160, slack=80)], om_nom=(390, 566),
         stars=[(150, 346), (225, 410), (308, 471)]),
    make("b2_l10", "Race the spider",
         "A spider comes down the left rope. Cut the three ropes one after the other, without a pause, in the right "
         "order: the candy is flung right, through the stars into Om Nom. The wrong order flings it wide; wait, and "
         "the spider takes it.",
         candies=[(200, 280)], ropes=[rope(120, 140, spider=0.5), rope(340, 200), rope(320, 180, slack=60)],
         om_nom=(383, 528), stars=[(254, 337), (303, 384), (341, 441)]),
    make("b2_l11", "Before the spider, after the swing",
         "A spider comes down one of the two short ropes: cut both before it arrives, and the slack rope catches the "
         "candy and swings it out to the right. Let go of it on the swing back, and it flies left to Om Nom; let go "
         "on the way out and it falls far to his right.",
         candies=[(240, 240)], ropes=[rope(225, 140, spider=0.0), rope(400, 190), rope(320, 70, slack=40)],
         om_nom=(150, 600), stars=[(410, 280), (217, 330), (173, 442)]),
    make("b2_l12", "Escape upward",
         "A spider is coming down the rope: cut it, and the bubble under the candy carries it up out of reach. Om Nom "
         "waits off to the left: puff the bubble over as it rises past the cushion, hard enough to reach him.",
         candies=[(340, 500)], ropes=[rope(340, 350, spider=0.0)], bubbles=[{"pos": (340, 590)}],
         cushions=[cushion(460, 320, 180)], om_nom=(145, 281), stars=[(340, 531), (340, 420), (249, 361)]),
    make("b2_l13", "Away from the spider",
         "A spider comes down the right rope. Cut the three ropes in the right order, one right after the other, "
         "and the candy is flung left through the stars into Om Nom. The wrong order flings it wide; wait, and the "
         "spider takes it.",
         candies=[(280, 240)], ropes=[rope(200, 160), rope(360, 100, spider=1.0), rope(360, 60, slack=100)],
         om_nom=(105, 447), stars=[(218, 274), (177, 308), (146, 355)]),
    make("b2_l14", "Three ropes and a spider",
         "A spider starts down the left rope at once. Cut the three ropes one after the other, without a pause, in "
         "the right order: the candy is flung left through the stars into Om Nom. The wrong order flings it wide; "
         "wait, and the spider takes it.",
         candies=[(240, 240)], ropes=[rope(130, 100, spider=0.0), rope(350, 160), rope(240, 100, slack=100)],
         om_nom=(93, 413), stars=[(192, 267), (154, 297), (126, 341)]),
    make("b2_l15", "Before the spider, in order",
         "A spider comes down the right rope. Cut the three ropes one after the other, without a pause, in the "
         "right order: the candy swings out to the right and flies through the stars into Om Nom. The wrong order "
         "drops it wide; wait, and the spider takes it.",
         candies=[(200, 280)], ropes=[rope(90, 200), rope(310, 170, spider=0.5), rope(360, 60, slack=60)],
         om_nom=(363, 468), stars=[(252, 315), (295, 347), (326, 394)]),
    make("b2_l16", "Cut loose before the spider",
         "A spider climbs the rope that ties the bubble down. Cut it loose in time, puff the rising bubble over, "
         "and pop it above Om Nom.",
         candies=[(90, 560)], bubbles=[{"pos": (90, 560)}], ropes=[rope(90, 660, spider=0.0)],
         cushions=[cushion(20, 330, 0)], om_nom=(265, 650), stars=[(90, 450), (180, 330), (265, 250)]),
    make("b2_l17", "Through the gap",
         "Spikes hang over the bubble's way up, with one gap, under Om Nom. Puff the rising bubble over by just the "
         "right amount: too few puffs or too many and it rises into the spikes.",
         candies=[(90, 560)], bubbles=[{"pos": (90, 560)}], ropes=[rope(90, 660)], cushions=[cushion(20, 330, 0)],
         spikes=[spikes((30, 150), (190, 150)), spikes((310, 150), (460, 150))], om_nom=(250, 60),
         stars=[(90, 420), (180, 300), (250, 200)]),
    make("b2_l18", "The spider's rope first",
         "Two ropes hold the candy, a spider coming down the left one. Cut that one first: the right one swings the "
         "candy out; let go as the swing carries it up toward Om Nom and it flies on through the stars into him. Cut the right one first and the candy waits for the "
         "spider; cut both at once and it drops far from him.",
         candies=[(200, 280)], ropes=[rope(60, 140, spider=0.0), rope(300, 120)], om_nom=(361, 423),
         stars=[(280, 308), (345, 304), (372, 320)]),
    make("b2_l19", "Swing over the spikes",
         "Puff the candy into a bigger swing than its rope alone would give, and cut it at the top: it clears the "
         "spikes and lands in Om Nom.",
         candies=[(130, 300)], ropes=[rope(130, 140), rope(240, 160, slack=0)], cushions=[cushion(30, 420, 30)],
         spikes=[spikes((230, 420), (330, 420))], om_nom=(420, 560), stars=[(200, 330), (300, 280), (380, 400)]),
    make("b2_l20", "Spider, bubble, cushion",
         "A spider comes down the rope that holds the bubble down. Cut it in time; the bubble rises, and the cushion "
         "pushes it over to Om Nom.",
         candies=[(150, 500)], bubbles=[{"pos": (150, 500)}], ropes=[rope(150, 640, spider=1.0)],
         cushions=[cushion(40, 250, 0)], om_nom=(360, 80), stars=[(150, 380), (250, 230), (340, 170)]),
    make("b2_l21", "Throw into the bubble, puff it over",
         "The red rope throws the candy into the bubble; then puff the bubble across to Om Nom.",
         candies=[(380, 600)], ropes=[rope(460, 690, balance=True), rope(260, 520, stretch=30)],
         bubbles=[{"pos": (170, 540)}], cushions=[cushion(30, 300, 0)], om_nom=(330, 90),
         stars=[(300, 540), (170, 400), (280, 220)]),
    make("b2_l22", "Puff, catch, swing",
         "Puff the candy toward the automatic rope's circle and cut its first rope: it flies into the circle and "
         "the automatic rope catches it and swings it round. Let go as the swing carries it up on the right and it "
         "drops through the stars into Om Nom; let go the moment it is caught and it still falls to him, but past "
         "every star; let go on the way down and it misses him.",
         candies=[(120, 380)], ropes=[rope(120, 260)], cushions=[cushion(20, 380, 0)],
         active_pins=[{"pos": (230, 320), "radius": 70}],
         om_nom=(340, 530), stars=[(258, 342), (308, 410), (312, 468)]),
    make("b2_l23", "Fabric finale",
         "A spider, a bubble, a cushion and spikes: beat the spider, ride the bubble, puff it clear of the spikes and "
         "pop it over Om Nom.",
         candies=[(380, 470)], ropes=[rope(380, 330, spider=0.5)], bubbles=[{"pos": (380, 560)}],
         cushions=[cushion(460, 300, 180)], spikes=[spikes((300, 150), (460, 150))],
         om_nom=(130, 600), stars=[(380, 400), (260, 260), (140, 200)]),
]

# -- box 3: Foil ------------------------------------------------------------------------------------


def track(x: float, y: float, period: float, phase: float = 0.0) -> dict:
    """A hook's track to (x, y): one round trip every `period` s, starting `phase` of the way round."""
    return {"to": (float(x), float(y)), "period": float(period), "phase": float(phase)}


def electric(a: Point, b: Point, period: float, on: float, phase: float = 0.0) -> dict:
    return {"a": a, "b": b, "period": period, "on": on, "phase": phase}


BOX3: list[Level] = [
    make("b3_l01", "A hook on a track",
         "The candy hangs from a hook that slides along its track by itself. Cut the rope when the candy is on its "
         "way over Om Nom.",
         candies=[(80, 280)], ropes=[rope(80, 130, track=track(400, 130, 8.0))], om_nom=(320, 620),
         stars=[(200, 300), (300, 420), (310, 520)]),
    make("b3_l02", "Sparks",
         "An electric barrier sparks on and off between the candy and Om Nom. Cut so that the candy passes it while "
         "it is off.",
         candies=[(240, 160)], ropes=[rope(240, 60)], electrics=[electric((140, 400), (340, 400), 3.0, 2.4)],
         om_nom=(240, 620), stars=[(240, 280), (240, 470), (240, 540)]),
    make("b3_l03", "A ramp",
         "Cut the two short ropes and the candy drops into the long rope's swing; let go of it at the top of the "
         "swing and it falls through the stars onto the metal ramp, which rolls it into Om Nom. Let go of the long "
         "rope first and a short one swings the candy away from the ramp.",
         candies=[(100, 260)], ropes=[rope(160, 110, slack=20), rope(30, 180), rope(130, 150)],
         walls=[wall((160, 440), (330, 580))], om_nom=(410, 610),
         stars=[(200, 290), (234, 385), (300, 515)]),
    make("b3_l04", "Hook and sparks",
         "The hook carries the candy back and forth above a barrier that sparks on and off. Cut when the candy is "
         "over Om Nom and the barrier will be off as it passes.",
         candies=[(100, 220)], ropes=[rope(100, 100, track=track(380, 100, 8.0))],
         electrics=[electric((200, 420), (460, 420), 1.6, 0.8)], om_nom=(360, 560), stars=[(240, 230), (330, 470), (330, 350)]),
    make("b3_l05", "Hook and anchor",
         "The hook carries the candy along; slack ropes from fixed pins on both sides would catch it and swing it "
         "back. Let it ride, and cut all three ropes in one swipe (or the hook's and the left one, then at once the "
         "right one) when the candy is where its fall ends in Om Nom, through the stars. Leave a rope on and it "
         "catches the candy; cut the hook's rope at once and the right rope swings the candy: let go of it at just "
         "the right moment and it still falls to Om Nom, but past every star.",
         candies=[(100, 300)], ropes=[rope(100, 150, track=track(250, 150, 4.0)), rope(420, 140, slack=40),
                                       rope(30, 140, slack=100)],
         om_nom=(260, 600), stars=[(165, 270), (190, 360), (215, 440)]),
    make("b3_l06", "Bounce off the wall",
         "Om Nom sits where no throw reaches him straight. Cut the three ropes in the right order, quickly: the "
         "candy is flung right, bounces off the wall and drops through the stars into him. Any other order flings it "
         "short or wide.",
         candies=[(200, 240)], ropes=[rope(110, 100), rope(310, 160), rope(160, 60, slack=140)],
         walls=[wall((410, 200), (410, 560))], om_nom=(363, 569), stars=[(291, 310), (338, 371), (380, 461)]),
    make("b3_l07", "Foil finale",
         "A hook, sparks and a ramp: let go of the moving candy when it will pass the barrier while it is off and "
         "land high on the ramp, which rolls it through the stars to Om Nom.",
         candies=[(100, 200)], ropes=[rope(100, 80, track=track(380, 80, 8.0))],
         electrics=[electric((130, 320), (440, 320), 2.0, 1.4, 1.4)], walls=[wall((250, 480), (390, 540))],
         om_nom=(440, 590), stars=[(251, 283), (290, 410), (376, 481)]),
]

# -- box 4: Magic -----------------------------------------------------------------------------------


def hats(a: Point, a_angle: float, b: Point, b_angle: float) -> dict:
    """A pair of magic hats: openings at a and b, facing the given angles (90: up, 270: down)."""
    return {"hats": ({"pos": a, "angle": a_angle}, {"pos": b, "angle": b_angle})}


BOX4: list[Level] = [
    make("b4_l01", "A magic hat",
         "Drop the candy into the hat: it comes out of the other hat of the same colour, across the screen, and falls "
         "on to Om Nom.",
         candies=[(100, 160)], ropes=[rope(100, 60)], hats=[hats((100, 420), 90, (360, 200), 270)], om_nom=(360, 600),
         stars=[(100, 300), (360, 330), (360, 460)]),
    make("b4_l02", "Out sideways",
         "The hat is not under the candy. Cut the left rope and let the right one swing the candy out; let go when "
         "its flight ends in the hat: the second hat faces sideways and shoots it across, as fast as it fell, to Om "
         "Nom. Both ropes at once drop it past the hat.",
         candies=[(110, 200)], ropes=[rope(50, 100), rope(170, 110)], hats=[hats((240, 520), 90, (180, 320), 0)],
         om_nom=(392, 339), stars=[(225, 285), (226, 432), (238, 320)]),
    make("b4_l03", "As fast as it went in",
         "The exit hat points up at Om Nom, high above it. The candy leaves as fast as it entered: let the bubble "
         "take it high before you pop it, so that it falls fast enough.",
         candies=[(100, 560)], bubbles=[{"pos": (100, 560)}], ropes=[rope(100, 660)],
         hats=[hats((100, 640), 90, (360, 620), 90)], om_nom=(360, 90), stars=[(100, 330), (100, 200), (360, 330)]),
    make("b4_l04", "Two pairs",
         "Two pairs of hats, told apart by their colours. Cut the left rope and let the right one swing the candy "
         "over; let go when its fall ends in the first hat: its pair throws the candy up into the second pair's "
         "hat, and that one drops it to Om Nom, under the spikes. Both ropes at once drop it straight, past the hats.",
         candies=[(240, 120)], ropes=[rope(150, 20), rope(300, 40)],
         hats=[hats((340, 380), 90, (420, 300), 180), hats((340, 243), 90, (420, 570), 270)],
         spikes=[spikes((330, 525), (470, 525))], om_nom=(420, 670), stars=[(390, 277), (340, 320), (340, 185)]),
    make("b4_l05", "Fling it into the hat",
         "Three ropes, one of them slack. Cut them one after the other, without a pause, in the right order, and the "
         "candy is flung down into the hat; its pair drops it through the stars into Om Nom. Any other order flings "
         "it past the hat.",
         candies=[(200, 200)], ropes=[rope(60, 120), rope(340, 90), rope(200, 220, slack=100)],
         hats=[hats((384, 445), 111, (420, 200), 270)], om_nom=(420, 560), stars=[(335, 340), (420, 276), (420, 379)]),
    make("b4_l06", "Puff into the hat",
         "Cut the left rope and the candy swings on the right one, too low for the hat. Puff it as it swings through "
         "the cushion's band, three puffs, and it flies up into the hat; its pair drops it to Om Nom. Five puffs throw "
         "it past the hat; cut loose, it falls short.",
         candies=[(120, 260)], ropes=[rope(40, 170), rope(210, 160)], cushions=[cushion(30, 315, 0)],
         hats=[hats((330, 225), 64, (380, 360), 270)], om_nom=(380, 624),
         stars=[(275, 282), (345, 150), (380, 500)]),
    make("b4_l07", "Around the spikes",
         "Spikes roof Om Nom over; the hat's pair opens under them. The hat is not under the candy: cut the left rope, "
         "let the right one swing the candy out, and let go at the far end of the swing, over the hat. Both ropes at "
         "once drop it beside the hat.",
         candies=[(110, 140)], ropes=[rope(30, 40), rope(170, 20)], hats=[hats((222, 434), 90, (360, 470), 270)],
         spikes=[spikes((280, 430), (440, 430))], om_nom=(360, 620), stars=[(222, 215), (223, 354), (360, 541)]),
    make("b4_l08", "Sling into the hat",
         "Cut the lower rope: the red rope slings the candy up past its pin and swings it back; let go of it at the "
         "end of the swing, right over the hat, and the candy drops in; the pair drops it from the top of the screen "
         "into Om Nom. Hold on and it swings over the hat; let go in the throw and it flies off.",
         candies=[(130, 560)], ropes=[rope(50, 640, balance=True), rope(200, 460, stretch=45)],
         hats=[hats((170, 621), 90, (100, 80), 270)], om_nom=(100, 420), stars=[(180, 548), (100, 146), (100, 280)]),
    make("b4_l09", "Out of the hat, into a rope",
         "The candy falls into the hat and shoots out of its pair sideways; the automatic rope catches it in flight "
         "and swings it round. Let go as the swing throws it back left, and it flies into Om Nom; hold on and it "
         "swings past him.",
         candies=[(80, 120)], ropes=[rope(80, 30)], hats=[hats((80, 420), 90, (160, 180), 0)],
         active_pins=[{"pos": (380, 230), "radius": 100}], om_nom=(204, 304), stars=[(238, 180), (340, 193), (406, 321)]),
    make("b4_l10", "The spider and the hat",
         "A spider comes down the left of the two short ropes. Cut both short ropes in one swipe before it arrives: "
         "the long rope swings the candy out to the right; let go of it at the far end of the swing, over the hat, "
         "and the pair drops the candy on Om Nom. Cut everything at once and it falls far from the hat.",
         candies=[(160, 240)], ropes=[rope(160, 140, spider=0.0), rope(280, 120, slack=0), rope(240, 140)],
         hats=[hats((383, 346), 90, (60, 360), 270)], om_nom=(60, 640), stars=[(273, 291), (383, 256), (60, 480)]),
    make("b4_l11", "Through the hat, past the sparks",
         "The pair of the hat opens above an electric barrier. Drop the candy when it will come out while the "
         "barrier is off.",
         candies=[(100, 140)], ropes=[rope(100, 40)], hats=[hats((100, 420), 90, (340, 120), 270)],
         electrics=[electric((260, 330), (440, 330), 3.0, 2.4)], om_nom=(340, 620), stars=[(100, 300), (340, 250), (340, 450)]),
    make("b4_l12", "Drop from the hook",
         "The hook carries the candy across; spikes roof Om Nom over, and the hat's pair opens under them. Drop the "
         "candy when its fall ends in the hat: a moment early or late and it misses.",
         candies=[(80, 200)], ropes=[rope(80, 80, track=track(400, 80, 8.0))], hats=[hats((200, 300), 90, (400, 480), 270)],
         spikes=[spikes((300, 430), (470, 430))], om_nom=(400, 660), stars=[(150, 205), (200, 240), (400, 590)]),
    make("b4_l13", "Roll into the hat",
         "The ramp is off to the right. Cut the left rope, let the right one swing the candy out, and let go at the "
         "far end of the swing: it drops on the ramp, rolls down into the hat at its foot, and the other hat throws "
         "it down to Om Nom. Both ropes at once drop it past the ramp.",
         candies=[(170, 180)], ropes=[rope(90, 90), rope(250, 90)], walls=[wall((380, 300), (250, 380))],
         hats=[hats((215, 395), 0, (400, 470), 270)], om_nom=(400, 640), stars=[(330, 200), (300, 330), (400, 560)]),
    make("b4_l14", "Puff the bubble under the hat",
         "The bubble rises beside the hat; puff it over so that it rises into the hat, and pop it when its pair lets "
         "it out over Om Nom.",
         candies=[(100, 560)], bubbles=[{"pos": (100, 560)}], ropes=[rope(100, 660)], cushions=[cushion(20, 420, 0)],
         hats=[hats((240, 200), 270, (340, 250), 0)], om_nom=(430, 620), stars=[(100, 470), (240, 300), (430, 400)]),
    make("b4_l15", "Magic finale",
         "Hook, hats, sparks and a spider. The hook carries the candy right until the long rope on the left holds it "
         "back over the hat. Let it go there, the hook's rope and that rope in one swipe and the right rope at once "
         "after (before it catches the candy), when the hat's pair will let it out while the barrier is off: it drops "
         "through the stars into the hat and on to Om Nom. No time for a second trip: a spider starts down the hook's "
         "rope. Cut the hook's rope at once and the right rope swings the candy into the hat, past every star.",
         candies=[(80, 220)], ropes=[rope(80, 100, track=track(380, 100, 8.0), spider=3.5), rope(260, 140, slack=0),
                                      rope(40, 210, slack=200)],
         hats=[hats((260, 450), 90, (420, 300), 270)], electrics=[electric((340, 420), (470, 420), 2.0, 1.0, 0.65)],
         om_nom=(420, 630), stars=[(280, 200), (270, 275), (270, 350)]),
]

# -- box 5: Valentine --------------------------------------------------------------------------------

BOX5: list[Level] = [
    make("b5_l01", "Two halves",
         "Two candy halves hang one above the other. Drop the upper one: it falls onto the lower one and they join "
         "into a whole candy; then drop that to Om Nom. Drop the lower one first and it reaches him alone: a half is "
         "no meal.",
         candies=[(240, 370), (240, 200)],
         ropes=[rope(240, 290, candy=0), rope(240, 100, candy=1)],
         om_nom=(240, 620), stars=[(240, 250), (240, 460), (240, 540)]),
    make("b5_l02", "Meet in the middle",
         "Both halves hang on two ropes each. Cut each half's outer rope (one swipe) and they swing together "
         "beneath the middle, join, and hang over Om Nom: then let them drop.",
         candies=[(120, 240), (360, 240)],
         ropes=[rope(40, 160, candy=0), rope(200, 140, candy=0), rope(280, 140, candy=1), rope(440, 160, candy=1)],
         om_nom=(240, 620), stars=[(195, 285), (300, 330), (240, 480)]),
    make("b5_l03", "Drop one onto the other",
         "One half hangs above the other. Drop it, then cut both of the lower half's ropes in one swipe: the upper "
         "half lands on the lower one (or, falling faster, catches it in the air) and the whole candy drops straight "
         "through the stars to Om Nom. Cut the two ropes one at a time and the last one swings the lower half aside: "
         "the halves miss each other, or the joined candy flies past the lowest star. Swipe at the first moment "
         "after the drop and the lower half falls ahead, to Om Nom alone.",
         candies=[(240, 420), (250, 200)],
         ropes=[rope(140, 330, candy=0), rope(320, 300, candy=0), rope(250, 90, candy=1)],
         om_nom=(240, 640), stars=[(250, 300), (240, 490), (215, 560)]),
    make("b5_l04", "A half in a bubble",
         "Drop the left half into the bubble and puff the rising bubble over to the right half: they join, floating "
         "on the right half's rope. Pop the bubble, then cut the rope, and the whole candy falls to Om Nom.",
         candies=[(140, 460), (320, 300)], bubbles=[{"pos": (140, 540)}],
         ropes=[rope(140, 350, candy=0), rope(320, 200, candy=1)], cushions=[cushion(20, 320, 0)],
         om_nom=(320, 640), stars=[(140, 400), (230, 320), (320, 480)]),
    make("b5_l05", "Puff the halves together",
         "Puff the right half three times: it swings up round its pin until it hangs over the left half. Let it go "
         "there and it drops onto the left half: they join on the left rope; cut that and the whole candy falls to "
         "Om Nom. One puff swings it only a little way (let go then and it meets the left half lower down, missing the "
         "high star); five puffs throw it over its pin and away; let go of the left half first and a half reaches Om "
         "Nom alone.",
         candies=[(180, 330), (300, 240)], ropes=[rope(180, 230, candy=0), rope(300, 140, candy=1)],
         cushions=[cushion(450, 240, 180)], om_nom=(140, 620), stars=[(215, 160), (176, 450), (168, 530)]),
    make("b5_l06", "Through the hat to the other half",
         "The left half drops into a hat; its pair throws it sideways into the right half. Joined, the candy hangs "
         "from the right half's rope: let it go over Om Nom.",
         candies=[(80, 150), (360, 330)], ropes=[rope(80, 50, candy=0), rope(360, 210, candy=1)],
         hats=[hats((80, 440), 90, (180, 330), 0)], om_nom=(380, 520), stars=[(80, 300), (270, 330), (360, 480)]),
    make("b5_l07", "Join over the spikes",
         "Spikes lie under the halves. Let them swing into each other first; only the joined candy, dropped at the "
         "right moment, clears the spikes to Om Nom.",
         candies=[(120, 280), (360, 280)],
         ropes=[rope(40, 200, candy=0), rope(200, 160, candy=0), rope(280, 160, candy=1), rope(440, 200, candy=1)],
         spikes=[spikes((60, 480), (200, 480)), spikes((280, 480), (420, 480))], om_nom=(240, 640),
         stars=[(240, 400), (240, 500), (160, 340)]),
    make("b5_l08", "The automatic rope brings them together",
         "Drop the left half: the automatic rope catches it and swings it into the right half. Joined, cut them "
         "loose over Om Nom.",
         candies=[(80, 150), (285, 395)], ropes=[rope(80, 50, candy=0), rope(285, 275, candy=1)],
         active_pins=[{"pos": (180, 320), "radius": 110}], om_nom=(285, 640), stars=[(80, 250), (200, 440), (285, 530)]),
    make("b5_l09", "Throw a half",
         "Cut the lower rope and the right half's rope in one swipe: the red rope throws the left half up into the "
         "falling right half and they join on the red rope. Let the whole candy swing down through the low star and "
         "back up, and let it go as it rises over Om Nom. Drop the right half late and it falls past the thrown one; "
         "let go of the candy too early and it flies off, or drops in without the low star.",
         candies=[(100, 500), (340, 300)],
         ropes=[rope(20, 580, candy=0, balance=True), rope(200, 400, candy=0, stretch=25), rope(340, 180, candy=1)],
         om_nom=(340, 640), stars=[(270, 390), (200, 530), (330, 450)]),
    make("b5_l10", "A spider on one half",
         "A spider comes down the right half's rope. Swing the left half into it before the spider arrives, then cut "
         "the joined candy loose.",
         candies=[(130, 300), (330, 300)],
         ropes=[rope(130, 180, candy=0), rope(280, 160, candy=0, slack=0), rope(330, 180, candy=1, spider=0.5)],
         om_nom=(300, 630), stars=[(230, 330), (300, 420), (300, 520)]),
    make("b5_l11", "Halves and sparks",
         "Cut the left half loose: it swings under the right half and they join, hanging from two ropes over an "
         "electric barrier. Cut both ropes in one swipe when the candy will pass the barrier while it is off.",
         candies=[(140, 200), (300, 270)],
         ropes=[rope(140, 100, candy=0), rope(300, 90, candy=0, slack=0), rope(300, 160, candy=1)],
         electrics=[electric((180, 440), (420, 440), 2.0, 0.8)], om_nom=(300, 640),
         stars=[(220, 280), (300, 370), (300, 520)]),
    make("b5_l12", "A half on the hook",
         "One half rides a hook along its track; drop it when it is over the other half's slack rope, which swings "
         "it into the other half. Joined, drop the candy on Om Nom.",
         candies=[(80, 200), (360, 420)],
         ropes=[rope(80, 100, candy=0, track=track(360, 100, 8.0)), rope(360, 300, candy=1)],
         om_nom=(360, 640), stars=[(220, 200), (360, 340), (360, 520)]),
    make("b5_l13", "Roll together",
         "Drop both halves on the ramp: they roll into each other at the bottom, join, and roll on into Om Nom.",
         candies=[(100, 200), (300, 300)], ropes=[rope(100, 100, candy=0), rope(300, 200, candy=1)],
         walls=[wall((60, 420), (340, 500))], om_nom=(420, 560), stars=[(100, 330), (200, 420), (300, 470)]),
    make("b5_l14", "Bubble and hat",
         "The left half rises in a bubble into a hat; its pair sets the bubble beside the right half. Pop it there "
         "so that the halves meet, then drop the candy to Om Nom.",
         candies=[(100, 560), (340, 300)], bubbles=[{"pos": (100, 560)}],
         ropes=[rope(100, 660, candy=0), rope(340, 200, candy=1)], hats=[hats((100, 200), 270, (340, 130), 270)],
         om_nom=(340, 640), stars=[(100, 380), (340, 220), (340, 470)]),
    make("b5_l15", "Two automatic ropes",
         "Each half falls through an automatic rope's circle; the two ropes swing the halves into each other. Then "
         "cut them loose over Om Nom.",
         candies=[(100, 100), (380, 100)], ropes=[rope(100, 30, candy=0), rope(380, 30, candy=1)],
         active_pins=[{"pos": (170, 300), "radius": 90}, {"pos": (310, 300), "radius": 90}], om_nom=(240, 630),
         stars=[(100, 230), (380, 230), (240, 480)]),
    make("b5_l16", "Puff one, drop the other",
         "The right half floats in a bubble; puff it over to the left half's line, pop it, and both meet as the left "
         "one falls. Joined, the candy falls on to Om Nom.",
         candies=[(120, 150), (360, 500)], bubbles=[{"pos": (360, 500)}],
         ropes=[rope(120, 50, candy=0), rope(360, 600, candy=1)], cushions=[cushion(460, 380, 180)],
         om_nom=(120, 640), stars=[(120, 260), (240, 390), (120, 520)]),
    make("b5_l17", "Stretched halves",
         "Two red ropes pull the halves toward each other, each held back by a rope behind it. Cut the two back ropes "
         "at once and they are thrown together.",
         candies=[(120, 300), (360, 300)],
         ropes=[rope(40, 300, candy=0, balance=True), rope(200, 300, candy=0, stretch=18),
                rope(440, 300, candy=1, balance=True), rope(280, 300, candy=1, stretch=18)],
         om_nom=(240, 640), stars=[(200, 330), (240, 420), (240, 520)]),
    make("b5_l18", "Spider between the halves",
         "A spider comes down the right half's rope; the left half hangs from a hook. Join them before it arrives, "
         "then let the whole candy drop into Om Nom.",
         candies=[(80, 260), (300, 320)],
         ropes=[rope(80, 140, candy=0, track=track(300, 140, 6.0)), rope(300, 180, candy=1, spider=1.0)],
         om_nom=(300, 640), stars=[(200, 270), (300, 420), (300, 520)]),
    make("b5_l19", "Valentine finale",
         "Cut the left half loose in its bubble, push the bubble across with the cushion to the right half, pop it "
         "as they meet, and drop the joined candy to Om Nom.",
         candies=[(80, 560), (360, 280)], bubbles=[{"pos": (80, 560)}],
         ropes=[rope(80, 660, candy=0), rope(360, 160, candy=1)], cushions=[cushion(20, 380, 0)], om_nom=(360, 640),
         stars=[(80, 440), (200, 300), (360, 480)]),
]

# -- the book ----------------------------------------------------------------------------------------

LEVELS: list[Level] = BOX1 + BOX2 + BOX3 + BOX4 + BOX5


def design(level_id: str) -> Level:
    for level in LEVELS:
        if level.id == level_id:
            return level
    raise KeyError(f"no design for level {level_id!r}")


def designed_ids() -> list[str]:
    return [lv.id for lv in LEVELS]


assert all(lv.box in BOXES for lv in LEVELS)
