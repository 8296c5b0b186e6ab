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


# -- prompts: one log per episode -------------------------------------------------------

from deepphy.chat import Image, ImagePart, Message, TextPart  # noqa: E402
from deepphy.prompts import prompt_as_json, prompt_digest  # noqa: E402
from deepphy.runs.store import episode_prompts, read_prompt, stored_prompt_json  # noqa: E402


def prompt(text: str, shade: int = 0) -> tuple[str, list[Message]]:
    scene = Image.from_array("scene", "the scene now", np.full((4, 6, 3), shade, np.uint8))
    messages = [Message(role="system", content=[TextPart(text="rules")]),
                Message(role="user", content=[ImagePart(image=scene), TextPart(text=text)])]
    return prompt_digest(messages), messages


def stored(messages: list[Message]) -> list[dict]:
    return json.loads(prompt_as_json(messages))


def test_a_stored_prompt_is_json_dumps_of_its_parts_byte_for_byte():
    """`prompt_as_json` joins remembered JSON strings by hand: the very bytes json.dumps gives,
    for the strings a prompt can hold (quotes, backslashes, control characters, non-ASCII),
    the second time as the first."""
    odd = 'a "quoted" \\ back\\slash\n\ttab \x00\x1f caf\u00e9 \u2713 \U0001f600 </script>'
    scene = Image.from_array(odd, odd[::-1], np.full((4, 6, 3), 3, np.uint8))
    messages = [Message(role="system", content=[TextPart(text=odd)]),
                Message(role="user", content=[TextPart(text=""), ImagePart(image=scene), TextPart(text=odd + "!")])]
    expected = json.dumps([{"role": "system", "content": [odd]},
                           {"role": "user", "content": ["", {"image": scene.digest, "name": odd, "caption": odd[::-1]}, odd + "!"]}],
                          separators=(",", ":"))
    assert prompt_as_json(messages) == expected
    assert prompt_as_json(messages) == expected  # from the remembered strings


def test_prompts_are_a_log_per_episode_a_line_per_distinct_prompt(tmp_path):
    (a, first), (b, second) = prompt("decide", 1), prompt("decide again", 2)
    with RunStore.create_or_resume(tmp_path, RunConfig(runs=2)) as store:
        for task, run, digest, messages in [("support", 0, a, first), ("support", 0, a, first),
                                            ("support", 0, b, second), ("support", 1, a, first), ("hinder", 0, b, second)]:
            store.write_prompt(task, run, digest, messages)
    files = sorted(str(p.relative_to(tmp_path)) for p in (tmp_path / "prompts").rglob("*") if p.is_file())
    assert files == ["prompts/hinder/r0.jsonl", "prompts/support/r0.jsonl", "prompts/support/r1.jsonl"]
    lines = (tmp_path / "prompts" / "support" / "r0.jsonl").read_bytes().split(b"\n")
    assert lines[-1] == b"" and [json.loads(line)["digest"] for line in lines[:-1]] == [a, b]
    assert episode_prompts(tmp_path, "support", 0) == {a: stored(first), b: stored(second)}
    assert stored_prompt_json(tmp_path, "support", 1, a) == stored(first)
    assert read_prompt(tmp_path, "hinder", 0, b) == second  # the images too: each stored once, by content
    assert len(list((tmp_path / "images").iterdir())) == 2
    with pytest.raises(RunDirError, match=f"prompt {b} is missing \\(in prompts/support/r1.jsonl\\)"):
        stored_prompt_json(tmp_path, "support", 1, b)  # in another episode's log only
    # a resume appends an episode's prompt again (the store forgot it): the first line counts
    with RunStore.create_or_resume(tmp_path, RunConfig(runs=2)) as store:
        store.write_prompt("support", 1, a, first)
    assert (tmp_path / "prompts" / "support" / "r1.jsonl").read_bytes().count(b"\n") == 2
    assert episode_prompts(tmp_path, "support", 1) == {a: stored(first)}


