"""Endpoints that do not answer well (issue 43): a silent or dripping endpoint is cut at the
default deadlines and named on the progress line; a body is capped while it is read; a
request the endpoint rejects (vLLM's 400) stops the run with one line instead of being
retried. Deadlines of minutes are run on a virtual clock (tests/virtual_time.py): the model
server and the client share its loop, over real HTTP on loopback."""

from __future__ import annotations

import asyncio

import pytest
import yaml

from deepphy.config import RunConfig, RuntimeOptions
from deepphy.metrics.live import endpoint_waits
from deepphy.models import ModelConfig, ModelError, RequestRejected, client_from_config
from deepphy.models.config import Timeouts
from deepphy.models.http import MAX_BODY_BYTES, SLOW_ANSWER_S
from deepphy.testing.model_server import MockServer, ServerConfig, ServerThread
from models_support import iphyre_request
from virtual_time import virtual_time


def endpoint(port: int, **fields) -> ModelConfig:
    """A models-file entry for the local server with every timeout and retry at its default."""
    return ModelConfig.model_validate({"name": "slow", "provider": "openai", "model": "deepphy-mock",
                                       "base_url": f"http://127.0.0.1:{port}/v1", "send_context": True, **fields})


async def watched(coro, watch, every_s: float = 5.0):
    """Await `coro`, calling `watch()` every `every_s` (virtual) seconds meanwhile; returns
    (the result or the error raised, the virtual seconds it took)."""
    loop = asyncio.get_running_loop()
    started = loop.time()
    task = asyncio.ensure_future(coro)
    while not task.done():
        await watch(loop.time() - started)
        await asyncio.wait([task], timeout=every_s)
    return (task.exception() or task.result()), loop.time() - started


@pytest.mark.parametrize("fault", ["drip", "hang"])
def test_the_default_deadlines_bound_a_dripping_or_silent_endpoint(fault):
    """A body that comes one byte a second (the old defaults let each try run 120 s and a
    request 360 s, six requests an episode: ~37 minutes), or no answer at all: with the
    default timeouts and retries a request ends within request_s + 60 s, and while it
    waits its client says for what (the progress line's figures)."""
    defaults = Timeouts()
    with virtual_time() as loop:
        server = MockServer(ServerConfig(faults={"rate": 1.0, "kinds": [fault], "drip_s": 1.0, "hang_s": 3600}))

        async def go():
            port = await server.start("127.0.0.1", 0)
            client = client_from_config(endpoint(port))
            seen = []

            async def watch(t):
                seen.append((t, await client.activity()))

            try:  # watched often: a back-off between two tries lasts 0.5-1 s
                return *(await watched(client.complete(iphyre_request(0)), watch, every_s=0.25)), seen
            finally:
                await client.close()
                await server.stop()

        error, took, seen = loop.run_until_complete(go())
    assert isinstance(error, ModelError) and error.kind in ("timeout", "deadline"), error
    assert took <= defaults.request_s + 60 + 1, took
    tries = server.stats()["requests"]
    if fault == "drip":  # each try ends body_s after its status line (the last: where the request's time ends)
        assert tries >= 3 and "no whole " in str(error)
    else:  # no status line: the first try waits request_s, and is named from SLOW_ANSWER_S on
        assert tries >= 2
        slow = [a for t, a in seen if SLOW_ANSWER_S + 5 < t < defaults.request_s]
        assert slow and all(a["answering_slow"] == 1 and a["answer_wait_s"] > SLOW_ANSWER_S for a in slow)
        assert endpoint_waits({**slow[-1], "config": {"model": "slow"}}).startswith("slow: 1 request waiting for an "
                                                                                      "answer for ")
    retrying = [a for _, a in seen if a["retrying"]]
    assert retrying and {a["retry_reason"] for a in retrying} == {"timeout"}


def test_a_silent_endpoint_holds_an_episode_minutes_and_the_progress_line_says_so(tmp_path):
    """The episode as the scheduler runs it: every request of every re-run of the attempt
    times out. It is left unfinished within minutes (it was 6 requests x 360 s + 62 s of
    back-off), and the progress line is never silent about it for longer than SLOW_ANSWER_S
    (a re-run's new request is named once it is that old; the re-queue itself is a warning line)."""
    from deepphy.protocol import LocalEnv
    from deepphy.plan import plan
    from deepphy.runs.store import RunStore
    from deepphy.scheduler import MODEL_REQUEUES, Scheduler

    config = RunConfig(env="iphyre", model="slow", runs=1, tasks=["support"])
    the_plan = plan(config)
    env = LocalEnv(the_plan.make_env())  # in this loop: no thread for the clock to outrun
    with virtual_time() as loop:
        server = MockServer(ServerConfig(faults={"rate": 1.0, "kinds": ["hang"], "hang_s": 3600}))

        async def go():
            port = await server.start("127.0.0.1", 0)
            client = client_from_config(endpoint(port))
            store = RunStore.create_or_resume(tmp_path / "run", config)
            scheduler = Scheduler(the_plan, RuntimeOptions(progress=False), store, [], client, None, local_env=env)
            lines = []

            async def watch(t):
                lines.append((t, endpoint_waits({**await client.activity(), "config": {"model": "slow"}})))

            try:
                _, took = await watched(scheduler.run([]), watch, every_s=10.0)
                return scheduler, took, lines
            finally:
                store.close()
                await client.close()
                await server.stop()

        scheduler, took, lines = loop.run_until_complete(go())
    assert scheduler.recorded == 0 and len(scheduler.failed) == 1 and "support run 0" in scheduler.failed[0]
    deadline = Timeouts().deadline_s
    assert took <= (MODEL_REQUEUES + 1) * deadline + 2 + 4 + 1 <= 10 * 60, took
    assert server.stats()["requests"] >= MODEL_REQUEUES + 1
    assert all(line.startswith("slow: 1 request waiting ") for _, line in lines if line), lines
    silent, since = 0.0, 0.0  # the longest stretch of progress lines that name no wait
    for t, line in lines:
        since = since if not line else t
        silent = max(silent, t - since)
    assert any(lines) and silent <= SLOW_ANSWER_S + 10 + 1, lines


