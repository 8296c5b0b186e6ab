"""Model configuration: a pydantic-validated YAML file of named model endpoints.

A models file holds no secrets: each entry names the ENVIRONMENT VARIABLE that holds its
key (`api_key_env`), and the key is read from the environment when a client is built.

Defaults live in exactly one place: the field defaults below, plus the provider's
`ProviderSpec` (deepphy/models/providers/) for what depends on the provider (base URL,
images per request, and where it declares them the key's variable and rate limits). An
entry in a models file states only what differs.

File shape::

    models:
      - name: gpt-4o                 # what `deepphy run --model` names
        provider: openai             # a registered provider (built in: openai, anthropic, gemini)
        model: gpt-4o-2024-08-06     # the provider's model id
        api_key_env: OPENAI_API_KEY  # the NAME of the variable, never the key
        rate_limits: {requests_per_min: 500, tokens_per_min: 300000, max_concurrent: 64}
        price: {input_per_mtok: 2.5, output_per_mtok: 10.0}
        retirement: {date: 2027-01-14, successor: gpt-6-luna, source: "..."}  # when its provider retires it

    groups:                          # names `--model` accepts for several entries at once
      paper-closed: [gpt-4o, ...]
      paper: [paper-open, paper-closed]   # a group may name groups
"""

from __future__ import annotations

import datetime
import os
import re
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from deepphy.loopback import is_loopback_url
from deepphy.yamlfile import read_yaml_model
from deepphy.models.limiter import RateLimits
from deepphy.models.providers import UnknownProvider, provider_spec
from deepphy.models.providers.spec import KEY_VARIABLE, ProviderSpec

DEFAULT_MODELS_FILE = Path(__file__).with_name("models.yaml")
MODELS_FILE_ENV = "DEEPPHY_MODELS_FILE"  # used when no file is given explicitly


TOTAL_SLACK_S = 60.0  # a request's default deadline: one whole try plus this (see Timeouts)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Timeouts(_Strict):
    """Deadlines of a request. Every try is bounded by its connection, its first byte (the
    status line), its body and its whole, and by what is left of `total_s`; a request never
    takes longer than `total_s`, retries and waits included.

    The defaults bound what one silent or dripping endpoint costs: a try that gets no status
    line ends at `request_s`, one whose body trickles in ends `body_s` after its status line
    (a provider sends the body it has already computed: seconds), and a request ends within
    `request_s` + 60 s, so an attempt re-queued after model errors (the scheduler's
    MODEL_REQUEUES) holds its episode for minutes, not the ~37 of 3 x request_s per request.
    The progress line names requests that wait long for an answer
    (deepphy.models.http.SLOW_ANSWER_S)."""

    connect_s: float = Field(10.0, gt=0, description="TCP (and TLS) connection")
    first_byte_s: float | None = Field(None, gt=0, description="from send to the response's status line (a "
                                       "provider computes the whole answer first); default request_s")
    body_s: float = Field(30.0, gt=0, description="from the status line to the end of the body (it is computed "
                          "by then: a body that trickles in is an endpoint in trouble)")
    request_s: float = Field(120.0, gt=0, description="one HTTP try, from send to the full response body")
    total_s: float | None = Field(None, gt=0, description="the whole request, every try and wait included; "
                                  "default request_s + 60 s (one whole try, and quick retries)")

    @property
    def deadline_s(self) -> float:
        return self.total_s if self.total_s is not None else self.request_s + TOTAL_SLACK_S


class RetryPolicy(_Strict):
    """Exponential backoff with jitter on 429, 408, 5xx, timeouts, connection errors and
    unusable 200s (malformed JSON, no choices). Bounded by `max_retries`."""

    max_retries: int = Field(5, ge=0)
    base_delay_s: float = Field(1.0, ge=0)
    max_delay_s: float = Field(60.0, ge=0)
    max_retry_after_s: float = Field(
        120.0, ge=0, description="the longest Retry-After (or Gemini RetryInfo delay) honoured; an endpoint that "
        "asks for a longer wait fails the request at once (a model error: the attempt is re-queued)")