def test_a_torn_prompt_line_is_skipped_then_cut_on_resume(tmp_path):
    """What a kill -9 in the middle of a prompt's write leaves: the line without its end.
    Readers skip it; the resume's first append to that episode's log cuts it off."""
    (a, first), (b, second), (c, third) = prompt("one"), prompt("two"), prompt("three")
    cfg = RunConfig(runs=1)
    with RunStore.create_or_resume(tmp_path, cfg) as store:
        store.write_prompt("support", 0, a, first)
    log = tmp_path / "prompts" / "support" / "r0.jsonl"
    whole = log.read_bytes()
    line = f'{{"digest":"{b}","messages":{prompt_as_json(second)}}}\n'.encode()
    log.write_bytes(whole + line[:-1])  # all of it but the newline: still torn
    assert episode_prompts(tmp_path, "support", 0) == {a: stored(first)}
    with pytest.raises(RunDirError, match=f"prompt {b} is missing"):
        stored_prompt_json(tmp_path, "support", 0, b)
    with RunStore.create_or_resume(tmp_path, cfg) as store:
        store.write_prompt("support", 0, c, third)
        store.write_prompt("support", 0, b, second)  # the attempt that had no record, run again
    assert log.read_bytes() == whole + f'{{"digest":"{c}","messages":{prompt_as_json(third)}}}\n'.encode() + line
    assert episode_prompts(tmp_path, "support", 0) == {a: stored(first), c: stored(third), b: stored(second)}
    log.write_bytes(line[:40])  # a log holding only a torn line is emptied
    with RunStore.create_or_resume(tmp_path, cfg) as store:
        store.write_prompt("support", 0, a, first)
    assert log.read_bytes() == whole


def test_a_tampered_prompt_log_is_skipped_line_by_line_and_reported_in_one_line(tmp_path, monkeypatch):
    from deepphy.runs import store as store_module

    (a, first), (b, second), (c, third), (d, fourth) = prompt("one"), prompt("two"), prompt("three"), prompt("four")
    with RunStore.create_or_resume(tmp_path, RunConfig(runs=1)) as store:
        for digest, messages in ((a, first), (b, second), (c, third), (d, fourth)):
            store.write_prompt("support", 0, digest, messages)
    log = tmp_path / "prompts" / "support" / "r0.jsonl"
    lines = log.read_text().splitlines()
    lines[0] = "garbage " + a
    lines[1] = json.dumps({"digest": b, "messages": {"role": "user"}})  # JSON, not a stored prompt
    lines[2] = json.dumps({"digest": c, "messages": [{"role": "user", "content": [{"image": "../../secret",
                                                                                     "name": "x", "caption": "y"}]}]})
    lines.insert(3, "[" * 100_000 + "]" * 100_000)  # nested too deep to parse
    log.write_text("\n".join(lines) + "\n")
    assert episode_prompts(tmp_path, "support", 0) == {d: stored(fourth)}
    for digest in (a, b, c):
        with pytest.raises(RunDirError) as e:
            stored_prompt_json(tmp_path, "support", 0, digest)
        assert str(e.value) == (f"{tmp_path}: prompt {digest} is not a stored prompt (a list of messages) "
                                "(in prompts/support/r0.jsonl)")
    assert read_prompt(tmp_path, "support", 0, d) == fourth
    monkeypatch.setattr(store_module, "MAX_PROMPT_BYTES", len(lines[4]) - 1)  # a line longer than any prompt
    assert episode_prompts(tmp_path, "support", 0) == {}
    with pytest.raises(RunDirError, match=f"prompt {d} is missing"):
        stored_prompt_json(tmp_path, "support", 0, d)
    for bad in ("../config", "x" * 20, d + "\n"):
        with pytest.raises(RunDirError, match="is not a prompt digest"):
            stored_prompt_json(tmp_path, "support", 0, bad)


