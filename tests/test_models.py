"""Model clients against the local server over real HTTP on loopback (no mocked aiohttp)."""

from __future__ import annotations

import asyncio
import base64
import logging
import pickle

import jsonschema
import pytest

from deepphy.models import (
    AccessDenied, ModelConfig, ModelError, RequestRejected, UnknownModel, client_from_config, load_models, model_config,
)
from deepphy.models.config import MissingKey, ModelsFile
from deepphy.agents import MockModel, make_agent
from deepphy.testing.model_server import DEFAULT_PORT, FAULT_KINDS, PROSE_REPLY, ServerConfig, ServerThread
from deepphy.models.wire import decode_context, encode_context, parse_retry_after
from deepphy.prompts import PromptFormat
from models_support import iphyre_request, local_config

FAKE_KEY = "sk-deepphy-FAKE-5ecret-key-0123456789"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def server():
    with ServerThread(ServerConfig(record_bodies=50)) as s:
        yield s


@pytest.fixture(autouse=True)
def _clean(request):
    if "server" in request.fixturenames:
        s = request.getfixturevalue("server")
        s.configure(latency_s=0.0, latency_jitter_s=0.0, require_key_env=None,
                    faults={"rate": 0.0, "first_tries": 0, "kinds": list(FAULT_KINDS), "retry_after_s": 1.0, "hang_s": 3600.0})
        s.reset()
    yield


def run(coro):
    return asyncio.run(coro)


async def complete_once(config: ModelConfig, request, limiter=None):
    client = client_from_config(config, limiter=limiter)
    try:
        return await client.complete(request)
    finally:
        await client.close()


# --- config ---------------------------------------------------------------------------------


def test_shipped_models_file_loads_and_holds_no_keys():
    models = load_models()
    assert {"gpt-4o", "claude-sonnet-4", "gemini-2.5-pro", "qwen2.5-vl-72b", "local-mock"} <= set(models)
    assert {m.provider for m in models.values()} == {"openai", "anthropic", "gemini"}
    for m in models.values():
        assert m.api_key_env is None or m.api_key_env.isupper()
    text = open(__import__("deepphy.models.config", fromlist=["x"]).DEFAULT_MODELS_FILE).read()
    assert "sk-" not in text


def test_the_shipped_local_mock_entry_reaches_the_model_servers_default_port():
    """`python -m deepphy.testing.model_server` with no flags is what `--model local-mock` calls:
    the port is said in the server (DEFAULT_PORT) and in the models file, and must agree."""
    from urllib.parse import urlsplit

    from deepphy.loopback import LOOPBACK_HOST

    url = urlsplit(load_models()["local-mock"].resolved_base_url)
    assert (url.hostname, url.port) == (LOOPBACK_HOST, DEFAULT_PORT)


@pytest.mark.parametrize("url, loopback", [
    ("http://127.0.0.1:8765/v1", True), ("http://127.0.0.2/v1", True), ("http://[::1]:8000/v1", True),
    ("http://LOCALHOST/v1", True), ("http://localhost./v1", True), ("http://10.0.0.1/v1", False),
    ("https://api.openai.com/v1", False), ("http://127.0.0.1.example.com/v1", False), ("/v1", False),
])
def test_send_context_goes_to_loopback_only(url, loopback):
    """One loopback test for the web pages' guard and the models file (deepphy.loopback)."""
    make = lambda: ModelConfig(name="x", provider="openai", model="m", base_url=url, send_context=True)  # noqa: E731
    if loopback:
        assert make().send_context
    else:
        with pytest.raises(ValueError, match="loopback"):
            make()


def test_models_file_validation(tmp_path):
    with pytest.raises(ValueError, match="loopback"):
        ModelConfig(name="x", provider="openai", model="m", base_url="https://api.openai.com/v1", send_context=True)
    with pytest.raises(ValueError, match="duplicate"):
        ModelsFile.model_validate({"models": [{"name": "a", "provider": "openai", "model": "m"}] * 2})
    with pytest.raises(ValueError):
        ModelsFile.model_validate({"models": [{"name": "a", "provider": "openai", "model": "m", "api_key": "sk-x"}]})
    f = tmp_path / "m.yaml"
    f.write_text("models:\n  - {name: mine, provider: gemini, model: g, rate_limits: {requests_per_min: 10}}\n")
    cfg = model_config("mine", f)
    assert cfg.resolved_base_url == "https://generativelanguage.googleapis.com/v1beta"
    assert cfg.resolved_max_images == 3000 and cfg.rate_limits.requests_per_min == 10
    assert make_agent("mock", f).name == "mock"
    with pytest.raises(UnknownModel, match="mine"):
        make_agent("other", f)


