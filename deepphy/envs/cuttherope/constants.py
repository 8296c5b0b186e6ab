"""Every number of the Cut the Rope game, in one place.

Units: the world is the screenshot. One unit is one pixel of the 480 x 720 image the model
sees; x grows to the right, y grows DOWNWARD (screen coordinates), time is in seconds.
The magnitudes start from the recovered web version of the game (a 320 x 480 map, see
/work/shared/notes/games.md), scaled by 1.5 to our 480 x 720 screen, then tuned in play.
Angles (air cushions, magic hats) are degrees counter-clockwise from "pointing right" as
seen on the screen: 0 right, 90 up, 180 left, 270 down.

Light module (no pymunk): the action space, the prompt and the level files read it.
"""

from __future__ import annotations

# -- the screen and the clock ---------------------------------------------------------------
WIDTH = 480  # world width = image width (units = pixels)
HEIGHT = 720  # world height = image height
DT = 0.01  # physics step (s); every time in the game is a whole number of steps
STEPS_PER_SECOND = 100  # = 1 / DT, as an exact integer
SOLVER_ITERATIONS = 10  # pymunk's solver iterations per step (pymunk's default; only wall contacts use them)
GRAVITY = 825.0  # downward acceleration (units/s^2): ~550 map units/s^2 of the web game x 1.5

# -- decisions ------------------------------------------------------------------------------
MAX_ACTIONS = 10  # decisions per attempt (EnvSpec.max_steps)
# The world runs ACTION_INTERVAL after every action but sleep/success/fail: about a player's
# visual reaction time (the quickest a player can act again on what an action did), shorter
# than every window our levels ask for (>= 0.3 s), and long enough that the action's first
# consequence shows (a candy let go falls ~26 px). Ropes that must go at the same moment are
# cut by one action naming them all (the game's long swipe), not by two quick actions.
ACTION_INTERVAL = 0.25
SLEEP_MIN = 0.1  # sleep(seconds): the world runs exactly `seconds` (no extra interval) ...
SLEEP_MAX = 10.0  # ... within [SLEEP_MIN, SLEEP_MAX] ...
SLEEP_DECIMALS = 2  # ... written with at most 2 decimals (whole physics steps)
TAP_TIMES = (1, 3, 5)  # tap_air_cushion(id, times): the allowed numbers of puffs
RUN_ON_CAP = 10.0  # s the world runs on after success(), fail() or the last action, to decide the outcome
SAMPLE_SLEEPS = (0.5, 1.0, 2.0)  # the sleeps ActionSpace.sample() draws from (uniform over a finite set)

# -- the candy ------------------------------------------------------------------------------
CANDY_RADIUS = 24.0  # a whole candy (the web game's ~37 x 35 map units)
CANDY_MASS = 1.0
HALF_RADIUS = 18.0  # each of the two candy halves of box 5
HALF_MASS = 0.5  # two halves make one candy; momentum is conserved when they join
OFFSCREEN_MARGIN = 60.0  # the candy is lost once its centre is this far outside the screen
CANDY_ELASTICITY = 0.3  # bounce off a wall: the normal speed after / before (pymunk multiplies it by the wall's 1.0)
CANDY_FRICTION = 0.6  # friction on a wall: the candy (a solid disc) rolls down slopes rather than sliding

# -- Om Nom, stars and walls ----------------------------------------------------------------
# Om Nom is drawn as a green disc with his mouth open in its middle; he eats the whole candy
# the moment it touches that disc, from any side (catch zone = what is drawn; the web game
# opens his mouth as the candy comes near and eats what overlaps it). A candy half touching
# him is lost: he eats it, and the level needs the whole candy.
OMNOM_RADIUS = 36.0  # his drawn disc and catch zone (1.5 x the candy's radius)
WALL_RADIUS = 6.0  # a wall (block) is a segment this thick on each side; the candy bounces off and rolls on it
STAR_RADIUS = 20.0  # a star is collected when the candy's edge touches its circle

