"""`deepphy dashboard` in a real headless browser: Debian's chromium driven by Playwright.

The server is the real CLI in a subprocess; the run directories are real MOCK runs. The
page must load without console errors, show exactly the numbers of `deepphy report
--json`, and show a record appended to a run within a few seconds, without a reload.
Screenshots go to $DEEPPHY_SCREENSHOTS (default: the test's tmp directory).
"""

import hashlib
import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from browser_support import needs_chromium
from dashboard_support import IPHYRE_TASKS, append, copy_run, mock_run, synthetic_run
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.runs.discovery import dir_id
from deepphy.metrics.report import report_of, table
from deepphy.runner import evaluate
from deepphy.runs.status import RunStatus, write_status
from deepphy.runs.store import ATTEMPTS, RunStore, read_config, read_records

UPDATE_LIMIT_S = 30.0  # a hang guard, not a speed claim: how fast a page updates is benchmarks/dashboard.py's

pytestmark = needs_chromium


@pytest.fixture(scope="module")
def runs(ray_cluster, tmp_path_factory):
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as pool:  # a thread of its own: Playwright's sync API may hold this one's loop
        return pool.submit(lambda: (mock_run(tmp_path_factory), mock_run(tmp_path_factory, fmt="wm"))).result()


class DashboardProcess:
    """`deepphy dashboard ... --port 0` in a subprocess; its URL read from its first line."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "deepphy.cli", "dashboard", *args, "--port", "0"],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        found = {}
        reader = threading.Thread(target=lambda: found.update(line=self.proc.stdout.readline()), daemon=True)
        reader.start()
        reader.join(120)
        match = re.search(r"http://127\.0\.0\.1:\d+/", found.get("line", ""))
        if not match:
            self.close()
            raise AssertionError(f"the dashboard did not start: {found.get('line')!r}")
        self.url = match.group(0)

    def close(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


@pytest.fixture
def serve():
    """Starts dashboards; stops them after the pages are closed (request it before open_page)."""
    servers = []

    def start(*args: str) -> DashboardProcess:
        servers.append(DashboardProcess(*args))
        return servers[-1]

    yield start
    for server in servers:
        server.close()


def report_json(run_dir) -> dict:
    """What `deepphy report --json` prints."""
    out = subprocess.run([sys.executable, "-m", "deepphy.cli", "report", "--json", str(run_dir)],
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out)


def card_values(page, run_id) -> dict:
    return page.eval_on_selector_all(
        f'.card[data-run="{run_id}"] dd[data-field]',
        "nodes => Object.fromEntries(nodes.map(n => [n.dataset.field, n.dataset.value]))")


def run_id_of(page, path) -> str:
    return page.eval_on_selector_all(".card", f"""cards => cards.find(c =>
        c.querySelector('.path').textContent === {json.dumps(str(Path(path).resolve()))}).dataset.run""")


def assert_page_shows(page, run_dir):
    """The card, the curve and the table of `run_dir` equal `deepphy report --json`."""
    report = report_json(run_dir)
    run_id = run_id_of(page, run_dir)
    per_run = report["overall"]["per_run"]
    values = card_values(page, run_id)
    for field in ("attempts", "solved", "invalid_attempts", "model_errors", "retries", "input_tokens"):
        assert float(values[field]) == sum(r[field] for r in per_run), field
    assert float(values["cost_usd"]) == pytest.approx(sum(r["cost_usd"] for r in per_run))
    assert int(values["episodes_done"]) == sum(r["tasks"] - r["unfinished"] for r in per_run)
    points = page.eval_on_selector_all(f'svg g[data-run="{run_id}"] circle',
                                       "cs => cs.map(c => [Number(c.dataset.x), Number(c.dataset.value)])")
    mean = report["overall"]["mean"]["success_at"]
    assert points == [[k + 1, v] for k, v in enumerate(mean)]
    page.select_option("#run-select", run_id)
    page.wait_for_selector(f'table.report[data-run="{run_id}"]')
    cells = page.eval_on_selector_all("#table table.report tr", "rows => rows.map(r => [...r.children].map(c => c.textContent))")
    header, rows = table([report_of(run_dir)])
    assert cells == [header, *rows]


def test_page_shows_the_report_of_finished_runs(runs, serve, open_page, screenshots):
    server = serve(*map(str, runs))
    page = open_page(server.url)
    page.wait_for_selector("#grid .cell")
    page.wait_for_function("document.querySelectorAll('.card').length === 2")
    for run_dir in runs:
        assert_page_shows(page, run_dir)
    page.select_option("#run-select", run_id_of(page, runs[0]))
    page.wait_for_selector("#grid .cell")
    # the grid: one cell per (task, run), states from the records
    states = page.eval_on_selector_all("#grid .cell", "cs => cs.map(c => [c.dataset.task, Number(c.dataset.r), c.dataset.state])")
    records = read_records(runs[0])
    expected = []
    for task in IPHYRE_TASKS:
        for run in range(2):
            solved = any(r.success for r in records if (r.task, r.run) == (task, run))
            expected.append([task, run, "solved" if solved else "failed"])
    assert states == expected
    assert page.inner_text(f'.card[data-run="{run_id_of(page, runs[0])}"] [data-field=status]') == "complete"
    page.screenshot(path=str(screenshots / "dashboard_finished.png"), full_page=True)


def test_episode_view_shows_prompts_replies_and_frames(runs, serve, open_page, screenshots):
    server = serve(*map(str, runs))
    page = open_page(server.url)
    records = read_records(runs[0])
    later = next(r for r in records if r.attempt >= 2)
    # the first run given is shown (runs load side by side; the page keeps the given order)
    page.click(f'#grid .cell[data-run="{dir_id(runs[0].resolve())}"][data-task="{later.task}"][data-r="{later.run}"]')
    page.wait_for_selector("#episode .attempt")
    attempts = [r for r in records if (r.task, r.run) == (later.task, later.run)]
    assert page.eval_on_selector_all("#episode details.attempt", "ds => ds.length") == len(attempts)
    # Open attempt 2 (setting `open` rather than clicking its summary, which toggles: on a
    # slow machine a click could land while the view is still being drawn).
    page.eval_on_selector('#episode details.attempt[data-attempt="2"]', "d => { d.open = true; }")
    replies = page.eval_on_selector_all("#episode pre.reply", "ps => ps.map(p => p.textContent)")
    assert sorted(replies) == sorted(r.steps[0].raw_output for r in attempts)
    # attempt 2's prompt shows attempt 1's key frame and the current observation: every
    # image the model saw, stored once by content (images/<sha256>.png)
    second = page.locator('#episode details.attempt[data-attempt="2"]')
    frame = hashlib.sha256((runs[0] / attempts[0].key_frames[0].path).read_bytes()).hexdigest()
    img = second.locator(f'.prompt img[src$="images/{frame}.png"]')
    img.wait_for()
    page.wait_for_function("img => img.complete && img.naturalWidth > 0", arg=img.element_handle())
    assert second.locator(".missing").count() == 0
    assert second.locator(".prompt img").count() == 3  # the key frame, the scene and the annotated scene
    assert "#run=" in page.url and "task=" in page.url
    page.screenshot(path=str(screenshots / "dashboard_episode.png"))
    page.keyboard.press("Escape")
    assert page.locator("#episode").is_hidden()

    # a link to an episode opens it; a WM run's episode shows its predictions
    wm = read_records(runs[1])
    page = open_page(f"{server.url}#run={dir_id(runs[1].resolve())}&task={wm[0].task}&r={wm[0].run}")
    page.wait_for_selector("#episode .attempt")
    mine = [r for r in wm if (r.task, r.run) == (wm[0].task, wm[0].run)]
    predictions = page.eval_on_selector_all("#episode pre.prediction", "ps => ps.map(p => p.textContent)")
    assert sorted(predictions) == sorted(r.steps[0].prediction for r in mine) and predictions


def test_records_appended_to_a_run_appear_without_reload(runs, serve, open_page, screenshots, tmp_path):
    copy = tmp_path / "live"
    log = copy_run(runs[0], copy, lines=20)
    server = serve(str(copy))
    page = open_page(server.url)
    page.wait_for_selector("#grid .cell")
    run_id = run_id_of(page, copy)
    page.evaluate("window.__notReloaded = true")
    attempts = f'.card[data-run="{run_id}"] dd[data-field=attempts]'
    assert page.get_attribute(attempts, "data-value") == "20"
    delays = []
    for n in range(21, 27):
        line = log[n - 1]
        record = json.loads(line)
        t0 = time.monotonic()
        append(copy, [line])
        page.wait_for_selector(f'{attempts}[data-value="{n}"]', timeout=UPDATE_LIMIT_S * 1000)
        delays.append(time.monotonic() - t0)
        cell = page.get_attribute(f'#grid .cell[data-task="{record["task"]}"][data-r="{record["run"]}"]', "data-attempts")
        assert int(cell) == record["attempt"]  # the grid follows too
    print(f"page update delay after an appended record: {', '.join(f'{d * 1000:.0f} ms' for d in delays)}")
    # a run in progress: every rate is over its finished episodes, marked partial with their count
    from deepphy.dashboard.source import RunSource

    source = RunSource(copy)
    source.poll()
    partial = source.partial_report(source.report())
    done = partial.overall.finished
    page.wait_for_function(f"""() => {{ const n = document.querySelector('.card[data-run="{run_id}"] [data-field=partial]');
        return n && n.textContent.includes('over the {done} of 12 episodes finished'); }}""", timeout=UPDATE_LIMIT_S * 1000)
    points = page.eval_on_selector_all(f'svg g[data-run="{run_id}"] circle', "cs => cs.map(c => Number(c.dataset.value))")
    assert points == partial.overall.mean.success_at
    assert "partial" in page.text_content(f'.chart-legend span[data-run="{run_id}"]')
    assert page.evaluate("window.__notReloaded") is True
    page.screenshot(path=str(screenshots / "dashboard_live.png"), full_page=True)
    append(copy, log[26:])
    page.wait_for_selector(f'{attempts}[data-value="{len(log)}"]', timeout=UPDATE_LIMIT_S * 1000)
    page.wait_for_function(f'document.querySelector(\'.card[data-run="{run_id}"] [data-field=status]\').textContent === "complete"')
    assert_page_shows(page, copy)
    assert report_of(copy) == report_of(runs[0])


@pytest.mark.slow
def test_a_live_evaluation_found_on_the_cluster(ray_cluster, serve, open_page, screenshots, tmp_path):
    """No run directory given: the dashboard finds the run by its metrics actor on the
    cluster, follows it while it runs, and ends with the report's numbers."""
    out = tmp_path / "live-eval"
    config = RunConfig(env="iphyre", model="mock", runs=3, seed=11)
    server = serve("--address", ray_cluster)
    thread = threading.Thread(target=evaluate, args=(config, out, RuntimeOptions(progress=False, env_workers=2)))
    try:
        page = open_page(server.url)
        thread.start()
        page.wait_for_selector(".card .badge.running", timeout=120_000)
        page.wait_for_selector("#grid .cell.solved", timeout=120_000)
        page.screenshot(path=str(screenshots / "dashboard_cluster_running.png"), full_page=True)
        thread.join(600)
        assert not thread.is_alive()
        page.wait_for_selector(".card .badge.complete", timeout=30_000)
        assert_page_shows(page, out)
    finally:
        thread.join(600)


