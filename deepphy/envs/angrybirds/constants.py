"""Every number of the Angry Birds game, in one place.

Units: lengths in world units (u), time in seconds, masses in the units densities give
(density x area). The magnitudes start from Science Birds / Phy-Q (Unity units, see
/work/shared/notes/games.md) and were tuned in play with our pymunk world; each constant
says what it is for. Renderer colours live with the renderer; everything else is here.
Light: no pymunk or OpenCV import (the action space and the prompt read these).
"""

from __future__ import annotations

import math

# -- the world ------------------------------------------------------------------------------

WORLD_W = 16.0  # the visible world: x from 0 to WORLD_W ...
WORLD_H = 9.0  # ... and y from GROUND_Y - GROUND_DEPTH to WORLD_H - GROUND_DEPTH (a 16:9 view)
GROUND_Y = 0.0  # the ground's surface
GROUND_DEPTH = 0.8  # how much ground the view shows below the surface
OUT_OF_WORLD_MARGIN = 1.0  # anything this far beyond the left/right edge (or below the ground) is gone
GRAVITY = 9.81 * 0.48  # Science Birds' gravity scale 0.48: ~4.7 u/s^2, a slow, readable flight

# -- the simulation -------------------------------------------------------------------------

DT = 1.0 / 120.0  # fixed step: a full-power yellow bird moves 0.17 u per step (thinnest block 0.22 u)
ITERATIONS = 30  # solver iterations: stacks of up to ~10 blocks stand still
SETTLE_TIME = 2.0  # s simulated at reset, objects immortal, so every level starts at rest
SHOT_MAX_TIME = 12.0  # s after launch: the shot ends here even if something still moves
SHOT_MIN_TIME = 1.0  # s after launch before the scene may count as at rest
REST_SPEED = 0.12  # u/s: every body slower than this ...
REST_SPIN = 0.3  # rad/s: ... and turning slower than this ...
REST_HOLD = 0.5  # s: ... for this long = the scene is at rest
ROLLING_DAMPING = 2.0  # 1/s: angular damping of round bodies (birds, pigs, circles) so they stop rolling
TRAIL_EVERY = 0.08  # s between the dots of a bird's trail in the images

# -- the slingshot and the launch -----------------------------------------------------------

SLING_X = 2.2  # launch point (the slingshot's pouch)
SLING_Y = 1.6
MAX_LAUNCH_SPEED = 10.0  # u/s at power 1.0; launch speed = power x MAX_LAUNCH_SPEED
ANGLE_MIN, ANGLE_MAX = 0.0, 90.0  # degrees above the horizontal, towards the right
POWER_MIN, POWER_MAX = 0.0, 1.0
ACTION_DECIMALS = 2  # angle and power are used to two decimal places

# -- materials --------------------------------------------------------------------------------
# density (mass per u^2), defense (damage absorbed per hit), friction and elasticity
# (pymunk multiplies the coefficients of the two shapes in contact).

MATERIALS: dict[str, dict[str, float]] = {
    "wood": {"density": 1.5, "defense": 2.5, "friction": 0.8, "elasticity": 0.05},
    "ice": {"density": 0.75, "defense": 2.0, "friction": 0.35, "elasticity": 0.2},
    "stone": {"density": 4.0, "defense": 50.0, "friction": 0.9, "elasticity": 0.1},
}
GROUND_FRICTION = 0.9
GROUND_ELASTICITY = 0.3
PLATFORM_MATERIAL = {"friction": 0.9, "elasticity": 0.1}  # static platforms never break

# -- block shapes: size (w, h) or diameter, and hit points per material -----------------------

BLOCK_SIZES: dict[str, tuple[float, float]] = {
    "rect_big": (2.06, 0.22),
    "rect_fat": (0.85, 0.43),
    "rect_medium": (1.68, 0.22),
    "rect_small": (0.85, 0.22),
    "rect_tiny": (0.43, 0.22),
    "square_hole": (0.84, 0.84),  # a hollow square: four walls
    "square_small": (0.43, 0.43),
    "square_tiny": (0.22, 0.22),
    "triangle": (0.82, 0.82),  # right triangle, the right angle at the bottom left
    "circle": (0.8, 0.8),
    "circle_small": (0.45, 0.45),
}
SQUARE_HOLE_WALL = 0.14  # wall thickness of a hollow square
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
    "circle": {"wood": 200, "ice": 125, "stone": 600},
    "circle_small": {"wood": 150, "ice": 100, "stone": 300},
}
ROUND_SHAPES = ("circle", "circle_small")

