"""Our wire formats against the providers' official SDKs (openai, anthropic, google-genai;
test-only dependencies): someone else's reading of the same three APIs.

1. Each SDK talks to the local model server and parses its replies into its own types,
   and its errors (429 with the retry hint, 500, 400, a wrong key) into its own error
   classes, in the provider's documented error shape; the SDKs' own retries honour our
   Retry-After.
2. Every request body our clients send validates against the SDK's request types,
   strictly (an unknown key anywhere is an error), and equals what the SDK itself sends
   for the same request.
3. The headers agree: auth header and scheme, anthropic-version, content-type.

The SDKs only ever see the server on 127.0.0.1 and a dummy key.
"""

from __future__ import annotations

import asyncio
import base64
import collections.abc
import functools
import json
import os
import types
import typing

import anthropic
import openai
import pydantic
import pytest
import typing_extensions as te
from anthropic.types.message_create_params import MessageCreateParamsNonStreaming
from google import genai
from google.genai import errors as genai_errors
from google.genai import types as gtypes
from openai.types.chat.completion_create_params import CompletionCreateParamsNonStreaming
from pydantic import ConfigDict, TypeAdapter

from deepphy.models import AccessDenied, client_from_config
from deepphy.agents import MockModel
from deepphy.models.wire import ANTHROPIC_NO_SAMPLING_FROM, CONTEXT_HEADER, encode_context, parse_retry_after, text_tokens
from deepphy.prompts import Message, PromptFormat
from deepphy.chat import ImagePart, TextPart
from deepphy.testing.model_server import (
    FAULT_KINDS, AnthropicFormat, ApiError, GeminiFormat, OpenAIFormat, ServerConfig, ServerThread,
)
from models_support import iphyre_request, local_config

KEY_ENV = "DEEPPHY_SDK_TEST_KEY"
KEY = "sk-deepphy-sdk-FAKE-0123456789"
RETRY_AFTER_S = 0.6  # longer than the Stainless SDKs' own first backoff (0.5 s at most)
PROVIDERS = ["openai", "anthropic", "gemini"]


@pytest.fixture(scope="module")
def server():
    with ServerThread(ServerConfig(record_bodies=8)) as s:
        assert s.host == "127.0.0.1"
        yield s


@pytest.fixture(autouse=True)
def _clean(server, monkeypatch):
    monkeypatch.setenv(KEY_ENV, KEY)
    server.configure(require_key_env=None, latency_s=0.0,
                     faults={"rate": 0.0, "first_tries": 0, "kinds": list(FAULT_KINDS), "retry_after_s": RETRY_AFTER_S})
    server.reset()


# --- strict validation against the SDKs' request types ----------------------------------------


def _strict_type(tp: typing.Any, memo: dict) -> typing.Any:
    """`tp` with every TypedDict rebuilt to forbid unknown keys (pydantic ignores them by
    default), Iterable/Sequence as list (pydantic validates an Iterable lazily, so a
    bad item would pass), the SDK's wire aliases as keys, and the Python-side-only
    file inputs (IO, PathLike; the SDK base64-encodes them) left out."""
    origin, args = te.get_origin(tp), te.get_args(tp)
    if te.is_typeddict(tp):
        if tp in memo:
            if memo[tp] is None:
                raise TypeError(f"recursive TypedDict {tp.__name__} is not supported")
            return memo[tp]
        memo[tp] = None
        fields = {}
        for name, hint in te.get_type_hints(tp, include_extras=True).items():
            key = name
            while te.get_origin(hint) in (te.Required, te.NotRequired, te.Annotated):
                key = next((m.alias for m in getattr(hint, "__metadata__", ()) if getattr(m, "alias", None)), key)
                hint = te.get_args(hint)[0]
            inner = _strict_type(hint, memo)
            fields[key] = te.Required[inner] if name in tp.__required_keys__ else te.NotRequired[inner]
        strict = te.TypedDict(tp.__name__, fields, total=False)
        strict.__pydantic_config__ = ConfigDict(extra="forbid")
        memo[tp] = strict
        return strict
    if origin is te.Annotated:
        return _strict_type(args[0], memo)
    if origin in (typing.Union, types.UnionType):
        kept = [a for a in args if (te.get_origin(a) or a) not in (typing.IO, os.PathLike)]
        return typing.Union[tuple(_strict_type(a, memo) for a in kept)]
    sequence = origin in (collections.abc.Iterable, collections.abc.Sequence, list)
    if sequence or getattr(origin, "__name__", "") == "SequenceNotStr":
        return list[_strict_type(args[0], memo)]
    if origin in (dict, collections.abc.Mapping):
        return dict[args[0], _strict_type(args[1], memo)]
    return tp


