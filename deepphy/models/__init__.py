"""Model endpoints over HTTP: configs (models files), providers (deepphy.models.providers),
their clients, rate limiting.

Knows nothing of environments, Ray or actors: the model worker injects the cluster's
shared limiter. Agents by name (baselines included) are made in deepphy/agents.py.
"""

from pathlib import Path

from deepphy.chat import Usage
from deepphy.models.base import (
    AccessDenied, ModelClient, ModelError, ModelRequest, ModelResponse, RequestContext, RequestRejected,
)
from deepphy.models.config import MissingKey, ModelConfig, ModelsFileError, load_models
from deepphy.models.limiter import Limiter


class UnknownModel(KeyError):
    def __init__(self, name: str, available: list[str] | None = None) -> None:
        super().__init__(name)
        self.available = list(available or [])

    def __str__(self) -> str:
        return f"unknown model {self.args[0]!r}; available: {', '.join(self.available)}"


def model_config(name: str, models_file: str | Path | None = None) -> ModelConfig:
    """The config of a named endpoint."""
    models = load_models(models_file)
    if name not in models:
        raise UnknownModel(name, sorted(models))
    return models[name]


def client_from_config(config: ModelConfig, limiter: Limiter | None = None) -> ModelClient:
    """The client for a config, of its provider's class; reads its key from the environment
    (MissingKey if unset)."""
    return config.spec.load_client()(config, limiter=limiter)


__all__ = [
    "AccessDenied", "MissingKey", "ModelClient", "ModelConfig", "ModelsFileError", "ModelError", "ModelRequest", "ModelResponse",
    "RequestContext", "RequestRejected", "Usage", "UnknownModel", "client_from_config", "load_models", "model_config",
]
