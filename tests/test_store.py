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


# -- a run directory is untrusted input ---------------------------------------------------

import json  # noqa: E402
import os  # noqa: E402

from deepphy.runs.records import KeyFrame  # noqa: E402
from deepphy.runs.store import (  # noqa: E402
    check_records, inside, problems, repair,
)

PNG = bytes.fromhex("89504e470d0a1a0a") + b"\0" * 40


def episode(store, task="support", attempts=(1, 2, 3), run=0):
    """Failed attempts with a key frame each, written through the store."""
    for a in attempts:
        rel = store.write_frame(task, run, a, "s1_outcome", PNG)
        store.append(AttemptRecord(env="iphyre", task=task, run=run, attempt=a, model="mock", format="vla", seed=0,
                                   steps=[], success=False, key_frames=[KeyFrame(path=rel, caption="c")]))


def raw_record(**fields):
    r = record().model_dump(mode="json")
    r.update(fields)
    return json.dumps(r)


@pytest.mark.parametrize("bad", [
    {"key_frames": [{"path": "../../../../../etc/passwd", "caption": "x"}]},
    {"key_frames": [{"path": "/etc/passwd", "caption": "x"}]},
    {"key_frames": [{"path": "frames/support/../../config.json", "caption": "x"}]},
    {"steps": [{"step": 1, "prompt": "../../../secret/x", "raw_output": ""}]},
    {"task": "../etc"},
    {"attempt": 0},
])
def test_records_naming_files_outside_the_run_are_refused_with_their_line(tmp_path, bad):
    with RunStore.create_or_resume(tmp_path, RunConfig(runs=1)) as store:
        store.append(record(attempt=1))
    with open(tmp_path / ATTEMPTS, "a") as f:
        f.write(raw_record(**bad) + "\n")
    with pytest.raises(RunDirError) as e:
        read_records(tmp_path)
    message = str(e.value)
    assert f"{tmp_path / ATTEMPTS}:2 is not a valid attempt record" in message and "\n" not in message


def test_inside_follows_symlinks_and_refuses_what_leads_out(tmp_path):
    root = (tmp_path / "run").resolve()
    (root / "frames" / "a").mkdir(parents=True)
    (root / "frames" / "a" / "f.png").write_bytes(PNG)
    (tmp_path / "secret").mkdir()
    (tmp_path / "secret" / "k.png").write_bytes(b"secret")
    os.symlink(tmp_path / "secret", root / "frames" / "out")
    os.symlink(tmp_path / "secret" / "k.png", root / "frames" / "a" / "link.png")
    os.symlink(root / "frames" / "a" / "f.png", root / "frames" / "a" / "ok.png")
    assert inside(root, "frames/a/f.png") == root / "frames/a/f.png"
    assert inside(root, "frames/a/ok.png") == root / "frames/a/f.png"  # a symlink within the run
    for rel in ("frames/out/k.png", "frames/a/link.png", "../secret/k.png", "/etc/passwd", "frames/a\0/f.png"):
        assert inside(root, rel) is None, rel


def test_a_history_frame_that_leads_out_of_the_run_is_refused_on_resume(tmp_path):
    """A key frame symlinked to a file elsewhere would be sent to the model as an image."""
    cfg = RunConfig(runs=1)
    with RunStore.create_or_resume(tmp_path / "run", cfg) as store:
        episode(store)
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"private")
    frame = tmp_path / "run" / "frames" / "support" / "r0_a2_s1_outcome.png"
    frame.unlink()
    frame.symlink_to(secret)
    records = read_records(tmp_path / "run")
    with pytest.raises(RunDirError) as e:
        check_records(tmp_path / "run", records, k_max=10)
    assert ("the key frame frames/support/r0_a2_s1_outcome.png of task support run 0 attempt 2 leads out of the "
            "run directory") in str(e.value) and "deepphy repair" in str(e.value)
    # a finished episode's history is never shown again: its frames do not block a resume
    check_records(tmp_path / "run", records, k_max=3)


