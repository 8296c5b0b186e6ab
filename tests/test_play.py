"""`deepphy play` without a browser: a person as a `ModelHandle`, the journal that makes a
play resumable mid-attempt, the server's guards, films of the environments' steps and the
replay of recorded attempts. (The page itself: tests/test_play_browser.py.)"""

from __future__ import annotations

import asyncio
import json
import subprocess
import time

import pytest
import toy_env
from aiohttp.test_utils import TestClient, TestServer

from deepphy.config import RunConfig
from deepphy.envs import get_spec, register, unregister
from deepphy.envs.base import FILM_FPS, Environment
from deepphy.play.human import JOURNAL, Journal
from deepphy.play.replay import film_attempt
from deepphy.play.server import PlayServer, make_app
from deepphy.play.session import PlaySession
from deepphy.runs.store import ATTEMPTS, RunDirError, read_records
from play_support import answer, model_run, person_run, same_records

TASKS = ["flag-03", "flag-07"]


@pytest.fixture(scope="module", autouse=True)
def toy():
    register(toy_env.SPEC)
    yield
    unregister(toy_env.SPEC.name)


def push(task: str, run: int, attempt: int, step: int) -> str:
    """A person's (and the scripted model's) answers: flag-03 is solved at attempt 2."""
    plans = {("flag-03", 1): [1, 0, 0, 0], ("flag-03", 2): [2, -1, -1, 0], ("flag-07", 1): [2, 1, 0, 0],
             ("flag-07", 2): [2, 2, -2, 0]}
    return f"push({plans[(task, attempt)][step - 1]})"


def config(**kw) -> RunConfig:
    return RunConfig(**{"env": "toy_cart", "model": "human:ana", "runs": 1, "tasks": TASKS, **kw})


async def answer_until(session: PlaySession, stop_after: int | None = None) -> list[str]:
    return await answer(session, push, stop_after)


def test_a_person_is_a_model_handle_and_records_equal_model_replies(tmp_path):
    session = PlaySession(config(), tmp_path / "person")
    try:
        keys = asyncio.run(answer_until(session))
    finally:
        session.close()
    person = read_records(tmp_path / "person")
    assert [r.key[:3] for r in person] == [("flag-03", 0, 1), ("flag-03", 0, 2), ("flag-07", 0, 1), ("flag-07", 0, 2)]
    assert person[1].success and not person[3].success
    assert len(keys) == sum(len(r.steps) for r in person)
    same_records(person, model_run(config(model="scripted"), tmp_path / "model", push))
    # every decision's time is the person's, and the journal holds every answer
    journal = [json.loads(line) for line in (tmp_path / "person" / JOURNAL).read_text().splitlines()]
    assert [a["text"] for a in journal] == [s.raw_output for r in person for s in r.steps]
    assert [a["seconds"] for a in journal] == [t for r in person for t in r.timing.decision_s]


def test_a_play_stopped_mid_attempt_resumes_at_the_same_decision(tmp_path):
    out = tmp_path / "person"
    first = PlaySession(config(), out)
    try:
        keys = asyncio.run(answer_until(first, stop_after=6))  # attempt 1 (4 pushes), then 2 of attempt 2
    finally:
        first.close()
    assert [r.key for r in read_records(out)] == [("flag-03", 0, 1)]  # attempt 2 is not recorded yet

    second = PlaySession(config(), out)
    try:
        async def resume() -> str:
            play = asyncio.ensure_future(second.play())
            while second.desk.pending is None:
                await asyncio.sleep(0.005)
            waiting = second.desk.pending.key
            play.cancel()
            return waiting
        waiting = asyncio.run(resume())
    finally:
        second.close()
    # asked from the first decision not yet answered: attempt 2, push 3
    assert waiting.split("|")[:4] == ["flag-03", "0", "2", "3"]
    assert keys[-1].split("|")[:4] == ["flag-03", "0", "2", "2"]

    third = PlaySession(config(), out)
    try:
        asyncio.run(answer_until(third))
    finally:
        third.close()
    person = read_records(out)
    same_records(person, model_run(config(model="scripted"), tmp_path / "model", push))
    journal = [json.loads(line) for line in (out / JOURNAL).read_text().splitlines()]
    # nothing lost: the two answers given before the stop count with the times they took
    assert person[1].timing.decision_s[:2] == [journal[4]["seconds"], journal[5]["seconds"]]
    assert len(journal) == sum(len(r.steps) for r in person)


