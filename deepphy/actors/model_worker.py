"""Model worker: an I/O actor (no CPU reserved) that keeps many model requests in flight."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from deepphy.actors import remote_class
from deepphy.agent import AgentClient, Episode, declared
from deepphy.agents import endpoint_config, make_agent
from deepphy.config import AgentSpec
from deepphy.envs import EnvSpec, register
from deepphy.models import ModelRequest, ModelResponse
from deepphy.models.providers import ProviderSpec, providers, register_provider


class ModelWorkerImpl:
    def __init__(self, model: str, spec: EnvSpec | Sequence[EnvSpec], models_file: str | None = None,
                 agent: AgentSpec | None = None, provider_specs: Sequence[ProviderSpec] = ()) -> None:
        from deepphy.actors.rate_limiter import RayLimiter  # imports Ray: only a worker on Ray makes one

        # The run's environments, also those not of deepphy's own (MOCK samples their spaces; an
        # agent's structured action is written in their syntax). A suite's agent serves several.
        for one in [spec] if isinstance(spec, EnvSpec) else spec:
            register(one)
        # The driver's providers, also those not of deepphy's own: the models file is read here.
        for provider in provider_specs:
            register_provider(provider)

        if agent is not None:
            # Every worker of the cluster consults each endpoint's one shared limiter actor.
            self.client = AgentClient(agent, models_file, limiter_for=lambda c: RayLimiter(c) if c.rate_limits.enabled
                                      else None)
            return
        config = endpoint_config(model, models_file)
        limiter = RayLimiter(config) if config is not None and config.rate_limits.enabled else None
        self.client = make_agent(model, models_file, limiter=limiter)

    async def complete(self, request: ModelRequest) -> ModelResponse:
        return await self.client.complete(request)

    async def end_episode(self, episode: tuple) -> None:
        """An agent's episode ended: its state is released (`deepphy.agent.Episode`)."""
        self.client.end_episode(Episode(*episode))

    async def activity(self) -> dict[str, int]:
        """Requests waiting now for the rate limit and before a retry (for the progress line)."""
        return await self.client.activity()

    async def close(self) -> None:
        """Close the client's connections (before the actor is killed at the end of a run)."""
        await self.client.close()

    def read_file(self, path: str) -> bytes | None:
        """`path`'s bytes on this worker's file system, None if it has no such file: the
        driver asks once whether the worker can read the run directory's key frames."""
        try:
            return Path(path).read_bytes()
        except OSError:
            return None


def make_model_worker(model: str, spec: EnvSpec | Sequence[EnvSpec], *, name: str | None = None,
                      models_file: str | None = None, max_concurrency: int = 1000, agent: AgentSpec | None = None):
    """`max_concurrency`: requests handled at once (a run passes its episodes in flight).
    An agent that declares Ray resources (a GPU) gets them, wherever the cluster has them;
    any other worker is an I/O actor beside the driver that reserves nothing."""
    from deepphy.actors.placement import beside_driver  # imports Ray: a run in this process never comes here

    options = {"num_cpus": 0, "scheduling_strategy": beside_driver()}
    if agent is not None:
        resources = declared(agent).resources
        if resources.requested:
            options = resources.actor_options()
    # Stateless (an agent's episode state is a cache): a crashed worker is restarted and its
    # in-flight calls retried by Ray.
    return ModelWorker.options(
        max_restarts=5, max_task_retries=3, max_concurrency=max_concurrency, name=name, **options,
    ).remote(model, spec, models_file, agent, list(providers().values()))


ModelWorker = remote_class(ModelWorkerImpl)  # one class per process (see env_worker.EnvWorker)
