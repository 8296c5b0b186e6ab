"""The dashboard's server side: tailing a run directory, the figures (from the report code),
the grid and episodes, the HTTP API and its live Server-Sent Events. The page itself is
tested in a real browser in test_dashboard_browser.py."""

import asyncio
import json
import re
import shutil
import socket
import subprocess
import time
import urllib.error
import urllib.request

import pytest
from aiohttp.test_utils import TestClient, TestServer

from dashboard_support import append, copy_run, mock_run, rewrite_prompt, synthetic_run
from deepphy.cli import main
from deepphy.dashboard.server import Dashboard, make_app
from deepphy.dashboard.source import RunSource, writer_holds_lock
from deepphy.metrics.report import report_of, table, table_key
from deepphy.runs.status import RunStatus, read_status, write_status
from deepphy.runs.store import ATTEMPTS, RunStore, read_config, read_prompt, read_records


@pytest.fixture(scope="module")
def run_dir(ray_cluster, tmp_path_factory):
    return mock_run(tmp_path_factory)


def loaded(path) -> RunSource:
    source = RunSource(path)
    while source.poll() or source.loading:
        pass
    return source


def test_tailing_consumes_whole_lines_only(run_dir, tmp_path):
    copy = tmp_path / "copy"
    log = copy_run(run_dir, copy, lines=10, torn=37)
    source = RunSource(copy)
    changed = source.poll()
    assert len(source.records) == 10 and source.offset == sum(len(line) + 1 for line in log[:10])
    assert changed == {(r.task, r.run) for r in source.records}
    assert source.poll() == set()  # nothing new: the torn line stays unread
    append(copy, [log[10][37:], *log[11:]])  # the writer finishes its line, then more

    changed = source.poll()
    assert len(source.records) == len(log) and changed
    assert source.report() == report_of(run_dir)  # the same report as `deepphy report --json`
    append(copy, [b'{"env": "iphyre", "task": "support"}'])  # not a record: reported, skipped
    assert source.poll() == set() and len(source.records) == len(log)
    assert len(source.errors) == 1 and "is not a valid attempt record" in source.view()["errors"][0]


def test_view_numbers_are_the_report(run_dir):
    source = loaded(run_dir)
    report = report_of(run_dir)
    view = source.view()
    assert view["report"] == report.to_json()
    header, rows = table([report])
    assert view["table"] == {"header": header, "rows": rows, "key": table_key([report])}
    assert view["title"] == "I-PHYRE"
    per_run = report.overall.per_run
    for key in ("solved", "attempts", "invalid_attempts", "model_errors", "retries", "input_tokens", "cost_usd"):
        assert view["totals"][key] == sum(getattr(r, key) for r in per_run)
    assert view["curve"] == {"kind": "attempts", "x": list(range(1, 11)),
                             "mean": report.overall.mean.success_at, "std": report.overall.std.success_at}
    p = view["progress"]
    assert p["status"] == "complete" and p["episodes_done"] == p["episodes_total"] == 12 and p["eta_s"] is None
    assert p["attempts"] == len(read_records(run_dir)) and p["attempts_per_s"] > 0


def test_a_run_in_progress_shows_rates_over_its_finished_episodes(run_dir, tmp_path):
    """While episodes are unfinished, the view's rates (card, curve, table) are the report over
    the finished episodes alone, marked partial with their count; `report` stays the whole one."""
    from deepphy.metrics.report import build_report

    copy = tmp_path / "copy"
    copy_run(run_dir, copy, lines=9)
    source = loaded(copy)
    view = source.view()
    records = read_records(copy)
    config = read_config(copy)
    partial = build_report(config, source.tasks, records, source.k_max, finished_only=True)
    finished = partial.overall.finished
    assert view["report"] == report_of(copy).to_json() and view["partial"] == {"finished": finished, "total": 12}
    assert 0 < finished < 12 and view["curve"]["mean"] == partial.overall.mean.success_at
    assert view["solved_rate"] == partial.overall.mean.success_at[-1]
    assert view["table"]["rows"] == table([partial])[1] and view["n"] == f"6x2 ({finished} done)"
    assert loaded(run_dir).view()["partial"] is None  # a finished run: the whole report