@functools.cache
def strict_adapter(tp: typing.Any) -> TypeAdapter:
    return TypeAdapter(_strict_type(tp, {}))


def unknown_fields(model: typing.Any, path: str = "$") -> list[str]:
    """Fields a (Stainless, extra="allow") SDK model kept without declaring them."""
    out: list[str] = []
    if isinstance(model, pydantic.BaseModel):
        out += [f"{path}.{k}" for k in (model.__pydantic_extra__ or {})]
        for name in type(model).model_fields:
            out += unknown_fields(getattr(model, name), f"{path}.{name}")
    elif isinstance(model, (list, tuple)):
        for i, v in enumerate(model):
            out += unknown_fields(v, f"{path}[{i}]")
    return out


def _camel(key: str) -> str:
    head, *rest = key.split("_")
    return head + "".join(w[:1].upper() + w[1:] for w in rest)


def gemini_canonical(value: typing.Any, *, camel: bool = True) -> typing.Any:
    """A Gemini body however it is spelled: lowerCamelCase names (proto3 JSON also accepts
    snake_case, which google-genai sends inside inlineData) and inline data as bytes (in
    either base64 alphabet: google-genai sends the URL-safe one)."""
    if isinstance(value, list):
        return [gemini_canonical(v, camel=camel) for v in value]
    if not isinstance(value, dict):
        return value
    out = {}
    for key, v in value.items():
        key = _camel(key) if camel else key
        if key == "data" and isinstance(v, str):
            out[key] = base64.b64decode(v.translate(str.maketrans("-_", "+/")))
        else:
            out[key] = gemini_canonical(v, camel=camel)
    return out


class GeminiRequest(pydantic.BaseModel):
    """The generateContent body as google-genai's converter writes it, from the SDK's own
    types (which forbid unknown fields and alias the API's lowerCamelCase names); only the
    top-level fields our client sends are declared, so another one is an error too."""

    model_config = ConfigDict(extra="forbid", alias_generator=pydantic.alias_generators.to_camel)

    contents: list[gtypes.Content]
    system_instruction: gtypes.Content | None = None
    generation_config: gtypes.GenerationConfig


def parse_gemini(body: dict) -> GeminiRequest:
    """Our Gemini body read by google-genai's types, from JSON as the API reads it (bytes in base64)."""
    parsed = GeminiRequest.model_validate_json(json.dumps(body))
    # nothing read differently or dropped, and our names are the API's
    dumped = parsed.model_dump(mode="json", by_alias=True, exclude_none=True)
    assert gemini_canonical(dumped, camel=False) == gemini_canonical(body, camel=False)
    return parsed


def validate_request(provider: str, body: dict, anthropic_version: str) -> None:
    """Our body against the SDK's request type, strictly."""
    if provider == "openai":
        strict_adapter(CompletionCreateParamsNonStreaming).validate_python(body, strict=True)
    elif provider == "anthropic":
        body = dict(body)
        if anthropic_version < ANTHROPIC_NO_SAMPLING_FROM:
            # anthropic 2.x types describe API version 2026-10-21, which removed the
            # sampling parameters; the version we send still takes temperature in [0, 1].
            assert 0 <= body.pop("temperature", 0) <= 1
        strict_adapter(MessageCreateParamsNonStreaming).validate_python(body, strict=True)
    else:
        parse_gemini(body)


