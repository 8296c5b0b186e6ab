"""The paper's models in the shipped models file: groups, retirements, each provider family's
wire format against the local model server, and the self-hosted entry within its server's
image and context limits."""

from __future__ import annotations

import asyncio
import datetime
import os
import re
from urllib.parse import urlparse

import jsonschema
import pytest
import yaml

from deepphy.agents import MockModel, expand_models, retiring
from deepphy.cli import main
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.models import ModelConfig, ModelError, ModelsFileError, client_from_config, load_models
from deepphy.models.config import load_groups, load_models_file
from deepphy.models.wire import image_tokens
from deepphy.prompts import PromptFormat
from deepphy.testing.model_server import ServerConfig, ServerThread
from models_support import BASES, iphyre_request
from test_models import SCHEMAS, _images

KEY_ENV = "DEEPPHY_PAPER_TEST_KEY"
FAKE_KEY = "sk-deepphy-PAPER-fake-0b1c2d3e4f"
os.environ[KEY_ENV] = FAKE_KEY  # before Ray starts: its workers inherit the environment
SELF_HOSTED = "qwen2.5-vl-7b"


@pytest.fixture(scope="module")
def server():
    with ServerThread(ServerConfig(record_bodies=20)) as s:
        yield s


@pytest.fixture(autouse=True)
def _clean(request):
    if "server" in request.fixturenames:
        s = request.getfixturevalue("server")
        s.configure(max_images_per_prompt=None, max_model_len=None)
        s.reset()


def at_server(name: str, server, **changes) -> ModelConfig:
    """The shipped entry `name`, pointed at the local server (which answers with MOCK)."""
    entry = load_models()[name]
    return entry.model_copy(update={
        "base_url": server.url + BASES[entry.provider], "send_context": True,
        "api_key_env": entry.api_key_env and KEY_ENV, **changes,
    })


def complete(config: ModelConfig, request):
    async def once():
        client = client_from_config(config)
        try:
            return await client.complete(request)
        finally:
            await client.close()

    return asyncio.run(once())


# --- the shipped file ------------------------------------------------------------------------


def test_the_paper_group_is_its_open_and_closed_entries_each_priced_and_limited():
    models, groups = load_models(), load_groups()
    assert groups["paper"] == groups["paper-open"] + groups["paper-closed"]
    assert len(set(groups["paper"])) == len(groups["paper"]) == 16  # the 16 the paper's tables name
    for name in groups["paper-closed"]:
        m = models[name]
        assert m.api_key_env and m.price.input_per_mtok > 0 and m.price.output_per_mtok > 0, name
        assert m.rate_limits.requests_per_min and m.rate_limits.tokens_per_min, name
        assert m.retirement is None or (m.retirement.successor and m.retirement.source), name
    ports = set()
    for name in groups["paper-open"]:
        m = models[name]
        url = urlparse(m.resolved_base_url)
        assert url.hostname == "127.0.0.1" and m.api_key_env is None, name  # your own server, no key
        assert m.max_images and m.max_context_tokens and "price" in m.model_fields_set, name
        ports.add(url.port)
    assert len(ports) == len(groups["paper-open"])  # one server each: the whole group can run at once


def test_groups_are_checked_when_the_file_is_read(tmp_path):
    entry = {"name": "a", "provider": "openai", "model": "m"}
    for groups, said in [
        ({"g": ["a", "nope"]}, "group g names 'nope'"),
        ({"g": ["h"], "h": ["g"]}, "contains itself"),
        ({"a": ["a"]}, "group a has the name of a model entry"),
        ({"g": []}, "group g is empty"),
        ({"mock": ["a"]}, "'mock' is built in"),
    ]:
        f = tmp_path / "m.yaml"
        f.write_text(yaml.safe_dump({"models": [entry], "groups": groups}))
        with pytest.raises(ModelsFileError, match=said):
            load_models_file(f)


def test_groups_expand_in_order_each_model_once(tmp_path):
    f = tmp_path / "m.yaml"
    f.write_text(yaml.safe_dump({
        "models": [{"name": n, "provider": "openai", "model": n} for n in ("a", "b", "c")],
        "groups": {"ab": ["a", "b"], "all": ["ab", "c", "a"]},
    }))
    assert expand_models(["all"], f) == ["a", "b", "c"]
    assert expand_models(["c", "ab", "mock", "b"], f) == ["c", "a", "b", "mock"]
    assert expand_models(["mock", "mock-uniform"], tmp_path / "absent.yaml") == ["mock", "mock-uniform"]


def test_a_retirement_reads_as_retired_on_and_after_its_date():
    entry = load_models()["gpt-4v"]
    r = entry.retirement
    before, on = r.date - datetime.timedelta(days=1), r.date
    assert r.status(before) == f"retires {r.date}" and r.status(on) == f"retired {r.date}"
    assert "is deprecated" in r.notice(entry.name, entry.model, before)
    assert "was retired" in r.notice(entry.name, entry.model, on) and r.successor in r.notice(entry.name, entry.model, on)
    assert [c.name for c in retiring(["mock", "gpt-4v", "qwen2.5-vl-7b"])] == ["gpt-4v"]