def test_an_answer_is_replayed_only_for_the_prompt_it_answered(tmp_path):
    out = tmp_path / "person"
    session = PlaySession(config(tasks=["flag-03"]), out)
    try:
        asyncio.run(answer_until(session, stop_after=2))
    finally:
        session.close()
    lines = (out / JOURNAL).read_text().splitlines()
    changed = json.loads(lines[1]) | {"prompt": "0" * 20, "text": "push(-2)"}  # as if the environment changed
    (out / JOURNAL).write_text(lines[0] + "\n" + json.dumps(changed) + "\n" + '{"task": "flag-03", "ru')  # + a torn line
    session = PlaySession(config(tasks=["flag-03"]), out)
    try:
        async def waiting() -> str:
            play = asyncio.ensure_future(session.play())
            while session.desk.pending is None:
                await asyncio.sleep(0.005)
            play.cancel()
            return session.desk.pending.key
        assert asyncio.run(waiting()).split("|")[:4] == ["flag-03", "0", "1", "2"]
    finally:
        session.close()
    assert (out / JOURNAL).read_bytes().endswith(b"}\n")  # the torn line was dropped
    (out / JOURNAL).write_text("not json\n")
    with pytest.raises(RunDirError, match=f"{JOURNAL}:1 is not a valid answer"):
        Journal(out)


def test_the_server_takes_answers_from_its_page_only(tmp_path):
    session = PlaySession(config(tasks=["flag-03"]), tmp_path / "person")

    async def main() -> None:
        play = asyncio.ensure_future(session.play())
        async with TestClient(TestServer(make_app(PlayServer(session)), host="127.0.0.1")) as client:
            while session.desk.pending is None:
                await asyncio.sleep(0.005)
            state = await (await client.get("/api/state")).json()
            decision = state["decision"]
            key, host = decision["key"], f"127.0.0.1:{client.port}"
            assert decision["space"]["kind"] == "toy_push" and decision["step"] == 1
            image = next(p for p in decision["observation"] if "image" in p)
            png = await (await client.get(image["image"])).read()
            assert png == session.desk.pending.images[0].load()

            ok = {"Origin": f"http://{host}"}
            checked = await (await client.post("/api/check", json={"key": key, "text": "push(9)"}, headers=ok)).json()
            assert checked == {"ok": False, "error": "F must be one of (-2, -1, 0, 1, 2), got 9"}
            checked = await (await client.post("/api/check", json={"key": key, "text": "I push(1)"}, headers=ok)).json()
            assert checked == {"ok": True, "action": "push(1)"}
            rebound = await client.get("/api/state", headers={"Host": f"evil.example:{client.port}"})
            assert rebound.status == 403  # a page whose name resolves here reads nothing
            refused = [
                await client.post("/api/answer", json={"key": key, "text": "push(1)"}, headers={"Origin": "http://evil.example"}),
                # a page of another site whose name resolves to this machine (DNS rebinding)
                await client.post("/api/answer", json={"key": key, "text": "push(1)"},
                                  headers={"Origin": f"http://evil.example:{client.port}", "Host": f"evil.example:{client.port}"}),
                await client.post("/api/answer", data=json.dumps({"key": key, "text": "push(1)"}), headers=ok),
                await client.post("/api/answer", json={"key": key + "x", "text": "push(1)"}, headers=ok),
                await client.post("/api/answer", json={"key": key, "text": "push(9)"}, headers=ok),
            ]
            assert [r.status for r in refused] == [403, 403, 415, 409, 400]
            assert session.desk.pending is not None and session.desk.pending.key == key  # still waiting
            accepted = await client.post("/api/answer", json={"key": key, "text": "I push(1)"}, headers=ok)
            assert accepted.status == 200 and (await accepted.json())["action"] == "push(1)"
            again = await client.post("/api/answer", json={"key": key, "text": "push(1)"}, headers=ok)
            assert again.status == 409  # answered once only
            while session.desk.pending is None or session.desk.pending.key == key:
                await asyncio.sleep(0.005)
            state = await (await client.get("/api/state")).json()
            assert state["decision"]["step"] == 2 and state["last"]["text"] == "I push(1)"
            # what the decision did reaches the page as it reaches a model: in the next prompt only
            assert set(state["last"]) == {"id", "attempt", "step", "text", "attempt_over", "episode"}
            assert "flag-03" not in json.dumps(state["last"]) and "flag-03" not in json.dumps(state["recent"])
            assert (await client.get(f"/api/last/{state['last']['id']}/0.png")).status == 404
            # no replay of a task still in play (a model sees none before its next decision)
            early = await client.get(f"/api/runs/{state['run_id']}/replay?task=flag-03&run=0&attempt=1")
            assert early.status == 403 and "still being played" in await early.text()
            # The page may still be loading the answered decision's pictures: they stay served.
            answered = await client.get(image["image"])
            assert answered.status == 200 and await answered.read() == png
            unknown = [await client.get(image["image"].replace("/0.png", "/-1.png")),
                       await client.get(image["image"].replace("/0.png", "/9.png"))]
            assert [r.status for r in unknown] == [404, 404]
        play.cancel()

    try:
        asyncio.run(main())
    finally:
        session.close()
    [step] = [json.loads(line) for line in (tmp_path / "person" / JOURNAL).read_text().splitlines()]
    assert step["text"] == "I push(1)"  # the reply is what the person sent; the action is parsed from it