# --- talking through the SDKs -----------------------------------------------------------------


def run(coro):
    return asyncio.run(coro)


async def complete_once(config, request):
    client = client_from_config(config, limiter=None)
    try:
        return await client.complete(request)
    finally:
        await client.close()


def context_header(req) -> dict[str, str]:
    return {CONTEXT_HEADER: encode_context(req.context)}


def images(req) -> list[bytes]:
    return [p.image.png for m in req.messages for p in m.content if isinstance(p, ImagePart)]


def sdk_call(provider: str, server, req, *, key: str = KEY, context: bool = True, retries: int = 0, extra_body=None):
    """One request written the way each SDK's users write it: the rules as system text, a
    user turn of text and a PNG image; the context header for the MOCK answer."""
    headers = context_header(req) if context else {}
    system, png = req.messages[0].text, images(req)[0]
    b64 = base64.b64encode(png).decode()
    question = "Which blocks do you remove, and when?"
    openai_image = {"type": "image_url", "image_url": {"url": f"data:image/png;base64,{b64}"}}
    anthropic_image = {"type": "image", "source": {"type": "base64", "media_type": "image/png", "data": b64}}
    gemini_image = gtypes.Part.from_bytes(data=png, mime_type="image/png")
    if provider == "openai":
        with openai.OpenAI(base_url=f"{server.url}/v1", api_key=key, max_retries=retries) as client:
            return client.chat.completions.create(
                model="deepphy-mock", max_tokens=256, extra_headers=headers, extra_body=extra_body,
                messages=[{"role": "system", "content": system},
                          {"role": "user", "content": [{"type": "text", "text": question}, openai_image]}],
            )
    if provider == "anthropic":
        with anthropic.Anthropic(base_url=server.url, api_key=key, max_retries=retries) as client:
            return client.messages.create(
                model="deepphy-mock", max_tokens=256, system=system, extra_headers=headers, extra_body=extra_body,
                messages=[{"role": "user", "content": [{"type": "text", "text": question}, anthropic_image]}],
            )
    retry = gtypes.HttpRetryOptions(attempts=retries + 1, initial_delay=0.05, max_delay=0.1, jitter=0.01) if retries else None
    with genai.Client(api_key=key, vertexai=False,
                      http_options=gtypes.HttpOptions(base_url=server.url, headers=headers, retry_options=retry)) as client:
        return client.models.generate_content(
            model="deepphy-mock",
            contents=[gtypes.Content(role="user", parts=[gtypes.Part(text=question), gemini_image])],
            config=gtypes.GenerateContentConfig(system_instruction=system, max_output_tokens=256),
        )


def lower(headers: dict[str, str]) -> dict[str, str]:
    return {k.lower(): v for k, v in headers.items()}


# --- 1. the SDKs read the server ----------------------------------------------------------------


@pytest.mark.parametrize("provider", PROVIDERS)
def test_each_sdk_parses_the_servers_reply(server, provider):
    req = iphyre_request(1)
    expected = run(MockModel().complete(req)).text
    resp = sdk_call(provider, server, req)
    rec = server.bodies()[-1]
    if provider == "openai":
        assert isinstance(resp, openai.types.chat.ChatCompletion)
        assert resp.choices[0].message.content == expected and resp.choices[0].finish_reason == "stop"
        tokens = resp.usage.prompt_tokens, resp.usage.completion_tokens
        assert resp.usage.total_tokens == sum(tokens) and resp._request_id.startswith("req_")
    elif provider == "anthropic":
        assert isinstance(resp, anthropic.types.Message)
        assert [b.text for b in resp.content] == [expected] and resp.stop_reason == "end_turn"
        tokens = resp.usage.input_tokens, resp.usage.output_tokens
        assert resp._request_id.startswith("req_")
    else:
        assert isinstance(resp, gtypes.GenerateContentResponse)
        assert resp.text == expected and resp.candidates[0].finish_reason == gtypes.FinishReason.STOP
        tokens = resp.usage_metadata.prompt_token_count, resp.usage_metadata.candidates_token_count
        assert resp.usage_metadata.total_token_count == sum(tokens)
        assert rec["path"].endswith("/models/deepphy-mock:generateContent")  # google-genai's own API version
    assert tokens[0] > 480 and tokens[1] == text_tokens(expected)  # the 600x600 image counted
    assert unknown_fields(resp) == []