# --- the command line --------------------------------------------------------------------------


def retiring_models_file(tmp_path, server_url: str = "http://127.0.0.1:9/v1") -> str:
    f = tmp_path / "models.yaml"
    old = {"name": "old", "provider": "openai", "model": "old-1", "base_url": server_url,
           "rate_limits": {"requests_per_min": 60}, "price": {"input_per_mtok": 1.0, "output_per_mtok": 2.0},
           "retirement": {"date": "2020-01-02", "successor": "new-1", "source": "a test"}}
    new = {"name": "new", "provider": "openai", "model": "new-1", "base_url": server_url,
           "rate_limits": {"requests_per_min": 120}, "price": {"input_per_mtok": 1.0, "output_per_mtok": 2.0}}
    f.write_text(yaml.safe_dump({"models": [old, new], "groups": {"both": ["old", "new"]}}))
    return str(f)


def test_a_run_naming_a_retired_model_says_so_in_one_line_before_ray_starts(tmp_path, capsys, monkeypatch):
    import deepphy.runner

    models = retiring_models_file(tmp_path)
    seen = []

    def evaluate(config, *args, **kw):  # where Ray would start: what has the user been told?
        seen.append((config.model, capsys.readouterr().err))
        raise KeyboardInterrupt

    monkeypatch.setattr(deepphy.runner, "evaluate", evaluate)
    argv = ["run", "--env", "iphyre", "--tasks", "support", "--runs", "1", "--models-file", models,
            "--out", str(tmp_path / "run")]
    assert main([*argv, "--model", "old"]) == 130
    (model, err), = seen
    lines = err.strip().splitlines()
    assert model == "old" and len(lines) == 1
    assert lines[0].startswith("deepphy: warning: model old (old-1) was retired by its provider on 2020-01-02")
    assert "successor: new-1" in lines[0]
    capsys.readouterr()  # "interrupted"
    assert main([*argv, "--model", "new"]) == 130
    assert seen[1] == ("new", "")  # an active model: nothing to say
    assert main([*argv, "--model", "both"]) == 2  # a group of two is not one run directory
    assert "several models need --suite" in capsys.readouterr().err


def test_a_suite_dry_run_of_a_group_sums_each_model_and_marks_the_retired(tmp_path, capsys):
    suite = tmp_path / "suite.yaml"
    suite.write_text(yaml.safe_dump({"name": "tiny", "envs": [{"env": "iphyre", "tasks": ["support", "hinder"]}],
                                     "formats": ["vla"], "runs": 1}))
    models = retiring_models_file(tmp_path)
    assert main(["run", "--suite", str(suite), "--model", "both,mock", "--models-file", models, "--dry-run",
                 "--out", str(tmp_path / "root")]) == 0
    out, err = capsys.readouterr()
    assert err.count("deepphy: warning:") == 1 and "model old (old-1) was retired" in err
    cells = {line.split()[0]: line.split() for line in out.splitlines() if "/iphyre/vla" in line}
    assert list(cells) == ["old/iphyre/vla", "new/iphyre/vla", "mock/iphyre/vla"]
    summary = out[out.index("model  "):].splitlines()
    rows = {line.split()[0]: line for line in summary[2:6]}
    assert list(rows) == ["old", "new", "mock", "total"]
    assert rows["old"].rstrip().endswith("retired 2020-01-02") and "retire" not in rows["new"]
    # each model's times: its cells' (one here) at its own limits (old 60/min, new 120/min)
    times = {name: re.findall(r"[\d.]+ min", " ".join(cells[f"{name}/iphyre/vla"])) for name in ("old", "new")}
    assert re.findall(r"[\d.]+ min", rows["old"]) == times["old"] and re.findall(r"[\d.]+ min", rows["new"]) == times["new"]
    assert times["old"] != times["new"]
    assert re.findall(r"[\d.]+ min", rows["total"]) == times["old"]  # the slowest endpoint
    assert "total (3 models)" in rows["total"]
    assert not (tmp_path / "root").exists()


# --- each provider family's wire format, with the paper's entries ------------------------------


@pytest.mark.parametrize("name", ["gpt-4v", "o4-mini", "claude-opus-4", "gemini-2.0-flash"])
def test_a_paper_entry_round_trips_through_the_server_in_its_wire_format(server, name):
    config = at_server(name, server)
    request = iphyre_request(2, fmt=PromptFormat.WM, history_frames=2)
    response = complete(config, request)
    assert response.text == asyncio.run(MockModel().complete(request)).text  # the server's MOCK answer, parsed
    (record,) = server.bodies()
    body, provider = record["body"], config.provider
    jsonschema.validate(body, SCHEMAS[provider])
    assert _images(provider, body) == [p.image.png for m in request.messages for p in m.content if p.type == "image"]
    if provider == "gemini":  # the entry's model id: in the path for Gemini, in the body for the others
        assert record["path"] == f"/v1beta/models/{config.model}:generateContent"
        assert body["generationConfig"]["maxOutputTokens"] == (config.max_tokens or request.max_tokens)
    else:
        assert body["model"] == config.model
    if name == "o4-mini":  # a reasoning model: its own token field, no temperature
        assert body["max_completion_tokens"] == config.max_tokens and "temperature" not in body
    usage = response.usage
    assert usage.input_tokens > 0 and usage.cost_usd == pytest.approx(config.price.cost(usage.input_tokens,
                                                                                         usage.output_tokens))


