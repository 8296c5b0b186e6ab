"""`deepphy export`: one Parquet row per decision, equal to the records; images copied;
loadable with pandas and with the datasets library's local Parquet loader."""

import json

import pandas as pd
import pyarrow.parquet as pq
import pytest

from dashboard_support import mock_run, synthetic_run
from deepphy.cli import main
from deepphy.export import DATA_FILE, FIELDS, export
from deepphy.runs.store import read_prompt, read_records


@pytest.fixture(scope="module")
def runs(ray_cluster, tmp_path_factory):
    """A real MOCK I-PHYRE run (one decision per attempt) and a multi-decision WM run."""
    base = tmp_path_factory.mktemp("export-runs")
    return [mock_run(tmp_path_factory), synthetic_run(base / "kinetix", fmt="wm", limit=5, max_steps=5)]


@pytest.fixture(scope="module")
def exported(runs, tmp_path_factory):
    out = tmp_path_factory.mktemp("export") / "dataset"
    summary = export(runs, out)
    return out, summary


def _rows(out):
    """The rows exactly as stored (pandas turns null strings into NaN)."""
    return [_Row(r) for r in pq.read_table(out / DATA_FILE).to_pylist()]


class _Row(dict):
    __getattr__ = dict.__getitem__


def _records(runs):
    return {(d.name, r.task, r.run, r.attempt): r for d in runs for r in read_records(d)}


def test_one_row_per_decision_with_the_records_fields(runs, exported):
    out, summary = exported
    df = pd.read_parquet(out / DATA_FILE)
    records = _records(runs)
    assert len(df) == summary.rows == sum(len(r.steps) for r in records.values())
    assert list(df.columns) == [name for name, _, _ in FIELDS]
    assert df.groupby("source").size().to_dict() == {
        d.name: sum(len(r.steps) for r in read_records(d)) for d in runs}
    assert (df["step"] > 1).any(), "the multi-decision run must export several steps per attempt"
    for row in _rows(out):
        r = records[(row.source, row.task, row.run, row.attempt)]
        s = r.steps[row.step - 1]
        assert s.step == row.step
        assert (row.env, row.group, row.model, row.format, row.seed) == (r.env, r.group, r.model, r.format, r.seed)
        assert row.prompt_digest == s.prompt and row.raw_output == s.raw_output
        assert row.prediction == s.prediction and row.action_text == s.action_text
        assert (json.loads(row.action) if row.action is not None else None) == s.action
        assert row.valid == (s.invalid_reason is None) and row.invalid_reason == s.invalid_reason
        assert row.feedback == s.feedback and json.loads(row.info) == s.info
        assert row.success == r.success and row.outcome == r.feedback and row.stars == r.stars
        assert row.attempt_invalid_reason == r.invalid_reason
        assert row.final_step == (row.step == len(r.steps))
        assert row.attempt_input_tokens == r.model_stats.usage.input_tokens


def test_images_are_copied_and_referenced_by_relative_path(runs, exported):
    out, summary = exported
    rows = _rows(out)
    run_dirs = {d.name: d for d in runs}
    records = _records(runs)
    referenced = set()
    for row in rows:
        r = records[(row.source, row.task, row.run, row.attempt)]
        for path in list(row.key_frames) + list(row.images):
            assert not path.startswith("/") and (out / path).is_file()
            referenced.add(path)
        # the key frames of an attempt, spread over its decisions, are exactly the record's
        if row.final_step:
            mine = [x for x in rows if (x.source, x.task, x.run, x.attempt) == (row.source, row.task, row.run, row.attempt)]
            paths = [p for x in mine for p in x.key_frames]
            assert [p.rsplit("/", 1)[-1] for p in paths] == [f.path.rsplit("/", 1)[-1] for f in r.key_frames]
            for p, f in zip(paths, r.key_frames):
                assert (out / p).read_bytes() == (run_dirs[row.source] / f.path).read_bytes()
        parts = [p for m in row.prompt for p in m["content"]]
        images = [p for p in parts if p["type"] == "image"]
        assert [p["image"] for p in images if p["image"]] == list(row.images)
        assert list(row.images) == list(row.history_images) + list(row.observation_images)
        if row.source == runs[1].name:
            # a run from before images/ (the synthetic one): the current observation was not kept
            assert sum(1 for p in images if p["image"] is None) == row.images_not_stored >= 1
            continue
        # every image the model saw is a file, and it is the very image the prompt held
        assert row.images_not_stored == 0 and len(row.observation_images) == 2  # scene, annotated
        shown = [i.png for m in read_prompt(run_dirs[row.source], row.task, row.run, row.prompt_digest)
                 for i in m.images]
        assert [(out / p).read_bytes() for p in row.images] == shown
    assert summary.images == len(referenced)
    assert any(row.images for row in rows), "later attempts show earlier key frames"


