"""The Kinetix action syntax: a JSON list of integers, one per controllable motor, then one
per thruster. Pure Python: no JAX, so a model process can rebuild the space from JSON.
"""

from __future__ import annotations

import json
from typing import Literal, Sequence

import numpy as np

from deepphy.envs.base import Action, ActionSpace, InvalidAction
from deepphy.envs.parsing import brief, is_number, last_json_array

MOTOR_VALUES = (0, 1, 2)  # off, forward, reverse
THRUSTER_VALUES = (0, 1)  # off, on


class KinetixAction(Action):
    """One decision: a value per controllable motor (0 off, 1 forward, 2 reverse) and per
    thruster (0 off, 1 on), in label order M0.., T0..."""

    motors: tuple[int, ...]
    thrusters: tuple[int, ...]




class KinetixSpace(ActionSpace):
    kind: Literal["kinetix_vector"] = "kinetix_vector"
    num_motors: int
    num_thrusters: int

    @property
    def length(self) -> int:
        return self.num_motors + self.num_thrusters

    def labels(self) -> list[str]:
        return [f"M{i}" for i in range(self.num_motors)] + [f"T{i}" for i in range(self.num_thrusters)]

    def parse(self, text: str) -> KinetixAction:
        values = last_json_array(text)
        if values is None:
            raise InvalidAction("no JSON list of integers found (expected e.g. [1, 0])")
        if any(isinstance(v, (list, dict)) for v in values):
            raise InvalidAction("the action must be a flat list of integers")
        if len(values) != self.length:
            raise InvalidAction(
                f"expected a list of {self.length} integers ({', '.join(self.labels()) or 'none'}), "
                f"got {len(values)} value(s)"
            )
        ints: list[int] = []
        for label, v in zip(self.labels(), values):
            if not is_number(v) or not float(v).is_integer():
                raise InvalidAction(f"{label} must be an integer, got {brief(v)}")
            ints.append(int(v))
        motors, thrusters = ints[: self.num_motors], ints[self.num_motors :]
        for i, v in enumerate(motors):
            if v not in MOTOR_VALUES:
                raise InvalidAction(f"M{i} must be 0 (off), 1 (forward) or 2 (reverse), got {v}")
        for i, v in enumerate(thrusters):
            if v not in THRUSTER_VALUES:
                raise InvalidAction(f"T{i} must be 0 (off) or 1 (on), got {v}")
        return KinetixAction(motors=tuple(motors), thrusters=tuple(thrusters))

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> KinetixAction:
        # Every entry uniform over its values. `exclude` (actions of failed attempts) is
        # ignored: on-the-fly decisions repeat legitimately.
        motors = tuple(int(v) for v in rng.integers(0, 3, size=self.num_motors))
        thrusters = tuple(int(v) for v in rng.integers(0, 2, size=self.num_thrusters))
        return KinetixAction(motors=motors, thrusters=thrusters)

    def format(self, action: Action) -> str:
        assert isinstance(action, KinetixAction)
        return json.dumps(list(action.motors) + list(action.thrusters))
