"""The run directory: append-only log, torn-line repair, config checks, locking."""

import numpy as np
import pytest

from deepphy.config import RunConfig
from deepphy.runs.records import AttemptRecord
from deepphy.runs.store import ATTEMPTS, RunDirError, RunStore, read_config, read_records


def record(task="support", attempt=1):
    return AttemptRecord(env="iphyre", task=task, run=0, attempt=attempt, model="mock", format="vla", seed=0,
                         steps=[], success=False)


def test_append_and_read_back(tmp_path):
    cfg = RunConfig(runs=1)
    with RunStore.create_or_resume(tmp_path / "r", cfg) as store:
        store.append(record(attempt=1))
        store.append(record(attempt=2))
    assert [r.attempt for r in read_records(tmp_path / "r")] == [1, 2]
    assert read_config(tmp_path / "r") == cfg


def test_torn_last_line_is_ignored_then_repaired(tmp_path):
    cfg = RunConfig(runs=1)
    with RunStore.create_or_resume(tmp_path, cfg) as store:
        store.append(record(attempt=1))
    log = tmp_path / ATTEMPTS
    full = record(attempt=2).model_dump_json()
    with open(log, "ab") as f:  # what a kill -9 in the middle of a write leaves behind
        f.write(full[: len(full) // 2].encode())
    assert [r.attempt for r in read_records(tmp_path)] == [1]
    with RunStore.create_or_resume(tmp_path, cfg) as store:
        store.append(record(attempt=2))
    assert [r.attempt for r in read_records(tmp_path)] == [1, 2]
    assert log.read_bytes().count(b"\n") == 2


def test_resume_with_other_config_is_refused_and_nothing_written(tmp_path):
    with RunStore.create_or_resume(tmp_path, RunConfig(runs=1)) as store:
        store.append(record())
    before = {p: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    with pytest.raises(RunDirError, match="runs: 1 -> 2"):
        RunStore.create_or_resume(tmp_path, RunConfig(runs=2))
    assert {p: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before


def test_second_writer_is_refused(tmp_path):
    cfg = RunConfig(runs=1)
    with RunStore.create_or_resume(tmp_path, cfg):
        with pytest.raises(RunDirError, match="in use"):
            RunStore.create_or_resume(tmp_path, cfg)


def test_unreadable_directories(tmp_path):
    with pytest.raises(RunDirError, match="does not exist"):
        read_config(tmp_path / "nope")
    with pytest.raises(RunDirError, match="no config.json"):
        read_config(tmp_path)
    (tmp_path / "config.json").write_text("{not json")
    with pytest.raises(RunDirError, match="not a valid run config"):
        read_config(tmp_path)
    (tmp_path / ATTEMPTS).write_text("garbage\n")
    with pytest.raises(RunDirError, match="not a valid attempt record"):
        read_records(tmp_path)
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(RunDirError, match="not a directory"):
        RunStore.create_or_resume(f, RunConfig())


def test_key_frames_come_back_as_files_not_bytes(tmp_path):
    """The store hands earlier key frames to prompts by file name: nothing is read until a
    model client encodes the request (`load`)."""
    from deepphy.chat import Image

    store = RunStore.create_or_resume(tmp_path / "run", RunConfig(env="iphyre", model="mock"))
    png = Image.from_array("f", "c", np.zeros((4, 6, 3), np.uint8)).png
    rel = store.write_frame("support", 0, 1, "s1_outcome", png)
    image = store.frame_image(rel, "the outcome")
    assert image.png == b"" and image.file == str((tmp_path / "run" / rel).resolve())
    assert image.load() == png and image.size == (6, 4)
    assert image.loaded().png == png and image.loaded().file is None
    with pytest.raises(ValueError, match="exactly one"):
        Image(name="x", caption="c")
    with pytest.raises(ValueError, match="exactly one"):
        Image(name="x", caption="c", png=png, file=image.file)