def test_the_episode_list_has_every_episode_with_its_outcome(run_dir):
    source = loaded(run_dir)
    data = source.samples()
    rows = [dict(zip(data["columns"], r)) for r in data["rows"]]
    records = read_records(run_dir)
    episodes: dict = {}
    for r in records:
        episodes.setdefault((r.task, r.run), []).append(r)
    assert [(r["task"], r["run"]) for r in rows] == sorted(episodes, key=lambda k: (source.task_index[k[0]], k[1]))
    for row in rows:
        mine = episodes[(row["task"], row["run"])]
        assert row["state"] == ("solved" if any(r.success for r in mine) else "failed")
        assert row["attempts"] == len(mine) and row["decisions"] == sum(len(r.steps) for r in mine)
        assert row["invalid"] == sum(r.invalid for r in mine)
        assert row["seconds"] == pytest.approx(sum(sum(r.timing.decision_s) for r in mine), abs=1e-3)
        assert mine[-1].feedback in row["words"]
    assert data["human"] is False and data["k_max"] == 10


def test_single_attempt_runs_get_a_per_decision_curve(tmp_path):
    kin = loaded(synthetic_run(tmp_path / "kin", limit=6, max_steps=6))
    report = kin.report()
    curve = kin.view()["curve"]
    assert curve["kind"] == "decisions" and curve["x"] == list(range(1, kin.max_steps + 1))
    assert curve["mean"] == report.overall.mean.success_by_step == sorted(curve["mean"])  # cumulative
    assert curve["mean"][-1] == pytest.approx(report.overall.mean.success_at[0])
    # every shot on a regular axis; the report's checkpoints are points of the curve
    pool = loaded(synthetic_run(tmp_path / "pool", env="pooltool", limit=6, max_steps=15, p_success=0.6))
    m = pool.report().overall.mean
    curve = pool.view()["curve"]
    assert curve["x"] == list(range(1, 16)) and curve["noun"] == "shot" and curve["checkpoints"] == [1, 3, 6, 9, 12, 15]
    assert [curve["mean"][k - 1] for k in curve["checkpoints"]] == list(m.success_within_steps.values())


def test_grid_pages_groups_and_cells(run_dir, tmp_path):
    source = loaded(run_dir)
    records = read_records(run_dir)
    grid = source.grid(page=0, page_size=4)
    assert grid["pages"] == 2 and [t for t, _ in grid["tasks"]] == ["support", "hinder", "direction", "hole"]
    assert source.grid(page=1, page_size=4)["tasks"][0][0] == "spring_flick"
    assert source.grid(page=9, page_size=4)["page"] == 1  # clamped
    basic = source.grid(group="basic")
    assert {g for _, g in basic["tasks"]} == {"basic"} and basic["tasks_total"] == 4
    for (task, _), cells in zip(grid["tasks"], grid["cells"]):
        for run, (state, attempts, solved_at, invalid, stars, steps) in enumerate(cells):
            mine = [r for r in records if (r.task, r.run) == (task, run)]
            assert attempts == len(mine) and invalid == sum(r.invalid for r in mine)
            solved = [r.attempt for r in mine if r.success]
            assert state == ("solved" if solved else "failed") and solved_at == (solved[0] if solved else None)
    # an episode cut short reads as in progress; one never started as pending
    copy = tmp_path / "copy"
    log = copy_run(run_dir, copy, lines=0)
    first = json.loads(log[0])
    append(copy, [log[0]])
    partial = loaded(copy)
    cell = partial.cells({(first["task"], first["run"])})[0]
    assert cell[2] == ("solved" if first["success"] else "progress")
    assert sum(c[0] == "pending" for cells in partial.grid()["cells"] for c in cells) == 6 * 2 - 1