@pytest.mark.parametrize("listening, origin, host, ours", [
    ("127.0.0.1", "http://127.0.0.1:8710", "127.0.0.1:8710", True),
    ("127.0.0.1", "http://localhost:8710", "localhost:8710", True),
    ("127.0.0.1", "http://evil.example:8710", "evil.example:8710", False),  # a name that resolves here
    ("127.0.0.1", "http://evil.example", "127.0.0.1:8710", False),
    ("127.0.0.2", "http://127.0.0.2:8710", "127.0.0.2:8710", True),  # loopback is 127.0.0.0/8
    ("127.0.0.2", "http://evil.example:8710", "evil.example:8710", False),
    ("::1", "http://[::1]:8710", "[::1]:8710", True),
    ("0.0.0.0", "http://10.1.2.3:8710", "10.1.2.3:8710", True),  # --host: reached from another machine
    ("0.0.0.0", "http://evil.example", "10.1.2.3:8710", False),
    ("0.0.0.0", None, "10.1.2.3:8710", True),  # not a browser's cross-site request (and it has the token)
])
def test_which_pages_may_answer(listening, origin, host, ours):
    from deepphy import webguard

    token = webguard.token_for(listening, "DEEPPHY_TEST_NO_SUCH_VARIABLE")
    assert (token is None) is (listening != "0.0.0.0")
    assert webguard.from_page(origin, host, token) is ours