async def _huge_body_server(declare_length: bool, sent: list[int]):
    """A server whose answer is 64 MB of JSON string, written 1 MB at a time (counted in
    `sent`) until the client stops reading."""
    total = 64 * 1024**2

    async def answer(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        head = await reader.readuntil(b"\r\n\r\n")
        length = int(next(line.split(b":")[1] for line in head.split(b"\r\n") if line.lower().startswith(b"content-length")))
        await reader.readexactly(length)
        writer.write(b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nConnection: close\r\n"
                     + (f"Content-Length: {total}\r\n".encode() if declare_length else b"") + b"\r\n")
        try:
            for _ in range(total // 2**20):
                writer.write(b'"' + b"x" * (2**20 - 2) + b'"')
                await writer.drain()
                sent[0] += 2**20
        except (ConnectionError, OSError):
            pass
        finally:
            writer.close()

    return await asyncio.start_server(answer, "127.0.0.1", 0)


@pytest.mark.parametrize("declare_length", [False, True])
def test_a_huge_body_is_cut_while_it_is_read(declare_length):
    """A 64 MB answer (the old client read a 50 MB one whole before cutting it): reading
    stops past MAX_BODY_BYTES, and one that says its length up front is not read at all."""
    sent = [0]

    async def go():
        server = await _huge_body_server(declare_length, sent)
        port = server.sockets[0].getsockname()[1]
        client = client_from_config(endpoint(port, retry={"max_retries": 0}))
        try:
            with pytest.raises(ModelError) as e:
                await client.complete(iphyre_request(0))
            await asyncio.sleep(0.2)  # the server notices the closed connection
            return e.value
        finally:
            await client.close()
            server.close()

    error = asyncio.run(go())
    assert error.kind == "too_large" and f"{MAX_BODY_BYTES:,}" in str(error)
    # what the kernel's socket buffers hold beyond what was read is all the server got out
    assert sent[0] < (1 if declare_length else 2) * MAX_BODY_BYTES + 8 * 2**20, sent[0]


@pytest.mark.parametrize("limit,words", [({"max_images_per_prompt": 1}, "At most 1 image(s) may be provided"),
                                         ({"max_model_len": 500}, "This model's maximum context length is 500 tokens")])
def test_a_request_the_endpoint_rejects_is_not_retried(limit, words):
    """vLLM's 400 for more images than it takes per prompt or a prompt longer than its
    context: one try, and an error that says what the server said and what to change."""
    with ServerThread(ServerConfig(**limit)) as server:
        async def go():
            client = client_from_config(endpoint(server.port))
            try:
                await client.complete(iphyre_request(0, history_frames=2))
            finally:
                await client.close()

        with pytest.raises(RequestRejected) as e:
            asyncio.run(go())
        assert server.stats()["requests"] == 1
    message = str(e.value)
    assert e.value.kind == "rejected" and e.value.retries == 0
    assert f"model slow at http://127.0.0.1:{server.port}/v1 rejected the request: HTTP 400: {words}" in message
    assert "this one sent 4; the entry's max_images is 50" in message and "\n" not in message


def test_a_rejected_request_stops_the_run_with_one_line_and_writes_nothing(tmp_path, capsys):
    """The run stops at the first 400, as for a refused key (it re-ran the attempt 6 times,
    back-off up to a minute, then told to resume a run directory that was never made)."""
    from deepphy.cli import main

    with ServerThread(ServerConfig(max_images_per_prompt=1)) as server:
        models = tmp_path / "models.yaml"
        models.write_text(yaml.safe_dump({"models": [
            {"name": "vllm", "provider": "openai", "model": "m", "base_url": f"{server.url}/v1", "send_context": True}]}))
        out = tmp_path / "run"
        status = main(["run", "--in-process", "--model", "vllm", "--models-file", str(models), "--tasks", "support",
                       "--runs", "1", "--no-progress", "--out", str(out)])
        requests = server.stats()["requests"]
    captured = capsys.readouterr()
    assert status == 2 and requests == 1
    (line,) = captured.err.splitlines()
    assert line.startswith("deepphy: error: model vllm at ") and "At most 1 image(s)" in line, line
    assert not out.exists() and str(out) not in captured.out + captured.err


def test_the_summary_never_names_a_run_directory_that_was_not_written(tmp_path):
    from deepphy.cli import run_summary
    from deepphy.runner import RunOutcome

    lines, status = run_summary(RunOutcome(out=tmp_path / "never", episodes_total=1, episodes_done=0, new_records=0,
                                           unfinished=["support run 0: slow: HTTP 500"]))
    assert status == 1 and not any(str(tmp_path / "never") in line for line in lines), lines
    assert lines[0].startswith("nothing was recorded (0/1 episodes complete") and "start it" in lines[-1]
    (tmp_path / "kept").mkdir()
    lines, _ = run_summary(RunOutcome(out=tmp_path / "kept", episodes_total=1, episodes_done=0, new_records=0,
                                      unfinished=["x"]))
    assert lines[0].startswith(f"run directory: {tmp_path / 'kept'} (0/1") and "resume it" in lines[-1]