def test_episode_shows_stored_images_and_marks_the_rest(run_dir):
    source = loaded(run_dir)
    records = read_records(run_dir)
    r = next(r for r in records if r.attempt == 3)
    ep = source.episode(r.task, r.run)
    assert [a["attempt"] for a in ep["attempts"]][:3] == [1, 2, 3]
    third = ep["attempts"][2]
    assert third["steps"][0]["raw_output"] == r.steps[0].raw_output
    parts = [p for m in ep["prompts"][r.steps[0].prompt] for p in m["content"] if p["type"] == "image"]
    # Every image the model saw is a file: the key frames of attempts 1 and 2 (the same
    # bytes as the key frames), then the current observation's scene and annotated scene.
    assert all(p["file"] for p in parts)
    history = [f.path for a in records if (a.task, a.run) == (r.task, r.run) and a.attempt < 3 for f in a.key_frames]
    assert [source.image(p["file"]) for p in parts[:-2]] == [(run_dir / f).read_bytes() for f in history]
    assert [p["name"] for p in parts[-2:]] == ["scene", "annotated"]
    prompt = read_prompt(run_dir, r.task, r.run, r.steps[0].prompt)
    assert [source.image(p["file"]) for p in parts] == [i.png for m in prompt for i in m.images]
    with pytest.raises(KeyError):
        source.episode("nosuch", 0)


def test_a_run_from_before_stored_images_still_shows_what_it_kept(tmp_path):
    run = synthetic_run(tmp_path / "old", "iphyre", limit=3, max_steps=1, p_success=0)  # prompts with "<image ...>" placeholders
    source = loaded(run)
    r = next(r for r in read_records(run) if r.attempt == 2)
    parts = [p for m in source.episode(r.task, r.run)["prompts"][r.steps[0].prompt] for p in m["content"]
             if p["type"] == "image"]
    assert [p["name"] for p in parts if not p["file"]] == ["scene"] and any(p["file"] for p in parts)


def test_only_frames_are_served(run_dir):
    source = loaded(run_dir)
    frame = read_records(run_dir)[0].key_frames[0].path
    assert source.frame_path(frame) == (run_dir / frame).resolve()
    image = next((run_dir / "images").iterdir())
    assert source.image(f"images/{image.name}") == image.read_bytes()
    for bad in ("config.json", "attempts.jsonl", f"{frame}/../../../config.json", "frames/../config.json",
                "../../etc/passwd", "/etc/passwd", "frames/nosuch.png", f"images/{image.name}"):
        assert source.frame_path(bad) is None, bad
    for bad in (f"images/../images/{image.name}", "images/nosuch.png", f"images/{image.stem}.jpg", "images/" + "0" * 64 + ".png"):
        assert source.image(bad) is None, bad


def test_a_writing_run_is_detected_without_taking_its_lock(run_dir, tmp_path):
    copy = tmp_path / "copy"
    copy_run(run_dir, copy, lines=3)
    assert writer_holds_lock(copy) is False
    store = RunStore.create_or_resume(copy, read_config(copy))
    try:
        assert writer_holds_lock(copy) is True
        assert loaded(copy).view()["progress"]["status"] == "running"
        assert loaded(copy).view()["progress"]["phase"] is None  # no status file: no phase to tell
        write_status(copy, RunStatus(run_id="ab12cd34", pid=1, phase="compiling", since=time.time()))
        assert loaded(copy).view()["progress"]["phase"] == "compiling"
    finally:
        store.close()
    assert writer_holds_lock(copy) is False
    assert read_status(copy) is None  # a status file without its writer is stale
    assert loaded(copy).view()["progress"]["status"] == "incomplete"
    assert loaded(copy).view()["progress"]["phase"] is None


def test_a_replaced_log_is_read_again(run_dir, tmp_path):
    copy = tmp_path / "copy"
    log = copy_run(run_dir, copy, lines=20)
    source = loaded(copy)
    (copy / ATTEMPTS).write_bytes(b"".join(line + b"\n" for line in log[:5]))  # shorter: a new log
    assert source.poll() is None and len(source.records) == 5