def test_missing_key_is_reported_by_variable_name(monkeypatch):
    monkeypatch.delenv("DEEPPHY_TEST_KEY", raising=False)
    cfg = ModelConfig(name="x", provider="anthropic", model="m", api_key_env="DEEPPHY_TEST_KEY")
    with pytest.raises(MissingKey, match="DEEPPHY_TEST_KEY"):
        client_from_config(cfg)


def test_context_header_round_trip():
    req = iphyre_request(3, fmt=PromptFormat.WM, tried=['[{"time": 1.0, "index": 0}]'])
    assert decode_context(encode_context(req.context)) == req.context


def test_retry_after_parsing():
    assert parse_retry_after({"Retry-After": "2"}) == 2.0
    assert parse_retry_after({"retry-after-ms": "250", "Retry-After": "9"}) == 0.25
    assert abs(parse_retry_after({"Retry-After": "Wed, 21 Oct 2015 07:28:10 GMT"}, now=1445412480.0) - 10.0) < 1e-6
    assert parse_retry_after({}) is None and parse_retry_after({"Retry-After": "soon"}) is None


# --- request bodies against the documented schemas --------------------------------------------

_TEXT = {"type": "object", "required": ["type", "text"], "additionalProperties": False,
         "properties": {"type": {"const": "text"}, "text": {"type": "string"}}}
OPENAI_SCHEMA = {
    "type": "object", "required": ["model", "messages"], "additionalProperties": False,
    "properties": {
        "model": {"type": "string"},
        "temperature": {"type": "number", "minimum": 0, "maximum": 2},
        "max_tokens": {"type": "integer", "minimum": 1},
        "max_completion_tokens": {"type": "integer", "minimum": 1},
        "seed": {"type": "integer"},
        "messages": {"type": "array", "minItems": 1, "items": {"oneOf": [
            {"type": "object", "required": ["role", "content"], "additionalProperties": False, "properties": {
                "role": {"enum": ["system", "developer"]},
                "content": {"oneOf": [{"type": "string"}, {"type": "array", "items": _TEXT}]}}},
            {"type": "object", "required": ["role", "content"], "additionalProperties": False, "properties": {
                "role": {"const": "user"},
                "content": {"oneOf": [{"type": "string"}, {"type": "array", "minItems": 1, "items": {"oneOf": [
                    _TEXT,
                    {"type": "object", "required": ["type", "image_url"], "additionalProperties": False, "properties": {
                        "type": {"const": "image_url"},
                        "image_url": {"type": "object", "required": ["url"], "additionalProperties": False, "properties": {
                            "url": {"type": "string", "pattern": "^data:image/png;base64,[A-Za-z0-9+/=]+$"},
                            "detail": {"enum": ["auto", "low", "high"]}}}}}]}}]}}},
        ]}},
    },
}
ANTHROPIC_SCHEMA = {
    "type": "object", "required": ["model", "max_tokens", "messages"], "additionalProperties": False,
    "properties": {
        "model": {"type": "string"},
        "max_tokens": {"type": "integer", "minimum": 1},
        "temperature": {"type": "number", "minimum": 0, "maximum": 1},
        "system": {"oneOf": [{"type": "string"}, {"type": "array", "items": _TEXT}]},
        "messages": {"type": "array", "minItems": 1, "items": {
            "type": "object", "required": ["role", "content"], "additionalProperties": False, "properties": {
                "role": {"enum": ["user", "assistant"]},
                "content": {"oneOf": [{"type": "string"}, {"type": "array", "items": {"oneOf": [
                    _TEXT,
                    {"type": "object", "required": ["type", "source"], "additionalProperties": False, "properties": {
                        "type": {"const": "image"},
                        "source": {"type": "object", "required": ["type", "media_type", "data"], "additionalProperties": False,
                                   "properties": {"type": {"const": "base64"},
                                                  "media_type": {"enum": ["image/jpeg", "image/png", "image/gif", "image/webp"]},
                                                  "data": {"type": "string", "pattern": "^[A-Za-z0-9+/=]+$"}}}}}]}}]}}}},
    },
}
_GPART = {"type": "object", "minProperties": 1, "maxProperties": 1, "additionalProperties": False, "properties": {
    "text": {"type": "string"},
    "inlineData": {"type": "object", "required": ["mimeType", "data"], "additionalProperties": False, "properties": {
        "mimeType": {"type": "string"}, "data": {"type": "string", "pattern": "^[A-Za-z0-9+/=]+$"}}}}}