def test_a_symlinked_frames_directory_is_refused_before_anything_is_written(tmp_path):
    cfg = RunConfig(runs=1)
    with RunStore.create_or_resume(tmp_path / "run", cfg) as store:
        episode(store)
    elsewhere = tmp_path / "elsewhere"
    (tmp_path / "run" / "frames").rename(elsewhere)
    (tmp_path / "run" / "frames").symlink_to(elsewhere)
    with pytest.raises(RunDirError, match="frames leads out of the run directory"):
        RunStore.create_or_resume(tmp_path / "run", cfg)


def test_a_missing_frame_is_reported_with_the_fix(tmp_path):
    with RunStore.create_or_resume(tmp_path, RunConfig(runs=1)) as store:
        episode(store)
    (tmp_path / "frames" / "support" / "r0_a3_s1_outcome.png").unlink()
    with pytest.raises(RunDirError) as e:
        check_records(tmp_path, read_records(tmp_path), k_max=10)
    assert "frames/support/r0_a3_s1_outcome.png of task support run 0 attempt 3 is missing; restore it, or run " \
           f"`deepphy repair {tmp_path}`" in str(e.value)


def test_a_gap_in_the_attempts_is_an_error_and_repair_keeps_the_attempts_before_it(tmp_path):
    with RunStore.create_or_resume(tmp_path, RunConfig(runs=1)) as store:
        episode(store, attempts=(1, 2, 3, 4, 5, 6))
        episode(store, task="hinder", attempts=(1, 2))
    lines = (tmp_path / ATTEMPTS).read_bytes().splitlines(keepends=True)
    del lines[3]  # attempt 4 of support: a deleted line
    (tmp_path / ATTEMPTS).write_bytes(b"".join(lines))
    records = read_records(tmp_path)
    with pytest.raises(RunDirError) as e:
        check_records(tmp_path, records, k_max=10)
    assert "task support run 0 has attempts 1, 2, 3, 5, 6: attempt 4 is missing" in str(e.value)
    done = repair(tmp_path, k_max=10)
    assert done.dropped_lines == 2 and [(p.task, p.attempt) for p in done.episodes] == [("support", 4)]
    assert done.backup.read_bytes() == b"".join(lines)  # nothing is lost
    kept = read_records(tmp_path)
    assert sorted((r.task, r.attempt) for r in kept) == [("hinder", 1), ("hinder", 2), ("support", 1),
                                                           ("support", 2), ("support", 3)]
    check_records(tmp_path, kept, k_max=10)
    assert repair(tmp_path, k_max=10).dropped_lines == 0


def test_duplicates_and_unreadable_lines_are_repaired(tmp_path):
    with RunStore.create_or_resume(tmp_path, RunConfig(runs=1)) as store:
        episode(store, attempts=(1, 2, 3))
    lines = (tmp_path / ATTEMPTS).read_bytes().splitlines(keepends=True)
    (tmp_path / ATTEMPTS).write_bytes(b"".join([*lines, lines[1], b"{not a record}\n"]))
    with pytest.raises(RunDirError, match="not a valid attempt record"):
        read_records(tmp_path)
    done = repair(tmp_path, k_max=10)
    assert done.unreadable == 1 and done.dropped_lines == 4  # attempts 2, 3, the copy of 2, the bad line
    assert [r.attempt for r in read_records(tmp_path)] == [1]
    assert problems(tmp_path, read_records(tmp_path), k_max=10) == []


def test_a_non_empty_directory_that_holds_no_run_is_refused(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(RunDirError, match="is not empty and holds no run .*notes.txt.*choose another --out"):
        RunStore.create_or_resume(tmp_path, RunConfig())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_duplicate_task_ids_are_refused():
    with pytest.raises(ValueError, match="task id.s. given more than once: support"):
        RunConfig(tasks=["support", "hinder", "support"])


def test_a_failed_first_open_leaves_nothing(tmp_path):
    store = RunStore.claim(tmp_path / "new", RunConfig())
    assert (tmp_path / "new" / "config.json").exists()
    store.discard()
    assert not (tmp_path / "new").exists()
