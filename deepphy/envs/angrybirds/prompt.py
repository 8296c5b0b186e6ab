"""Angry Birds prompt: launch the bird in the slingshot; kill every pig with the birds given.

By default it says what the paper's prompt said (the picture's legend, the birds and their
abilities in words, the action syntax, how stars are earned), no number a model could aim
or time with. The environment option `state_text` adds deepphy's richer text from before
parity (the picture's size in pixels, the abilities' times and damage factors, the score's
points); `physics_hints` (an ablation) adds the ballistics: gravity, launch speed per unit
of power, the picture's scale and launch pixel. The task's params carry both.
"""

from deepphy.envs.angrybirds import constants as C
from deepphy.envs.base import Observation, Task
from deepphy.prompts.base import EnvPrompt


def _g(x: float) -> str:
    return f"{x:.3g}"


class AngryBirdsPrompt(EnvPrompt):
    def rules(self, task: Task, observation: Observation) -> str:
        w, h = observation.images[0].size
        numbers = bool(task.params.get("state_text"))
        hints = self._hints(w, h) if task.params.get("physics_hints") else ""
        factor = C.BIRD_MATERIAL_FACTOR
        size = f"{w}x{h} pixels; " if numbers else ""
        soon = f"{_g(C.ABILITY_TIME)} s after launch" if numbers else "shortly after launch"
        fuse = f"{_g(C.BLACK_FUSE)} s after launch" if numbers else "a while after launch"
        wood = f" ({_g(factor['yellow']['wood'])}x damage to wood)" if numbers else ""
        ice = f" ({_g(factor['blue']['ice'])}x damage to ice)" if numbers else ""
        stone = (f"; its impact does\n  {_g(factor['black']['stone'])}x damage to stone" if numbers
                 else "; it is the bird\n  for stone and for chain reactions")
        score = (f"{C.SCORE_PIG} per pig killed, {C.SCORE_BLOCK} per block destroyed and, when the level is won,\n"
                 f"{C.SCORE_UNUSED_BIRD} per bird left unused" if numbers else
                 "points for every pig killed and block destroyed and, when the level is won, a bonus\n"
                 "for every bird left unused")
        return f"""You are playing Angry Birds, level "{task.id}": launch birds from a slingshot to kill every pig.

The picture is a side view ({size}gravity pulls down):
- the slingshot stands on the left; the bird sitting in it is the one you launch now, and the
  birds waiting on the ground behind it come next, the nearest one first;
- pigs are green round faces; small, medium and big pigs (bigger ones take more to kill);
- blocks are light brown (wood), pale blue (ice) or gray (stone): bars, squares, hollow
  squares, triangles, hollow triangles and round logs. Ice breaks easily, wood less so,
  stone hardly at all. A damaged block turns darker and shows black cracks; a hurt pig
  shows a purple bruise;
- dark brown-gray shapes are fixed ledges and slopes: they never move or break;
- red crates marked TNT explode when hit hard, damaging and throwing everything nearby;
- white dots trace the flight of the previous shot, up to where the bird first hit something.
The text under the picture names the bird in the slingshot, the birds after it, the pigs
left, the shots used and the score so far.

Goal: kill every pig with the level's birds, launched one at a time in their fixed order.
A pig dies when it is hit hard enough: by a bird, by a falling or flying block, by a fall
of its own, or by an explosion; a pig pushed out of the picture dies too. Blocks break
the same way. After each shot the scene is simulated until everything is at rest (a spent
bird disappears once it lies still); then you see it and choose the next shot. The level
is won as soon as no pig is left, and lost when the birds run out first. Aim with what
you see and what earlier shots did: hit the weak points that hold a structure up, and plan
around the birds' fixed order.

The birds (their abilities act by themselves; you only choose the launch):
- red: a plain bird, for impact and toppling.
- yellow: {soon} it dashes forward, much faster along its flight; it
  punches through wood{wood}.
- blue: {soon} it splits into three small birds that fan out slightly;
  it shatters ice{ice}.
- black: a bomb. It explodes at its first impact (or {fuse} if it has hit
  nothing by then), damaging and throwing everything near it{stone}.
A yellow or blue bird that hits something before its ability acts does not use it.

Action syntax (one line): shoot(angle=A, power=P)
- A is the launch angle in degrees above the horizontal, from {_g(C.ANGLE_MIN)} to {_g(C.ANGLE_MAX)}: 0 shoots
  straight to the right, 45 diagonally up and to the right, 90 straight up.
- P is the power, from {_g(C.POWER_MIN)} to {_g(C.POWER_MAX)}: how far the slingshot is pulled (1 = fully);
  the bird's launch speed is proportional to it.
- A and P are used to {C.ACTION_DECIMALS} decimal places. A reply that does not give one such shot, or
  gives a value out of range, is an invalid action: it is recorded as such and ends the level, lost.
{hints}
Score: {score}. Stars come from the birds: a win with as few birds as good
play needs on this level earns 3 stars, one star less for each bird more, and any win at least 1."""

    @staticmethod
    def _hints(w: int, h: int) -> str:
        px = w / C.WORLD_W  # pixels per world unit
        sling_x = C.SLING_X * px
        sling_y = h - (C.SLING_Y - C.GROUND_Y + C.GROUND_DEPTH) * px
        ground_y = h - C.GROUND_DEPTH * px
        blast = C.BLACK_BLAST["radius"]
        return f"""
Physics for aiming (the physics_hints option):
- 1 unit = {_g(px)} pixels; gravity is {_g(C.GRAVITY)} units/s^2 downwards; there is no air resistance.
- The bird leaves from pixel ({sling_x:.0f}, {sling_y:.0f}) of the picture (x to the right, y down from the
  top edge) at P x {_g(C.MAX_LAUNCH_SPEED)} units/s; the ground's surface is at pixel row {ground_y:.0f}.
- The yellow bird's dash adds {_g(C.YELLOW_BOOST)} units/s; the blue bird's two extra birds fly
  {_g(C.BLUE_SPLIT_DEGREES)} degrees above and below the first; the black bird's blast reaches
  {_g(blast)} units ({_g(blast * px)} pixels).
"""

    def prediction_hint(self) -> str:
        return ("where the bird will fly and what it will hit first, what will break, fall or explode, "
                "and which pigs will die")

    def example(self, observation: Observation) -> str:
        return "shoot(angle=30, power=0.85)"