def test_http_api_and_live_events(run_dir, tmp_path):
    copy = tmp_path / "copy"
    log = copy_run(run_dir, copy, lines=30)

    async def scenario():
        source = RunSource(copy)
        dashboard = Dashboard([source], poll_s=0.1)
        async with TestClient(TestServer(make_app(dashboard))) as client:
            page = await client.get("/")
            assert page.status == 200 and "app.js" in await page.text()
            events = await client.get("/api/events")
            first = await _next_event(events)
            assert first[0] == "state"
            while not (await (await client.get("/api/state")).json())["runs"]:
                await asyncio.sleep(0.05)
            state = await (await client.get("/api/state")).json()
            assert state["runs"][0]["progress"]["attempts"] == 30
            report = await (await client.get(f"/api/runs/{source.id}/report")).json()
            assert report == report_of(copy).to_json()
            grid = await (await client.get(f"/api/runs/{source.id}/grid?page=0")).json()
            assert len(grid["tasks"]) == 6
            frame = read_records(copy)[0].key_frames[0].path
            assert (await client.get(f"/files/{source.id}/{frame}")).status == 200
            assert (await client.get(f"/files/{source.id}/frames/..%2Fconfig.json")).status == 404
            assert (await client.get(f"/files/{source.id}/config.json")).status == 404
            assert (await client.get("/api/runs/nosuch/report")).status == 404
            assert (await client.get(f"/api/runs/{source.id}/episode?task=nosuch&run=0")).status == 404
            assert (await client.get(f"/api/runs/{source.id}/grid?page=x")).status == 400

            # a new record reaches the open event stream (how fast: benchmarks/dashboard.py)
            for n, line in enumerate(log[30:33]):
                append(copy, [line])
                record = json.loads(line)
                while True:
                    name, data = await asyncio.wait_for(_next_event(events), 30)
                    if name == "message" and data["run"]["progress"]["attempts"] > 30 + n:
                        break
                assert [record["task"], record["run"]] in [c[:2] for c in data["cells"]]
            events.close()

    asyncio.run(scenario())


@pytest.mark.parametrize("bad", [b'{"env": "iphyre", "task": "support"}', b"x" * (17 * 1024 * 1024)])
def test_a_bad_line_appended_to_a_watched_run_reaches_the_page(run_dir, tmp_path, bad):
    """A record arrives with the start of a line that is not one (the page says "loading"
    meanwhile); the line ends: the page gets the error and the run loaded, not a "loading"
    that never ends (the poll recorded the error but reported no change, so no view went out)."""
    copy = tmp_path / "copy"
    log = copy_run(run_dir, copy, lines=20)

    async def scenario() -> dict:
        source = RunSource(copy)
        dashboard = Dashboard([source], poll_s=0.05)
        async with TestClient(TestServer(make_app(dashboard))) as client:
            events = await client.get("/api/events")
            with open(copy / ATTEMPTS, "ab") as f:
                f.write(log[20] + b"\n" + bad[:10])
            while True:
                name, data = await asyncio.wait_for(_next_event(events), 30)
                if name == "message" and data["run"]["progress"]["attempts"] == 21:
                    break
            assert data["run"]["progress"]["loading"] and not data["run"]["errors"]
            with open(copy / ATTEMPTS, "ab") as f:
                f.write(bad[10:] + b"\n")
            while True:
                name, data = await asyncio.wait_for(_next_event(events), 30)
                if name == "message" and data["run"]["errors"]:
                    events.close()
                    return data["run"]

    view = asyncio.run(scenario())
    assert not view["progress"]["loading"] and view["progress"]["attempts"] == 21
    assert re.search("not a valid attempt record|longer than 16 MiB", view["errors"][0]), view["errors"]


async def _next_event(response):
    """(event name, data) of the next Server-Sent Event, skipping heartbeats."""
    name, data = "message", None
    while True:
        line = (await response.content.readline()).decode().rstrip("\n")
        if line.startswith("event: "):
            name = line[7:]
        elif line.startswith("data: "):
            data = json.loads(line[6:])
        elif line == "" and data is not None:
            return name, data


def test_cli_errors(tmp_path, capsys):
    assert main(["dashboard"]) == 2
    assert "give run directories" in capsys.readouterr().err
    (tmp_path / "notes.txt").write_text("")
    assert main(["dashboard", str(tmp_path / "notes.txt")]) == 2
    assert "is not a directory" in capsys.readouterr().err
    bad = tmp_path / "runs" / "bad"
    bad.mkdir(parents=True)
    (bad / "config.json").write_text('{"env": "nosuch"}')
    assert main(["dashboard", str(tmp_path / "runs")]) == 2
    assert "is not a valid run config" in capsys.readouterr().err