def _with_a_zero_star_win(run_dir):
    """The run with its first won level re-scored 0 stars (Cut the Rope allows it)."""
    lines = (run_dir / ATTEMPTS).read_bytes().splitlines()
    first = next(i for i, line in enumerate(lines) if json.loads(line)["success"])
    record = json.loads(lines[first])
    lines[first] = json.dumps({**record, "stars": 0}).encode()
    (run_dir / ATTEMPTS).write_bytes(b"".join(line + b"\n" for line in lines))
    return run_dir


def test_charts_per_environment_stars_colours_and_phase(serve, open_page, screenshots, tmp_path):
    """One success chart per environment on its own regular x axis; the stars chart counts
    a level won with 0 stars and its label clears the ticks; run colours are not status
    colours; a compiling run says so; episode images load without scrolling to them."""
    pool = synthetic_run(tmp_path / "pool", env="pooltool", limit=6, max_steps=15, p_success=0.6)
    kin = synthetic_run(tmp_path / "kin", limit=6, max_steps=8)
    ctr = _with_a_zero_star_win(synthetic_run(tmp_path / "ctr", env="cuttherope", limit=8, stars=True,
                                              max_steps=6, p_success=0.6))
    compiling = tmp_path / "compiling"
    copy_run(kin, compiling, lines=0)
    store = RunStore.create_or_resume(compiling, read_config(compiling))
    try:
        write_status(compiling, RunStatus(run_id="c0ffee00", pid=os.getpid(), phase="compiling", since=time.time()))
        server = serve(str(pool), str(kin), str(ctr), str(compiling))
        page = open_page(server.url)
        page.wait_for_function("document.querySelectorAll('.card').length === 4")
        page.wait_for_selector('.chart[data-env="cuttherope"][data-kind="stars"] rect')
        badge = f'.card[data-run="{run_id_of(page, compiling)}"] [data-field=status]'
        page.wait_for_function(f"document.querySelector('{badge}').textContent === 'compiling'")

        kinds = page.eval_on_selector_all(".chart", "cs => cs.map(c => [c.dataset.env, c.dataset.kind, c.querySelector('h3').textContent])")
        assert ["pooltool", "decisions-pooltool", "Pooltool: success rate within k shots"] in kinds
        assert ["kinetix", "decisions-kinetix", "Kinetix: success rate within k decisions"] in kinds
        assert ["cuttherope", "stars", "Cut the Rope: levels won with 0, 1, 2, 3 stars (light to dark)"] in kinds
        ticks = page.eval_on_selector_all('.chart[data-env="pooltool"] svg text[text-anchor=middle]',
                                          "ts => ts.map(t => t.textContent)")
        assert ticks[:15] == [str(k) for k in range(1, 16)]  # every shot, evenly spaced

        zero = page.eval_on_selector_all('.chart[data-kind="stars"] rect[data-stars="0"]', "rs => rs.map(r => Number(r.dataset.value))")
        assert zero == [report_of(ctr).overall.mean.stars.levels_with["0"]] and zero[0] > 0
        overlaps = page.evaluate("""() => {
            const svg = document.querySelector('.chart[data-kind="stars"] svg');
            const label = [...svg.querySelectorAll('text')].find(t => t.textContent === 'levels won').getBBox();
            return [...svg.querySelectorAll('text[text-anchor=end]')].filter(t => { const b = t.getBBox();
                return b.x < label.x + label.width && label.x < b.x + b.width && b.y < label.y + label.height && label.y < b.y + b.height; }).length;
        }""")
        assert overlaps == 0

        status_colours = page.evaluate("""() => ['--solved', '--failed', '--progress'].map(v =>
            getComputedStyle(document.documentElement).getPropertyValue(v).trim().toLowerCase())""")
        run_colours = page.eval_on_selector_all(".card", "cs => cs.map(c => c.style.getPropertyValue('--run-color').toLowerCase())")
        assert len(set(run_colours)) == 4 and not set(run_colours) & set(status_colours)
        page.screenshot(path=str(screenshots / "dashboard_charts.png"), full_page=True)

        # an episode with several decisions: every key frame loads (none lazily), even below the fold
        page.select_option("#run-select", run_id_of(page, kin))
        page.wait_for_selector('#grid .cell[data-state="failed"]')
        page.click('#grid .cell[data-state="failed"]')
        page.wait_for_selector("#episode .attempt")
        page.eval_on_selector_all("#episode details", "ds => ds.forEach(d => { d.open = true; })")
        assert page.eval_on_selector_all("#episode img[loading=lazy]", "is => is.length") == 0
        page.wait_for_function("() => { const is = [...document.querySelectorAll('#episode img')];"
                               " return is.length > 2 && is.every(i => i.complete && i.naturalWidth > 0); }")
        page.screenshot(path=str(screenshots / "dashboard_episode_frames.png"))
    finally:
        store.close()