class Pricing(_Strict):
    input_per_mtok: float = Field(0.0, ge=0, description="USD per 1M input tokens")
    output_per_mtok: float = Field(0.0, ge=0, description="USD per 1M output tokens")

    def cost(self, input_tokens: int, output_tokens: int) -> float:
        return (input_tokens * self.input_per_mtok + output_tokens * self.output_per_mtok) / 1e6


class Retirement(_Strict):
    """Its provider's end of a model: announced (deprecated) before `date`, retired from it on.
    Retired models stay in the models file (the paper's table names them) and still run, with a
    warning: some accounts and platforms keep an endpoint after the public date."""

    date: datetime.date = Field(description="the provider's shutdown (retirement) date")
    successor: str = Field(description="the model id the provider recommends instead")
    source: str = Field(description="where the date and successor were read, and when")

    def status(self, today: datetime.date) -> str:
        """`retired DATE` or `retires DATE`, as of `today`."""
        return f"{'retired' if self.date <= today else 'retires'} {self.date}"

    def notice(self, name: str, model: str, today: datetime.date) -> str:
        """One line for the user, as of `today`."""
        if self.date <= today:
            return (f"model {name} ({model}) was retired by its provider on {self.date} (successor: "
                    f"{self.successor}); unless this account or endpoint still serves it, its episodes will be "
                    "left unfinished")
        return (f"model {name} ({model}) is deprecated: its provider retires it on {self.date} "
                f"(successor: {self.successor})")


MODEL_NAME = r"^[A-Za-z0-9._:+-]+$"


class ModelConfig(_Strict):
    name: str = Field(pattern=MODEL_NAME)
    provider: str = Field(description="a registered provider's name (deepphy.models.providers)")
    model: str = Field(description="the provider's model id")
    base_url: str | None = Field(None, description="default: the provider's public endpoint")
    api_key_env: str | None = Field(None, pattern=KEY_VARIABLE, description="NAME of the env var with the key; "
                                    "default: the provider's (none for the built-in ones)")
    rate_limits: RateLimits = Field(RateLimits(), description="default: the provider's (none for the built-in ones)")
    timeouts: Timeouts = Timeouts()
    retry: RetryPolicy = RetryPolicy()
    price: Pricing = Pricing()
    max_images: int | None = Field(None, ge=0, description="images per request; default: the provider's "
                                   "(a vLLM server's --limit-mm-per-prompt)")
    max_context_tokens: int | None = Field(
        None, ge=1, description="the server's context length (vLLM --max-model-len, SGLang --context-length): the "
        "oldest images are replaced by text until the estimated input plus max_tokens fits")
    max_tokens: int | None = Field(None, ge=1, description="overrides the run's max_tokens (reasoning models need more)")
    send_temperature: bool = True  # some reasoning models reject temperature
    send_seed: bool = True  # OpenAI-compatible and Gemini take a seed; Anthropic has none
    max_tokens_param: Literal["max_tokens", "max_completion_tokens"] = "max_tokens"  # OpenAI only
    anthropic_version: str = "2023-06-01"
    extra_body: dict[str, Any] = Field(default_factory=dict, description="merged into every request body")
    send_context: bool = Field(
        False,
        description="send the RequestContext in an X-Deepphy-Context header, for the local MOCK "
        "server only (refused unless base_url is a loopback address)",
    )
    retirement: Retirement | None = Field(None, description="set once the provider has announced its retirement")

    @field_validator("provider")
    @classmethod
    def _registered(cls, name: str) -> str:
        try:
            provider_spec(name)
        except UnknownProvider as e:
            raise ValueError(str(e)) from None
        return name

    @model_validator(mode="before")
    @classmethod
    def _provider_defaults(cls, data: Any) -> Any:
        """The key's variable and the rate limits an entry leaves out are its provider's, where
        it declares them (`api_key_env: null` says "no key" whatever the provider's default)."""
        if not isinstance(data, dict) or not isinstance(data.get("provider"), str):
            return data  # the field validators say what is wrong
        try:
            spec = provider_spec(data["provider"])
        except UnknownProvider:
            return data  # said by `_registered`
        defaults = {"api_key_env": spec.api_key_env, "rate_limits": spec.rate_limits}
        return {**{k: v for k, v in defaults.items() if v != cls.model_fields[k].default}, **data}

    @model_validator(mode="after")
    def _has_an_endpoint(self) -> "ModelConfig":
        if self.base_url is None and self.spec.base_url is None:
            raise ValueError(f"{self.name}: provider {self.provider} has no public endpoint: set base_url")
        return self

    @model_validator(mode="after")
    def _context_only_to_loopback(self) -> "ModelConfig":
        if self.send_context and not is_loopback_url(self.resolved_base_url):
            raise ValueError(f"{self.name}: send_context is only allowed for a loopback base_url")
        return self

    @property
    def spec(self) -> ProviderSpec:
        """Its provider's declaration."""
        return provider_spec(self.provider)

    @property
    def resolved_base_url(self) -> str:
        return (self.base_url or self.spec.base_url or "").rstrip("/")

    @property
    def resolved_max_images(self) -> int:
        return self.max_images if self.max_images is not None else self.spec.max_images

    @property
    def limiter_key(self) -> str:
        return self.rate_limits.key or self.name

    def api_key(self) -> str | None:
        """The key from the environment (None when the entry needs none). Raises if unset."""
        if self.api_key_env is None:
            return None
        value = os.environ.get(self.api_key_env)
        if not value:
            raise MissingKey(f"model {self.name!r}: environment variable {self.api_key_env} is not set")
        return value