# --- the self-hosted entry within its server's limits -------------------------------------------


def test_the_self_hosted_entry_sends_at_most_the_servers_image_limit(server):
    server.configure(max_images_per_prompt=2)  # vLLM --limit-mm-per-prompt '{"image": 2}'
    request = iphyre_request(1, history_frames=4)  # 4 key frames + 2 observation images
    shown = [p.image.png for m in request.messages for p in m.content if p.type == "image"]
    response = complete(at_server(SELF_HOSTED, server, max_images=2), request)
    assert response.images_dropped == 4 and response.text == asyncio.run(MockModel().complete(request)).text
    assert _images("openai", server.bodies()[-1]["body"]) == shown[-2:]  # the newest two
    with pytest.raises(ModelError) as refused:  # the entry as shipped (16 images) exceeds this server's 2
        complete(at_server(SELF_HOSTED, server, retry={"max_retries": 0}), request)
    assert refused.value.kind == "rejected" and "At most 2 image(s)" in str(refused.value)


def test_the_self_hosted_entry_replaces_old_images_by_text_to_fit_the_context(server):
    request = iphyre_request(1, history_frames=4)  # 6 images
    tokens = complete(at_server(SELF_HOSTED, server), request).usage.input_tokens  # as the server counts them
    image = image_tokens(request.messages[1].images[0].load())
    context = tokens + 1024 - image  # this prompt and max_tokens 1024 exceed it by an image
    server.configure(max_model_len=context)  # vLLM --max-model-len
    with pytest.raises(ModelError) as refused:  # the entry without its limit: the server refuses the request
        complete(at_server(SELF_HOSTED, server, max_tokens=1024, retry={"max_retries": 0}), request)
    assert refused.value.kind == "rejected" and "maximum context length" in str(refused.value)
    response = complete(at_server(SELF_HOSTED, server, max_context_tokens=context, max_tokens=1024), request)
    assert 1 <= response.images_dropped < 6 and response.usage.input_tokens + 1024 <= context
    body = server.bodies()[-1]["body"]
    assert len(_images("openai", body)) == 6 - response.images_dropped  # the oldest went
    texts = [p["text"] for m in body["messages"] if isinstance(m["content"], list) for p in m["content"]
             if p["type"] == "text"]
    assert sum("image omitted (context length limit)" in t for t in texts) == response.images_dropped
    tiny = at_server(SELF_HOSTED, server, max_context_tokens=1100, max_tokens=1024)
    with pytest.raises(ModelError, match="do not fit max_context_tokens 1100") as hopeless:  # not even the text
        complete(tiny, request)
    assert hopeless.value.kind == "context"


@pytest.mark.slow
def test_a_run_of_the_self_hosted_entry_against_a_server_of_two_images_equals_the_mock_run(
        server, ray_cluster, tmp_path):
    from deepphy.runner import evaluate
    from deepphy.runs.store import read_records

    server.configure(max_images_per_prompt=2)
    entry = at_server(SELF_HOSTED, server, max_images=2).model_dump(mode="json")
    models = tmp_path / "models.yaml"
    models.write_text(yaml.safe_dump({"models": [entry]}))
    runtime = RuntimeOptions(progress=False, env_workers=2, models_file=str(models))
    config = RunConfig(env="iphyre", model=SELF_HOSTED, runs=1, seed=5, tasks=["support", "hinder"])
    assert evaluate(config, tmp_path / "qwen", runtime).complete
    assert evaluate(config.model_copy(update={"model": "mock"}), tmp_path / "mock", runtime).complete
    records = read_records(tmp_path / "qwen")
    assert all(r.model_stats.model_errors == 0 and r.model_stats.retries == 0 for r in records)
    assert server.stats(arrivals=False)["status"] == {"200": sum(len(r.steps) for r in records)}
    frames = {r.key: len(r.key_frames) for r in records}
    assert any(r.model_stats.images_dropped for r in records)
    for r in records:  # attempt k shows the frames of attempts 1..k-1 and the 2 observation images
        shown = sum(frames[(r.task, r.run, k)] for k in range(1, r.attempt)) + 2
        assert r.model_stats.images_dropped == shown - 2

    def actions(path):
        return sorted((r.task, r.attempt, tuple(s.raw_output for s in r.steps), r.success)
                      for r in read_records(path))

    assert actions(tmp_path / "qwen") == actions(tmp_path / "mock")