GEMINI_SCHEMA = {
    "type": "object", "required": ["contents"], "additionalProperties": False,
    "properties": {
        "contents": {"type": "array", "minItems": 1, "items": {
            "type": "object", "required": ["role", "parts"], "additionalProperties": False,
            "properties": {"role": {"enum": ["user", "model"]}, "parts": {"type": "array", "minItems": 1, "items": _GPART}}}},
        "systemInstruction": {"type": "object", "required": ["parts"], "properties": {"parts": {"type": "array", "items": _GPART}}},
        "generationConfig": {"type": "object", "additionalProperties": False, "properties": {
            "temperature": {"type": "number", "minimum": 0, "maximum": 2},
            "maxOutputTokens": {"type": "integer", "minimum": 1}, "seed": {"type": "integer"},
            "topP": {"type": "number"}, "topK": {"type": "integer"}}},
    },
}
SCHEMAS = {"openai": OPENAI_SCHEMA, "anthropic": ANTHROPIC_SCHEMA, "gemini": GEMINI_SCHEMA}


def _images(provider: str, body: dict) -> list[bytes]:
    out = []
    if provider == "openai":
        for m in body["messages"]:
            for p in m["content"] if isinstance(m["content"], list) else []:
                if p["type"] == "image_url":
                    out.append(base64.b64decode(p["image_url"]["url"].split(",", 1)[1]))
    elif provider == "anthropic":
        for m in body["messages"]:
            out += [base64.b64decode(b["source"]["data"]) for b in m["content"] if b["type"] == "image"]
    else:
        for c in body["contents"]:
            out += [base64.b64decode(p["inlineData"]["data"]) for p in c["parts"] if "inlineData" in p]
    return out


@pytest.mark.parametrize("provider", ["openai", "anthropic", "gemini"])
def test_request_body_matches_provider_schema(server, provider, monkeypatch):
    monkeypatch.setenv("DEEPPHY_TEST_KEY", FAKE_KEY)
    req = iphyre_request(2, fmt=PromptFormat.WM, history_frames=3)
    cfg = local_config(server.url, provider, api_key_env="DEEPPHY_TEST_KEY")
    resp = run(complete_once(cfg, req))
    assert resp.text.startswith("Prediction:") and resp.usage.input_tokens > 0 and resp.usage.output_tokens > 0
    (rec,) = server.bodies()
    body = rec["body"]
    jsonschema.validate(body, SCHEMAS[provider])
    # every image of the prompt, in order, as the PNG bytes we rendered
    expected = [p.image.png for m in req.messages for p in m.content if p.type == "image"]
    assert len(expected) == 5 and _images(provider, body) == expected
    assert all(png.startswith(PNG_MAGIC) for png in _images(provider, body))
    system = req.messages[0].text
    headers = set(rec["headers"])
    if provider == "openai":
        assert body["messages"][0] == {"role": "system", "content": system}
        assert body["temperature"] == 0.1 and body["max_tokens"] == 1024 and isinstance(body["seed"], int)
        assert "Authorization" in headers
    elif provider == "anthropic":
        assert body["system"] == system and [m["role"] for m in body["messages"]] == ["user"]
        assert "anthropic-version" in headers and "x-api-key" in headers and "seed" not in body
    else:
        assert body["systemInstruction"] == {"parts": [{"text": system}]}
        assert body["generationConfig"]["maxOutputTokens"] == 1024 and "x-goog-api-key" in headers
        assert rec["path"] == "/v1beta/models/deepphy-mock:generateContent"
    # the context travels only in the header, never in the body a provider reads
    assert "X-Deepphy-Context" in headers and req.context.task_id not in str(body.get("model"))
    assert "action_space" not in str(body)


def test_openai_reasoning_model_options(server):
    cfg = local_config(server.url, "openai", max_tokens_param="max_completion_tokens", send_temperature=False,
                       send_seed=False, max_tokens=4096, extra_body={"reasoning_effort": "low"})
    run(complete_once(cfg, iphyre_request(0)))
    body = server.bodies()[-1]["body"]
    assert body["max_completion_tokens"] == 4096 and body["reasoning_effort"] == "low"
    assert not {"max_tokens", "temperature", "seed"} & set(body)