@pytest.mark.parametrize("text", ['[{"time": 1.0, "index": 0}]', None], ids=["answer", "empty"])
def test_server_replies_are_the_sdks_response_types(text):
    assert unknown_fields(openai.types.chat.ChatCompletion.model_validate(OpenAIFormat.reply({"model": "m"}, text, 3, 4))) == []
    assert unknown_fields(anthropic.types.Message.model_validate(AnthropicFormat.reply({"model": "m"}, text, 3, 4))) == []
    gtypes.GenerateContentResponse.model_validate(GeminiFormat.reply({"model": "m"}, text, 3, 4))  # extra="forbid"


def test_gemini_bodies_are_read_however_spelled(server):
    """proto3 JSON takes snake_case names and either base64 alphabet, as google-genai
    sends them; the server reads them as the Gemini API does, to the same token count."""
    req = iphyre_request(0)
    run(complete_once(local_config(server.url, "gemini"), req))
    ours = server.bodies()[-1]["body"]
    respelled = json.loads(json.dumps(ours).replace('"inlineData"', '"inline_data"').replace('"mimeType"', '"mime_type"')
                           .replace('"systemInstruction"', '"system_instruction"'))
    for content in respelled["contents"]:
        for part in content["parts"]:
            if "inline_data" in part:
                part["inline_data"]["data"] = base64.urlsafe_b64encode(base64.b64decode(part["inline_data"]["data"])).decode()
    assert respelled != ours and gemini_canonical(respelled) == gemini_canonical(ours)
    assert any("-" in p["inline_data"]["data"] or "_" in p["inline_data"]["data"]
               for c in respelled["contents"] for p in c["parts"] if "inline_data" in p)
    normalized = GeminiFormat.normalize(respelled)
    assert GeminiFormat.prompt_tokens(normalized) == GeminiFormat.prompt_tokens(GeminiFormat.normalize(ours))
    assert GeminiFormat.prompt_tokens(normalized) > 2 * 480  # both 600x600 images read from their PNG headers


def test_retry_hints_in_each_providers_place():
    ra = parse_retry_after
    gemini_429, _ = GeminiFormat.error(ApiError(429, "slow down", retry_after_s=22), "")
    assert ra({}, body=json.dumps(gemini_429).encode()) == 22.0
    assert ra({"Retry-After": "3"}, body=json.dumps(gemini_429).encode()) == 3.0  # a header wins
    _, headers = OpenAIFormat.error(ApiError(429, "slow down", retry_after_s=0.25), "")
    assert ra(headers) == 0.25
    unreadable = b'{"error": {"details": [{"@type": "type.googleapis.com/google.rpc.RetryInfo", "retryDelay": "soon"}]}}'
    for body in (b"", b"not json", unreadable):
        assert ra({}, body=body) is None


# provider -> case -> (the SDK's error class, HTTP status, the provider's error type / status)
SDK_ERRORS = {
    "openai": {
        "429": (openai.RateLimitError, 429, "requests"),
        "500": (openai.InternalServerError, 500, "server_error"),
        "400": (openai.BadRequestError, 400, "invalid_request_error"),
        "key": (openai.AuthenticationError, 401, "invalid_request_error"),
    },
    "anthropic": {
        "429": (anthropic.RateLimitError, 429, "rate_limit_error"),
        "500": (anthropic.InternalServerError, 500, "api_error"),
        "400": (anthropic.BadRequestError, 400, "invalid_request_error"),
        "key": (anthropic.AuthenticationError, 401, "authentication_error"),
    },
    "gemini": {
        "429": (genai_errors.ClientError, 429, "RESOURCE_EXHAUSTED"),
        "500": (genai_errors.ServerError, 500, "INTERNAL"),
        "400": (genai_errors.ClientError, 400, "INVALID_ARGUMENT"),
        "key": (genai_errors.ClientError, 400, "INVALID_ARGUMENT"),  # the Gemini API's answer to a wrong key
    },
}


