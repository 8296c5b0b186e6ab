"""Every image of every prompt is stored once, content-addressed, in the run directory
(images/<sha256>.png): the exact request a model received can be rebuilt from the run
directory alone, runs from before still read, and the export names each decision's
input images."""

from __future__ import annotations

import asyncio
import hashlib
import json
import os
import re
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml

from dashboard_support import rewrite_prompt, to_old_layout
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.chat import ImagePart
from deepphy.envs import get_spec
from deepphy.export import CHAT_FIELDS, CHAT_FILE, DATA_FILE, export
from deepphy.models.clients import OpenAIChatClient
from deepphy.models.wire import CONTEXT_HEADER, decode_context
from deepphy.prompts.base import CURRENT_OBSERVATION
from deepphy.runner import evaluate
from deepphy.runs.store import ATTEMPTS, RunDirError, read_image, read_prompt, read_records, stored_prompt_json
from deepphy.testing.model_server import ServerConfig, ServerThread

RUNTIME = RuntimeOptions(progress=False, env_workers=1)


@pytest.mark.parametrize("env, tasks, attempts", [
    ("iphyre", ["support", "hinder"], 3),  # history: earlier attempts' key frames
    ("cuttherope", ["b1_l03", "b2_l05"], None),  # history: earlier decisions' scenes
])
def test_a_request_rebuilt_from_the_run_directory_equals_what_the_server_received(
        ray_cluster, tmp_path, env, tasks, attempts):
    with ServerThread(ServerConfig(seed=1, record_bodies=1000)) as server:
        models = tmp_path / "models.yaml"
        models.write_text(yaml.safe_dump({"models": [{
            "name": "local", "provider": "openai", "model": "deepphy-mock", "base_url": server.url + "/v1",
            "send_context": True, "timeouts": {"request_s": 10.0, "connect_s": 2.0},
        }]}))
        run = tmp_path / "run"
        config = RunConfig(env=env, model="local", runs=1, seed=2, tasks=tasks, max_attempts=attempts)
        outcome = evaluate(config, run, RuntimeOptions(progress=False, env_workers=1, models_file=str(models)))
        assert outcome.complete
        received = [b for b in server.bodies() if b["path"] == "/v1/chat/completions"]
    records = {r.key: r for r in read_records(run)}
    assert all(r.model_stats.images_dropped == 0 and r.model_stats.retries == 0 for r in records.values())
    assert len(received) == sum(len(r.steps) for r in records.values())
    histories = 0
    for body in received:
        headers = {k.lower(): v for k, v in body["headers"].items()}
        ctx = decode_context(headers[CONTEXT_HEADER.lower()])
        step = records[(ctx.task_id, ctx.run, ctx.attempt)].steps[ctx.step - 1]
        messages = read_prompt(run, ctx.task_id, ctx.run, step.prompt)
        assert [OpenAIChatClient.message(m) for m in messages] == body["body"]["messages"]
        assert "data:image/png;base64," in json.dumps(body["body"])  # the images themselves are compared
        parts = [p for m in messages for p in m.content]
        current = next(i for i, p in enumerate(parts) if getattr(p, "text", None) == CURRENT_OBSERVATION)
        histories += any(hasattr(p, "image") for p in parts[:current])
    assert histories, "some request showed history images"
    # Stored once: one file per distinct image; a history key frame is a second name of its frame file.
    images = sorted((run / "images").iterdir())
    assert all(hashlib.sha256(p.read_bytes()).hexdigest() == p.stem for p in images)
    frames = {f.stat().st_ino for f in (run / "frames").rglob("*.png")}
    if env == "iphyre":
        assert any(p.stat().st_ino in frames for p in images), "key frames are hard-linked, not copied"


@pytest.fixture(scope="module")
def cuttherope_run(ray_cluster, tmp_path_factory):
    run = tmp_path_factory.mktemp("ctr") / "run"
    config = RunConfig(env="cuttherope", model="mock", runs=2, seed=4, tasks=["b1_l01", "b1_l03", "b2_l05", "b5_l02"])
    assert evaluate(config, run, RUNTIME).complete
    return run