def test_runs_that_appear_later_join(run_dir, tmp_path):
    """A directory given before any run is in it shows a placeholder, then the run."""
    root = tmp_path / "runs"

    async def scenario():
        dashboard = Dashboard([], roots=[root])
        queue = asyncio.Queue()
        dashboard.clients.add(queue)
        await dashboard._scan_roots()
        (waiting,) = dashboard.views.values()
        assert waiting["waiting"] and waiting["progress"]["status"] == "waiting"
        copy_run(run_dir, root / "later", lines=12)
        await dashboard._scan_roots()
        (source,) = dashboard.sources.values()
        assert source.path == (root / "later").resolve() and not dashboard.views
        await dashboard._poll(source)
        assert dashboard.views[source.id]["progress"]["attempts"] == 12
        sent = [queue.get_nowait() for _ in range(queue.qsize())]
        assert [m.split(b"\n", 1)[0] for m in sent] == [b"event: message", b"event: state", b"event: message"]
        dashboard.executor.shutdown()

    asyncio.run(scenario())


def test_runs_nested_below_a_directory_are_found(run_dir, tmp_path):
    """runs/<model>/<env>/ and the like: run directories two folders down are found; a run
    directory's own folders and hidden folders are not searched."""
    from deepphy.runs.discovery import runs_in

    copy_run(run_dir, tmp_path / "runs" / "gpt" / "iphyre", lines=3)
    copy_run(run_dir, tmp_path / "runs" / "mock" / "phyre-like", lines=3)
    copy_run(run_dir, tmp_path / "runs" / "direct", lines=3)
    copy_run(run_dir, tmp_path / "runs" / ".hidden" / "x", lines=3)
    copy_run(run_dir, tmp_path / "runs" / "direct" / "frames" / "inner", lines=3)  # inside a run: not searched
    root = tmp_path / "runs"
    assert runs_in(root) == [root / "direct", root / "gpt" / "iphyre", root / "mock" / "phyre-like"]
    assert runs_in(tmp_path, depth=1) == []


def test_cli_port_in_use(run_dir, capsys):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(["dashboard", str(run_dir), "--port", str(port)]) == 2
    assert f"cannot listen on 127.0.0.1:{port}" in capsys.readouterr().err


def test_live_runs_from_metrics_snapshots(run_dir):
    """What the Ray loop does with the metrics actors' snapshots (`deepphy watch --json`
    prints the same objects): a readable run directory becomes a full run; an unreadable
    one shows the snapshot, and is marked ended once its actor is gone."""
    config = read_config(run_dir).model_dump(mode="json")
    snap = {"episodes_done": 3, "episodes_total": 12, "attempts": 9, "attempts_per_s": 2.5, "solved": 2,
            "invalid_attempts": 1, "model_errors": 0, "retries": 4, "input_tokens": 10, "output_tokens": 2,
            "cost_usd": 0.5, "elapsed_s": 6.0, "eta_s": 20.0, "phase": "running", "config": config}

    async def scenario():
        dashboard = Dashboard([])
        queue = asyncio.Queue()
        dashboard.clients.add(queue)
        await dashboard._merge_live({"aa11": {**snap, "run_dir": str(run_dir)},
                                     "bb22": {**snap, "run_dir": "/elsewhere/run"}})
        assert [s.path for s in dashboard.sources.values()] == [run_dir.resolve()]
        source = next(iter(dashboard.sources.values()))
        assert source.snapshot["attempts"] == 9
        view = dashboard.views["ray-bb22"]
        assert view["live_only"] and view["progress"]["status"] == "running"
        assert view["progress"]["eta_s"] == 20.0 and view["progress"]["phase"] == "running"  # the run's own
        assert view["totals"]["retries"] == 4 and view["label"] == "mock VLA" and view["env"] == "iphyre"
        await dashboard._merge_live({})
        assert dashboard.views["ray-bb22"]["progress"]["status"] == "ended" and source.snapshot is None
        await dashboard._poll(source)  # the directory-backed run is read like any other
        assert dashboard.views[source.id]["report"] == report_of(run_dir).to_json()
        sent = [queue.get_nowait() for _ in range(queue.qsize())]
        assert len(sent) == 3 and all(m.startswith(b"event: message\n") for m in sent)
        dashboard.executor.shutdown()

    asyncio.run(scenario())