@pytest.mark.parametrize("provider,case", [(p, c) for p in PROVIDERS for c in ("429", "500", "400", "key")])
def test_each_sdk_parses_the_servers_errors(server, provider, case):
    """429 and 500 injected, 400 for a request without the context header, a wrong key."""
    cls, status, kind = SDK_ERRORS[provider][case]
    if case in ("429", "500"):
        server.configure(faults={"first_tries": 1, "kinds": [case]})
    if case == "key":
        server.configure(require_key_env=KEY_ENV)
    with pytest.raises(cls) as info:
        sdk_call(provider, server, iphyre_request(0), key="sk-wrong" if case == "key" else KEY, context=case != "400")
    e = info.value
    assert server.stats()["requests"] == 1  # the SDK's retries are off
    if provider == "openai":
        assert e.status_code == status and e.type == kind
        assert set(e.body) == {"message", "type", "param", "code"}
        assert unknown_fields(openai.types.shared.ErrorObject.model_validate(e.body)) == []
        assert e.code == {"429": "rate_limit_exceeded", "key": "invalid_api_key"}.get(case)
        assert e.request_id == e.response.headers["x-request-id"] and e.request_id.startswith("req_")
        retry_hint = e.response.headers.get("retry-after")
    elif provider == "anthropic":
        assert e.status_code == status and e.type == kind and e.api_message
        assert unknown_fields(anthropic.types.ErrorResponse.model_validate(e.body)) == []
        assert e.request_id == e.body["request_id"] and e.request_id.startswith("req_")
        retry_hint = e.response.headers.get("retry-after")
    else:
        assert e.code == status and e.status == kind and e.message
        error = e.details["error"]
        assert set(e.details) == {"error"} and set(error) <= {"code", "message", "status", "details"}
        details = {d["@type"]: d for d in error.get("details", [])}
        if case == "key":
            assert details["type.googleapis.com/google.rpc.ErrorInfo"]["reason"] == "API_KEY_INVALID"
        assert "retry-after" not in e.response.headers  # Gemini says it in the body
        retry_hint = details.get("type.googleapis.com/google.rpc.RetryInfo", {}).get("retryDelay")
    expected_hint = {"openai": "0.6", "anthropic": "0.6", "gemini": "0.600s"}[provider] if case == "429" else None
    assert retry_hint == expected_hint


# Each provider's documented status -> error type (Anthropic) / canonical status (Gemini).
ANTHROPIC_ERROR_TYPES = {400: "invalid_request_error", 401: "authentication_error", 403: "permission_error",
                         404: "not_found_error", 429: "rate_limit_error", 500: "api_error", 503: "api_error",
                         504: "timeout_error", 529: "overloaded_error"}
GEMINI_STATUSES = {400: "INVALID_ARGUMENT", 401: "UNAUTHENTICATED", 403: "PERMISSION_DENIED", 404: "NOT_FOUND",
                   429: "RESOURCE_EXHAUSTED", 500: "INTERNAL", 503: "UNAVAILABLE", 504: "DEADLINE_EXCEEDED",
                   529: "INTERNAL"}


