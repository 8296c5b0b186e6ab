"""Model worker: an I/O actor (no CPU reserved) that keeps many model requests in flight."""

from __future__ import annotations

from pathlib import Path

from deepphy.actors import remote_class
from deepphy.envs import EnvSpec, register
from deepphy.models import ModelRequest, ModelResponse


class ModelWorkerImpl:
    def __init__(self, model: str, spec: EnvSpec, models_file: str | None = None) -> None:
        from deepphy.actors.rate_limiter import RayLimiter
        from deepphy.agents import endpoint_config, make_agent

        register(spec)  # the run's environment, also when it is not one of deepphy's own (MOCK samples its space)

        config = endpoint_config(model, models_file)
        # Every worker of the cluster consults the endpoint's one shared limiter actor.
        limiter = RayLimiter(config) if config is not None and config.rate_limits.enabled else None
        self.client = make_agent(model, models_file, limiter=limiter)

    async def complete(self, request: ModelRequest) -> ModelResponse:
        return await self.client.complete(request)

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


def make_model_worker(model: str, spec: EnvSpec, *, name: str | None = None, models_file: str | None = None,
                      max_concurrency: int = 1000):
    """`max_concurrency`: requests handled at once (a run passes its episodes in flight)."""
    from deepphy.actors.placement import beside_driver

    # Stateless: a crashed worker is restarted and its in-flight calls retried by Ray.
    return ModelWorker.options(
        num_cpus=0, max_restarts=5, max_task_retries=3, max_concurrency=max_concurrency, name=name,
        scheduling_strategy=beside_driver(),
    ).remote(model, spec, models_file)


ModelWorker = remote_class(ModelWorkerImpl)  # one class per process (see env_worker.EnvWorker)
