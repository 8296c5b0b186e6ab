"""The cart: integer positions 0..RAIL-1, velocity changed by each push, then one move."""

from __future__ import annotations

import numpy as np

from deepphy.envs import Environment, Image, Observation, StepResult, Task
from toy_env import SPEC
from toy_env.space import MAX_PUSHES, PushAction, PushSpace

RAIL = 12


class CartEnv(Environment):
    spec = SPEC

    @classmethod
    def tasks(cls, options) -> list[Task]:
        return [Task(env=SPEC.name, id=f"flag-{f:02d}", group="near" if f < 6 else "far", params={"flag": f})
                for f in range(2, RAIL)]

    def reset(self, task: Task) -> Observation:
        self.flag, self.x, self.v, self.pushes = task.params["flag"], 0, 0, 0
        return self._observation()

    def step(self, action: PushAction) -> StepResult:
        self.pushes += 1
        self.v += action.force
        self.x = min(max(self.x + self.v, 0), RAIL - 1)
        if self.x in (0, RAIL - 1) and self.v:
            self.v = 0  # the buffers stop it
        won = self.x == self.flag and self.v == 0
        out_of_pushes = self.pushes >= MAX_PUSHES and not won
        feedback = f"the cart is at {self.x} moving {self.v:+d}"
        return StepResult(
            terminated=won, truncated=out_of_pushes, success=won, feedback=feedback,
            observation=None if won or out_of_pushes else self._observation(),
            key_frames=[Image.from_array("after", f"after push {self.pushes}", self._render())],
            info={"x": self.x, "v": self.v},
        )

    def _render(self) -> np.ndarray:
        img = np.full((20, 10 * RAIL, 3), 255, np.uint8)
        img[12:20, 10 * self.flag : 10 * self.flag + 10] = (0, 160, 0)
        img[4:12, 10 * self.x + 2 : 10 * self.x + 8] = (200, 30, 30)
        return img

    def _observation(self) -> Observation:
        return Observation(images=[Image.from_array("rail", "The rail: cart red, flag green.", self._render())],
                           text=f"Cart at {self.x}, velocity {self.v:+d}, flag at {self.flag}.",
                           action_space=PushSpace())