# -- pigs -------------------------------------------------------------------------------------

PIG_RADIUS = {"small": 0.215, "medium": 0.37, "big": 0.465}
PIG_HIT_POINTS = {"small": 4.0, "medium": 10.0, "big": 25.0}
PIG_DENSITY = 1.0
PIG_FRICTION = 0.8
PIG_ELASTICITY = 0.1
PIG_DEFENSE = 0.5  # so that settling and slow nudges do not wear a pig down

# -- TNT ----------------------------------------------------------------------------------------

TNT_SIZE = 0.5  # a square crate
TNT_DENSITY = 1.0
TNT_HIT_POINTS = 3.0
TNT_DEFENSE = 2.0  # so that resting on it or a nudge does not set it off
TNT_BLAST = {"radius": 2.0, "impulse": 4.0, "damage": 100.0}

# -- birds ---------------------------------------------------------------------------------------

BIRD_RADIUS = {"red": 0.17, "yellow": 0.16, "blue": 0.12, "black": 0.2}
BIRD_MASS = {"red": 1.0, "yellow": 0.6, "blue": 0.45, "black": 1.4}  # each of the blue bird's three
BIRD_FRICTION = 0.6
BIRD_ELASTICITY = 0.3
# Impact damage multiplier of each bird against each material (Science Birds' values).
BIRD_MATERIAL_FACTOR: dict[str, dict[str, float]] = {
    "red": {"wood": 1.0, "ice": 1.0, "stone": 1.0},
    "yellow": {"wood": 2.4, "ice": 1.2, "stone": 1.0},
    "blue": {"wood": 1.0, "ice": 4.0, "stone": 1.0},
    "black": {"wood": 1.0, "ice": 1.0, "stone": 2.5},
}
BIRD_NAMES = {"red": "red bird", "yellow": "yellow bird", "blue": "blue bird", "black": "black bird"}
BIRD_LETTERS = {"R": "red", "Y": "yellow", "B": "blue", "K": "black"}  # the reference set's sequences

# Abilities: triggered automatically, as the reference protocol's fixed taps did.
ABILITY_TIME = 0.3  # s after launch: yellow dashes, blue splits (only if it has hit nothing yet)
YELLOW_BOOST = 8.0  # u/s added along the yellow bird's velocity
BLUE_SPLIT_DEGREES = 9.0  # the two extra blue birds fly this many degrees above and below the first
BLACK_FUSE = 2.0  # s after launch the black bird explodes at the latest; at its first impact if sooner
BLACK_BLAST = {"radius": 2.0, "impulse": 4.0, "damage": 130.0}

# -- damage ----------------------------------------------------------------------------------------
# A hit (the first contact step between two bodies) carries an impulse J (mass x speed).
# Each body with hit points takes damage  J x IMPACT_DAMAGE x factor - its defense  (never
# negative), where factor is the bird's material factor when a bird is involved and
# NON_BIRD_FACTOR otherwise. Explosions deal damage x (1 - d / radius) within their radius
# and push with impulse x (1 - d / radius), away from the centre.

IMPACT_DAMAGE = 11.22
NON_BIRD_FACTOR = 1.0

# -- score and stars --------------------------------------------------------------------------------

SCORE_PIG = 5000
SCORE_BLOCK = 500  # per block destroyed (TNT included)
SCORE_UNUSED_BIRD = 10000  # per bird not launched, when the level is won
# Stars: 1 for a win; 2 and 3 from per-level thresholds derived from the oracle's best score B.
# With W = SCORE_PIG x pigs (the least any win scores): threshold = W + fraction x (B - W),
# rounded down to a multiple of STAR_ROUNDING (so B itself always earns 3 stars).
TWO_STAR_FRACTION = 0.4
THREE_STAR_FRACTION = 0.8
STAR_ROUNDING = 500

# -- levels ------------------------------------------------------------------------------------------

MAX_BIRDS = 8  # the largest bird count of the reference levels (scene 1, level 21)
SCENE_LEVELS = {1: 21, 2: 13}


def launch_velocity(angle: float, power: float) -> tuple[float, float]:
    """The launch velocity (u/s) of an action."""
    a = math.radians(angle)
    speed = power * MAX_LAUNCH_SPEED
    return speed * math.cos(a), speed * math.sin(a)