@pytest.mark.parametrize("status", sorted(ANTHROPIC_ERROR_TYPES))
def test_every_error_status_is_in_each_providers_shape(status):
    e = ApiError(status, "boom", retry_after_s=1.5 if status == 429 else None)
    body, _ = OpenAIFormat.error(e, "req_1")
    assert set(body) == {"error"} and unknown_fields(openai.types.shared.ErrorObject.model_validate(body["error"])) == []
    body, _ = AnthropicFormat.error(e, "req_1")
    parsed = anthropic.types.ErrorResponse.model_validate(body)
    assert unknown_fields(parsed) == [] and parsed.error.type == ANTHROPIC_ERROR_TYPES[status] and parsed.request_id == "req_1"
    body, _ = GeminiFormat.error(e, "req_1")
    with pytest.raises(genai_errors.ServerError if status >= 500 else genai_errors.ClientError) as info:
        genai_errors.APIError.raise_error(status, body, None)
    assert (info.value.code, info.value.status, info.value.message) == (status, GEMINI_STATUSES[status], "boom")


@pytest.mark.parametrize("provider", PROVIDERS)
def test_each_sdks_own_retry_gets_through_a_429(server, provider):
    server.configure(faults={"first_tries": 1, "kinds": ["429"]})
    req = iphyre_request(0)
    sdk_call(provider, server, req, retries=1)
    st = server.stats()
    assert st["requests"] == 2 and st["faults"] == {"429": 1} and st["status"] == {"429": 1, "200": 1}
    gap = st["arrivals"][1] - st["arrivals"][0]
    if provider != "gemini":  # the Stainless SDKs honour Retry-After (their own first backoff is at most 0.5 s)
        assert gap >= RETRY_AFTER_S
    # google-genai waits by its own exponential backoff: it reads neither Retry-After nor
    # RetryInfo, so the hint is checked with our client below.


@pytest.mark.parametrize("provider", PROVIDERS)
def test_our_clients_wait_as_each_provider_says(server, provider):
    server.configure(faults={"first_tries": 1, "kinds": ["429"]})
    cfg = local_config(server.url, provider, retry={"max_retries": 1, "base_delay_s": 0.01, "max_delay_s": 0.02})
    assert run(complete_once(cfg, iphyre_request(0))).retries == 1
    arrivals = server.stats()["arrivals"]
    assert arrivals[1] - arrivals[0] >= RETRY_AFTER_S  # Gemini: from RetryInfo, there is no header


@pytest.mark.parametrize("provider,missing,wrong", [("openai", 401, 401), ("anthropic", 401, 401), ("gemini", 403, 400)])
def test_our_clients_fail_at_once_on_each_providers_key_errors(server, monkeypatch, provider, missing, wrong):
    server.configure(require_key_env=KEY_ENV)
    monkeypatch.setenv("DEEPPHY_SDK_WRONG_KEY", "sk-wrong")
    for key_env, status in ((None, missing), ("DEEPPHY_SDK_WRONG_KEY", wrong)):
        cfg = local_config(server.url, provider, api_key_env=key_env)
        with pytest.raises(AccessDenied) as info:  # stops the run: no retry, no re-queue
            run(complete_once(cfg, iphyre_request(0)))
        assert (info.value.kind, info.value.retries) == ("denied", 0) and f"HTTP {status}" in str(info.value)
        assert ("$DEEPPHY_SDK_WRONG_KEY" if key_env else "no key (this entry has no api_key_env)") in str(info.value)


# --- 2. our requests are the SDKs' requests -------------------------------------------------------


def conversation(req):
    """A multi-turn prompt: the rules, an observation, our earlier answer, another image."""
    system, user = req.messages
    again = Message(role="user", content=[TextPart(text="That failed. Try again."), ImagePart(image=req.messages[1].images[-1])])
    answer = Message(role="assistant", content=[TextPart(text='[{"time": 1.0, "index": 0}]')])
    return req.model_copy(update={"messages": [system, user, answer, again]})


def requests():
    return [iphyre_request(0), iphyre_request(2, fmt=PromptFormat.WM, history_frames=3), conversation(iphyre_request(1))]


