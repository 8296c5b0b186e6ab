"""PHYRE prompt: place one red ball so that the green object ends up touching its goal.

By default it gives what the paper's PHYRE prompt gives (docs/comparability.md): the colour
legend, the numbered grid, the radius levels as shares of the image's width, the validity
rules; no sizes in pixels, no physical constants, no time limits. `state_text=true` gives
deepphy's earlier, richer text. Every number comes from the environment's space and sim.
"""

from deepphy.envs.base import Observation, Task
from deepphy.envs.phyre import sim
from deepphy.envs.phyre.space import MAX_RADIUS, MIN_RADIUS, SCENE, PhyreContinuousSpace, PhyreSpace
from deepphy.prompts.base import EnvPrompt


class PhyrePrompt(EnvPrompt):
    def rules(self, task: Task, observation: Observation) -> str:
        space = observation.action_space
        if task.params.get("state_text") or isinstance(space, PhyreContinuousSpace):
            return self._rich_rules(space)
        assert isinstance(space, PhyreSpace)
        g, levels = space.grid, space.radius_levels
        n = g * g
        return f"""You are an expert at physics puzzles. This one is a PHYRE puzzle: a 2D side view with gravity
pulling everything down; the edges of the picture are walls and its bottom edge is the floor.
Colours:
- red: the ball you add;
- green: the object that has to reach the goal;
- blue: a goal object that moves; purple: a goal object that is fixed;
- gray: other objects that move (they fall, roll, slide and tip over);
- black: fixed obstacles; they never move.

Goal: place one red ball so that, once everything moves, the green object ends up touching the
blue or purple goal object and stays in contact (a brief touch does not count). The ball is
placed before anything moves; nothing else can be changed.

Where the ball goes: the second image overlays a {g} x {g} grid of cells, each with its number
printed in it, 1 to {n}, row by row from the top-left. The centre of the red ball is placed at
the centre of the chosen cell. Its radius is one of {levels} levels: level 1 is tiny, about
{_share(space.radius_px(1))} of the image's width, level {levels} the largest, about {_share(space.radius_px(levels))} of it, and the
levels in between grow evenly. The ball starts at rest and falls when everything starts.

Validity: the ball must lie wholly inside the scene and must not overlap any object (touching
is allowed). A placement that breaks either rule is an invalid attempt: nothing is simulated
and the attempt is used up. An answer that is not in the format below is invalid too.

Answer format: Cell: <1..{n}>, Radius: <1..{levels}>"""

    def retry(self, task: Task, observation: Observation) -> str:
        space = observation.action_space
        if not isinstance(space, PhyreSpace):
            return super().retry(task, observation)
        return (f"{super().retry(task, observation)} Never reuse a cell and radius pair you have already tried. "
                f"Choose the cell on the image with the numbered grid; radius levels run from 1 (about "
                f"{_share(space.radius_px(1))} of the image's width) to {space.radius_levels} (about "
                f"{_share(space.radius_px(space.radius_levels))}).")

    def _rich_rules(self, space) -> str:
        """deepphy's text before paper parity (`state_text=true`; the continuous action space)."""
        held = sim.SOLVED_STEPS / sim.FPS
        total = sim.MAX_STEPS / sim.FPS
        head = f"""You are solving a PHYRE physics puzzle.

The scene is a 2D side view, {SCENE} x {SCENE} pixels, with gravity pulling everything down.
The edges of the picture are solid walls and the bottom edge is the floor.
Colours:
- black: fixed objects; they never move;
- gray: loose objects that fall, roll, slide and tip over;
- green: the loose object your goal is about;
- blue: a loose goal object; purple: a fixed goal object;
- red: the ball you add.
Objects are balls, bars and jars (open cups). All objects have the same density, so a
bigger ball is heavier. Objects bounce only a little.

Your move: add one red ball to the scene before the simulation starts; then nothing else
can be changed. The simulation runs for up to {total:.1f} seconds. The goal (stated below
the images) must hold for {held:g} seconds in a row: the two goal objects must stay in
contact for {held:g} seconds; brief bounces do not count.

"""
        if isinstance(space, PhyreContinuousSpace):
            where = f"""Where the ball goes: X and Y are the position of the ball's centre as fractions of the
scene: X from 0 (left edge) to 1 (right edge), Y from 0 (BOTTOM edge) to 1 (top edge); the
second image shows lines at every 0.1. R sets the radius: R = 0 is {MIN_RADIUS} px, R = 1 is {MAX_RADIUS} px,
linear in between. The ball starts at rest and falls as soon as the simulation starts.

Answer format: X: <0..1>, Y: <0..1>, R: <0..1>"""
        else:
            assert isinstance(space, PhyreSpace)
            g, levels = space.grid, space.radius_levels
            n = g * g
            radii = ", ".join(f"{k} = {space.simulated_radius(k)} px" for k in range(1, levels + 1))
            where = f"""Where the ball goes: the second image overlays a {g} x {g} grid of cells, numbered 1 to {n}
row by row starting at the TOP-LEFT cell (1 is top-left, {g} is top-right, {n} is
bottom-right). The centre of the red ball is placed at the centre of the chosen cell
(marked with a small cross). Radius levels: {radii} (the whole scene is {SCENE} px wide; a
grid cell is {SCENE / g:g} px wide). The ball starts at rest and falls as soon as the
simulation starts.

Answer format: Cell: <1..{n}>, Radius: <1..{levels}>"""
        return head + where + """

Validity: the ball must lie entirely inside the scene and must not overlap any object
(touching is allowed). A placement that breaks either rule is an invalid attempt: nothing
is simulated and the attempt is used up. An answer that is not in the format above is also
an invalid attempt."""

    def prediction_hint(self) -> str:
        return "what the red ball will hit, where the green object will end up, and whether the goal will hold"

    def example(self, observation: Observation) -> str:
        if isinstance(observation.action_space, PhyreContinuousSpace):
            return "X: 0.5, Y: 0.8, R: 0.3"
        return "Cell: 8, Radius: 3"


def _share(radius_px: float) -> str:
    """A radius as a share of the scene's width, as the paper states the levels: "1/128"."""
    return f"1/{SCENE / radius_px:.0f}"