def check_export(run: Path, out: Path) -> list[dict]:
    """Every row's observation images exist and are the images its prompt held; datasets loads it."""
    summary = export([run], out)
    rows = pq.read_table(out / DATA_FILE).to_pylist()
    assert len(rows) == summary.rows == sum(len(r.steps) for r in read_records(run))
    for row in rows:
        messages = read_prompt(run, row["task"], row["run"], row["prompt_digest"])
        parts = [p for m in messages for p in m.content]
        current = next(i for i, p in enumerate(parts) if getattr(p, "text", None) == CURRENT_OBSERVATION)
        observation = [p.image.png for p in parts[current:] if hasattr(p, "image")]
        assert row["observation_images"] and row["images_not_stored"] == 0
        assert [(out / p).read_bytes() for p in row["observation_images"]] == observation
        assert [(out / p).read_bytes() for p in row["images"]] == [i.png for m in messages for i in m.images]
    assert summary.images == len(list((out / "images").rglob("*.png")))
    by_digest = list((out / "images" / "sha256").iterdir())  # each prompt image once, named by its bytes
    assert all(hashlib.sha256(f.read_bytes()).hexdigest() == f.stem for f in by_digest)

    os.environ["HF_DATASETS_OFFLINE"] = os.environ["HF_HUB_OFFLINE"] = "1"
    import datasets

    ds = datasets.load_dataset("parquet", data_files=str(out / DATA_FILE), cache_dir=str(out.parent / "hf"))["train"]
    assert ds.num_rows == len(rows) and ds[0]["observation_images"] == rows[0]["observation_images"]
    import cv2

    assert cv2.imread(str(out / ds[0]["observation_images"][0])) is not None
    return rows


def test_export_of_a_cut_the_rope_run_names_every_input_image(cuttherope_run, tmp_path):
    rows = check_export(cuttherope_run, tmp_path / "ds")
    assert any(r["history_images"] for r in rows), "later decisions show earlier scenes"
    # The first observation of a task is one file, shared by its runs.
    firsts = {}
    for r in rows:
        if r["step"] == 1:
            firsts.setdefault(r["task"], set()).add(r["observation_images"][0])
    assert all(len(paths) == 1 for paths in firsts.values())


@pytest.mark.slow
def test_export_of_a_pooltool_run_names_every_input_image(ray_cluster, tmp_path):
    run = tmp_path / "run"
    config = RunConfig(env="pooltool", model="mock", runs=1, seed=4, tasks=["rack_000", "rack_001"])
    assert evaluate(config, run, RuntimeOptions(progress=False, env_workers=1, step_timeout_s=900)).complete
    rows = check_export(run, tmp_path / "ds")
    assert len(rows) > 2


def check_chat_export(run: Path, out: Path) -> list[dict]:
    """The chat layout: each row is the conversation `read_prompt` rebuilds (the request the
    model was sent), image by image, then the reply; datasets loads it and its images open."""
    summary = export([run], out, layout="chat")
    rows = pq.read_table(out / CHAT_FILE).to_pylist()
    records = {r.key: r for r in read_records(run)}
    assert len(rows) == summary.rows == sum(len(r.steps) for r in records.values())
    assert list(rows[0]) == [name for name, _, _ in CHAT_FIELDS]
    for row in rows:
        record = records[(row["task"], row["run"], row["attempt"])]
        step = record.steps[row["step"] - 1]
        *conversation, reply = row["messages"]
        assert reply == {"role": "assistant", "content": [{"type": "text", "text": step.raw_output, "image": None}]}
        sent = read_prompt(run, row["task"], row["run"], row["prompt_digest"])
        assert [m["role"] for m in conversation] == [m.role for m in sent]
        for mine, theirs in zip(conversation, sent):
            assert len(mine["content"]) == len(theirs.content)
            for part, p in zip(mine["content"], theirs.content):
                if isinstance(p, ImagePart):
                    assert part["type"] == "image" and (out / part["image"]).read_bytes() == p.image.png
                else:
                    assert part == {"type": "text", "text": p.text, "image": None}
        assert row["images"] == [p["image"] for m in conversation for p in m["content"] if p["type"] == "image"]
        assert row["observation_images"] and set(row["observation_images"]) <= set(row["images"])
        assert row["images_not_stored"] == 0
        assert (row["success"], row["valid"], row["stars"]) == (record.success, step.invalid_reason is None,
                                                                record.stars)
    # the dataset holds the conversations' images, each once, and nothing else
    files = {p.relative_to(out).as_posix() for p in (out / "images").rglob("*.png")}
    assert files == {p for r in rows for p in r["images"]} and summary.images == len(files)
    card = (out / "README.md").read_text()
    assert all(f"| `{name}` |" in card for name, _, _ in CHAT_FIELDS) and CHAT_FILE in card
    assert get_spec(rows[0]["env"]).title in card

    os.environ["HF_DATASETS_OFFLINE"] = os.environ["HF_HUB_OFFLINE"] = "1"
    import datasets
    from PIL import Image

    ds = datasets.load_dataset("parquet", data_files=str(out / CHAT_FILE), cache_dir=str(out.parent / "hf"))["train"]
    last = ds[len(rows) - 1]
    assert ds.num_rows == len(rows) and last["messages"] == rows[-1]["messages"]
    for path in last["images"]:
        with Image.open(out / path) as image:
            image.load()
            assert image.size[0] > 0 and image.mode in ("RGB", "RGBA")
    return rows