# -- a run directory is untrusted; the server answers only whom it should ----------------


def test_nothing_outside_the_run_directory_is_read_or_served(run_dir, tmp_path):
    """A record naming a prompt outside the run, a frames/ directory symlinked out of it, a
    prompt of the wrong shape, a task's prompt logs symlinked out of it, a NUL byte in a file
    path: refused, never a 500."""
    copy = tmp_path / "copy"
    log = copy_run(run_dir, copy, lines=12)
    secret = tmp_path / "secret"
    secret.mkdir()
    (secret / "x.json").write_text('[{"role": "user", "content": ["the secret"]}]')
    first = read_records(copy)[0]
    other = next(r for r in read_records(copy) if r.task != first.task)
    bad = json.loads(log[12])
    bad["steps"][0]["prompt"] = "../../../secret/x"
    append(copy, [json.dumps(bad).encode()])
    rewrite_prompt(copy, first.task, first.run, first.steps[0].prompt,
                   json.dumps({"digest": first.steps[0].prompt, "messages": {"role": "user", "content": {"a": 1}}}))
    frames = copy / "frames"
    shutil.move(frames, secret / "frames")
    frames.symlink_to(secret / "frames")
    shutil.move(copy / "prompts" / other.task, secret / "prompts")
    (copy / "prompts" / other.task).symlink_to(secret / "prompts")
    rewrite_prompt(copy, other.task, other.run, other.steps[0].prompt,  # written there, through the link
                   json.dumps({"digest": other.steps[0].prompt, "messages": [{"role": "user", "content": ["the secret"]}]}))

    async def scenario():
        source = RunSource(copy)
        dashboard = Dashboard([source], poll_s=0.1)
        async with TestClient(TestServer(make_app(dashboard))) as client:
            while not (await (await client.get("/api/state")).json())["runs"]:
                await asyncio.sleep(0.05)
            (view,) = (await (await client.get("/api/state")).json())["runs"]
            assert view["progress"]["attempts"] == 12 and "not a valid attempt record" in view["errors"][0]
            episode = await client.get(f"/api/runs/{source.id}/episode?task={first.task}&run={first.run}")
            assert episode.status == 200
            body = await episode.json()
            assert body["prompts"][first.steps[0].prompt] is None and "the secret" not in await episode.text()
            episode = await client.get(f"/api/runs/{source.id}/episode?task={other.task}&run={other.run}")
            assert episode.status == 200 and "the secret" not in await episode.text()
            assert (await episode.json())["prompts"] and not any((await episode.json())["prompts"].values())
            frame = first.key_frames[0].path
            assert (await client.get(f"/files/{source.id}/{frame}")).status == 404  # frames/ leads out
            assert (await client.get(f"/files/{source.id}/frames/a%00b.png")).status == 404

    asyncio.run(scenario())


def test_a_duplicated_attempt_is_flagged_not_counted(run_dir, tmp_path):
    copy = tmp_path / "copy"
    log = copy_run(run_dir, copy, lines=12)
    append(copy, [log[3]])
    source = loaded(copy)
    assert len(source.records) == 12
    assert any("is recorded twice" in e and "deepphy repair" in e for e in source.view()["errors"])
    assert main(["report", str(copy)]) == 2  # the report refuses it


def test_a_huge_line_is_read_in_linear_time_and_skipped(tmp_path):
    """One 60 MB line: read once (not grown piece by piece), skipped, and the records after
    it are read."""
    run = synthetic_run(tmp_path / "run", env="iphyre", limit=2, runs=1)
    lines = (run / ATTEMPTS).read_bytes().splitlines()
    (run / ATTEMPTS).write_bytes(lines[0] + b"\n" + b"x" * (60 * 1024 * 1024) + b"\n" + b"\n".join(lines[1:]) + b"\n")
    source = RunSource(run)
    while source.poll() or source.loading:
        pass
    assert len(source.records) == len(lines) and "longer than 16 MiB" in source.errors[0]


