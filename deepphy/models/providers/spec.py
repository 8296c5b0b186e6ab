"""`ProviderSpec`: everything the rest of deepphy needs to know about a model provider.

A provider is a wire format (how a request is written and its answer read: an
`HTTPModelClient` subclass) with its defaults. Each built-in provider is one module,
`deepphy/models/providers/<name>.py`, that defines `SPEC = ProviderSpec(...)`; the registry
(`deepphy.models.providers`) finds them. The models file's validation, the client factory
and the dry-run estimate read the spec and never name a provider. A spec names its client
class by import path, loaded only when a client is built: the clients import aiohttp, which
validating a models file does not need.
"""

from __future__ import annotations

import importlib
from typing import Callable

from pydantic import BaseModel, ConfigDict, Field

from deepphy.models.base import ModelClient
from deepphy.models.limiter import RateLimits

KEY_VARIABLE = r"^[A-Za-z_][A-Za-z0-9_]*$"  # an environment variable's name


class ProviderSpec(BaseModel):
    model_config = ConfigDict(frozen=True)

    name: str = Field(pattern=r"^[a-z][a-z0-9_-]*$", description="what a models file's `provider:` names")
    title: str = Field(description="its API, in words (\"OpenAI Chat Completions\")")
    client: str = Field(pattern=r"^[\w.]+:\w+$", description="\"module:Class\" of its HTTPModelClient subclass "
                        "(called with the entry's ModelConfig and a limiter)")
    base_url: str | None = Field(description="its public endpoint, API version included (the client appends its "
                                 "path); None: every entry names its own")
    max_images: int = Field(ge=0, description="images per request an entry gets unless it says otherwise")
    image_tokens: Callable[[int, int], int] = Field(
        description="input tokens of a width x height image, by the provider's published rule (the dry run's "
        "estimate of a request's tokens and cost)")
    api_key_env: str | None = Field(None, pattern=KEY_VARIABLE, description="the variable an entry reads its key "
                                    "from when it names none; None: such an entry sends no key (a self-hosted server)")
    rate_limits: RateLimits = Field(RateLimits(), description="limits an entry gets when it states none "
                                    "(default none: each entry states its own account's)")

    def load_client(self) -> type[ModelClient]:
        """The client class (imports the HTTP client: aiohttp)."""
        module, _, attr = self.client.partition(":")
        return getattr(importlib.import_module(module), attr)