# The options our providers have that change the body.
VARIANTS = {
    "openai": {
        "default": {},
        "reasoning": {"max_tokens_param": "max_completion_tokens", "send_temperature": False, "send_seed": False,
                      "max_tokens": 4096, "extra_body": {"reasoning_effort": "low"}},
        "one-image": {"max_images": 1},
    },
    "anthropic": {
        "default": {},
        "2026-10-21": {"anthropic_version": ANTHROPIC_NO_SAMPLING_FROM},
        "one-image": {"max_images": 1},
    },
    "gemini": {
        "default": {},
        "thinking": {"send_seed": False, "max_tokens": 4096,
                     "extra_body": {"generationConfig": {"thinkingConfig": {"thinkingBudget": 128}}}},
        "one-image": {"max_images": 1},
    },
}


def send_as_sdk(provider: str, server, cfg, body: dict, req) -> int:
    """The same request through the SDK; returns the input tokens it read from the reply."""
    headers = context_header(req)
    if provider == "openai":
        with openai.OpenAI(base_url=cfg.resolved_base_url, api_key=KEY, max_retries=0) as client:
            return client.chat.completions.create(**body, extra_headers=headers).usage.prompt_tokens
    if provider == "anthropic":
        # 2.x has no temperature parameter: for 2023-06-01 it goes in extra_body
        sampling = {k: body[k] for k in ("temperature",) if k in body}
        rest = {k: v for k, v in body.items() if k not in sampling}
        with anthropic.Anthropic(base_url=cfg.resolved_base_url.removesuffix("/v1"), api_key=KEY, max_retries=0,
                                 default_headers={"anthropic-version": cfg.anthropic_version}) as client:
            return client.messages.create(**rest, extra_body=sampling or None, extra_headers=headers).usage.input_tokens
    base_url, api_version = cfg.resolved_base_url.rsplit("/", 1)
    parsed = parse_gemini(body)
    config = gtypes.GenerateContentConfig(system_instruction=parsed.system_instruction,
                                          **parsed.generation_config.model_dump(exclude_none=True))
    with genai.Client(api_key=KEY, vertexai=False,
                      http_options=gtypes.HttpOptions(base_url=base_url, api_version=api_version, headers=headers)) as client:
        resp = client.models.generate_content(model=cfg.model, contents=parsed.contents, config=config)
        return resp.usage_metadata.prompt_token_count


# (our auth header, the SDK's auth header): Anthropic's 2.x SDK sends the key as Bearer;
# the API takes either (x-api-key first), and so does the server.
AUTH_HEADERS = {"openai": ("authorization", "authorization"), "anthropic": ("x-api-key", "authorization"),
                "gemini": ("x-goog-api-key", "x-goog-api-key")}


@pytest.mark.parametrize("provider,variant", [(p, v) for p in PROVIDERS for v in VARIANTS[p]])
def test_our_requests_are_the_sdks_requests(server, provider, variant):
    server.configure(require_key_env=KEY_ENV)  # each side's key placement must get through
    cfg = local_config(server.url, provider, api_key_env=KEY_ENV, **VARIANTS[provider][variant])
    for req in requests():
        ours = run(complete_once(cfg, req))
        rec = server.bodies()[-1]
        body = rec["body"]
        validate_request(provider, body, cfg.anthropic_version)
        sdk_input_tokens = send_as_sdk(provider, server, cfg, body, req)
        sdk_rec = server.bodies()[-1]
        assert sdk_rec["path"] == rec["path"]
        if provider == "gemini":
            assert gemini_canonical(sdk_rec["body"]) == gemini_canonical(body)
        else:
            assert sdk_rec["body"] == body
        assert sdk_input_tokens == ours.usage.input_tokens  # the server read both the same
        # headers
        mine, theirs = lower(rec["headers"]), lower(sdk_rec["headers"])
        assert mine["content-type"] == theirs["content-type"] == "application/json"
        ours_auth, sdk_auth = AUTH_HEADERS[provider]
        assert mine[ours_auth] == ("Bearer ***" if ours_auth == "authorization" else "***")
        assert theirs[sdk_auth] == ("Bearer ***" if sdk_auth == "authorization" else "***")
        if provider == "anthropic":
            assert mine["anthropic-version"] == theirs["anthropic-version"] == cfg.anthropic_version
    # what each variant is about
    n_images = len(images(req))
    if variant == "one-image":
        assert n_images > 1 and ours.images_dropped == n_images - 1
    if variant == "reasoning":
        assert body["max_completion_tokens"] == 4096 and body["reasoning_effort"] == "low"
    if variant == "2026-10-21":
        assert "temperature" not in body
    if variant == "default" and provider == "anthropic":
        assert body["temperature"] == 0.1
    if variant == "thinking":  # extra_body adds to generationConfig, it does not replace it
        assert body["generationConfig"] == {"maxOutputTokens": 4096, "temperature": 0.1, "thinkingConfig": {"thinkingBudget": 128}}