def test_prompt_logs_that_lead_out_of_the_run_are_neither_read_nor_written(tmp_path):
    (a, first), (b, second) = prompt("one"), prompt("two")
    cfg = RunConfig(runs=1)
    run = tmp_path / "run"
    with RunStore.create_or_resume(run, cfg) as store:
        store.write_prompt("support", 0, a, first)
        store.write_prompt("hinder", 0, a, first)
    secret = tmp_path / "secret"
    (run / "prompts" / "support").rename(secret)  # a valid log, but outside the run
    (run / "prompts" / "support").symlink_to(secret)
    for read in (lambda: episode_prompts(run, "support", 0), lambda: stored_prompt_json(run, "support", 0, a)):
        with pytest.raises(RunDirError, match="prompts/support/r0.jsonl leads out of the run directory"):
            read()
    for task, run_ in (("../support", 0), ("support/..", 0), ("hinder", -1)):
        with pytest.raises(RunDirError, match="leads out of the run directory"):
            episode_prompts(run, task, run_)
    with RunStore.create_or_resume(run, cfg) as store:
        with pytest.raises(RunDirError, match="prompts/support leads out of the run directory"):
            store.write_prompt("support", 0, b, second)
        (run / "prompts" / "hinder" / "r1.jsonl").symlink_to(secret / "r0.jsonl")  # a log symlinked out
        with pytest.raises(RunDirError, match="is a symbolic link"):
            store.write_prompt("hinder", 1, b, second)
    assert (secret / "r0.jsonl").read_bytes().count(b"\n") == 1  # nothing was written there
    with pytest.raises(RunDirError, match="leads out of the run directory"):
        episode_prompts(run, "hinder", 1)


def test_prompts_of_a_run_from_before_the_logs_are_still_read(tmp_path):
    """Runs before the logs stored prompts/<digest>.json; a resumed one holds both."""
    (a, first), (b, second) = prompt("one"), prompt("two")
    cfg = RunConfig(runs=1)
    with RunStore.create_or_resume(tmp_path, cfg) as store:
        store.write_prompt("support", 0, a, first)  # its images, under images/
    (tmp_path / "prompts" / f"{a}.json").write_text(json.dumps(stored(first), indent=1))
    (tmp_path / "prompts" / "support" / "r0.jsonl").unlink()
    assert episode_prompts(tmp_path, "support", 0) == {}
    assert stored_prompt_json(tmp_path, "support", 0, a) == stored(first)
    assert read_prompt(tmp_path, "support", 0, a) == first
    with RunStore.create_or_resume(tmp_path, cfg) as store:  # resumed with this version
        store.write_prompt("support", 0, b, second)
    logged = episode_prompts(tmp_path, "support", 0)
    assert logged == {b: stored(second)}
    assert [stored_prompt_json(tmp_path, "support", 0, d, logged) for d in (a, b)] == [stored(first), stored(second)]
    (tmp_path / "prompts" / f"{a}.json").write_text('{"role": "user"}')
    with pytest.raises(RunDirError, match=f"prompts/{a}.json is not a stored prompt"):
        stored_prompt_json(tmp_path, "support", 0, a, logged)


# -- the record's bounds ------------------------------------------------------------------------

@pytest.mark.parametrize("field, value", [
    ("stars", 10**30), ("run", 10**30), ("input_tokens", 10**30), ("attempt", 10**30), ("seed", 2**64),
    ("retries", -1),
])
def test_a_record_outside_the_bounds_is_refused_with_its_line_by_every_reader(tmp_path, capsys, field, value):
    """Integers beyond any real record (export overflowed its columns with a traceback; a
    run of 10**30 was silently left out of the report) and a negative count: report,
    export, leaderboard, a resume and the dashboard each refuse the line, in one line."""
    from dashboard_support import synthetic_run

    from deepphy.cli import main
    from deepphy.dashboard.source import RunSource

    run = synthetic_run(tmp_path / "run", env="iphyre", runs=1, limit=2)
    lines = (run / ATTEMPTS).read_text().splitlines()
    last = json.loads(lines[-1])
    where = last["model_stats"] if field == "retries" else last["model_stats"]["usage"] if field == "input_tokens" else last
    where[field] = value
    (run / ATTEMPTS).write_text("\n".join([*lines[:-1], json.dumps(last)]) + "\n")
    said = f"{run / ATTEMPTS}:{len(lines)} is not a valid attempt record"
    for command in (["report", str(run)], ["export", str(run), "--out", str(tmp_path / "ds")],
                    ["leaderboard", str(run)], ["run", "--env", "iphyre", "--runs", "1", "--limit", "2", "--out", str(run),
                                                "--no-progress"]):
        assert main(command) == 2, command
        err = capsys.readouterr().err
        assert err.startswith(f"deepphy: error: {said}") and err.count("\n") == 1, err
    assert not (tmp_path / "ds").exists()
    source = RunSource(run)
    source.poll()
    assert len(source.records) == len(lines) - 1 and "is not a valid attempt record" in source.errors[0]
