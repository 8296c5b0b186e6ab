"""Model worker: an I/O actor (no CPU reserved) that keeps many model requests in flight."""

from __future__ import annotations

import ray

from deepphy.models import ModelRequest, ModelResponse, make_client


class ModelWorkerImpl:
    def __init__(self, model: str, **client_options) -> None:
        self.client = make_client(model, **client_options)

    async def complete(self, request: ModelRequest) -> ModelResponse:
        return await self.client.complete(request)

    async def close(self) -> None:
        await self.client.close()


def make_model_worker(model: str, *, name: str | None = None, max_concurrency: int = 1000, **client_options):
    # Stateless: a crashed worker is restarted and its in-flight calls retried by Ray.
    actor = ray.remote(num_cpus=0, max_restarts=5, max_task_retries=3, max_concurrency=max_concurrency)(ModelWorkerImpl)
    return actor.options(name=name).remote(model, **client_options)