# -- ropes, pins, active pins, spiders ------------------------------------------------------
# A rope is an elastic segment from its pin to the candy's centre with a rest length: slack
# (it pulls nothing) while the candy is closer than that, a stiff spring once stretched beyond
# it. It swings the candy like a pendulum (stretched ~1 px per candy weight it carries), gives
# when jerked taut and throws the candy back (a damped bounce), and a rope that starts shorter
# than the pin-candy distance (a stretched rope, drawn red) contracts at once and throws the
# candy toward its pin, as the web game's Verlet chains do (its light nodes carry ~2 % of
# the candy's mass, so the rope's own mass is left out). Ropes pass through everything, as
# in the web game (no rope collides there). Cutting it removes it: the candy keeps its velocity.
PIN_RADIUS = 7.0  # drawn
ROPE_STIFFNESS = 1.0  # candy weights of tension per px of stretch (omega = sqrt(g / 1 px) ~ 29 rad/s)
ROPE_DAMPING = 18.0  # 1/s: tension (x candy mass) per px/s of stretching speed, only while stretched;
#                      damping ratio ~0.3: a rope jerked taut throws the candy back at ~0.35 x its speed
# A swing dies down, as in the game (the web game's Verlet chains lose a little of their motion
# every frame and a hanging candy settles): while a rope pulls the candy, the candy's velocity
# relaxes at ROPE_DRAG, so a free swing keeps exp(-ROPE_DRAG * t / 2) of its amplitude (half
# in ~5.5 s, ~30 % after 10 s). A candy in free flight or in a bubble is not slowed by it.
ROPE_DRAG = 0.25  # 1/s
ROPE_RED_STRETCH = 12.0  # px of stretch at which a rope is drawn fully red (the web game's red ropes)
ACTIVE_PIN_MARGIN = 0.0  # an active pin attaches a rope when the candy centre is within radius + margin
SPIDER_SPEED = 58.0  # units/s a spider crawls along its rope toward the candy (39 map units/s x 1.5)

# -- bubbles --------------------------------------------------------------------------------
BUBBLE_RADIUS = 36.0  # drawn
BUBBLE_CAPTURE = 42.0  # a free bubble captures the candy whose centre comes this close (28 map units x 1.5)
BUBBLE_RISE_SPEED = 105.0  # terminal rising speed of a bubble carrying the candy (units/s)
BUBBLE_DRAG = 4.0  # 1/s: velocity relaxation toward the rising speed while in a bubble

# -- air cushions ---------------------------------------------------------------------------
PUFF_DELAY = 0.05  # s from the tap to the first puff ...
PUFF_GAP = 0.05  # ... and between the puffs of one tap
PUFF_SPEED = 300.0  # velocity change (units/s) a puff gives a candy right at the nozzle ...
PUFF_RANGE = 312.0  # ... decaying linearly to 0 at this distance along the cushion's direction ...
PUFF_WIDTH = 150.0  # ... and only inside a column this wide, centred on the cushion's axis
CUSHION_SIZE = 30.0  # drawn

# -- magic hats -----------------------------------------------------------------------------
HAT_RADIUS = 30.0  # the candy enters a hat when its centre comes this close to the hat's opening while moving into it
HAT_SPEED_FACTOR = 1.0  # exit speed / entry speed (the candy keeps its speed)
HAT_EXIT_GAP = 4.0  # the candy leaves the paired hat's opening this far beyond the hat's zone

# -- hazards --------------------------------------------------------------------------------
HAZARD_REACH = 22.0  # a spike row or a live electric segment destroys the candy whose centre comes this close to its line
SPIKE_TOOTH = 10.0  # drawn: height of the spike teeth on each side of the line

# -- the picture ----------------------------------------------------------------------------
TRAIL_EVERY = 5  # key frames trace the candy's path, one dot every 5 physics steps