def test_a_run_that_takes_long_to_load_does_not_hold_up_the_others(run_dir, tmp_path):
    """Each run has its own thread: while a large log loads, another run's API answers."""
    big = tmp_path / "big"
    log = copy_run(run_dir, big, lines=0)
    config = json.loads((big / "config.json").read_text())
    config["runs"] = 4000
    (big / "config.json").write_text(json.dumps(config))
    with open(big / ATTEMPTS, "wb") as f:
        for run in range(4000):  # ~170k records, distinct episodes
            for line in log[:44]:
                record = json.loads(line)
                if record["run"] == 0:
                    record["run"] = run
                    f.write(json.dumps(record).encode() + b"\n")
    small = loaded(run_dir)

    async def scenario():
        dashboard = Dashboard([RunSource(big), small], poll_s=0.1)
        async with TestClient(TestServer(make_app(dashboard))) as client:
            await asyncio.sleep(0.5)  # the big run's first slices are being read
            assert dashboard.sources[next(iter(dashboard.sources))].loading
            big_source = dashboard.sources[next(iter(dashboard.sources))]
            answered = 0  # answers given while the big run was still loading
            while big_source.loading and answered < 3:  # one shared thread made these wait for the whole log
                assert (await client.get(f"/api/runs/{small.id}/report")).status == 200
                answered += big_source.loading
                await asyncio.sleep(0.1)
            return answered

    assert asyncio.run(scenario()) == 3


def test_only_loopback_hosts_are_answered_without_a_token(run_dir):
    async def scenario():
        dashboard = Dashboard([RunSource(run_dir)])
        async with TestClient(TestServer(make_app(dashboard))) as client:
            ok = await client.get("/api/state")
            rebound = await client.get("/api/state", headers={"Host": "attacker.example:8700"})
            local = await client.get("/api/state", headers={"Host": "localhost:8700"})
            return ok.status, rebound.status, local.status

    assert asyncio.run(scenario()) == (200, 403, 200)


def test_beyond_loopback_every_request_needs_the_token(run_dir):
    token = "t0ken-for-the-test"

    async def scenario():
        dashboard = Dashboard([RunSource(run_dir)], poll_s=0.1)
        async with TestClient(TestServer(make_app(dashboard, token))) as client:
            statuses = [(await client.get(path, allow_redirects=False)).status
                        for path in ("/", "/api/state", "/static/app.js", "/api/state?token=wrong")]
            entry = await client.get(f"/?token={token}", allow_redirects=False)
            assert entry.status == 302 and entry.headers["Location"] == "/"
            assert "HttpOnly" in entry.headers["Set-Cookie"] and "SameSite=Strict" in entry.headers["Set-Cookie"]
            # the cookie now goes with the page's own requests (the event stream included)
            assert (await client.get("/api/state")).status == 200
            events = await client.get("/api/events")
            assert (await _next_event(events))[0] == "state"
            events.close()
            client.session.cookie_jar.clear()
            assert (await client.get("/api/state")).status == 401
            bearer = await client.get("/api/state", headers={"Authorization": f"Bearer {token}",
                                                             "Host": "dashboard.lan:8700"})
            return statuses, bearer.status

    statuses, bearer = asyncio.run(scenario())
    assert statuses == [401, 401, 401, 401] and bearer == 200


def test_cli_prints_the_token_with_the_url_beyond_loopback(run_dir, deepphy_cmd):
    proc = subprocess.Popen([*deepphy_cmd, "dashboard", str(run_dir), "--host", "0.0.0.0", "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        url = re.search(r"http://\S+", line).group(0)
        assert re.fullmatch(r"http://0\.0\.0\.0:\d+/\?token=[A-Za-z0-9_-]{20,}", url), line
        port, token = re.search(r":(\d+)/\?token=(\S+)", url).groups()
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/api/state", timeout=30)
        assert e.value.code == 401
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/state?token={token}", timeout=30) as r:
            assert json.load(r)["runs"] is not None
    finally:
        proc.terminate()
        proc.wait(timeout=30)
