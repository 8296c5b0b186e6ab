"""Environment worker: one CPU actor hosting many live environment instances.

Instances are keyed by episode id and live for one attempt. Step requests that arrive
while the worker is busy are stepped together through `Environment.step_many`, so an
environment that can batch (Kinetix: vmap) does; the others step one after another.
A worker that dies is restarted by Ray with no instances; a call for an instance it no
longer holds raises `LostEpisode`, and the scheduler re-runs that attempt.
"""

from __future__ import annotations

import asyncio
from typing import Any

import ray

from deepphy.envs import Action, Environment, Observation, StepResult, Task, get_env_class


class LostEpisode(KeyError):
    """The worker does not hold this episode (it was restarted). Re-run the attempt."""


class EnvWorkerImpl:
    def __init__(self, env: str, options: dict[str, Any]) -> None:
        self.cls: type[Environment] = get_env_class(env)
        self.options = self.cls.Options(**options)
        self.live: dict[str, Environment] = {}
        self.idle: list[Environment] = []  # instances are reused: simulators are costly to build
        self.pending: list[tuple[str, Action, asyncio.Future]] = []
        self.draining = False

    async def reset(self, episode: str, task: Task) -> Observation:
        env = self.idle.pop() if self.idle else self.cls(self.options)
        self.live[episode] = env
        return env.reset(task)

    async def step(self, episode: str, action: Action) -> StepResult:
        if episode not in self.live:
            raise LostEpisode(episode)
        future = asyncio.get_running_loop().create_future()
        self.pending.append((episode, action, future))
        if not self.draining:
            self.draining = True
            asyncio.get_running_loop().call_soon(self._drain)
        return await future

    def _drain(self) -> None:
        batch, self.pending, self.draining = self.pending, [], False
        try:
            results = self.cls.step_many([self.live[e] for e, _, _ in batch], [a for _, a, _ in batch])
        except Exception as error:  # noqa: BLE001 - one bad batch must not hang its callers
            for _, _, f in batch:
                f.set_exception(error)
            return
        for (_, _, f), result in zip(batch, results):
            f.set_result(result)

    async def release(self, episode: str) -> None:
        env = self.live.pop(episode, None)
        if env is not None:
            self.idle.append(env)

    async def ping(self) -> int:
        import os

        return os.getpid()


def make_env_worker(
    env: str, options: dict[str, Any], *, name: str | None = None, resource: str | None = None, max_restarts: int = 5
):
    """An EnvWorker actor handle: one logical CPU, restarted if its process dies.

    `resource` places it only on nodes that declare that custom resource (e.g. `physics`);
    a token amount is asked so CPUs, not the resource, bound the number of workers."""
    actor = ray.remote(num_cpus=1, max_restarts=max_restarts, max_concurrency=1000)(EnvWorkerImpl)
    resources = {resource: 0.001} if resource else None
    return actor.options(name=name, resources=resources).remote(env, options)
