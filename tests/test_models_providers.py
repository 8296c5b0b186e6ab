"""A provider added from outside deepphy, as a plug-in adds one (docs/providers.md): a toy wire
format with its client and a loopback server of its own, declared by one `ProviderSpec` and
`register_provider`. A models entry naming it validates with its defaults, a run builds its
client from the registry and gets MOCK's answers through it over HTTP (on Ray too), and the
dry run counts its images with its own rule."""

from __future__ import annotations

import asyncio
import json
import os
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest
import yaml

from dashboard_support import IPHYRE_TASKS, mock_run
from deepphy.agents import MockModel, make_agent, mock_text
from deepphy.chat import ImagePart, Message
from deepphy.cli import main
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.estimate import estimate
from deepphy.models import ModelRequest, ModelsFileError, load_models
from deepphy.models.http import HTTPModelClient
from deepphy.models.limiter import RateLimits
from deepphy.models.providers import ProviderSpec, register_provider, unregister_provider
from deepphy.models.wire import CONTEXT_HEADER, decode_context, png_b64
from deepphy.runner import evaluate
from deepphy.runs.store import read_records
from models_support import iphyre_request

# Ray workers inherit the environment of the process that starts Ray (the session fixture):
# the key is set at import time, before any test runs.
TOY_KEY_ENV = "DEEPPHY_TOY_PROVIDER_KEY"
TOY_KEY = "toy-key-4c1e9b"
os.environ[TOY_KEY_ENV] = TOY_KEY
TOY_IMAGE_TOKENS = 1000  # what the toy provider bills for any image


# -- the toy provider: its wire format, its image-token rule, its declaration ---------------------


class ToyClient(HTTPModelClient):
    """POST {base}/reply {"model", "limit", "turns": [{"role", "text", "images": [base64 PNG]}]}
    -> {"answer", "used": {"in", "out"}}; the key in `X-Toy-Key`."""

    def url(self) -> str:
        return f"{self.config.resolved_base_url}/reply"

    def auth_headers(self, key: str) -> dict[str, str]:
        return {"X-Toy-Key": key}

    def build_body(self, request: ModelRequest, messages: list[Message], max_tokens: int) -> dict:
        turns = [{"role": m.role, "text": m.text,
                  "images": [png_b64(p.image.load()) for p in m.content if isinstance(p, ImagePart)]}
                 for m in messages]
        return {"model": self.config.model, "limit": max_tokens, "turns": turns}

    def parse(self, data: dict) -> tuple[str, int | None, int | None]:
        return data["answer"], data["used"]["in"], data["used"]["out"]


def toy_image_tokens(width: int, height: int) -> int:
    return TOY_IMAGE_TOKENS


TOY = ProviderSpec(
    name="toy", title="Toy JSON", client=f"{__name__}:ToyClient", base_url=None, max_images=16,
    image_tokens=toy_image_tokens, api_key_env=TOY_KEY_ENV, rate_limits=RateLimits(requests_per_min=6000),
)


# -- its server: MOCK's answer to the context a loopback client sends ------------------------------


