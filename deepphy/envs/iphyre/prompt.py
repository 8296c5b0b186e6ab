"""I-PHYRE prompt: plan the removal of gray blocks so that every red ball falls out."""

from deepphy.envs.base import Observation, Task
from deepphy.envs.iphyre.space import FPS, MAX_TIME
from deepphy.prompts.base import EnvPrompt


class IPhyrePrompt(EnvPrompt):
    def rules(self, task: Task, observation: Observation) -> str:
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
