"""Every number of the Angry Birds game, in one place, each with its reason.

Units: lengths in world units (u), time in seconds, masses in the units densities give
(density x area). The magnitudes start from Science Birds / Phy-Q (Unity units; the values
are listed in /work/shared/notes/games.md and quoted below as "SB"); where ours differ the
comment says "SB: ..." and why. Renderer colours live with the renderer; everything else is
here. Light: no pymunk or OpenCV import (the action space and the prompt read these).
"""

from __future__ import annotations

import math

# -- the world ------------------------------------------------------------------------------

WORLD_W = 16.0  # the visible world: x from 0 to WORLD_W (SB levels are ~17.5 u wide; ours fit a 16:9 view)
WORLD_H = 9.0  # ... and y from GROUND_Y - GROUND_DEPTH to WORLD_H - GROUND_DEPTH
GROUND_Y = 0.0  # the ground's surface
GROUND_DEPTH = 0.8  # how much ground the view shows below the surface
OUT_OF_WORLD_MARGIN = 1.0  # anything this far beyond the left/right edge (or below the ground) is gone
GRAVITY = 9.81 * 0.48  # SB's gravity scale 0.48: ~4.7 u/s^2, a slow, readable flight

# -- the simulation -------------------------------------------------------------------------

# SB steps 0.02 s with 100 iterations (Box2D). pymunk needs a finer step for our fastest
# body: a dashing yellow bird (~18 u/s) moves 0.15 u per step, less than the thinnest
# block (0.22 u), so nothing tunnels; 30 iterations keep stacks of ~10 blocks still.
DT = 1.0 / 120.0
ITERATIONS = 30
SETTLE_TIME = 2.0  # SB: objects are immortal for the first 2 s while the level settles; so are ours
SHOT_MIN_TIME = 1.0  # s after launch before the scene may count as at rest (the bird is still flying)
# A shot ends when every bird of it is gone (see SPENT_BIRD_TIME) and every body has been
# slower than REST_SPEED and REST_SPIN for REST_HOLD: then nothing visible moves any more
# (a body at 0.05 u/s would need 20 s to move one unit). The reference waited ~8 s per
# shot; our shots end on the state itself, typically 3-6 s after launch.
REST_SPEED = 0.05  # u/s
REST_SPIN = 0.15  # rad/s
REST_HOLD = 0.5  # s
SHOT_MAX_TIME = 30.0  # s: a safety cap only; no shot of our calibration comes near it (tests check)
TRAIL_EVERY = 0.08  # s between the dots of a bird's trail in the images

# Spent birds. SB: a bird that has hit something starts checking its speed 3 s later and
# vanishes once it is still. Ours leave once they lie still (slower than the rest
# thresholds, touching something, for BIRD_REST_HOLD) or SPENT_BIRD_TIME after their first
# hit at the latest, whichever comes first; the world then runs on until it is at rest, so
# what a removed bird was propping falls before the shot ends.
SPENT_BIRD_TIME = 3.0  # s after a bird's first hit
BIRD_REST_HOLD = 0.25  # s lying still

# Rolling and skidding. pymunk's circles roll without resistance: a bird that lands rolled on
# for 7+ u and out of the world, so grazing the ground in front of a structure won levels.
# SB's birds are polygons that tumble to a stop. Ours: each round body has a motor that holds
# its spin at 0 with at most the torque that slows it by ROLL_RESISTANCE u/s^2 when it rolls
# on flat ground (solved with the contacts, so a pig stays put on a gentle slope and a log
# rolls down a steep one), and a bird loses BIRD_SKID u/s^2 of speed while it touches
# anything (it digs in; it does not skid like a puck). Result (tests check it): a red bird
# shot flat lands at x ~ 6.9 (power 0.6) or ~10 (power 1) and stops within
# BIRD_STOP_DISTANCE of where it lands. With this, nothing creeps: after 1,000 random shots
# no body moved more than 0.001 u in 10 idle seconds (so no sleeping is needed; Chipmunk's
# sleeping with these motors crashed pymunk once in ~20,000 simulations).
ROLL_RESISTANCE = {  # u/s^2
    "bird": 5.0,
    "pig": 2.0,  # a pig knocked off a ledge rolls about a unit
    "log": 0.5,  # circle blocks are wheels: on a slope of more than ~10 degrees they roll down
}
BIRD_SKID = 12.0  # u/s^2
# Angular drag: Unity (SB's engine) damps every body's spin. Ours: blocks and crates have a
# spin brake of at most SPIN_BRAKE x weight x reach (the farthest corner from the centre).
# For a standing post that is ~12 % of the torque that tips it over (for a lying bar ~6 %):
# a toppling post still falls as before, a nudge that barely tilts it does not, and a plank
# rocking on a round pig (which rocked for ever without it) stops within a few swings.
SPIN_BRAKE = 0.03
BIRD_STOP_DISTANCE = 2.5  # u: the documented bound (a flat full-power red bird stops ~2.2 u after landing)

