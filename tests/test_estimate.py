"""`deepphy run --dry-run`: what a run will ask of its model, measured on the rendered
prompts, without calling it or writing anything."""

import json
import re
import socket

import pytest

from dashboard_support import IPHYRE_TASKS, mock_run
from deepphy.cli import main
from deepphy.config import RunConfig
from deepphy.estimate import estimate
from deepphy.models.providers import provider_spec
from deepphy.chat import ImagePart
from deepphy.runs.store import read_prompt, read_records


def test_image_token_rules_match_the_providers_worked_examples():
    openai, anthropic, gemini = (
        provider_spec(name).image_tokens for name in ("openai", "anthropic", "gemini"))
    # OpenAI's guide: 1024x1024 high detail -> 765; 2048x4096 -> 1105
    assert openai(1024, 1024) == 765
    assert openai(2048, 4096) == 1105
    # Anthropic's table: 1092x1092 -> ~1590 (w*h/750); larger images are scaled to 1568 px first
    assert anthropic(1092, 1092) == 1590
    assert anthropic(3136, 3136) == anthropic(1568, 1568)
    # Gemini: 258 up to 384x384, else 258 per 768x768 tile
    assert gemini(384, 384) == 258
    assert gemini(1000, 700) == 2 * 258


def test_bounds_hold_for_a_real_run(ray_cluster, tmp_path_factory):
    run = mock_run(tmp_path_factory)  # MOCK on six I-PHYRE games, 2 runs, seed 3
    config = RunConfig(env="iphyre", model="mock", runs=2, seed=3, tasks=IPHYRE_TASKS)
    est = estimate(config, sample=len(IPHYRE_TASKS))
    records = read_records(run)
    requests = sum(len(r.steps) for r in records)
    assert est.episodes == 12 and est.attempts_max == 120
    assert est.requests_min <= requests <= est.requests_max
    # expected: MOCK's requests per episode on the sampled tasks (its run 0), which is what this run's 0 asked
    assert est.requests_expected == pytest.approx(config.runs * sum(len(r.steps) for r in records if r.run == 0))
    images = {}  # prompt digest -> images in it
    for r in records:
        for s in r.steps:
            messages = read_prompt(run, r.task, r.run, s.prompt)
            images[s.prompt] = sum(isinstance(part, ImagePart) for m in messages for part in m.content)
    first = [images[r.steps[0].prompt] for r in records if r.attempt == 1]
    assert est.images_first == pytest.approx(sum(first) / len(first))
    assert max(images.values()) <= est.images_max
    assert est.tokens_first is None and est.cost_input_max is None  # a baseline: no model, no tokens


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # nothing listens once this closes