def test_datasets_loads_it_offline(exported, tmp_path, monkeypatch):
    monkeypatch.setenv("HF_DATASETS_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    import datasets

    out, summary = exported
    ds = datasets.load_dataset("parquet", data_files=str(out / DATA_FILE), cache_dir=str(tmp_path / "hf"))["train"]
    df = pd.read_parquet(out / DATA_FILE)
    assert ds.num_rows == summary.rows
    assert ds[0]["raw_output"] == df.iloc[0]["raw_output"] and ds[0]["prompt"][0]["role"] == "system"
    card = (out / "README.md").read_text()
    assert all(f"`{name}`" in card for name, _, _ in FIELDS) and DATA_FILE in card
    # the planning of every environment, from the EnvSpecs
    from deepphy.envs import specs
    from deepphy.envs.base import Planning

    on_the_fly = [s.title for s in specs().values() if s.planning is Planning.ON_THE_FLY]
    assert {"Kinetix", "Pooltool", "Angry Birds", "Cut the Rope"} <= set(on_the_fly)
    assert f"on-the-fly ones ({', '.join(on_the_fly)}) several" in " ".join(card.split())


def test_cli_export_replaces_an_earlier_export_and_refuses_other_directories(runs, tmp_path, capsys):
    out = tmp_path / "ds"
    assert main(["export", str(runs[1]), "--out", str(out)]) == 0
    assert "decisions from 1 run directory" in capsys.readouterr().out
    first = len(pd.read_parquet(out / DATA_FILE))
    assert main(["export", *map(str, runs), "--out", str(out)]) == 0  # an earlier export: replaced
    assert len(pd.read_parquet(out / DATA_FILE)) > first
    assert not list(tmp_path.glob(".ds.*")), "no staging directory is left behind"

    foreign = tmp_path / "notes"
    foreign.mkdir()
    (foreign / "mine.txt").write_text("keep me")
    assert main(["export", str(runs[1]), "--out", str(foreign)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert [p.name for p in foreign.iterdir()] == ["mine.txt"]
    assert main(["export", str(tmp_path / "nosuch"), "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()


def test_nothing_outside_a_run_directory_is_exported(runs, tmp_path, capsys):
    """A key frame symlinked to a file elsewhere, a prompt file that is not a prompt, a
    duplicated attempt: one line each, and no dataset."""
    import shutil

    from dashboard_support import append

    secret = tmp_path / "secret.png"
    secret.write_bytes(b"private")
    linked = tmp_path / "linked"
    shutil.copytree(runs[1], linked)
    frame = linked / next(r for r in read_records(linked) if r.key_frames).key_frames[0].path
    frame.unlink()
    frame.symlink_to(secret)
    shaped = tmp_path / "shaped"
    shutil.copytree(runs[1], shaped)
    (shaped / "prompts" / f"{read_records(shaped)[0].steps[0].prompt}.json").write_text('{"role": "user"}')
    doubled = tmp_path / "doubled"
    shutil.copytree(runs[1], doubled)
    append(doubled, [(doubled / "attempts.jsonl").read_bytes().splitlines()[0]])
    for run, words in ((linked, "leads out of the run directory"), (shaped, "is not a stored prompt"),
                       (doubled, "is recorded 2 times")):
        assert main(["export", str(run), "--out", str(tmp_path / f"ds-{run.name}")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err
        assert not (tmp_path / f"ds-{run.name}").exists()