# -- the slingshot and the launch -----------------------------------------------------------

SLING_X = 2.2  # launch point (the slingshot's pouch)
SLING_Y = 1.6
MAX_LAUNCH_SPEED = 10.0  # u/s at power 1.0 (SB: full pull ~10 u/s); launch speed = power x MAX_LAUNCH_SPEED
ANGLE_MIN, ANGLE_MAX = 0.0, 90.0  # degrees above the horizontal, towards the right
POWER_MIN, POWER_MAX = 0.0, 1.0
ACTION_DECIMALS = 2  # angle and power are used to two decimal places (the reference's rounding)

# -- materials --------------------------------------------------------------------------------
# density (mass per u^2), defense (damage absorbed per hit), friction and elasticity.
# SB (density / defense / friction / bounciness): wood 1.5 / 2.5 / 4 / 0, stone 4 / 15 / 4 /
# 0.1, ice 0.75 / 2 / 0.7 / 0.2. Densities are SB's. Box2D mixes friction as sqrt(f1 f2) and
# bounciness as max; pymunk multiplies both, so our coefficients are chosen for the products:
# wood on wood 1.0 and stone on stone 1.0 (SB's 4 means stacked blocks never slide; ours
# only slide when pushed hard), ice on ice 0.12 and ice on wood 0.35 (SB's ice grips like
# wood; ours is slippery, so sliding is one of the things a level can ask about).
# Stone defense: SB 15. A red bird at full speed deals ~50-60 to a stone bar; with 15, two
# or three red hits break any stone bar and stone is just heavy wood. With 50 a red bird
# dents stone and the black bird (x2.5 against stone, and its blast) is what breaks it.

MATERIALS: dict[str, dict[str, float]] = {
    "wood": {"density": 1.5, "defense": 2.5, "friction": 1.0, "elasticity": 0.05},
    "ice": {"density": 0.75, "defense": 2.0, "friction": 0.35, "elasticity": 0.2},
    "stone": {"density": 4.0, "defense": 50.0, "friction": 1.0, "elasticity": 0.1},
}
GROUND_FRICTION = 0.9  # grass: blocks that fall over stay near where they fall
GROUND_ELASTICITY = 0.3  # times each body's own: a dull landing (bird on ground: 0.09)
TERRAIN_MATERIAL = {"friction": 0.9, "elasticity": 0.1}  # fixed platforms and slopes (never break)

# -- block shapes: size (w, h) or diameter, and hit points per material -----------------------
# Sizes and hit points are SB's (their Unity units are ours).

BLOCK_SIZES: dict[str, tuple[float, float]] = {
    "rect_big": (2.06, 0.22),
    "rect_fat": (0.85, 0.43),
    "rect_medium": (1.68, 0.22),
    "rect_small": (0.85, 0.22),
    "rect_tiny": (0.43, 0.22),
    "square_hole": (0.84, 0.84),  # a hollow square: four walls
    "square_small": (0.43, 0.43),
    "square_tiny": (0.22, 0.22),
    "triangle": (0.82, 0.82),  # a right triangle, the right angle at the bottom left
    "triangle_hole": (0.82, 0.82),  # the same triangle, hollow: three walls
    "circle": (0.8, 0.8),
    "circle_small": (0.45, 0.45),
}
HOLLOW_WALL = 0.14  # wall thickness of the hollow square and the hollow triangle
BLOCK_HIT_POINTS: dict[str, dict[str, float]] = {  # wood / ice / stone
    "rect_big": {"wood": 100, "ice": 65, "stone": 140},
    "rect_fat": {"wood": 80, "ice": 53, "stone": 140},
    "rect_medium": {"wood": 70, "ice": 47, "stone": 120},
    "rect_small": {"wood": 50, "ice": 33, "stone": 80},
    "rect_tiny": {"wood": 40, "ice": 26, "stone": 60},
    "square_hole": {"wood": 120, "ice": 70, "stone": 160},
    "square_small": {"wood": 60, "ice": 40, "stone": 100},
    "square_tiny": {"wood": 20, "ice": 13, "stone": 30},
    "triangle": {"wood": 80, "ice": 53, "stone": 140},
    "triangle_hole": {"wood": 70, "ice": 48, "stone": 140},
    "circle": {"wood": 200, "ice": 125, "stone": 600},
    "circle_small": {"wood": 150, "ice": 100, "stone": 300},
}
ROUND_SHAPES = ("circle", "circle_small")

