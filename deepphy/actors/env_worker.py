"""Environment worker: one CPU actor hosting many live environment instances.

Instances are keyed by episode id and live for one attempt: a step that ends the attempt
releases its instance, and the first step of an attempt may carry its task, so the
attempt's reset happens in the same call (the driver already holds the initial
observation: reset is deterministic). Step requests that arrive
while the worker is busy are stepped together through `Environment.step_many`, so an
environment that can batch (Kinetix) does; the others step one after another. A batch
that raises is stepped again one instance at a time, so an environment bug fails only
the episode that hit it. The driver sends the decisions of many episodes as one call
(`step_batch`: one Ray task, not one per decision). A worker that dies is restarted by
Ray with no instances; a step of an instance it no longer holds raises `LostEpisode`,
and the scheduler re-runs that attempt.
"""

from __future__ import annotations

import asyncio
import os
import pickle
import traceback
from typing import Sequence

from deepphy.actors import remote_class
from deepphy.allocator import keep_freed_memory
from deepphy.envs import Action, EnvOptions, EnvSpec, Environment, Observation, StepResult, Task


class LostEpisode(KeyError):
    """The worker does not hold this episode (it was restarted). Re-run the attempt."""


class EnvWorkerImpl:
    def __init__(self, spec: EnvSpec, options: EnvOptions, log_path: str | None = None) -> None:
        _redirect_output(log_path)  # library noise (XLA, numba, deprecations) goes to the run's log
        keep_freed_memory()  # attempts reuse their arrays' pages instead of faulting them in (deepphy/allocator.py)
        self.cls: type[Environment] = spec.load()
        self.batches_steps = self.cls.step_many.__func__ is not Environment.step_many.__func__  # type: ignore[attr-defined]
        self.options = options  # validated by the driver's plan (deepphy.plan)
        self.live: dict[str, Environment] = {}
        self.idle: list[Environment] = []  # instances are reused: simulators are costly to build
        self.pending: list[tuple[str, Action, asyncio.Future]] = []
        self.draining = False
        self.batches = self.steps = self.max_batch = self.calls = 0

    async def warm_up(self, tasks: Sequence[Task]) -> None:
        self.cls.warm_up(self.options, tasks)

    async def reset(self, episode: str, task: Task) -> Observation:
        env = self.idle.pop() if self.idle else self.cls(self.options)
        self.live[episode] = env
        return env.reset(task)

    async def step(self, episode: str, action: Action, reset: Task | None = None) -> StepResult:
        """One decision. `reset`: the attempt's task, to reset first (its first decision)."""
        if reset is not None:
            await self.reset(episode, reset)
        if episode not in self.live:
            raise LostEpisode(episode)
        future = asyncio.get_running_loop().create_future()
        self.pending.append((episode, action, future))
        if not self.draining:
            self.draining = True
            asyncio.get_running_loop().call_soon(self._drain)
        result = await future
        if result.done:
            await self.release(episode)
        return result

    async def step_batch(self, requests: Sequence[tuple[str, Action, Task | None]]) -> list[StepResult | Exception]:
        """`step` for several episodes in one call; each gets its result or its own error
        (one episode's failure, `LostEpisode` included, leaves the others' results whole)."""
        self.calls += 1
        outcomes = await asyncio.gather(*(self.step(*request) for request in requests), return_exceptions=True)
        return [_sendable(o) if isinstance(o, BaseException) else o for o in outcomes]

    def _drain(self) -> None:
        if self.batches_steps:
            batch, self.pending, self.draining = self.pending, [], False
        else:  # one now, the rest on the loop's next turns (after this result has gone out)
            batch, self.pending = self.pending[:1], self.pending[1:]
            if self.pending:
                asyncio.get_running_loop().call_soon(self._drain)
            else:
                self.draining = False
        envs = [self.live[e] for e, _, _ in batch]
        actions = [a for _, a, _ in batch]
        self.batches += 1
        self.steps += len(batch)
        self.max_batch = max(self.max_batch, len(batch))
        try:
            results = self.cls.step_many(envs, actions)
        except Exception:  # noqa: BLE001 - find the instance that fails; the others go on
            for env, action, (_, _, future) in zip(envs, actions, batch):
                try:
                    future.set_result(self.cls.step_many([env], [action])[0])
                except Exception as error:  # noqa: BLE001
                    future.set_exception(error)
            return
        for (_, _, future), result in zip(batch, results):
            future.set_result(result)

    async def release(self, episode: str) -> None:
        env = self.live.pop(episode, None)
        if env is not None:
            self.idle.append(env)

    async def stats(self) -> dict[str, int]:
        """Steps, step_many calls, the largest batch and the step_batch calls so far (batching
        is observable here, never in records)."""
        return {"steps": self.steps, "batches": self.batches, "max_batch": self.max_batch, "calls": self.calls,
                "pid": os.getpid()}


def _sendable(error: BaseException) -> Exception:
    """`error` ready to travel back in a list (not as Ray's task error): its traceback in
    this worker kept as a note (the driver logs it), or a RuntimeError naming it if it
    cannot be pickled."""
    where = "".join(traceback.format_exception(error))
    if isinstance(error, Exception):
        try:
            error.add_note(f"in the environment worker:\n{where}")
            pickle.loads(pickle.dumps(error))
            return error
        except Exception:  # noqa: BLE001 - an exception type that cannot cross processes
            pass
    return RuntimeError(f"{type(error).__name__}: {error}\nin the environment worker:\n{where}")


def _redirect_output(log_path: str | None) -> None:
    """Send this process's stdout and stderr (file descriptors, so C libraries' output too)
    to `log_path`, if that file can be opened here (a remote node may not see it)."""
    if not log_path:
        return
    try:
        fd = os.open(log_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    except OSError:
        return
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)


def make_env_worker(spec: EnvSpec, options: EnvOptions, *, name: str | None = None,
                    resource: str | None = None, log_path: str | None = None, max_restarts: int = 5,
                    max_concurrency: int = 1000, num_cpus: float = 1.0):
    """An EnvWorker actor handle: one logical CPU (`num_cpus`: a suite's settings running
    at once share the CPUs), restarted if its process (or its node)
    dies, spread over the cluster's nodes.

    `resource` places it only on nodes that declare that custom resource (e.g. `physics`);
    a token amount is asked so CPUs, not the resource, bound the number of workers."""
    resources = {resource: 0.001} if resource else None
    return EnvWorker.options(
        num_cpus=num_cpus, max_restarts=max_restarts, max_concurrency=max_concurrency, name=name, resources=resources,
        scheduling_strategy="SPREAD",
    ).remote(spec, options, log_path)


# One actor class per process, options per run: a class made per run is exported to the
# cluster and remembered by this driver each time (memory that grew with every run). Made
# when first used: a run in this process (`deepphy run --in-process`) never imports Ray.
EnvWorker = remote_class(EnvWorkerImpl)