def test_chat_export_of_a_cut_the_rope_run_is_the_conversation_the_model_saw(cuttherope_run, tmp_path):
    rows = check_chat_export(cuttherope_run, tmp_path / "chat")
    assert any(r["history_images"] for r in rows) and any(r["step"] > 1 for r in rows)


def test_chat_export_of_a_phyre_run_is_the_conversation_the_model_saw(ray_cluster, tmp_path):
    run = tmp_path / "run"
    config = RunConfig(env="phyre", model="mock", runs=1, seed=0, limit=3, max_attempts=4)
    assert evaluate(config, run, RUNTIME).complete
    rows = check_chat_export(run, tmp_path / "chat")
    assert any(len(r["images"]) > len(r["observation_images"]) for r in rows), "later attempts show earlier ones"
    # the CLI writes the same
    from deepphy.cli import main

    assert main(["export", str(run), "--out", str(tmp_path / "cli"), "--layout", "chat"]) == 0
    assert pq.read_table(tmp_path / "cli" / CHAT_FILE).to_pylist() == rows


def test_a_run_from_before_stored_images_still_reads(cuttherope_run, tmp_path):
    """Old prompts (a file each, before the episode logs) hold "<image NAME: CAPTION>"
    placeholders and no images/: records, the export and the dashboard still read them;
    rebuilding a request says why it cannot."""
    old = tmp_path / "old"
    shutil.copytree(cuttherope_run, old)
    to_old_layout(old)
    shutil.rmtree(old / "images")
    for prompt in (old / "prompts").iterdir():
        messages = json.loads(prompt.read_text())
        for m in messages:
            m["content"] = [p if isinstance(p, str) else f"<image {p['name']}: {p['caption']}>" for p in m["content"]]
        prompt.write_text(json.dumps(messages, indent=1))
    assert read_records(old) == read_records(cuttherope_run)
    export([old], tmp_path / "ds")
    rows = pq.read_table(tmp_path / "ds" / DATA_FILE).to_pylist()
    assert all(r["images_not_stored"] >= 1 and not r["observation_images"] for r in rows)
    with pytest.raises(RunDirError, match="did not store"):
        read_prompt(old, rows[0]["task"], rows[0]["run"], rows[0]["prompt_digest"])
    export([old], tmp_path / "chat", layout="chat")  # its conversations say where an image was not kept
    chat = pq.read_table(tmp_path / "chat" / CHAT_FILE).to_pylist()
    assert all(r["images_not_stored"] >= 1 and not r["observation_images"] for r in chat)
    assert any(p["text"].startswith("<image not stored: ") for m in chat[0]["messages"] for p in m["content"])