def test_no_context_is_sent_unless_configured(server):
    cfg = local_config(server.url, "openai", send_context=False, retry={"max_retries": 0})
    with pytest.raises(RequestRejected) as e:  # the server's 400: the same request would get it again
        run(complete_once(cfg, iphyre_request(0)))
    assert e.value.kind == "rejected" and e.value.retries == 0
    assert "X-Deepphy-Context" not in server.bodies()[-1]["headers"]


# --- the server answers exactly what MOCK answers ---------------------------------------------


@pytest.mark.parametrize("provider", ["openai", "anthropic", "gemini"])
def test_server_answers_exactly_like_mock(server, provider):
    reqs = [
        iphyre_request(i, fmt=fmt, run=r, attempt=a, seed=s, tried=tried)
        for i, fmt, r, a, s, tried in [
            (0, PromptFormat.VLA, 0, 1, 0, []),
            (5, PromptFormat.WM, 1, 3, 7, ['[{"time": 2.0, "index": 0}]', "garbage"]),
            (11, PromptFormat.VLA, 2, 10, 123, []),
        ]
    ]

    async def both():
        client = client_from_config(local_config(server.url, provider))
        try:
            return [((await client.complete(r)).text, (await MockModel().complete(r)).text) for r in reqs]
        finally:
            await client.close()

    for via_http, direct in run(both()):
        assert via_http == direct


# --- images per request ---------------------------------------------------------------------------


def test_image_limit_keeps_the_most_recent(server):
    req = iphyre_request(1, history_frames=4)  # 4 key frames + 2 observation images
    all_images = [p.image.png for m in req.messages for p in m.content if p.type == "image"]
    resp = run(complete_once(local_config(server.url, "anthropic", max_images=3), req))
    assert resp.images_dropped == 3
    body = server.bodies()[-1]["body"]
    assert _images("anthropic", body) == all_images[-3:]
    texts = [b["text"] for b in body["messages"][0]["content"] if b["type"] == "text"]
    assert sum("image omitted" in t for t in texts) == 3
    resp = run(complete_once(local_config(server.url, "anthropic"), req))
    assert resp.images_dropped == 0


# --- retries, Retry-After, faults --------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["429", "500", "hang", "malformed", "empty"])
def test_each_transport_fault_is_retried(server, kind):
    server.configure(faults={"first_tries": 1, "kinds": [kind], "retry_after_s": 0.2, "hang_s": 30})
    cfg = local_config(server.url, "openai", timeouts={"request_s": 0.6})
    req = iphyre_request(4)
    resp = run(complete_once(cfg, req))
    assert resp.retries == 1  # a hang: the try was cut at request_s (the server would hang 30 s) and retried
    assert resp.text == run(MockModel().complete(req)).text
    st = server.stats()
    assert st["requests"] == 2 and st["faults"] == {kind: 1}
    if kind == "429":
        gap = st["arrivals"][1] - st["arrivals"][0]
        assert gap >= 0.2  # Retry-After honoured (the backoff alone would be <= 0.1 s here): a lower bound, which load cannot break


def test_prose_fault_is_an_answer_not_an_error(server):
    server.configure(faults={"first_tries": 1, "kinds": ["prose"]})
    resp = run(complete_once(local_config(server.url, "gemini"), iphyre_request(4)))
    assert resp.text == PROSE_REPLY and resp.retries == 0


def test_retries_are_bounded_and_raise_model_error(server):
    server.configure(faults={"rate": 1.0, "kinds": ["500"]})
    cfg = local_config(server.url, "anthropic", retry={"max_retries": 2, "base_delay_s": 0.01, "max_delay_s": 0.02})
    with pytest.raises(ModelError) as e:
        run(complete_once(cfg, iphyre_request(0)))
    assert e.value.retries == 2 and e.value.kind == "http_500" and "after 2 retries" in str(e.value)
    assert server.stats()["requests"] == 3


def test_a_retry_after_above_the_cap_fails_the_request_at_once(server):
    """`Retry-After: 3600` is not waited out (nor cut short and retried): the request fails at
    once, one try, as a model error the scheduler re-queues."""
    server.configure(faults={"rate": 1.0, "kinds": ["429"], "retry_after_s": 3600})
    cfg = local_config(server.url, "openai", retry={"max_retry_after_s": 60, "base_delay_s": 0.01})
    with pytest.raises(ModelError) as e:
        run(complete_once(cfg, iphyre_request(0)))
    assert server.stats()["requests"] == 1
    assert e.value.kind == "retry_after" and "asks to wait 3600 s, longer than max_retry_after_s (60 s)" in str(e.value)
    # within the cap it is waited out
    server.configure(faults={"rate": 0.0, "first_tries": 1, "kinds": ["429"], "retry_after_s": 0.3})
    server.reset()
    assert run(complete_once(cfg, iphyre_request(1))).retries == 1
    arrivals = server.stats()["arrivals"]
    assert arrivals[1] - arrivals[0] >= 0.3


