"""Model clients. `make_client(name, models_file)` builds the client a run config names.

"mock" is built in; every other name comes from a models file (deepphy/models/config.py):
the shipped deepphy/models/models.yaml unless `models_file` (or $DEEPPHY_MODELS_FILE)
names another.
"""

from pathlib import Path

from deepphy.models.base import ModelClient, ModelError, ModelRequest, ModelResponse, RequestContext, Usage
from deepphy.models.config import MissingKey, ModelConfig, ModelsFileError, load_models


class UnknownModel(KeyError):
    def __init__(self, name: str, available: list[str] | None = None) -> None:
        super().__init__(name)
        self.available = ["mock", *(available or [])]

    def __str__(self) -> str:
        return f"unknown model {self.args[0]!r}; available: {', '.join(self.available)}"


def model_config(name: str, models_file: str | Path | None = None) -> ModelConfig | None:
    """The config of a named model (None for the built-in mock)."""
    if name == "mock":
        return None
    models = load_models(models_file)
    if name not in models:
        raise UnknownModel(name, sorted(models))
    return models[name]


def client_from_config(config: ModelConfig, limiter="auto") -> ModelClient:
    """The client for a config; reads its key from the environment (MissingKey if unset)."""
    from deepphy.models.providers import CLIENTS

    return CLIENTS[config.provider.value](config, limiter=limiter)


def make_client(name: str, models_file: str | Path | None = None) -> ModelClient:
    if name == "mock":
        from deepphy.models.mock import MockModel

        return MockModel()
    return client_from_config(model_config(name, models_file))


__all__ = [
    "MissingKey", "ModelClient", "ModelConfig", "ModelsFileError", "ModelError", "ModelRequest", "ModelResponse", "RequestContext",
    "Usage", "UnknownModel", "client_from_config", "load_models", "make_client", "model_config",
]