def test_stored_images_are_validated_and_confined(cuttherope_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(cuttherope_run, run)
    first = read_records(run)[0]
    episode, digest = (first.task, first.run), first.steps[0].prompt
    stored = stored_prompt_json(run, *episode, digest)
    image = next(p["image"] for m in stored for p in m["content"] if isinstance(p, dict))
    target = run / "images" / f"{image}.png"
    target.write_bytes(target.read_bytes()[:-10])  # altered: its bytes no longer match its name
    with pytest.raises(RunDirError, match="is damaged: its bytes do not hash to its name"):
        read_prompt(run, *episode, digest)
    secret = tmp_path / "secret.png"
    shutil.copyfile(cuttherope_run / "images" / f"{image}.png", secret)
    target.unlink()
    target.symlink_to(secret)  # leads out of the run directory: not read
    with pytest.raises(RunDirError, match="leads out of the run directory"):
        read_image(run, image)
    with pytest.raises(RunDirError, match="leads out of the run directory"):
        read_prompt(run, *episode, digest)
    target.unlink()
    with pytest.raises(RunDirError, match="is missing"):
        read_prompt(run, *episode, digest)
    for bad in ("../config", "x" * 20, "0" * 19 + "/"):
        with pytest.raises(RunDirError):
            read_prompt(run, *episode, bad)
    with pytest.raises(RunDirError, match="is not an image digest"):
        read_image(run, "../" + image)
    # An edited prompt whose image reference is not a digest is not a stored prompt.
    line = json.dumps({"digest": digest, "messages": stored})
    rewrite_prompt(run, *episode, digest, re.sub(r'"image": "[0-9a-f]{64}"', '"image": "../../secret"', line, count=1))
    with pytest.raises(RunDirError, match="not a stored prompt"):
        read_prompt(run, *episode, digest)


def _first_image(run: Path, task: str, run_number: int) -> str:
    """The digest of the first image of the episode's first prompt (the task's first scene)."""
    first = next(r for r in read_records(run) if (r.task, r.run) == (task, run_number))
    stored = stored_prompt_json(run, task, run_number, first.steps[0].prompt)
    return next(p["image"] for m in stored for p in m["content"] if isinstance(p, dict))


def test_a_damaged_image_is_refused_by_every_reader_and_a_resume_writes_it_again(cuttherope_run, tmp_path, capsys,
                                                                                 caplog):
    """An image whose bytes no longer hash to its name: the dashboard does not serve it (one
    line, and the episode says why), the export refuses the run in one line and writes
    nothing, a prompt that shows it is not rebuilt; a resume that shows it again writes it
    again (it has its bytes), after which every prompt of the run is whole."""
    from aiohttp.test_utils import TestClient, TestServer

    from deepphy.cli import main
    from deepphy.dashboard.server import Dashboard, make_app
    from deepphy.dashboard.source import RunSource

    run = tmp_path / "run"
    shutil.copytree(cuttherope_run, run)
    task = read_records(run)[0].task
    image = _first_image(run, task, 0)
    (run / "images" / f"{image}.png").write_bytes(b"\x89PNG not the scene")
    damaged = f"{run}/images/{image}.png is damaged: its bytes do not hash to its name"

    with pytest.raises(RunDirError, match="is damaged"):
        read_prompt(run, task, 0, read_records(run)[0].steps[0].prompt)
    assert main(["export", str(run), "--out", str(tmp_path / "ds")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"deepphy: error: {damaged}") and err.count("\n") == 1, err
    assert not (tmp_path / "ds").exists()

    async def dashboard() -> tuple[int, str, list[dict]]:
        source = RunSource(run)
        async with TestClient(TestServer(make_app(Dashboard([source])))) as client:
            served = await client.get(f"/files/{source.id}/images/{image}.png")
            episode = await (await client.get(f"/api/runs/{source.id}/episode?task={task}&run=0")).json()
            parts = [p for prompt in episode["prompts"].values() for m in prompt for p in m["content"]
                     if p["type"] == "image"]
            return served.status, await served.text(), parts

    status, text, parts = asyncio.run(dashboard())
    assert status == 409 and text.startswith(damaged)
    shown = [p for p in parts if p.get("problem")]
    assert shown and all(p["file"] is None and p["problem"].startswith(damaged) for p in shown)
    assert any(p["file"] for p in parts)  # the intact ones are shown

    # The resume of an episode that shows the image again (the task's second run, set aside)
    lines = (run / ATTEMPTS).read_text().splitlines()
    (run / ATTEMPTS).write_text("".join(line + "\n" for line in lines if json.loads(line)["task"] != task
                                        or json.loads(line)["run"] != 1))
    config = RunConfig.model_validate_json((run / "config.json").read_text())
    assert evaluate(config, run, RUNTIME).complete
    assert f"{run}/images/{image}.png did not hash to its name; written again" in caplog.text
    assert hashlib.sha256((run / "images" / f"{image}.png").read_bytes()).hexdigest() == image
    assert len(read_records(run)) == len(lines)
    for r in read_records(run):
        for step in r.steps:
            read_prompt(run, r.task, r.run, step.prompt)  # every prompt whole again, the earlier run's too


def test_a_run_whose_images_lead_out_is_refused_by_the_export_as_by_a_resume(cuttherope_run, tmp_path, capsys):
    """images/ symlinked out of the run: the export said nothing and exported every row
    without its images; now it refuses in one line, as a resume does."""
    from deepphy.cli import main

    run = tmp_path / "run"
    shutil.copytree(cuttherope_run, run)
    shutil.move(run / "images", tmp_path / "elsewhere")
    (run / "images").symlink_to(tmp_path / "elsewhere")
    said = f"{run}/images leads out of the run directory (a symlink?); refusing to use it"
    assert main(["export", str(run), "--out", str(tmp_path / "ds")]) == 2
    assert capsys.readouterr().err == f"deepphy: error: {said}\n"
    assert not (tmp_path / "ds").exists()
    config = RunConfig.model_validate_json((run / "config.json").read_text())
    with pytest.raises(RunDirError) as refused:  # what a resume says
        evaluate(config, run, RUNTIME)
    assert str(refused.value) == said