def test_a_dripped_body_is_cut_at_the_try_deadline(server):
    """A 200 whose body arrives a byte a second: each try ends at request_s (the whole
    response), and the request at its total deadline, retries included."""
    server.configure(faults={"rate": 1.0, "kinds": ["drip"], "drip_s": 1.0})
    cfg = local_config(server.url, "openai", timeouts={"request_s": 0.8, "total_s": 2.0},
                       retry={"max_retries": 10, "base_delay_s": 0.01, "max_delay_s": 0.02})
    with pytest.raises(ModelError) as e:
        run(complete_once(cfg, iphyre_request(0)))
    assert e.value.kind in ("timeout", "deadline"), str(e.value)
    assert "whole response" in str(e.value) or "2 s" in str(e.value)
    assert 2 <= server.stats()["requests"] <= 3  # 0.8 s tries within 2 s


def test_first_byte_deadline(server):
    server.configure(faults={"first_tries": 1, "kinds": ["hang"], "hang_s": 30})
    cfg = local_config(server.url, "openai", timeouts={"first_byte_s": 0.4, "request_s": 5.0},
                       retry={"base_delay_s": 0.01})
    resp = run(complete_once(cfg, iphyre_request(2)))
    assert resp.retries == 1 and server.stats()["faults"] == {"hang": 1}  # the hung try was cut at first_byte_s


def test_waiting_requests_are_counted(server):
    """What the progress line shows: requests waiting for the rate limit and before a retry."""
    server.configure(faults={"first_tries": 1, "kinds": ["429"], "retry_after_s": 1.0})
    cfg = local_config(server.url, "openai", rate_limits={"requests_per_min": 60, "burst": 1},
                       retry={"max_retry_after_s": 5})

    async def go():
        client = client_from_config(cfg)
        seen = []
        try:
            calls = [asyncio.ensure_future(client.complete(iphyre_request(i))) for i in range(3)]
            while not all(c.done() for c in calls):
                seen.append(await client.activity())
                await asyncio.sleep(0.05)
            await asyncio.gather(*calls)
            return seen, await client.activity()
        finally:
            await client.close()

    seen, after = run(go())
    assert max(a["rate_limited"] for a in seen) >= 1 and max(a["retrying"] for a in seen) >= 1
    # a retry says why and for how long: the 429's Retry-After (1 s, plus up to 10 % jitter)
    retrying = [a for a in seen if a["retrying"]]
    assert {a["retry_reason"] for a in retrying} == {"429"} and 0 < max(a["retry_wait_s"] for a in retrying) <= 1.1
    assert after["rate_limited"] == after["retrying"] == after["answering_slow"] == 0


def test_connection_refused_is_retried_then_model_error():
    cfg = local_config("http://127.0.0.1:9", "openai", retry={"max_retries": 1, "base_delay_s": 0.01})
    with pytest.raises(ModelError) as e:
        run(complete_once(cfg, iphyre_request(0)))
    assert e.value.kind == "connection" and e.value.retries == 1


