"""I-PHYRE prompt: plan the removal of gray blocks so that every red ball falls out.

By default it gives what the paper's I-PHYRE prompt gives (docs/comparability.md): the
legend, the number of removable blocks and their indices, the time window, what to weigh
before a first plan, and after a failure its generic diagnosis checklist and revised-strategy
demands; no geometry. `state_text=true` gives deepphy's earlier, richer text (the game's
name, the scene's size in pixels, each block's centre).
"""

from deepphy.envs.base import Observation, Task
from deepphy.envs.iphyre.space import FPS, MAX_TIME
from deepphy.prompts.base import EnvPrompt


class IPhyrePrompt(EnvPrompt):
    def rules(self, task: Task, observation: Observation) -> str:
        if task.params.get("state_text"):
            return self._rich_rules(task, observation)
        n = observation.action_space.num_blocks  # type: ignore[attr-defined]
        t = f"{MAX_TIME:g}"
        return f"""You are solving an I-PHYRE physics puzzle: remove gray blocks at the right moments so
that every red ball drops into the abyss below the scene.

The scene shows (gravity pulls down):
- red balls: they must all fall out of the bottom of the scene;
- gray blocks: the only objects you can remove; the annotated image labels each with its
  index, 0 to {n - 1} (check the numbers against the image before you choose);
- black blocks: fixed, they cannot be removed; gray blocks stay fixed until removed;
- blue blocks: they move under gravity and collisions; green lines attach some of them to
  others with springs or rigid sticks.

Your only way to act is to remove gray blocks. You plan every removal in advance: the plan
then runs from the start to the end ({t} s) without further input. A plan is a JSON array of
objects, each with "time" (seconds after the start, from 0.0 to less than {t}; one decimal
is enough) and "index" (a gray block's index). An empty array [] removes nothing. The JSON
must be valid: a plan that is not such an array, or has a time or index out of range, is an
invalid attempt.

Before you plan, consider: the path each ball would take from where it starts; what removing
a block earlier or later changes; the chain reactions a removal sets off; and the physical
constraints (supports, springs, sticks, collisions)."""

    def retry(self, task: Task, observation: Observation) -> str:
        if task.params.get("state_text"):
            return super().retry(task, observation)
        return (f"{super().retry(task, observation)}\n"
                "Diagnose the failure: timing (a block removed too early or too late); sequencing (the wrong "
                "block first, a chain reaction missed); physics (a trajectory or a collision predicted wrongly).\n"
                "Then revise your strategy: avoid every approach that already failed, use the motion the pictures "
                "of your failures show, remove as few blocks as you can, and account for any behaviour you did not "
                "expect before.")

    def _rich_rules(self, task: Task, observation: Observation) -> str:
        """deepphy's text before paper parity (`state_text=true`)."""
        n = observation.action_space.num_blocks  # type: ignore[attr-defined]
        w, h = observation.images[0].size
        t = f"{MAX_TIME:g}"
        return f"""You are solving an I-PHYRE physics puzzle ("{task.id}").

The scene ({w}x{h} pixels, gravity pulls down) shows:
- red circles: balls, moved only by physics;
- gray bars: blocks you may remove; each carries its index (0..{n - 1}) in a yellow box in the annotated image;
- black bars: fixed blocks that cannot be removed;
- blue bars: blocks that move under physics and cannot be removed;
- green lines: joints or springs connecting two objects.

Goal: every red ball must fall below the bottom edge of the scene within {t} seconds.

Your only way to act is to remove gray blocks. You plan every removal in advance, before
the simulation starts; the plan then runs to the end without further input. A plan is a
JSON array of objects, each with "time" (seconds after the start, 0 <= time < {t}) and
"index" (a gray block's index, 0..{n - 1}). An empty array [] means: remove nothing.
Removals happen in time order, at most one per 1/{FPS} s. Removing a block that is already
gone has no effect.

A plan that is not such an array, or has a time or index outside those ranges, is an
invalid attempt and counts as a failed attempt."""

    def prediction_hint(self) -> str:
        return "where each red ball will go, and whether all of them will leave the scene"

    def example(self, observation: Observation) -> str:
        last = observation.action_space.num_blocks - 1  # type: ignore[attr-defined]
        return f'[{{"time": 1.5, "index": 0}}, {{"time": 4.0, "index": {last}}}]'
