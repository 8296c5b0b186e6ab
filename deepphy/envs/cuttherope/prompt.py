"""Cut the Rope prompt: the scene's legend, the elements' rules, the goal and stars, the
action syntax. Every number comes from constants.py.

By default the words carry what the DeepPHY paper's prompt carries (../shared/notes/
paper-prompts.md, section 6), in our own words: the legend and glossary of the elements,
the goal, the failures and the stars, advice on order and timing, the rules of time and
the action menu with their ranges; no number about the world (gravity, speeds, reaches,
sizes). The task's `state_text` parameter (the environment option) gives the prompt that
goes with the numeric state: the picture's pixel coordinates, gravity, the ropes' give,
the bubbles', puffs' and spiders' numbers."""

from __future__ import annotations

import math

from deepphy.envs.base import Observation, Task
from deepphy.envs.cuttherope import constants as C
from deepphy.prompts.base import EnvPrompt


class CutTheRopePrompt(EnvPrompt):
    def rules(self, task: Task, observation: Observation) -> str:
        if task.params.get("state_text"):
            return self._rules_with_numbers(task)
        return f"""You are playing Cut the Rope, level "{task.id}". Feed the candy to Om Nom.

The picture is the whole level, seen from the front: gravity pulls the candy down the screen.
- Candy: the red disc with white stripes. In some levels there are two smaller pink candy halves
  instead: they join into one candy when they touch, and Om Nom eats only a whole candy.
- Om Nom: the round green creature with his mouth open in the middle. The level is won the
  moment the candy touches him. A candy half that touches him is lost.
- Ropes: lines from a pin to the candy; you can cut them. A sagging rope is slack and holds
  nothing until the candy pulls it straight; a straight rope holds the candy like a pendulum.
  A rope turns red when it is stretched: under tension it pulls the candy toward its pin, and
  a stretched rope left alone throws the candy that way (a stronger swing). Cut a rope and the
  candy flies on as it was moving at that moment. Ropes pass through everything.
- Pins (gray dots, yellow labels P1, P2, ...): the anchors of the ropes, one rope each. A hook is
  a pin that slides back and forth along a light gray groove by itself; its rope moves with it.
- Active pins (blue dots in a dashed blue circle, labels A1, ...): when the candy enters the
  dashed circle, a new rope shoots from that pin onto the candy, and the candy swings on it.
- Bubbles (light blue rings, labels B1, ...; the label moves with the bubble): a bubble closes
  around the candy that comes close enough and floats it upward; pop it and the candy falls
  free. Ropes still attached hold the bubble back.
- Air cushions (blue-gray boxes with an arrow, labels C1, ...): a tap makes it puff; each puff
  pushes the candy (or the bubble carrying it) in the arrow's direction, if it is in front of
  the cushion inside the pale band, harder the nearer it is.
- Magic hats (black hats with a coloured band, white labels H1, ...; the two hats of a pair
  share the colour and the label): the candy that moves into one hat's opening comes out of
  the other hat's opening, moving the way that hat faces, with the speed it had (its momentum
  is kept). The ropes holding it snap.
- Walls (thick brown bars): the candy bounces off them and rolls along them.
- Spikes (dark gray teeth) and electric barriers (a yellow zigzag while live, gray dashes while
  off, white labels E1, ...; they switch on and off by themselves) destroy the candy that
  touches them while they are deadly.
- Spiders (black, on a rope) climb down the rope toward the candy; if one reaches it, it takes
  the candy. Cut that rope before it arrives.
- Stars (gold): collected when the candy touches them.

Goal: Om Nom eats the candy (two halves: join them first). The level is lost when the candy
(or a half) leaves the screen, touches spikes or a live barrier, or a spider takes it. Stars:
the candy should touch all three stars on its way to Om Nom; the stars it touched (0 to 3)
count if the level is won. Win first; collect stars if you can.

Advice: the order of your actions matters, and so does their timing: a rope cut at the top of
a swing lets the candy fly furthest sideways, and a bubble popped at the right moment drops the
candy where you want it. Before you act, picture what gravity, momentum and a bubble's lift
will do with the candy, and combine the tools of the level.

{self._time_and_actions()}"""

    @staticmethod
    def _time_and_actions() -> str:
        times = ", ".join(str(t) for t in C.TAP_TIMES)
        return f"""Time: the world is paused while you decide. After each action the world runs for {C.ACTION_INTERVAL:g} s so
that you see its first consequence, then stops again; sleep(seconds) instead runs the world for
exactly that many seconds. You have at most {C.MAX_ACTIONS} actions. The level ends by itself as soon as
it is won or lost. After success(), fail(), or your {C.MAX_ACTIONS}th action, the world runs on without
you for up to {C.RUN_ON_CAP:g} s and the game decides: calling success() when Om Nom does not get the
candy counts as a loss, and a candy already on its way to him still wins after fail().

Actions (one per reply):
- cut_pin(id): cut the rope of pin P<id>, e.g. cut_pin(2) for P2. Several ids cut those ropes
  at the same moment (one long swipe), e.g. cut_pin(2, 3).
- cut_active_pin(id): cut the rope of active pin A<id> (several ids: at the same moment);
  before it has caught the candy this removes the active pin instead.
- pop_bubble(id): pop bubble B<id> (the candy it carries falls free).
- tap_air_cushion(id, times=n): n puffs of air cushion C<id>, n one of {times}.
- sleep(seconds): let the world run for {C.SLEEP_MIN:g} to {C.SLEEP_MAX:g} seconds (two decimals).
- success(): you are sure the candy will reach Om Nom; stop acting and let it happen.
- fail(): stop acting; the world runs on and the game decides.
Use only ids shown on the image that can still be used (the text lists them under "You can
now"); a rope already cut or a bubble already popped cannot be used again. Anything else
(unknown id, value out of range, no action) is an invalid action: it ends the level, lost."""

    def _rules_with_numbers(self, task: Task) -> str:
        fall_100 = math.sqrt(2 * 100 / C.GRAVITY)
        return f"""You are playing Cut the Rope, level "{task.id}". Feed the candy to Om Nom.

The picture ({C.WIDTH} x {C.HEIGHT} pixels) is the whole level; positions in the text are in these
pixels (px), x to the right and y DOWNWARD from the top-left corner. Gravity pulls the candy down
the screen at {C.GRAVITY:g} px/s^2 (let go from rest, it falls 100 px in about {fall_100:.2f} s).
- Candy: the red disc with white stripes. In some levels there are two smaller pink candy halves
  instead: they join into one candy when they touch, and Om Nom eats only a whole candy.
- Om Nom: the round green creature with his mouth open in the middle (a disc of radius
  {C.OMNOM_RADIUS:g} px). The level is won the moment the candy touches him, from any side. A candy
  half that touches him is lost.
- Ropes: lines from a pin to the candy. A rope pulls only when stretched beyond its length:
  slack (drawn sagging) it pulls nothing; taut it holds the candy like a pendulum (it swings)
  and gives a little, like a stiff elastic ({1 / C.ROPE_STIFFNESS:g} px per candy weight it carries); jerked
  taut it bounces the candy back. A rope
  drawn red is stretched: it contracts fast and throws the candy toward its pin. Cutting a
  rope lets the candy fly on with the velocity it had at that moment. Ropes pass through
  everything.
- Pins (gray dots, yellow labels P1, P2, ...): each holds one rope. A hook is a pin that slides
  back and forth along a light gray groove by itself (the text gives its round-trip time); its
  rope moves with it.
- Active pins (blue dots in a dashed blue circle, labels A1, ...): when the candy's centre
  enters the dashed circle, a new rope attaches from that pin (as long as the candy's distance
  then), and the candy swings on it.
- Bubbles (light blue rings, labels B1, ...; the label moves with the bubble): a bubble catches
  the candy that comes within {C.BUBBLE_CAPTURE:g} px of its centre and carries it upward (rising at
  about {C.BUBBLE_RISE_SPEED:g} px/s) until you pop it; ropes still attached hold it back.
- Air cushions (blue-gray boxes with an arrow, labels C1, ...): each puff pushes a candy (or the
  bubble carrying it) that is in front of the cushion, inside the pale band, in the arrow's
  direction: a velocity change of {C.PUFF_SPEED:g} px/s right at the nozzle, fading to nothing
  {C.PUFF_RANGE:g} px away; the band is {C.PUFF_WIDTH:g} px wide. The puffs of one tap come
  {C.PUFF_GAP:g} s apart.
- Magic hats (black hats with a coloured band, white labels H1, ...; the two hats of a pair
  share the colour and the label): the candy moving into the opening of one hat comes out of
  the other hat's opening, moving in the direction that hat faces, at the same speed. The
  ropes holding it snap.
- Walls (thick brown bars): the candy bounces off them and rolls along them.
- Spikes (dark gray teeth) and live electric barriers (yellow zigzag; gray dashed when off,
  white labels E1, ...; the text says when they switch) destroy the candy that touches them.
- Spiders (black, on a rope) crawl from the pin down the rope toward the candy at {C.SPIDER_SPEED:g} px/s;
  if one reaches the candy it takes it and the level is lost. Cutting that rope removes the
  spider.
- Stars (gold): collected when the candy touches them.
The level is lost when the candy (or a half) leaves the screen, touches spikes or a live
barrier, or a spider reaches it.

Goal: Om Nom eats the candy. Stars: the stars the candy touched on the way (0 to 3) count if
the level is won. Win first; collect stars if you can.

{self._time_and_actions()}"""

    def prediction_hint(self) -> str:
        return ("where the candy will move during the next moments, which stars it will touch, and "
                "whether it will reach Om Nom, hit a hazard or leave the screen")

    def example(self, observation: Observation) -> str:
        # A wait: the syntax of an action without a hint of any level's answer (doing nothing
        # wins no level; a test checks that this example wins none).
        return EXAMPLE


EXAMPLE = "sleep(0.5)"
