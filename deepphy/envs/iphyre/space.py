"""The I-PHYRE action syntax: a JSON array of {"time": seconds, "index": gray block}.
Light (no iphyre, no pymunk): MOCK and the model server rebuild it from JSON."""

from __future__ import annotations

import json
import math
from typing import Literal, Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict

from deepphy.envs.base import Action, ActionSpace, InvalidAction
from deepphy.envs.parsing import brief, is_number, last_json_array

MAX_TIME = 15.0  # seconds simulated per attempt (iphyre's max_time)
FPS = 60
MAX_CLICKS = 12  # more clicks than blocks is never useful; bounds the plan a model may send
# The reference implementation's random baseline: remove k distinct blocks, k uniform in
# [ceil(REFERENCE_SHARE * n), n] of n, each at a time uniform in [REFERENCE_T0, MAX_TIME] s
# rounded to 2 decimals (a time of exactly MAX_TIME is possible, and invalid here).
REFERENCE_SHARE = 0.9
REFERENCE_T0 = 0.1


class Click(BaseModel):
    model_config = ConfigDict(frozen=True)

    time: float
    index: int


class IPhyrePlan(Action):
    clicks: tuple[Click, ...]


class IPhyreSpace(ActionSpace):
    """Plans over `num_blocks` eliminable blocks, each removal at a time in [0, 15)."""

    kind: Literal["iphyre_plan"] = "iphyre_plan"
    num_blocks: int

    def parse(self, text: str) -> IPhyrePlan:
        raw = last_json_array(text)
        if raw is None:
            raise InvalidAction('no JSON array of {"time", "index"} objects found')
        if len(raw) > MAX_CLICKS:
            raise InvalidAction(f"at most {MAX_CLICKS} removals per plan, got {len(raw)}")
        clicks = []
        for item in raw:
            if not isinstance(item, dict):
                raise InvalidAction(f"plan entries must be objects with time and index, got {brief(item)}")
            keys = {str(k).strip().lower(): v for k, v in item.items()}
            if set(keys) != {"time", "index"}:
                raise InvalidAction(f"each entry needs exactly the keys time and index, got {brief(sorted(keys))}")
            t, i = keys["time"], keys["index"]
            if not is_number(t) or not math.isfinite(t):
                raise InvalidAction(f"time must be a number of seconds, got {brief(t)}")
            if not is_number(i) or not float(i).is_integer():
                raise InvalidAction(f"index must be an integer, got {brief(i)}")
            if not 0.0 <= t < MAX_TIME:
                raise InvalidAction(f"time {t} is outside [0, {MAX_TIME:g})")
            if not 0 <= int(i) < self.num_blocks:
                raise InvalidAction(f"index {int(i)} is not a gray block (0..{self.num_blocks - 1})")
            clicks.append(Click(time=round(float(t), 4), index=int(i)))
        return IPhyrePlan(clicks=tuple(sorted(clicks, key=lambda c: (c.time, c.index))))

    def reference_reply(self, rng: np.random.Generator, earlier: Sequence[str] = ()) -> str:
        n = self.num_blocks
        k = int(rng.integers(math.ceil(REFERENCE_SHARE * n), n + 1))
        blocks = rng.permutation(n)[:k]
        times = [round(float(rng.uniform(REFERENCE_T0, MAX_TIME)), 2) for _ in blocks]
        return json.dumps([{"time": t, "index": int(b)} for t, b in zip(times, blocks)])

    def sample(self, rng: np.random.Generator, exclude: Sequence[Action] = ()) -> IPhyrePlan:
        # mock-uniform: remove 1-3 distinct blocks at uniform times (as in I-PHYRE's own baselines).
        n = int(rng.integers(1, min(3, self.num_blocks) + 1))
        blocks = rng.choice(self.num_blocks, size=n, replace=False)
        times = np.round(rng.uniform(0.0, MAX_TIME, size=n), 1)
        times = np.minimum(times, MAX_TIME - 0.1)
        clicks = [Click(time=float(t), index=int(b)) for t, b in zip(times, blocks)]
        return IPhyrePlan(clicks=tuple(sorted(clicks, key=lambda c: (c.time, c.index))))

    def format(self, action: Action) -> str:
        assert isinstance(action, IPhyrePlan)
        return json.dumps([{"time": c.time, "index": c.index} for c in action.clicks])