def test_the_strict_validation_rejects_what_the_sdk_types_reject(server):
    req = iphyre_request(0)
    bodies = {}
    for provider in PROVIDERS:
        run(complete_once(local_config(server.url, provider), req))
        bodies[provider] = server.bodies()[-1]["body"]
    o, a, g = bodies["openai"], bodies["anthropic"], bodies["gemini"]
    image_part = o["messages"][1]["content"][2]
    assert image_part["type"] == "image_url"
    bad = {
        "openai": [
            {**o, "bogus": 1},
            {**o, "seed": 1.5},
            {**o, "messages": [o["messages"][0], {"role": "user", "content": [{**image_part, "bogus": 1}]}]},
            {**o, "messages": [{"role": "system", "content": [image_part]}]},  # system content is text only
            {**o, "messages": [{"role": "robot", "content": "hi"}]},
        ],
        "anthropic": [
            {**a, "seed": 1},
            {**a, "messages": [{"role": "user", "content": [
                {"type": "image", "source": {"type": "base64", "media_type": "image/bmp", "data": "AA"}}]}]},
            {**a, "messages": [{"role": "robot", "content": "hi"}]},
            {**a, "system": [{"type": "image", "source": a["messages"][0]["content"][2]["source"]}]},  # system is text only
        ],
        "gemini": [
            {**g, "safety": []},
            {**g, "contents": [{"role": "user", "parts": [{"text": "hi", "bogus": 1}]}]},
            {**g, "generationConfig": {**g["generationConfig"], "maxTokens": 5}},
        ],
    }
    for provider, cases in bad.items():
        for body in cases:
            with pytest.raises(pydantic.ValidationError):
                validate_request(provider, body, "2023-06-01")
    for provider in PROVIDERS:
        validate_request(provider, bodies[provider], "2023-06-01")
    with pytest.raises(pydantic.ValidationError):  # 2026-10-21 has no temperature
        validate_request("anthropic", a, ANTHROPIC_NO_SAMPLING_FROM)


def test_api_version_2026_10_21_has_no_sampling_parameters(server):
    with pytest.raises(anthropic.BadRequestError, match="temperature: Extra inputs are not permitted"):
        sdk_call("anthropic", server, iphyre_request(0), extra_body={"temperature": 0.1})


@pytest.mark.parametrize("provider", PROVIDERS)
def test_images_only_where_the_provider_takes_them(server, provider):
    req = iphyre_request(0)
    image = ImagePart(image=req.messages[1].images[0])
    cfg = local_config(server.url, provider)
    bad_system = req.model_copy(update={"messages": [Message(role="system", content=[TextPart(text="rules"), image]), req.messages[1]]})
    with pytest.raises(ValueError, match="system message cannot carry images"):
        run(complete_once(cfg, bad_system))
    with_answer = conversation(req)
    answer_image = Message(role="assistant", content=[TextPart(text="[]"), image])
    messages = [*with_answer.messages[:2], answer_image, with_answer.messages[3]]
    if provider == "openai":  # assistant content is text (or refusal) parts only
        with pytest.raises(ValueError, match="assistant message cannot carry images"):
            run(complete_once(cfg, req.model_copy(update={"messages": messages})))
    assert server.stats()["requests"] == 0  # refused before sending