# -- pigs -------------------------------------------------------------------------------------
# Radii are SB's. SB's hit points (small 1, medium 15, big 80) belong to SB's damage scale;
# ours are set by what kills a pig (tests check the order of the falls): a fall onto flat
# ground of ~1.8 u kills a small pig, ~2.2 u a medium one, ~3.5 u a big one; a direct hit by
# a red bird kills from ~2.4, ~3.3 and ~4.8 u/s (the blue bird's small birds: ~2.8, ~4.5,
# ~7.2 u/s). A stone bar must drop 0.07 u onto a small pig, 0.75 u onto a medium one and
# ~3 u onto a big one to kill it (it was 0.03 u for both small and medium: fragile pigs).
# Big pigs need real hits, falls from high, heavy stone or explosions.
PIG_RADIUS = {"small": 0.215, "medium": 0.37, "big": 0.465}
PIG_HIT_POINTS = {"small": 3.0, "medium": 11.0, "big": 22.0}
PIG_DENSITY = 1.0  # lighter than wood (1.5): a plank pushes a pig, a pig hardly moves a plank
PIG_FRICTION = 0.8
PIG_ELASTICITY = 0.1
PIG_DEFENSE = 0.5  # settling, resting and slow nudges never wear a pig down

# -- TNT ----------------------------------------------------------------------------------------
# SB: hit points 3, blast radius 2.5, impulse 4, damage 100. Our radius is 2.0: our
# structures are packed into x 6..15.5 (SB spreads them over ~12 u), and 2.5 u reached the
# neighbouring structure, so one crate decided a whole level wherever a bird hit near it.

TNT_SIZE = 0.5  # a square crate
TNT_DENSITY = 1.0
TNT_HIT_POINTS = 3.0
TNT_DEFENSE = 2.0  # so that resting on it or a nudge does not set it off (a thrown block does)
TNT_BLAST = {"radius": 2.0, "impulse": 4.0, "damage": 100.0}

# -- birds ---------------------------------------------------------------------------------------

BIRD_RADIUS = {"red": 0.17, "yellow": 0.16, "blue": 0.12, "black": 0.2}  # SB's
# SB's red bird weighs 0.5. Ours are heavier than a wooden plank (0.55) so that a hit moves a
# structure rather than bouncing off it; the order (black > red > yellow > blue) is SB's.
BIRD_MASS = {"red": 1.0, "yellow": 0.6, "blue": 0.45, "black": 1.4}  # blue: each of its three
BIRD_FRICTION = 0.6
BIRD_ELASTICITY = 0.3
# Impact damage multiplier of each bird against each material (SB's values; against pigs 1).
BIRD_MATERIAL_FACTOR: dict[str, dict[str, float]] = {
    "red": {"wood": 1.0, "ice": 1.0, "stone": 1.0},
    "yellow": {"wood": 2.4, "ice": 1.2, "stone": 1.0},
    "blue": {"wood": 1.0, "ice": 4.0, "stone": 1.0},
    "black": {"wood": 1.0, "ice": 1.0, "stone": 2.5},
}
BIRD_NAMES = {"red": "red bird", "yellow": "yellow bird", "blue": "blue bird", "black": "black bird"}
BIRD_LETTERS = {"R": "red", "Y": "yellow", "B": "blue", "K": "black"}  # the reference set's sequences

