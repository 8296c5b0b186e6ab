"""Model clients. `make_client(name)` builds the client a run config names."""

from deepphy.models.base import ModelClient, ModelError, ModelRequest, ModelResponse, RequestContext, Usage


class UnknownModel(KeyError):
    def __str__(self) -> str:
        return f"unknown model {self.args[0]!r}; available: mock"


def make_client(name: str) -> ModelClient:
    if name == "mock":
        from deepphy.models.mock import MockModel

        return MockModel()
    raise UnknownModel(name)


__all__ = ["ModelClient", "ModelError", "ModelRequest", "ModelResponse", "RequestContext", "Usage", "UnknownModel", "make_client"]