class ToyServer:
    """The toy wire format on 127.0.0.1, answering with MOCK (`send_context` entries only)."""

    def __init__(self) -> None:
        self.requests: list[dict] = []
        server = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # noqa: N802 - http.server's name
                body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
                server.requests.append({"path": self.path, "key": self.headers.get("X-Toy-Key"), "body": body})
                if self.path != "/toy/reply" or self.headers.get("X-Toy-Key") != TOY_KEY:
                    return self.answer(401 if self.path == "/toy/reply" else 404, {"error": "no"})
                text = mock_text(decode_context(self.headers[CONTEXT_HEADER]))
                images = sum(len(t["images"]) for t in body["turns"])
                self.answer(200, {"answer": text, "used": {"in": 7 + images, "out": len(text) // 4}})

            def answer(self, status: int, payload: dict) -> None:
                data = json.dumps(payload).encode()
                self.send_response(status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def log_message(self, *args) -> None:  # quiet
                pass

        self._http = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self._http.server_address[1]}"
        self._thread = threading.Thread(target=self._http.serve_forever, daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._http.shutdown()
        self._http.server_close()


@pytest.fixture(scope="module", autouse=True)
def toy_registered():
    register_provider(TOY)
    yield TOY
    unregister_provider(TOY.name)


@pytest.fixture(scope="module")
def server():
    s = ToyServer()
    yield s
    s.close()


def write_models(path, *entries: dict) -> str:
    path.write_text(yaml.safe_dump({"models": list(entries)}))
    return str(path)


@pytest.fixture(scope="module")
def models_file(server, tmp_path_factory) -> str:
    return write_models(tmp_path_factory.mktemp("models") / "models.yaml", {
        "name": "toy-local", "provider": "toy", "model": "toy-1", "base_url": server.url + "/toy",
        "send_context": True, "price": {"input_per_mtok": 2.0, "output_per_mtok": 8.0},
        "retry": {"max_retries": 1, "base_delay_s": 0.05, "max_delay_s": 0.2},
    })


def test_a_models_entry_naming_a_registered_provider_validates_with_its_defaults(server, tmp_path):
    models = load_models(write_models(
        tmp_path / "models.yaml",
        {"name": "toy-local", "provider": "toy", "model": "toy-1", "base_url": server.url + "/toy/"},
        {"name": "toy-own", "provider": "toy", "model": "toy-1", "base_url": server.url + "/toy",
         "api_key_env": None, "rate_limits": {"max_concurrent": 2}, "max_images": 3},
    ))
    toy, own = models["toy-local"], models["toy-own"]
    assert toy.spec is TOY and toy.resolved_base_url == server.url + "/toy"
    # what the entry leaves out is the provider's ...
    assert (toy.api_key_env, toy.rate_limits.requests_per_min, toy.resolved_max_images) == (TOY_KEY_ENV, 6000, 16)
    # ... and what it states is its own (`api_key_env: null`: no key at all)
    assert (own.api_key_env, own.rate_limits.requests_per_min, own.rate_limits.max_concurrent) == (None, None, 2)
    assert own.resolved_max_images == 3
    # the toy declares no public endpoint: an entry must name one
    with pytest.raises(ModelsFileError, match="toy-nowhere: provider toy has no public endpoint: set base_url"):
        load_models(write_models(tmp_path / "nowhere.yaml",
                                 {"name": "toy-nowhere", "provider": "toy", "model": "toy-1"}))


def test_an_unknown_provider_is_one_line_naming_the_registered_ones(tmp_path, capsys):
    models = write_models(tmp_path / "models.yaml", {"name": "typo", "provider": "toi", "model": "m",
                                                     "base_url": "http://127.0.0.1:9/v1"})
    assert main(["run", "--env", "iphyre", "--model", "typo", "--models-file", models, "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("deepphy: error: ")
    assert "models.0.provider: unknown provider 'toi'; registered: anthropic, gemini, openai, toy" in err


def test_a_runs_client_for_it_is_built_from_the_registry_and_round_trips_a_request(server, models_file):
    client = make_agent("toy-local", models_file)
    assert type(client) is ToyClient
    request = iphyre_request(0, history_frames=1)
    server.requests.clear()

    async def ask():
        try:
            return await client.complete(request)
        finally:
            await client.close()

    response = asyncio.run(ask())
    assert response.text == asyncio.run(MockModel().complete(request)).text  # MOCK's answer, through the toy
    (seen,) = server.requests
    images = [png_b64(p.image.load()) for m in request.messages for p in m.content if isinstance(p, ImagePart)]
    assert seen["key"] == TOY_KEY and seen["body"]["model"] == "toy-1" and seen["body"]["limit"] == request.max_tokens
    assert [i for t in seen["body"]["turns"] for i in t["images"]] == images and images
    assert (response.usage.input_tokens, response.usage.output_tokens) == (7 + len(images), len(response.text) // 4)


def test_a_ray_run_on_the_toy_provider_makes_mocks_decisions(ray_cluster, server, models_file, tmp_path_factory,
                                                             tmp_path):
    """The model worker builds the client in its own process: the driver's registration goes with it."""
    config = RunConfig(env="iphyre", model="toy-local", runs=2, seed=3, tasks=IPHYRE_TASKS)
    server.requests.clear()
    outcome = evaluate(config, tmp_path / "run", RuntimeOptions(progress=False, env_workers=2,
                                                                models_file=models_file))
    assert outcome.complete, outcome.unfinished

    def decisions(path) -> list[str]:
        views = [r.deterministic_view() for r in read_records(path)]
        return sorted(json.dumps({k: v for k, v in view.items() if k != "model"}, sort_keys=True) for view in views)

    records = read_records(tmp_path / "run")
    assert decisions(tmp_path / "run") == decisions(mock_run(tmp_path_factory))
    assert len(server.requests) == sum(r.decisions for r in records) > 0
    # the toy's usage (7 + its images) and the entry's price reached the records
    assert all(r.model_stats.usage.input_tokens > 7 and r.model_stats.usage.cost_usd > 0 for r in records if r.decisions)


def test_the_dry_run_counts_its_images_with_its_own_rule(models_file, tmp_path, capsys):
    # The same provider with images free: what the toy's rule adds is all the difference.
    register_provider(TOY.model_copy(update={"name": "toy-text", "image_tokens": lambda width, height: 0}))
    try:
        (entry,) = yaml.safe_load(Path(models_file).read_text())["models"]
        both = write_models(tmp_path / "models.yaml", entry, entry | {"name": "toy-text-local", "provider": "toy-text"})
        config = RunConfig(env="iphyre", model="toy-local", runs=1, tasks=["support", "hinder"])
        toy = estimate(config, both)
        free = estimate(config.model_copy(update={"model": "toy-text-local"}), both)
    finally:
        unregister_provider("toy-text")
    assert toy.images_first > 0 and toy.images_max <= TOY.max_images
    assert toy.tokens_first - free.tokens_first == pytest.approx(toy.images_first * TOY_IMAGE_TOKENS)
    assert toy.tokens_max - free.tokens_max == pytest.approx(toy.images_max * TOY_IMAGE_TOKENS)
    assert toy.cost_input_max == pytest.approx(toy.input_tokens_max * 2.0 / 1e6)
    # and the command says it
    assert main(["run", "--env", "iphyre", "--tasks", "support,hinder", "--runs", "1", "--model", "toy-local",
                 "--models-file", models_file, "--out", str(tmp_path / "run"), "--dry-run"]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("iphyre toy-local vla"))
    assert f"${toy.cost_input_max:,.2f}" in row