def board_rows(page) -> list[list[str]]:
    return page.eval_on_selector_all("table.leaderboard tbody tr", "rows => rows.map(r => [...r.children].map(c => c.textContent))")


def leaderboard_rows(root) -> list[list[str]]:
    """The rows `deepphy leaderboard ROOT --json` prints, as the page shows them."""
    out = subprocess.run([sys.executable, "-m", "deepphy.cli", "leaderboard", "--json", str(root)],
                         capture_output=True, text=True, check=True).stdout
    return [[f"{r['model']} {r['format'].upper()}", *(c["text"] for c in r["cells"])] for r in json.loads(out)["rows"]]


def test_leaderboard_of_a_suite_root_follows_its_runs(serve, open_page, screenshots, tmp_path):
    """A suite root: its leaderboard is `deepphy leaderboard`'s table, a cell not started and
    a run cut short shown unfinished; the run's records arriving turn it into figures live."""
    root = tmp_path / "suite"
    synthetic_run(root / "mock" / "iphyre" / "vla", env="iphyre", limit=4, p_success=0.3)
    synthetic_run(root / "mock" / "angrybirds" / "vla", env="angrybirds", limit=4, stars=True, p_success=0.5)
    full = synthetic_run(tmp_path / "full", env="iphyre", limit=4, model="gpt-4o", p_success=0.7)
    log = copy_run(full, root / "gpt-4o" / "iphyre" / "vla", lines=3)
    cells = [{"dir": str(p.parent.relative_to(root)), "config": read_config(p.parent).model_dump(mode="json")}
             for p in sorted(root.rglob("config.json"))]
    waiting = RunConfig(env="angrybirds", model="gpt-4o", runs=2, limit=4)
    cells.append({"dir": "gpt-4o/angrybirds/vla", "config": waiting.model_dump(mode="json")})
    (root / "suite.json").write_text(json.dumps({"suite": "test", "description": "", "cells": cells}))

    server = serve(str(root))
    page = open_page(server.url)
    page.wait_for_function("document.querySelectorAll('.card').length === 3")
    expected = leaderboard_rows(root)
    page.wait_for_function("rows => JSON.stringify([...document.querySelectorAll('table.leaderboard tbody tr')]"
                           ".map(r => [...r.children].map(c => c.textContent))) === JSON.stringify(rows)", arg=expected)
    gpt = next(r for r in expected if r[0] == "gpt-4o VLA")
    # Angry Birds not started; I-PHYRE cut; each with its n
    assert gpt[1:3] == ["4x2 (0 done)", "unfinished 0/8"] and gpt[5].startswith("unfinished ") and gpt[4].startswith("4x2 (")
    header = page.eval_on_selector_all("table.leaderboard thead tr:first-child th[colspan]", "ths => ths.map(t => t.textContent)")
    assert header == ["Angry Birds", "I-PHYRE"]
    page.screenshot(path=str(screenshots / "dashboard_leaderboard_unfinished.png"), full_page=True)

    page.evaluate("window.__notReloaded = true")
    append(root / "gpt-4o" / "iphyre" / "vla", log[3:])
    cell = 'table.leaderboard tr[data-model="gpt-4o"] td[data-column="I-PHYRE Succ@10"]'
    page.wait_for_selector(f'{cell}[data-unfinished=""]', timeout=UPDATE_LIMIT_S * 1000)
    expected = leaderboard_rows(root)
    assert board_rows(page) == expected
    assert float(page.get_attribute(cell, "data-mean")) == report_of(full).overall.mean.success_at[-1]
    assert page.evaluate("window.__notReloaded") is True
    page.screenshot(path=str(screenshots / "dashboard_leaderboard.png"), full_page=True)