class MissingKey(RuntimeError):
    pass


class ModelsFile(_Strict):
    models: list[ModelConfig]
    groups: dict[str, list[str]] = Field(
        default_factory=dict, description="name -> entries (or other groups): what `--model NAME` runs")

    @model_validator(mode="after")
    def _unique(self) -> "ModelsFile":
        names = [m.name for m in self.models]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"duplicate model names: {', '.join(dup)}")
        if "mock" in [*names, *self.groups]:
            raise ValueError("'mock' is built in and cannot be redefined")
        return self

    @model_validator(mode="after")
    def _groups_name_entries(self) -> "ModelsFile":
        entries = {m.name for m in self.models}
        for group, members in self.groups.items():
            if not re.match(MODEL_NAME, group):
                raise ValueError(f"group name {group[:40]!r} may hold only letters, digits and . _ : + -")
            if group in entries:
                raise ValueError(f"group {group} has the name of a model entry")
            if not members:
                raise ValueError(f"group {group} is empty")
            unknown = [m for m in members if m not in entries and m not in self.groups]
            if unknown:
                raise ValueError(f"group {group} names {unknown[0]!r}, neither a model entry nor a group")
        for group in self.groups:
            self.members(group)  # a cycle: a clear error here, not at run time
        return self

    def members(self, group: str, _seen: tuple[str, ...] = ()) -> list[str]:
        """The entries of `group`, its groups expanded, in order, each once."""
        if group in _seen:
            raise ValueError(f"group {group} contains itself (via {' -> '.join(_seen)})")
        out: list[str] = []
        for name in self.groups[group]:
            out += self.members(name, (*_seen, group)) if name in self.groups else [name]
        return list(dict.fromkeys(out))


def models_file_path(models_file: str | Path | None = None) -> Path:
    if models_file is not None:
        return Path(models_file)
    return Path(os.environ.get(MODELS_FILE_ENV) or DEFAULT_MODELS_FILE)


class ModelsFileError(ValueError):
    """A models file that cannot be read or is invalid. The message is for the user."""


def load_models(models_file: str | Path | None = None) -> dict[str, ModelConfig]:
    """name -> config, from `models_file` (default: $DEEPPHY_MODELS_FILE, else the shipped file)."""
    return {m.name: m for m in load_models_file(models_file).models}


def load_groups(models_file: str | Path | None = None) -> dict[str, list[str]]:
    """group name -> the entries it stands for (its groups expanded), from `models_file`."""
    parsed = load_models_file(models_file)
    return {group: parsed.members(group) for group in parsed.groups}


def load_models_file(models_file: str | Path | None = None) -> ModelsFile:
    """The whole models file, validated (default: $DEEPPHY_MODELS_FILE, else the shipped file)."""
    path = models_file_path(models_file)
    return read_yaml_model(path, ModelsFile, ModelsFileError, "models file")
