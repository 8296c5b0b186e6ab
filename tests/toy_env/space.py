"""`push(F)` with F in -2..2: the cart's velocity changes by F cells per push."""

from __future__ import annotations

import re
from typing import Literal, Sequence

import numpy as np

from deepphy.envs import Action, ActionSpace, InvalidAction

MAX_PUSHES = 4
FORCES = (-2, -1, 0, 1, 2)
_PUSH = re.compile(r"push\(\s*(-?[0-9]{1,3})\s*\)", re.I | re.ASCII)


class PushAction(Action):
    force: int


class PushSpace(ActionSpace):
    kind: Literal["toy_push"] = "toy_push"

    def parse(self, text: str) -> PushAction:
        found = _PUSH.findall(text[-10_000:])
        if not found:
            raise InvalidAction("expected push(F)")
        force = int(found[-1])
        if force not in FORCES:
            raise InvalidAction(f"F must be one of {FORCES}, got {force}")
        return PushAction(force=force)

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> PushAction:
        return PushAction(force=int(rng.choice(FORCES)))

    def format(self, action: Action) -> str:
        assert isinstance(action, PushAction)
        return f"push({action.force})"
