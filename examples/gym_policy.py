"""Any Gymnasium policy as a deepphy agent: a callable from `deepphy.gym`'s observation to
an action, e.g. one trained on `gymnasium.make("deepphy/iphyre-v0")`, evaluated by
`deepphy run` under the benchmark's protocol (its attempts, its history, its records).

    deepphy run --env iphyre --agent examples.gym_policy:GymPolicyAgent \\
        --agent-arg policy=examples.gym_policy:iphyre_brightness_policy

- `policy`: `package.module:name` of a callable `observation -> action`, where the
  observation is `DeepPhyEnv`'s (`{"images": uint8 (n, H, W, 3), "text": str}`, the
  decision's, as `deepphy.gym.observation_of` reads it from the request) and the action is
  text in the environment's syntax (what `DeepPhyEnv.step` takes) or a deepphy `Action`.
- `policy_args` (a JSON object): then `name` is a loader, called once with them where the
  agent runs (load a checkpoint there), which returns the callable.
- `num_gpus`: the GPUs the agent's actor asks of Ray (a policy on a GPU).
- `concurrency`: policy calls at once, each in a thread (default 1: a policy need not be
  thread-safe; the episodes' other requests wait their turn).

A Gymnasium policy sees the current observation only: it keeps no memory of the task's
failed attempts, so a deterministic one repeats its action on every attempt.
"""

from __future__ import annotations

import asyncio
import importlib
import json
from typing import Any, Callable

import numpy as np

from deepphy.agent import Agent, Endpoints
from deepphy.envs import Action
from deepphy.gym import observation_of
from deepphy.models import ModelRequest


class GymPolicyAgent(Agent):
    def __init__(self, policy: str, policy_args: dict[str, Any] | None = None, num_gpus: float = 0,
                 concurrency: int = 1) -> None:
        if ":" not in policy:
            raise ValueError(f"policy {policy!r}: expected package.module:name")
        self.policy_entry, self.policy_args = policy, policy_args
        self.resources = {"num_gpus": num_gpus} if num_gpus else {}
        self.concurrency = concurrency

    async def setup(self, endpoints: Endpoints) -> None:
        module, _, name = self.policy_entry.partition(":")
        target = getattr(importlib.import_module(module), name)
        self.policy: Callable[[dict[str, Any]], str | Action] = (
            await asyncio.to_thread(target, **self.policy_args) if self.policy_args is not None else target)
        self.turns = asyncio.Semaphore(self.concurrency)

    async def act(self, request: ModelRequest, state: dict[str, Any]) -> str | Action:
        observation = observation_of(request)
        async with self.turns:
            return await asyncio.to_thread(self.policy, observation)


def iphyre_brightness_policy(observation: dict[str, Any]) -> str:
    """A stand-in for a trained I-PHYRE policy, a function of the observation's pixels only:
    remove block 0 at a time set by the scene's mean brightness."""
    brightness = float(np.asarray(observation["images"][0], dtype=np.float64).mean()) / 255.0
    return json.dumps([{"time": round(14.9 * brightness, 2), "index": 0}])