# Abilities: triggered automatically, as the reference protocol's fixed taps did.
ABILITY_TIME = 0.3  # s after launch (the reference tapped 0.3 s after launch): yellow dashes, blue splits
YELLOW_BOOST = 8.0  # u/s added along the yellow bird's velocity (SB: "a large speed-up")
BLUE_SPLIT_DEGREES = 9.0  # the two extra blue birds fly this many degrees above and below the first
BLACK_FUSE = 2.0  # s after launch the black bird explodes at the latest (the reference: ~2 s); at its first impact if sooner
# SB's black bird: radius 3, impulse 4, damage 20. A 3 u blast covers a third of our world
# and 20 breaks nothing but ice; ours is the level's answer to stone: within ~1 u of it a
# stone bar (80-140 hp) breaks, beyond 2 u nothing is touched.
BLACK_BLAST = {"radius": 2.0, "impulse": 4.0, "damage": 130.0}

# -- damage ----------------------------------------------------------------------------------------
# SB: a bird hitting a block deals  rel_speed x bird_mass x material factor x 11.22 -
# defense; any other collision  rel_speed x attacker_mass x 11.22 x 0.5 - defense.
# - A bird's hit on a block or TNT crate: SB's rule, rel_speed being how fast the two close
#   along the contact's normal as it begins (a graze along a face is no blow) and the mass
#   BIRD_DAMAGE_MASS. So a full-power red bird (10 u/s) deals 10 x 0.5 x 11.22 - 2.5 = 53.6
#   to wood and breaks a lone small bar (50 hp) wherever it stands; at half power (25.6) it
#   does not. (Ours took the contact's impulse here: a light block barely stops a bird, so a
#   lone small bar took only 53-67 % of its hit points from a full-power red bird.)
# - Everything else (bodies falling, toppling, thrown, and a bird's hit on a pig): the
#   impulse J of the contact's first step (mass x speed change, what SB's product measures
#   for two bodies that stop each other) in place of rel_speed x mass: J x IMPACT_DAMAGE x
#   factor - defense, factor 1 for a bird's hit on a pig (our pigs' hit points are set by
#   this rule, see PIG_HIT_POINTS) and NON_BIRD_FACTOR (SB's 0.5) otherwise.
# Damage is never negative. Explosions deal damage x (1 - d / radius) within their radius
# and push with impulse x (1 - d / radius), away from the centre.

IMPACT_DAMAGE = 11.22
NON_BIRD_FACTOR = 0.5
# SB's masses in the damage rule: SB's red bird weighs 0.5; the others keep our ratios
# (BIRD_MASS, which is twice SB's so that a hit moves a structure). Hit points and defenses
# are SB's, so a bird's blow is SB's too. Against our blocks at full power: red breaks small
# wooden bars and any ice bar, not a long wooden one (70-100 hp); a dashing yellow (~17 u/s,
# x2.4) breaks any wooden bar; each of the blue's three breaks ice (x4); black x2.5 dents stone.
BIRD_DAMAGE_MASS = {"red": 0.5, "yellow": 0.3, "blue": 0.225, "black": 0.7}

# -- score and stars --------------------------------------------------------------------------------
# SB's (and the game's) score: 5000 per pig, 500 per block destroyed, 10000 per bird left
# unused at the end of a won level. (SB also gives 10 x damage for hits that break nothing;
# ours leaves that out, so the score counts what was destroyed.)

SCORE_PIG = 5000
SCORE_BLOCK = 500  # per block destroyed (TNT included)
SCORE_UNUSED_BIRD = 10000  # per bird not launched, when the level is won
# Stars (levels.stars_for): fewer birds come first. A win with no more birds than the
# oracle's stored plan uses earns 3 stars (fewer than the oracle's: 3 too); each bird more
# costs a star, down to 1. Destruction counts in the score, not in the stars: a threshold on
# the oracle's destruction made a clean one-bird win 2 stars (the game gives 3), and score
# thresholds printed per level revealed the oracle's bird count ((3-star threshold - 5000 x
# pigs) // 10000). Nothing shown to a model states the oracle's count.
STARS_MAX = 3
# -- levels ------------------------------------------------------------------------------------------

MAX_BIRDS = 8  # the largest bird count of the reference levels (scene 1, level 21)
SCENE_LEVELS = {1: 21, 2: 13}


def launch_velocity(angle: float, power: float) -> tuple[float, float]:
    """The launch velocity (u/s) of an action."""
    a = math.radians(angle)
    speed = power * MAX_LAUNCH_SPEED
    return speed * math.cos(a), speed * math.sin(a)
