"""Pooltool prompt: single-player nine-ball; choose the cue speed and where to strike the cue ball.

By default it gives what the paper's Pooltool prompt gives (docs/comparability.md): the table
image, the speed and strike-spot names with what spin does, the goal; not the speeds in m/s,
the spots' offsets, the shot budget, that the aim is automatic, or a history of earlier shots
(the updated table is the feedback). `state_text=true` gives deepphy's earlier, richer text."""

from deepphy.envs.base import Observation, Task
from deepphy.envs.pooltool.space import ACTIONS, MAX_SHOTS, SPEEDS, SPOT_OFFSETS
from deepphy.prompts.base import EnvPrompt


NINEBALL_GOAL = """Goal: pot the 9-ball on a legal shot, within {shots} shots in total. The 9-ball counts whenever
it drops on a legal shot, even if other balls are still on the table (for example when the
target ball knocks it in)."""
NINEBALL_RULES = """Rules:
- The cue ball must hit the target ball before any other ball.
- After that contact, some ball must fall into a pocket or some ball must touch a cushion.
- The cue ball must not fall into a pocket (a scratch).
- The first shot is the break: it is legal if a ball is potted or at least four numbered
  balls touch a cushion, and the cue ball stays on the table.
Breaking any of these is a foul. A foul does not end the game: you get ball in hand, which
here means the cue ball is placed on the head spot (or right next to it if a ball is in
the way). Balls potted on a foul stay down, except the 9-ball, which is put back on the
spot in the right half of the table."""
REFERENCE_GOAL = """Goal: pot the 9-ball, within {shots} shots in total. Any shot that pots the 9-ball wins,
even if other balls are still on the table or the shot would be a foul in real nine-ball."""
REFERENCE_RULES = """Rules: there are no fouls and no break. The first shot starts from the head spot like any
other. Potted balls stay down. If the cue ball falls into a pocket, it is put back on the
head spot (or right next to it if a ball is in the way)."""


PAPER_TEXT = """You are playing single-player nine-ball pool, one shot at a time.

The image shows the table from directly above: green cloth inside brown rails, the six black
circles are the pockets, the plain white ball is the cue ball (the only ball you strike), and
the coloured balls carry their numbers 1 to 9 (the 9-ball is white with a yellow band). Balls
potted earlier have been removed; a cue ball that was potted has been put back on the table.

Goal: pot the 9-ball, in any pocket, by striking the lowest-numbered ball on the table. Potting
the cue ball is a foul: avoid it. Leave the cue ball well placed for the next shot.

Each shot, choose how hard to strike and where the cue tip strikes the cue ball:
- speed: {speeds};
- strike spot, as seen from behind the cue ball:
    top-left     top-centre     top-right
    middle-left  middle-centre  middle-right
    bottom-left  bottom-centre  bottom-right
  Top spots give follow (the cue ball rolls on after it hits a ball), bottom spots give draw
  (it stops or comes back), left and right spots give side spin (English), which bends the cue
  ball's path to one side, most visibly off a cushion; middle-centre gives no spin.
{rules}
Answer format (one line, nothing else): Speed: <speed>, Strikespot: <spot>"""
PAPER_NINEBALL = """
Rules of this game (deepphy's nine-ball option): the cue ball must hit the lowest-numbered ball
first, and then some ball must be potted or touch a cushion; the first shot is the break. A
foul gives ball in hand: the cue ball is placed on the head spot. A 9-ball potted on a foul is
put back on the table.
"""


class PooltoolPrompt(EnvPrompt):
    def recent_steps(self, task: Task) -> int:
        # The paper's prompt has no history of shots: the updated table is the feedback
        return self.recent_steps_shown if task.params.get("state_text") else 0

    def rules(self, task: Task, observation: Observation) -> str:
        if not task.params.get("state_text"):
            speeds = list(SPEEDS)
            return PAPER_TEXT.format(speeds=f"{', '.join(speeds[:-1])} or {speeds[-1]}",
                                     rules=PAPER_NINEBALL if task.params.get("rules") == "nineball" else "")
        return self._rich_rules(task)

    def _rich_rules(self, task: Task) -> str:
        """deepphy's text before paper parity (`state_text=true`)."""
        speeds = list(SPEEDS)
        speed_names = f"{', '.join(speeds[:-1])} or {speeds[-1]}"
        metres = f"{', '.join(f'{v:g}' for v in list(SPEEDS.values())[:-1])} or {list(SPEEDS.values())[-1]:g}"
        edge = SPOT_OFFSETS["top-centre"][1]  # the edge spots' distance from the centre, in ball radii
        if task.params.get("rules") == "reference":
            goal, rules = REFERENCE_GOAL.format(shots=MAX_SHOTS), REFERENCE_RULES
        else:
            goal, rules = NINEBALL_GOAL.format(shots=MAX_SHOTS), NINEBALL_RULES
        return f"""You are playing nine-ball pool alone ("{task.id}"), one shot at a time.

The image is the table seen from directly above:
- green cloth inside brown rails; the darker green strips along the edges are the cushions;
- the six black circles are the pockets (four corners, two in the middle of the long sides);
- the plain white ball is the cue ball, the only ball you strike;
- the coloured balls carry their numbers 1 to 9; the 9-ball is white with a yellow band;
- the lowest-numbered ball on the table is the target: it is circled in magenta, and a
  dashed line runs from the cue ball to it;
- the faint vertical line near the left end is the head string, and the faint dot on it is
  the head spot.
The text under the image lists the balls still on the table and their positions.

{goal}

How a shot works: you do not aim. The cue is always pointed straight at the centre of the
target (lowest-numbered) ball, as the dashed line shows. You choose only how hard to hit
and where on the cue ball the cue tip strikes. You keep playing after every shot, whether
or not you potted a ball.

{rules}

Action syntax (one line): Speed: <speed>, Strikespot: <spot>
- speed is {speed_names}: the cue hits the cue ball at {metres} metres per second.
- spot is one of nine points on the cue ball, as seen by a player standing behind the
  cue ball and looking along the dashed line:
    top-left     top-centre     top-right
    middle-left  middle-centre  middle-right
    bottom-left  bottom-centre  bottom-right
  Top spots give topspin (after hitting a ball the cue ball keeps rolling forward), bottom
  spots give backspin (the cue ball stops or comes back), middle-centre gives no spin, and
  left / right spots give side spin, which changes how the cue ball leaves a cushion and
  pushes it slightly off the line, to the side opposite the spin. The edge spots lie {edge:g}
  ball radius from the centre; the corner spots lie the same distance away, diagonally.
There are {len(ACTIONS)} actions in all. A reply that does not give one speed and one spot from these
lists is an invalid action: it is recorded as such and ends the game unsolved."""

    def prediction_hint(self) -> str:
        return (
            "which balls the cue ball and the target ball will hit, which balls (if any) will be "
            "potted, whether the shot will be legal, and where the cue ball will stop"
        )

    def example(self, observation: Observation) -> str:
        return "Speed: Medium, Strikespot: top-centre"
