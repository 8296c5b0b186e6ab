"""PHYRE prompt: place one red ball so that the green object reaches its goal."""

from deepphy.envs.base import Observation, Task
from deepphy.envs.phyre.scene import FPS, MAX_STEPS, SOLVE_STEPS, W
from deepphy.prompts.base import EnvPrompt


class PhyrePrompt(EnvPrompt):
    def rules(self, task: Task, observation: Observation) -> str:
        space = observation.action_space
        g, levels = space.grid, space.radius_levels  # type: ignore[attr-defined]
        n = g * g
        radii = ", ".join(f"{k} = {space.radius_px(k):g} px" for k in range(1, levels + 1))  # type: ignore[attr-defined]
        return f"""You are solving a PHYRE physics puzzle.

The scene is a 2D side view, {W:g} x {W:g} pixels, with gravity pulling everything down.
The edges of the picture are solid walls and the bottom edge is the floor.
Colours:
- black: fixed objects; they never move;
- gray: loose objects that fall, roll, slide and tip over;
- green: the loose object your goal is about;
- blue: a loose goal object; purple: a fixed goal object (a purple strip along an edge
  means that wall or floor is the goal object);
- red: the ball you add.
Objects are balls, bars, open jars (cups) and wedges. All objects have the same density,
so a bigger ball is heavier. Objects bounce only a little.

Your move: add one red ball to the scene before the simulation starts; then nothing else
can be changed. The simulation runs for up to about {MAX_STEPS / FPS:.0f} seconds. The goal (stated below
the images) must hold for {SOLVE_STEPS / FPS:g} seconds in a row: when it asks that the green object touches
a goal object, they must stay in contact for {SOLVE_STEPS / FPS:g} seconds; brief bounces do not count.

Where the ball goes: the second image overlays a {g} x {g} grid of cells, numbered 1 to {n}
row by row starting at the TOP-LEFT cell (1 is top-left, {g} is top-right, {n} is
bottom-right). The centre of the red ball is placed at the centre of the chosen cell
(marked with a small cross). Radius levels: {radii} (the whole scene is {W:g} px wide; a
grid cell is {W / g:g} px wide). The ball starts at rest and falls as soon as the
simulation starts.

Answer format: Cell: <1..{n}>, Radius: <1..{levels}>

Validity: the ball must lie entirely inside the scene and must not overlap any object.
A placement that breaks either rule is an invalid attempt: nothing is simulated and the
attempt is used up. An answer that is not in the format above is also an invalid attempt."""

    def prediction_hint(self) -> str:
        return "what the red ball will hit, where the green object will end up, and whether the goal will hold"

    def example(self, observation: Observation) -> str:
        return "Cell: 8, Radius: 3"
