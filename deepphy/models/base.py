"""The model interface: prompt messages in, text plus token usage out.

Every model, the MOCK baselines included (deepphy/baselines.py), is reached through `ModelClient.complete`, so the parsing
path is exercised the same way for a random baseline and for a real VLM.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

from pydantic import BaseModel, Field

from deepphy.chat import ImagePart, Message, PromptFormat, Usage


class RequestContext(BaseModel):
    """What deepphy knows about a request. Real providers never see it; MOCK answers from it."""

    env: str
    task_id: str
    run: int
    attempt: int
    step: int
    seed: int
    format: PromptFormat
    action_space: dict[str, Any]  # ActionSpace JSON (see ActionSpace.from_json)
    env_options: dict[str, Any] = Field(default_factory=dict)  # the run's environment options
    tried: list[str] = Field(default_factory=list)  # actions of failed attempts of this task
    earlier: list[str] = Field(default_factory=list)  # actions of this attempt's earlier decisions


class ModelRequest(BaseModel):
    messages: list[Message]
    temperature: float = 0.1
    max_tokens: int = 1024
    context: RequestContext

    def with_images_loaded(self) -> "ModelRequest":
        """This request with every image carrying its bytes, for a reader on another file system."""
        messages = [
            m.model_copy(update={"content": [
                p.model_copy(update={"image": p.image.loaded()}) if isinstance(p, ImagePart) else p for p in m.content
            ]})
            for m in self.messages
        ]
        return self.model_copy(update={"messages": messages})


class ModelResponse(BaseModel):
    text: str
    usage: Usage = Field(default_factory=Usage)
    retries: int = 0  # transport retries it took (429, 5xx, timeouts)
    images_dropped: int = 0  # oldest images left out to meet the provider's per-request image limit
    # The agent's own time for this answer (a person's, kept across a resume); None: the call's duration.
    seconds: float | None = None


class ModelError(RuntimeError):
    """The provider could not answer (after retries). Not a wrong answer: the attempt is re-queued.

    `retries` counts the transport retries spent before giving up and `kind` names the last
    failure (e.g. "http_429", "http_500", "timeout", "connection", "malformed", "empty",
    "http_401"), so the scheduler can count them. The message never carries a key.
    """

    def __init__(self, message: str = "", *, retries: int = 0, kind: str = "") -> None:
        super().__init__(message)
        self.retries = retries
        self.kind = kind

    def __reduce__(self):  # keep retries/kind when the error crosses Ray (pickled)
        return (_rebuild_model_error, (type(self), str(self), self.retries, self.kind))


class AccessDenied(ModelError):
    """The endpoint refused the key (authentication or permission): no retry, no re-queue;
    the run stops. The message names the endpoint and the key's variable, never the key."""


class RequestRejected(ModelError):
    """The endpoint rejected the request itself (a 4xx other than 401/403/408/409/429: e.g.
    vLLM's 400 for more images than it takes per prompt, or a prompt longer than the model's
    context). The same request would be rejected again: no retry, no re-queue; the run
    stops with the endpoint's own words and what to change."""


def _rebuild_model_error(cls: type, message: str, retries: int, kind: str) -> "ModelError":
    return cls(message, retries=retries, kind=kind)


class ModelClient(ABC):
    name: str
    # Computes its reply in this process without waiting on anything (the random baselines):
    # the scheduler sets no deadline on it.
    answers_at_once: ClassVar[bool] = False

    @abstractmethod
    async def complete(self, request: ModelRequest) -> ModelResponse: ...

    async def close(self) -> None:
        """Release connections."""

    async def activity(self) -> dict[str, int]:
        """Requests waiting now: for the rate limit (`rate_limited`), before a retry (`retrying`)."""
        return {"rate_limited": 0, "retrying": 0}