def test_cli_prices_a_models_file_endpoint_that_is_not_listening(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DRYRUN_TEST_KEY", raising=False)  # a dry run needs no key
    models = tmp_path / "models.yaml"
    port = _closed_port()
    models.write_text(json.dumps({"models": [
        {"name": "priced", "provider": "anthropic", "model": "x", "base_url": f"http://127.0.0.1:{port}/v1",
         "api_key_env": "DRYRUN_TEST_KEY", "rate_limits": {"requests_per_min": 60},
         "price": {"input_per_mtok": 3.0, "output_per_mtok": 15.0}},
        {"name": "unpriced", "provider": "openai", "model": "y", "base_url": f"http://127.0.0.1:{port}/v1"},
    ]}))
    out = tmp_path / "run"
    argv = ["run", "--env", "iphyre", "--tasks", "support,hinder", "--runs", "1", "--models-file", str(models),
            "--out", str(out), "--dry-run"]
    assert main([*argv, "--model", "priced"]) == 0
    text = capsys.readouterr().out
    row = next(line for line in text.splitlines() if line.startswith("iphyre priced vla"))
    # 2 episodes x 10 attempts x 1 decision; 20 requests paced at 60/min (61 s windows): 19 s at
    # least; expected: MOCK's requests on these tasks, at 10 s a reply, two at once (2 episodes)
    expected = re.search(r"\b2\s+20\s+2\.\.20\s+(\d+)\s", row)
    assert expected and 2 <= int(expected[1]) <= 20
    n = int(expected[1])
    assert row.rstrip().endswith(f"{max((n - 1) * 61 / 60, n * 10 / 2) / 60:.1f} min  {19 * 61 / 60 / 60:.1f} min")
    est = estimate(RunConfig(env="iphyre", model="priced", runs=1, tasks=["support", "hinder"]), str(models))
    assert f"${est.cost_input_max:,.2f}" in row and f"${est.cost_output_max:,.2f}" in row
    assert est.cost_output_max == pytest.approx(20 * 1024 * 15 / 1e6)
    assert est.cost_input_max == pytest.approx(est.input_tokens_max * 3 / 1e6)
    assert est.tokens_first < est.tokens_max  # later attempts carry the failed attempts' key frames
    assert "no model was called" in text
    assert main([*argv, "--model", "unpriced"]) == 0
    assert "unknown price" in capsys.readouterr().out
    assert not out.exists()  # nothing written
    assert main([*argv, "--model", "nonesuch"]) == 2
    assert "nonesuch" in capsys.readouterr().err


def test_a_suites_expected_time_is_its_slowest_endpoints_sum():
    from dataclasses import replace

    from deepphy.estimate import render, suite_time

    base = estimate(RunConfig(env="iphyre", model="mock", runs=1, tasks=["support"]))
    cells = [replace(base, label=f"c{i}", endpoint=e, requests_expected=n, requests_max=m, expected_min=n / rpm,
                     rate_limit_min=m / rpm)
             for i, (e, rpm, n, m) in enumerate([("a", 60, 300, 600), ("a", 60, 300, 600), ("b", 120, 900, 1200)])]
    # a: 600 expected at 60/min = 10 min (bound 20); b: 900 at 120/min = 7.5 min (bound 10)
    assert suite_time(cells) == ["10 min", "20 min"]
    total = next(line for line in render(cells).splitlines() if line.startswith("total"))
    assert total.endswith("10 min  20 min")
    assert suite_time([base]) == ["-", "-"]  # a baseline has no limit


def _limiter_pace(limits, requests: int, input_tokens: int, max_tokens: int, reply_s: float, output_tokens: int,
                  in_flight: int) -> float:
    """Virtual seconds the real limiter (AsyncRateLimiter, as a run's model client uses it)
    takes until the last of `requests` requests is answered: `in_flight` callers, each
    asking for input + max_tokens, holding the grant `reply_s`, then releasing it with
    input + output tokens used. On a virtual clock (tests/virtual_time.py)."""
    import asyncio

    from deepphy.models.limiter import AsyncRateLimiter
    from virtual_time import virtual_time

    with virtual_time() as loop:
        limiter = AsyncRateLimiter(limits, clock=loop.time)
        left = [requests]

        async def caller() -> None:
            while left[0] > 0:
                left[0] -= 1
                grant = await limiter.acquire(input_tokens + max_tokens, lease_s=3600)
                await asyncio.sleep(reply_s)
                await limiter.release(grant, input_tokens + output_tokens)

        async def run() -> float:
            started = loop.time()
            await asyncio.gather(*(caller() for _ in range(in_flight)))
            return loop.time() - started

        return loop.run_until_complete(run())


# (limits, requests, input tokens per request, max_tokens, reply s, output tokens, episodes in flight)
PACES = {
    "requests/min": ({"requests_per_min": 600}, 1500, 2000, 1024, 0.0, 0, 256),
    "tokens/min": ({"tokens_per_min": 200_000}, 1000, 5000, 1024, 0.0, 0, 256),
    "tokens/min, reservation held while answered": ({"tokens_per_min": 450_000}, 2000, 4000, 1024, 10.0, 1024, 256),
    "max_tokens reservation near the limit": ({"tokens_per_min": 30_000}, 200, 4000, 16_000, 0.0, 0, 64),
    "max_concurrent": ({"max_concurrent": 8}, 400, 3000, 1024, 10.0, 200, 256),
    "the run's episodes in flight": ({"requests_per_min": 10_000}, 300, 3000, 1024, 10.0, 200, 6),
    "all at once (gpt-4o's shipped limits)": ({"requests_per_min": 500, "tokens_per_min": 450_000,
                                               "max_concurrent": 64}, 1000, 8000, 1024, 10.0, 1024, 256),
}


@pytest.mark.parametrize("case", PACES)
def test_the_estimated_time_is_the_limiters_own_pace(case):
    """The dry-run's time under each limit the limiter enforces, and all of them together,
    against the limiter itself granting the same requests (it once used requests/min alone:
    the paper suite's 252M input tokens for gpt-4o were "2.5-3.1 h", 9 h at its 450k TPM)."""
    from deepphy.estimate import limit_seconds
    from deepphy.models.config import RateLimits

    limits, n, tokens_in, max_tokens, reply_s, out, in_flight = PACES[case]
    limits = RateLimits(**limits)
    estimated = limit_seconds(limits, n, n * tokens_in, max_tokens, reply_s, out, in_flight)
    simulated = _limiter_pace(limits, n, tokens_in, max_tokens, reply_s, out, in_flight)
    assert estimated == pytest.approx(simulated, rel=0.05, abs=reply_s + 1), (estimated, simulated)


def test_the_dry_run_honours_tokens_per_minute(tmp_path):
    """An endpoint whose tokens/min binds before its requests/min: the least time is the
    run's input tokens over the limit, not its requests over requests/min."""
    models = tmp_path / "models.yaml"
    models.write_text(json.dumps({"models": [
        {"name": "tight", "provider": "openai", "model": "x", "base_url": "http://127.0.0.1:9/v1",
         "rate_limits": {"requests_per_min": 600, "tokens_per_min": 20_000}}]}))
    est = estimate(RunConfig(env="iphyre", model="tight", runs=1, tasks=["support", "hinder"]), str(models))
    by_tokens = est.input_tokens_max / 20_000  # minutes, had every token gone through at the limit
    assert est.rate_limit_min >= 0.9 * by_tokens > 2 * est.requests_max / 600
    assert est.expected_min is not None and est.expected_min > 0