def test_fault_injection_is_deterministic_from_the_seed(server):
    server.configure(seed=5, faults={"rate": 0.5, "kinds": ["500", "empty", "malformed"]})
    reqs = [iphyre_request(i % 8, run=i // 8) for i in range(24)]

    async def go():
        # 20 retries: at a 50% fault rate, failing for good would take 21 faults in a row.
        client = client_from_config(local_config(server.url, "openai", retry={"max_retries": 20, "base_delay_s": 0.0}))
        try:
            return [(await client.complete(r)).retries for r in reqs]
        finally:
            await client.close()

    first = run(go())
    faults1 = server.stats()["faults"]
    server.reset()
    assert run(go()) == first and server.stats()["faults"] == faults1
    assert 0 < sum(first) < 3 * len(reqs)


def test_usage_and_cost(server):
    cfg = local_config(server.url, "openai", price={"input_per_mtok": 2.5, "output_per_mtok": 10.0})
    resp = run(complete_once(cfg, iphyre_request(0)))
    u = resp.usage
    assert u.input_tokens > 500  # two rendered images count
    assert u.cost_usd == pytest.approx((u.input_tokens * 2.5 + u.output_tokens * 10.0) / 1e6)


# --- secrets ------------------------------------------------------------------------------------------


def test_fake_key_never_leaks(server, monkeypatch, caplog, capsys):
    caplog.set_level(logging.DEBUG)
    monkeypatch.setenv("DEEPPHY_TEST_KEY", FAKE_KEY)
    server.configure(require_key_env="DEEPPHY_TEST_KEY")
    seen: list[str] = []
    for provider in ("openai", "anthropic", "gemini"):
        cfg = local_config(server.url, provider, api_key_env="DEEPPHY_TEST_KEY")
        client = client_from_config(cfg)
        seen += [repr(client), str(client), repr(cfg), cfg.model_dump_json(), repr(client.__dict__)]
        assert FAKE_KEY.encode() not in pickle.dumps(client)
        assert run(complete_once(cfg, iphyre_request(0))).text  # the key is accepted
    # a wrong key: 401 fails at once, and the message does not echo any key
    monkeypatch.setenv("DEEPPHY_OTHER_KEY", FAKE_KEY[::-1])
    for provider in ("openai", "anthropic", "gemini"):  # 401, 401, Gemini's 400 API_KEY_INVALID
        cfg = local_config(server.url, provider, api_key_env="DEEPPHY_OTHER_KEY")
        with pytest.raises(AccessDenied) as e:
            run(complete_once(cfg, iphyre_request(0)))
        assert e.value.kind == "denied" and e.value.retries == 0
        assert f"model local-{provider} at {cfg.resolved_base_url} refused the key in $DEEPPHY_OTHER_KEY" in str(e.value)
        seen += [str(e.value), repr(e.value)]
    seen += [str(e.value), repr(e.value)]
    # failures after retries
    server.configure(require_key_env=None, faults={"rate": 1.0, "kinds": ["500", "malformed", "hang"], "hang_s": 5})
    with pytest.raises(ModelError) as e:
        run(complete_once(local_config(server.url, "gemini", api_key_env="DEEPPHY_TEST_KEY",
                                       timeouts={"request_s": 0.3}, retry={"max_retries": 2, "base_delay_s": 0.01}),
                          iphyre_request(0)))
    seen += [str(e.value), repr(e.value), str(pickle.loads(pickle.dumps(e.value)))]
    out = capsys.readouterr()
    seen += [out.out, out.err, caplog.text, str(server.bodies()), str(server.stats())]
    assert not [s for s in seen if FAKE_KEY in s or FAKE_KEY[::-1] in s]


def test_a_model_worker_without_the_run_directory_is_sent_image_bytes(tmp_path):
    """Key frames travel by file name only to a worker that can read the driver's files;
    any other gets the same request with every image's bytes, in the same order."""
    from deepphy.chat import Image, ImagePart
    from deepphy.models import ModelResponse
    from deepphy.scheduler import WorkerModel

    request = iphyre_request(history_frames=2)
    by_file = []
    for m in request.messages:
        content = []
        for p in m.content:
            if isinstance(p, ImagePart) and p.image.name.startswith("past"):
                path = tmp_path / f"{p.image.name}.png"
                path.write_bytes(p.image.png)
                p = ImagePart(image=Image(name=p.image.name, caption=p.image.caption, file=str(path)))
            content.append(p)
        by_file.append(m.model_copy(update={"content": content}))
    request_by_file = request.model_copy(update={"messages": by_file})

    class Worker:  # stands in for the actor handle: `complete.remote(request)` is awaitable
        def __init__(self):
            self.sent = []
            self.complete = self

        def remote(self, req):
            self.sent.append(req)
            done = asyncio.get_running_loop().create_future()
            done.set_result(ModelResponse(text="[]"))
            return done

    def images(req):
        return [(p.image.name, p.image.png, p.image.file) for m in req.messages for p in m.content
                if isinstance(p, ImagePart)]

    for shares_files in (True, False):
        worker = Worker()
        asyncio.run(WorkerModel(worker, shares_files).complete(request_by_file))
        (sent,) = worker.sent
        if shares_files:
            assert sum(file is not None for _, _, file in images(sent)) == 2
        else:
            assert images(sent) == [(name, png, None) for name, png, _ in images(request)]