def test_episode_browser_filters_searches_and_steps_through_the_list(runs, serve, open_page, screenshots):
    """The episodes of a run as a list to filter (outcome, invalid reason, group, attempts) and
    search; an episode opened from it steps to the previous and next of the filtered list
    (buttons and arrow keys), puts another run of the same task beside it, and enlarges an
    image on a click."""
    run_dir = runs[0]
    records = read_records(run_dir)
    server = serve(str(run_dir))
    page = open_page(server.url)
    page.wait_for_selector("#samples tr.sample")
    listed = lambda: page.eval_on_selector_all("#samples tr.sample", "rs => rs.map(r => [r.dataset.task, Number(r.dataset.r)])")  # noqa: E731
    episodes = {}
    for r in records:
        episodes.setdefault((r.task, r.run), []).append(r)
    order = [(t, run) for t in IPHYRE_TASKS for run in range(2)]
    listed_all = listed()
    assert listed_all == [list(k) for k in order] and page.text_content("#f-count") == "12 of 12 episodes"

    solved = [list(k) for k in order if any(r.success for r in episodes[k])]
    page.select_option("#f-outcome", "solved")
    assert listed() == solved and 0 < len(solved) < 12
    page.select_option("#f-outcome", "failed")
    assert listed() == [list(k) for k in order if list(k) not in solved]
    page.select_option("#f-outcome", "")
    groups = {r.task: r.group for r in records}
    page.select_option("#f-group", groups["hinder"])
    assert listed() == [list(k) for k in order if groups[k[0]] == groups["hinder"]] != listed_all
    page.select_option("#f-group", "")
    page.select_option("#f-attempts", "1")
    assert listed() == [list(k) for k in order if len(episodes[k]) == 1]
    page.select_option("#f-attempts", "")
    page.select_option("#f-reason", "*")
    assert listed() == [list(k) for k in order if any(r.invalid_reason for r in episodes[k])]
    page.select_option("#f-reason", "")
    page.fill("#f-search", "hinder")
    assert listed() == [list(k) for k in order if "hinder" in k[0]]

    # open the first of the filtered list, then next, next by key, previous
    page.fill("#f-search", "")
    page.select_option("#f-outcome", "solved")
    page.click("#samples tr.sample >> nth=0")
    page.wait_for_selector("#episode .timeline")
    title = lambda: page.text_content("#episode-title")  # noqa: E731
    assert title().startswith(f"{solved[0][0]} · run {solved[0][1]} ·") and page.text_content("#episode-place") == f"1 of {len(solved)}"
    assert page.is_disabled("#episode-prev")
    page.click("#episode-next")
    page.wait_for_function("t => document.querySelector('#episode-title').textContent.startsWith(t)", arg=f"{solved[1][0]} · run {solved[1][1]} ·")
    page.keyboard.press("ArrowRight")
    page.wait_for_function("t => document.querySelector('#episode-title').textContent.startsWith(t)", arg=f"{solved[2][0]} · run {solved[2][1]} ·")
    assert page.text_content("#episode-place") == f"3 of {len(solved)}"
    page.click("#episode-prev")
    page.wait_for_function("t => document.querySelector('#episode-title').textContent.startsWith(t)", arg=f"{solved[1][0]} · run {solved[1][1]} ·")
    # the decision timeline: a bar per decision, with the model's time to answer
    task, r = solved[1]
    bars = page.eval_on_selector_all("#episode .tl-bar", "bs => bs.map(b => Number(b.dataset.seconds))")
    assert bars == [s for a in sorted(episodes[(task, r)], key=lambda a: a.attempt) for s in a.timing.decision_s]
    # the other run of the task beside it
    page.select_option("#episode-compare", f"{dir_id(run_dir.resolve())}|{1 - r}")
    page.wait_for_selector("#episode .compare-grid .side >> nth=1")
    assert page.text_content("#episode .compare-grid .side:nth-child(2) .side-title").endswith(f"run {1 - r}")
    # an image, enlarged on a click
    page.eval_on_selector("#episode .side details.attempt", "d => { d.open = true; }")
    img = page.locator("#episode .side img.zoomable").first
    src = img.get_attribute("src")
    img.click()
    assert page.is_visible("#lightbox") and page.get_attribute("#lightbox img", "src") == src
    page.screenshot(path=str(screenshots / "dashboard_browser_lightbox.png"))
    page.keyboard.press("Escape")
    assert page.is_hidden("#lightbox") and page.is_visible("#episode")
    page.screenshot(path=str(screenshots / "dashboard_browser_compare.png"))


@pytest.mark.parametrize("width", [390, 1280])
def test_the_dashboard_holds_at_a_phones_and_a_laptops_width(runs, serve, open_page, browser, screenshots, width):
    """No part of the page is wider than the screen (tables scroll in their own boxes), the
    episode view included."""
    server = serve(*map(str, runs))
    page = open_page(server.url)
    page.set_viewport_size({"width": width, "height": 844})
    page.wait_for_selector("#samples tr.sample")
    page.wait_for_function("document.querySelectorAll('.chart svg').length > 0")
    assert page.evaluate("document.documentElement.scrollWidth") <= width
    page.screenshot(path=str(screenshots / f"dashboard_{width}.png"), full_page=True)
    page.click("#samples tr.sample >> nth=0")
    page.wait_for_selector("#episode .timeline")
    page.select_option("#episode-compare", index=1)
    page.wait_for_selector("#episode .compare-grid")
    assert page.evaluate("document.documentElement.scrollWidth") <= width
    assert page.evaluate("document.querySelector('#episode .modal-box').scrollWidth") <= width
    page.screenshot(path=str(screenshots / f"dashboard_episode_{width}.png"))