@pytest.mark.parametrize("listen", ["127.0.0.2", "0.0.0.0"])
def test_play_on_any_address_answers_only_its_own_page(deepphy_cmd, tmp_path, listen):
    """`--host 127.0.0.2` is loopback too: a foreign Host and a rebinding Origin (a page whose
    name resolves here) are refused, as on 127.0.0.1 (the check trusted three literal names).
    Beyond loopback every request needs the token printed with the URL (there was none)."""
    import re
    import signal
    import urllib.error
    import urllib.request

    proc = subprocess.Popen([*deepphy_cmd, "play", "--env", "phyre", "--tasks", "within_00000-000", "--player", "ana",
                             "--out", str(tmp_path / "p"), "--host", listen, "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        line = proc.stdout.readline()
        port, token = re.search(r"http://[^/\s]+:(\d+)/(?:\?token=(\S+))?", line).groups()
        assert (token is None) is (listen == "127.0.0.2"), line
        base = f"http://{'127.0.0.2' if listen == '127.0.0.2' else '127.0.0.1'}:{port}"
        evil = f"evil.example:{port}"

        def call(path: str, headers: dict | None = None, body: dict | None = None) -> tuple[int, bytes]:
            request = urllib.request.Request(base + path, headers=headers or {},
                                             data=None if body is None else json.dumps(body).encode())
            if body is not None:
                request.add_header("Content-Type", "application/json")
            try:
                with browser.open(request, timeout=30) as r:
                    return r.status, r.read()
            except urllib.error.HTTPError as e:
                return e.code, e.read()

        browser = urllib.request.build_opener(urllib.request.HTTPCookieProcessor())  # keeps the token's cookie
        mine = {"Authorization": f"Bearer {token}"} if token else {}
        for _ in range(600):  # the first decision waits for the person
            status, body = call("/api/state", mine)
            assert status == 200, body
            if json.loads(body)["decision"]:
                break
            time.sleep(0.1)
        answer = {"key": json.loads(body)["decision"]["key"], "text": "Cell: 5, Radius: 4"}
        if token:
            assert call("/api/state")[0] == 401 and call(f"/api/state?token={token}x")[0] == 401
            assert call(f"/?token={token}")[0] == 200  # the URL printed: the page, the token kept in a cookie
            assert call("/api/state")[0] == 200
            mine = {}  # the page's own requests: the cookie
        else:
            assert call("/api/state", {"Host": evil})[0] == 403
            assert call("/api/answer", {"Host": evil, "Origin": f"http://{evil}"}, answer)[0] == 403  # rebinding
        assert call("/api/answer", {**mine, "Origin": f"http://{evil}"}, answer)[0] == 403
        status, body = call("/api/answer", {**mine, "Origin": base}, answer)
        assert status == 200 and json.loads(body)["action"] == "Cell: 5, Radius: 4"
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()


@pytest.mark.parametrize("args, message", [
    (["--player", "ana smith"], "player name 'ana smith'"),
    (["--port", "70000"], "--port must be 0..65535"),
    (["--env", "nope"], "unknown environment 'nope'"),
])
def test_play_refuses_bad_options_in_one_line(deepphy_cmd, tmp_path, args, message):
    done = subprocess.run([*deepphy_cmd, "play", "--out", str(tmp_path / "p"), *args], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and message in done.stderr, done.stderr
    assert not (tmp_path / "p").exists()


def test_play_refuses_a_run_directory_of_a_model_or_of_other_options(deepphy_cmd, tmp_path):
    from deepphy.runs.store import RunStore

    RunStore.create_or_resume(tmp_path / "m", RunConfig(env="iphyre", model="mock")).close()
    done = subprocess.run([*deepphy_cmd, "play", "--out", str(tmp_path / "m")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "holds a run of the model mock, not a person's" in done.stderr
    RunStore.create_or_resume(tmp_path / "h", RunConfig(env="iphyre", model="human:ana", runs=1)).close()
    done = subprocess.run([*deepphy_cmd, "play", "--out", str(tmp_path / "h"), "--runs", "2"], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 2 and 'holds a run with a different config (runs: 1 -> 2)' in done.stderr


# -- films and replays ----------------------------------------------------------------------------

FILMED = {  # environment, task, an action (after the actions before it): the environments whose steps are filmed
    "phyre": ("within_00000-000", "Cell: 5, Radius: 4"),
    "iphyre": ("support", '[{"time": 1.0, "index": 0}]'),
    "kinetix": ("s_h3_point_the_thruster", "[1, 1]"),
    "pooltool": ("rack_000", "Speed: High, Strikespot: top-left"),
    "angrybirds": ("s1_l01", "shoot(angle=40, power=0.9)"),
    "cuttherope": ("b1_l01", "sleep(2)"),
}
BEFORE = {"cuttherope": ["cut_pin(1)"]}  # a candy hangs still until a rope is cut


@pytest.mark.parametrize("env_name", [pytest.param(e, marks=[pytest.mark.slow] if e == "kinetix" else [])
                                      for e in sorted(FILMED)])  # Kinetix traces two programs: ~35 s
def test_a_filmed_step_is_the_step(env_name):
    task_id, text = FILMED[env_name]
    cls = get_spec(env_name).load()
    assert cls.film is not Environment.film
    task = next(t for t in cls.tasks(cls.Options()) if t.id == task_id)
    env = cls()

    def start():
        observation = env.reset(task)
        for before in BEFORE.get(env_name, []):
            observation = env.step(observation.action_space.parse(before)).observation
        return observation

    action = start().action_space.parse(text)
    stepped = env.step(action)
    start()
    filmed, pictures = env.film(action)
    assert filmed.model_dump(exclude={"observation"}) == stepped.model_dump(exclude={"observation"})
    assert (filmed.observation is None) == (stepped.observation is None)
    # about FILM_FPS pictures per simulated second of the world moving (until it rests), more than its key frames
    times = [float(p.caption.split()[2]) for p in pictures]
    assert times == sorted(times) and len(pictures) > 2 * len(stepped.key_frames)
    assert times[-1] == pytest.approx(len(pictures) / FILM_FPS, abs=1.0)
    assert len({p.rgb.tobytes() for p in pictures}) >= 4


def test_replay_simulates_the_recorded_actions_and_says_when_it_differs(tmp_path):
    config = RunConfig(env="phyre", model="scripted", runs=1, tasks=["within_00000-000"], max_attempts=2)
    answers = {1: "Cell: 1, Radius: 1", 2: "Cell: 5, Radius: 4"}
    records = model_run(config, tmp_path / "run", lambda task, run, attempt, step: answers[attempt])
    assert [r.success for r in records] == [False, True]
    film = film_attempt(tmp_path / "run", "within_00000-000", 0, 2)
    assert film.matches and film.filmed and film.note == ""
    assert [d["action"] for d in film.decisions] == ["Cell: 5, Radius: 4"]
    assert len(film.pictures) > 100 and all(p.startswith(b"\xff\xd8") for p in film.pictures)  # JPEG
    with pytest.raises(KeyError):
        film_attempt(tmp_path / "run", "within_00000-000", 0, 3)
    # a record the environment no longer reproduces is said to differ, not shown as what happened
    log = tmp_path / "run" / ATTEMPTS
    lines = log.read_text().splitlines()
    record = json.loads(lines[1])
    record["steps"][0]["feedback"] = "something else"
    log.write_text(lines[0] + "\n" + json.dumps(record) + "\n")
    film = film_attempt(tmp_path / "run", "within_00000-000", 0, 2)
    assert not film.matches and "differs from the record" in film.note


def test_work_off_the_loop_hands_any_error_to_its_caller():
    """A StopIteration (a `next()` that found nothing) cannot be set on a Future: the caller
    gets a RuntimeError that says so instead of waiting forever."""
    from deepphy.play.background import off_loop

    async def main() -> None:
        with pytest.raises(RuntimeError, match="next raised StopIteration"):
            await asyncio.wait_for(off_loop(next, iter([])), 30)
        assert await asyncio.wait_for(off_loop(sum, [1, 2]), 30) == 3

    asyncio.run(main())


def test_the_replay_of_a_record_whose_task_is_not_the_runs_answers_with_one_line(tmp_path):
    """A record naming a task the run does not have (edited, or copied from another run): the
    replay page (dashboard and play) shows why, instead of a request that never answers."""
    from deepphy.dashboard.server import Dashboard, make_app as dashboard_app
    from deepphy.dashboard.source import RunSource

    out = tmp_path / "run"
    model_run(config(model="scripted", tasks=["flag-03"]), out, push)
    foreign = json.loads((out / ATTEMPTS).read_text().splitlines()[0]) | {"task": "flag-07"}
    with open(out / ATTEMPTS, "a") as f:
        f.write(json.dumps(foreign) + "\n")

    async def main() -> list[tuple[int, str]]:
        source = RunSource(out)
        async with TestClient(TestServer(dashboard_app(Dashboard([source])))) as client:
            answers = []
            for task in ("flag-07", "flag-03"):
                response = await asyncio.wait_for(
                    client.get(f"/api/runs/{source.id}/replay?task={task}&run=0&attempt=1"), 60)
                answers.append((response.status, await response.text()))
            return answers

    (status, text), (ok, _) = asyncio.run(main())
    assert status == 404 and text == "no such attempt: the record's task flag-07 is not one of this run's toy_cart tasks"
    assert ok == 200


def test_an_environment_that_does_not_film_replays_its_key_frames(tmp_path):
    config = RunConfig(env="toy_cart", model="scripted", runs=1, tasks=["flag-03"])
    records = model_run(config, tmp_path / "run", push)
    film = film_attempt(tmp_path / "run", "flag-03", 0, 1)
    assert not film.filmed and "does not film its steps" in film.note and film.matches
    # the scene before the first decision, each decision's key frames and the observation after it (but the last)
    assert len(film.pictures) == 1 + len(records[0].key_frames) + len(records[0].steps) - 1


def test_a_persons_run_is_reported_and_plotted_beside_a_models(tmp_path):
    from deepphy.metrics.report import render_text, report_of, table
    from deepphy.plots import plot_all

    person_run(config(), tmp_path / "person", push)
    model_run(config(model="mock-scripted"), tmp_path / "model", lambda task, run, attempt, step: "push(0)")
    reports = [report_of(tmp_path / "person"), report_of(tmp_path / "model")]
    header, rows = table(reports)
    assert {row[0] for row in rows} == {"human:ana VLA", "mock-scripted VLA"}  # a row per group and setting
    assert reports[0].overall.per_run[0].solved == 1 and reports[1].overall.per_run[0].solved == 0
    assert "human:ana" in render_text(reports)
    written = plot_all(reports, tmp_path / "figures")
    assert written and all(path.stat().st_size > 0 for path in written)
    assert "human:ana" in (tmp_path / "figures" / "figures.json").read_text()


def test_ctrl_c_stops_play_at_once_and_the_same_command_resumes(deepphy_cmd, tmp_path):
    import re
    import signal
    import urllib.request

    args = [*deepphy_cmd, "play", "--env", "phyre", "--tasks", "within_00000-000", "--player", "ana",
            "--out", str(tmp_path / "p"), "--port", "0"]
    for _ in range(2):
        proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        url = re.search(r"http://127\.0\.0\.1:\d+/", proc.stdout.readline()).group(0)
        for _ in range(600):  # the first decision waits for the person
            if json.load(urllib.request.urlopen(url + "api/state", timeout=10))["decision"]:
                break
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
        assert proc.returncode == 130 and "interrupted; run the same command again to resume" in out
    assert read_records(tmp_path / "p") == []
