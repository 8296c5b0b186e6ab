"""`deepphy play` in a real headless browser (Debian's chromium, driven by Playwright): a
person's controls play tasks through the page, and the records equal those of the same
actions given as a model's replies; a page closed (and a server stopped) in the middle of
a level resumes at the same decision; replays animate; a screenshot of each environment's
play page goes to $DEEPPHY_SCREENSHOTS (default: the test's tmp directory).

The actions come from the environments' own data: a PHYRE grid action that solves its task
(tests/data), the stored winning plans of the Angry Birds and Cut the Rope levels
(their level files), so the tests follow the games as they change.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from conftest import data_file
from deepphy.config import RunConfig
from deepphy.envs import ActionSpace, get_spec
from deepphy.envs.base import FILM_FPS
from deepphy.play.human import JOURNAL
from deepphy.runs.store import episode_prompts, read_records, stored_image
from play_support import PlayThread, model_run, person_run, same_records
from browser_support import needs_chromium

pytestmark = needs_chromium
ACT_TIMEOUT_MS = 180_000  # a decision's physics, on a loaded machine (Pooltool's first shot compiles if uncached)
ENVS = Path(__file__).resolve().parents[1] / "deepphy" / "envs"


@pytest.fixture
def play():
    """Starts play servers in this process; stops them after the test."""
    servers = []

    def start(config: RunConfig, out: Path) -> PlayThread:
        servers.append(PlayThread(config, out))
        return servers[-1]

    yield start
    for server in servers:
        server.close()


# -- the stored actions ----------------------------------------------------------------------


def phyre_solution() -> tuple[str, str]:
    """A PHYRE task of the evaluation set and a grid action that solves it (real PHYRE's outcome)."""
    data = json.loads(data_file("phyre_real_grid_outcomes.json").read_text())
    task = sorted(data["outcomes"])[0]
    cell, radius = data["actions"][data["outcomes"][task].index(1)]
    return f"within_{task.replace(':', '-')}", f"Cell: {cell}, Radius: {radius}"


def angrybirds_plan() -> tuple[str, list[str]]:
    """The level with the longest stored winning plan (the first such) and the plan's shots."""
    levels = sorted((ENVS / "angrybirds" / "levels").glob("*.json"))
    plans = {p.stem: json.loads(p.read_text())["oracle"]["plan"] for p in levels}
    level = max(plans, key=lambda k: (len(plans[k]), [-ord(c) for c in k]))
    return level, [f"shoot(angle={s['angle']}, power={s['power']})" for s in plans[level]]


def cuttherope_plan() -> tuple[str, list[str]]:
    """A level whose stored winning plan uses the most kinds of action (several ropes cut at
    once counting as one more), the shorter and the first on ties, and its actions."""
    plans = {p.stem: json.loads(p.read_text())["solution"]["actions"]
             for p in sorted((ENVS / "cuttherope" / "levels").glob("*.json"))}

    def richness(level: str) -> tuple:
        actions = plans[level]
        kinds = {a.split("(")[0] for a in actions} | {"multi" for a in actions if re.match(r"cut\w*\(\d+,", a)}
        return len(kinds), -len(actions)

    level = max(plans, key=lambda k: (richness(k), [-ord(c) for c in k]))
    return level, plans[level]


POOL_SHOTS = ["Speed: High, Strikespot: top-left", "Speed: Medium, Strikespot: middle-centre",
              "Speed: Low, Strikespot: bottom-right", "Speed: Medium, Strikespot: top-centre"]


# -- driving the controls --------------------------------------------------------------------


def decision(page) -> dict:
    return page.evaluate("() => state.decision")


def canonical(page, text: str) -> str:
    """The action text as the waiting decision's space writes it."""
    get_spec(page.evaluate("() => state.env")).load_package()  # registers its kinds of space
    space = ActionSpace.from_json(decision(page)["space"])
    return space.format(space.parse(text))


def click_fraction(page, selector: str, fx: float, fy: float) -> None:
    box = page.locator(selector).bounding_box()
    page.click(selector, position={"x": fx * box["width"], "y": fy * box["height"]})


def drive_phyre(page, text: str) -> None:
    cell, radius = map(int, re.findall(r"\d+", text))
    n = decision(page)["space"]["grid"]
    row, col = divmod(cell - 1, n)
    click_fraction(page, "canvas[data-image=grid]", (col + 0.5) / n, (row + 0.5) / n)
    page.click(f'[data-control=radius] button[data-value="{radius}"]')


def drive_angrybirds(page, text: str) -> None:
    angle, power = re.fullmatch(r"shoot\(angle=(.*), power=(.*)\)", text).groups()
    page.fill("[data-control=angle]", angle)
    page.fill("[data-control=power]", power)


def drive_cuttherope(page, text: str) -> None:
    name, args = re.fullmatch(r"(\w+)\((.*)\)", text).groups()
    values = [a.strip() for a in args.split(",") if a.strip()]
    if name in ("cut_pin", "cut_active_pin", "pop_bubble"):
        letter = {"cut_pin": "P", "cut_active_pin": "A", "pop_bubble": "B"}[name]
        first, *more = values
        # the first element by a click on the scene, where the text state places it
        where = re.search(rf"\b{letter}{first} (?:at )?\((-?[\d.]+), (-?[\d.]+)\)", "\n".join(
            p["text"] for p in decision(page)["observation"] if "text" in p))
        if where:
            # the scene's size once its image has loaded (a new decision's image loads after its text)
            page.wait_for_function("() => document.querySelector('img[data-image=scene]')?.naturalWidth > 0")
            size = page.evaluate("() => { const i = document.querySelector('img[data-image=scene]'); "
                                 "return [i.naturalWidth, i.naturalHeight]; }")
            click_fraction(page, "canvas[data-image=scene]", float(where[1]) / size[0], float(where[2]) / size[1])
        else:
            page.click(f'[data-element="{letter}{first}"]')
        for ident in more:
            page.click(f'[data-element="{letter}{ident}"]')
    elif name == "tap_air_cushion":
        page.click(f'[data-element="C{values[0]}"]')
        times = values[1].split("=")[-1].strip() if len(values) > 1 else "1"
        page.click(f'[data-control=times] button[data-value="{times}"]')
    elif name == "sleep":
        page.fill("[data-control=seconds]", values[0])
        page.click("[data-control=wait]")
    else:
        page.click(f"[data-control={name}]")


def drive_pooltool(page, text: str) -> None:
    speed, spot = re.fullmatch(r"Speed: (\w+), Strikespot: ([\w-]+)", text).groups()
    page.click(f'[data-control=speed] button[data-value="{speed}"]')
    page.click(f'svg[data-control=spot] circle[data-value="{spot}"]')


def drive_iphyre(page, text: str) -> None:
    for removal in json.loads(text):
        page.click(f'.lane[data-index="{removal["index"]}"]')  # somewhere on its timeline, then exactly:
        page.fill(f'input[data-control=time][data-index="{removal["index"]}"]', str(removal["time"]))


def drive_kinetix(page, text: str) -> None:
    space = decision(page)["space"]
    for i, value in enumerate(json.loads(text)):
        label = f"M{i}" if i < space["num_motors"] else f"T{i - space['num_motors']}"
        page.click(f'[data-control="{label}"] button[data-value="{value}"]')


def set_action(page, drive, text: str) -> str:
    """Drive the controls to `text`; returns the action text they wrote (checked by the server)."""
    expected = canonical(page, text)
    drive(page, text)
    page.wait_for_function("t => document.querySelector('#check').textContent === '✓ ' + t", arg=expected)
    written = page.input_value("#action")
    assert written == expected
    return written


def act(page) -> None:
    """Act, and wait for the next decision or the end of the play."""
    key = page.get_attribute("#decision", "data-key")
    page.evaluate("() => { window.__clicks = 0; document.querySelector('#submit').addEventListener('click', () => window.__clicks++); }")
    page.click("#submit")
    try:
        page.wait_for_function("""k => { const s = document.querySelector('#status').dataset.state;
            const d = document.querySelector('#decision');
            return s === 'finished' || (s === 'deciding' && !d.hidden && d.dataset.key !== k); }""",
                               arg=key, timeout=ACT_TIMEOUT_MS)
    except Exception as e:  # say what the page and the server were showing
        shown = page.evaluate("""async () => ({clicks: window.__clicks, checked, status: document.querySelector('#status').dataset.state,
            check: document.querySelector('#check').textContent, action: document.querySelector('#action').value,
            submit_disabled: document.querySelector('#submit').disabled, conn: document.querySelector('#conn').dataset.state,
            page_state: {version: state.version, busy: state.busy, decision: state.decision && state.decision.key},
            server: await (await fetch('/api/state')).json().then(s => ({version: s.version, busy: s.busy,
                decision: s.decision && s.decision.key, last: s.last, finished: s.finished, error: s.error}))})""")
        raise AssertionError(f"no next decision after acting on {key} (clicks on Act that reached it: "
                             f"{shown.pop('clicks')}): {json.dumps(shown)[:3000]}") from e


def wait_for_decision(page) -> None:
    page.wait_for_selector("#status[data-state=deciding]", state="attached", timeout=ACT_TIMEOUT_MS)


def screenshot(page, path: Path) -> None:
    """The whole page. Chromium takes it by resizing the viewport, and moves the page back
    afterwards: wait until it has (a click meanwhile can land where the button was)."""
    page.screenshot(path=str(path), full_page=True)
    page.evaluate("() => new Promise(done => requestAnimationFrame(() => requestAnimationFrame(done)))")
    page.wait_for_timeout(300)


def play_through(page, drive, texts: list[str], shot: Path | None = None, shot_at: int = 1) -> list[str]:
    """Play the decisions with `texts` (in order) until the play is finished; returns the
    action texts the controls wrote. A screenshot with decision `shot_at`'s controls set."""
    written = []
    wait_for_decision(page)
    while page.get_attribute("#status", "data-state") != "finished":
        assert len(written) < len(texts), f"the play goes on after the {len(texts)} actions given"
        written.append(set_action(page, drive, texts[len(written)]))
        if shot is not None and len(written) == shot_at:
            screenshot(page, shot)
            # Chromium's full-page capture resizes the viewport and restores it late on a tall
            # page (a click then reached nothing): act from the same decision on a fresh load
            page.reload()
            wait_for_decision(page)
            set_action(page, drive, texts[len(written) - 1])
        act(page)
    return written


def check_equal_to_model_replies(config: RunConfig, person: Path, tmp_path: Path, written: list[str]) -> None:
    """The person's records: the controls' texts as replies, and equal to the records of a
    model replying the same texts (same seed)."""
    records = read_records(person)
    keys = [(r.task, r.run, r.attempt, s.step) for r in records for s in r.steps]
    assert [s.raw_output for r in records for s in r.steps] == written
    replies = dict(zip(keys, written))
    model = model_run(config.model_copy(update={"model": "scripted"}), tmp_path / "model", lambda *key: replies[key])
    same_records(records, model)


# -- the tests ----------------------------------------------------------------------------------


def test_phyre_task_solved_by_clicking_a_cell_and_a_radius(play, open_page, screenshots, tmp_path):
    task, action = phyre_solution()
    config = RunConfig(env="phyre", model="human:tester", runs=1, tasks=[task])
    server = play(config, tmp_path / "person")
    page = open_page(server.url)
    written = play_through(page, drive_phyre, [action], shot=screenshots / "play_phyre.png")
    assert written == [action]
    assert page.text_content("#last [data-outcome]").startswith("Solved")
    [record] = read_records(tmp_path / "person")
    assert record.success and record.attempt == 1 and record.steps[0].action_text == action
    assert record.timing.decision_s[0] > 0
    check_equal_to_model_replies(config, tmp_path / "person", tmp_path, written)

    # its replay: the world simulated again, as an animation
    with page.context.expect_page() as opened:
        page.click("#last a.replay")
    replay = opened.value
    replay.wait_for_selector("#player:not([hidden])", timeout=60_000)
    pictures = int(replay.get_attribute("#player", "data-pictures"))
    assert pictures > 100  # 12 per simulated second, not the 4 key frames
    replay.wait_for_function("() => Number(document.querySelector('#player').dataset.frame) >= 5")  # it plays
    assert "equals the record" in replay.text_content("#note")
    replay.wait_for_function("() => { const i = document.querySelector('#picture'); return i.complete && i.naturalWidth > 0; }")
    replay.screenshot(path=str(screenshots / "play_replay_phyre.png"))
    replay.close()


def test_angrybirds_level_played_with_its_stored_plan(play, open_page, screenshots, tmp_path):
    level, plan = angrybirds_plan()
    config = RunConfig(env="angrybirds", model="human:tester", runs=1, tasks=[level])
    server = play(config, tmp_path / "person")
    page = open_page(server.url)
    written = play_through(page, drive_angrybirds, plan, shot=screenshots / "play_angrybirds.png")
    [record] = read_records(tmp_path / "person")
    assert record.success, record.feedback  # the stored plan wins
    assert [s.action_text for s in record.steps] == written
    check_equal_to_model_replies(config, tmp_path / "person", tmp_path, written)

    # the level over, its replay: every shot filmed from the simulator, FILM_FPS per simulated second
    with page.context.expect_page() as opened:
        page.click("#last a.replay")
    replay = opened.value
    replay.wait_for_selector("#player:not([hidden])", timeout=120_000)
    simulated = sum(s.info["sim_time"] for s in record.steps)
    pictures = int(replay.get_attribute("#player", "data-pictures"))
    assert pictures >= FILM_FPS * simulated  # not the key frames: 2 a shot
    assert "equals the record" in replay.text_content("#note")
    replay.wait_for_function("() => Number(document.querySelector('#player').dataset.frame) >= 12")  # it plays
    assert re.search(r"t = \d+\.\d\d s of shot 1", replay.text_content("#caption"))
    replay.wait_for_function("() => { const i = document.querySelector('#picture'); return i.complete && i.naturalWidth > 0; }")
    replay.screenshot(path=str(screenshots / "play_replay_angrybirds.png"))
    replay.close()


def test_cuttherope_level_played_with_its_stored_plan(play, open_page, screenshots, tmp_path):
    level, plan = cuttherope_plan()
    config = RunConfig(env="cuttherope", model="human:tester", runs=1, tasks=[level])
    server = play(config, tmp_path / "person")
    page = open_page(server.url)
    written = play_through(page, drive_cuttherope, plan, shot=screenshots / "play_cuttherope.png", shot_at=2)
    [record] = read_records(tmp_path / "person")
    assert record.success, record.feedback
    assert len(written) == len(plan)
    check_equal_to_model_replies(config, tmp_path / "person", tmp_path, written)


def test_pooltool_game_played_shot_by_shot(play, open_page, screenshots, tmp_path):
    config = RunConfig(env="pooltool", model="human:tester", runs=1, tasks=["rack_000"])
    server = play(config, tmp_path / "person")
    page = open_page(server.url)
    shots = [POOL_SHOTS[k % len(POOL_SHOTS)] for k in range(get_spec("pooltool").max_steps)]
    written = play_through(page, drive_pooltool, shots, shot=screenshots / "play_pooltool.png", shot_at=2)
    [record] = read_records(tmp_path / "person")
    assert written == shots[: len(record.steps)]
    check_equal_to_model_replies(config, tmp_path / "person", tmp_path, written)


def test_iphyre_and_kinetix_controls_write_their_actions(play, open_page, screenshots, tmp_path):
    """The timeline of I-PHYRE and the motors and thrusters of Kinetix write actions their
    parsers take; one I-PHYRE attempt is played and recorded."""
    config = RunConfig(env="iphyre", model="human:tester", runs=1, tasks=["hinder"], max_attempts=1)
    server = play(config, tmp_path / "iphyre")
    page = open_page(server.url)
    plan = '[{"time": 0.5, "index": 0}, {"time": 2.5, "index": 1}]'
    written = play_through(page, drive_iphyre, [plan], shot=screenshots / "play_iphyre.png")
    [record] = read_records(tmp_path / "iphyre")
    assert record.steps[0].action_text == written[0] == plan

    config = RunConfig(env="kinetix", model="human:tester", runs=1, tasks=[kinetix_level()])
    server = play(config, tmp_path / "kinetix")
    page = open_page(server.url)
    wait_for_decision(page)
    space = decision(page)["space"]
    vector = json.dumps([1 + i % 2 for i in range(space["num_motors"])] + [1] * space["num_thrusters"])
    set_action(page, drive_kinetix, vector)
    screenshot(page, screenshots / "play_kinetix.png")


def kinetix_level() -> str:
    """A small Kinetix level with both a motor and a thruster, if there is one."""
    cls = get_spec("kinetix").load()
    env = cls()
    for task in cls.tasks(cls.Options(sizes=("S",))):
        space = env.reset(task).action_space
        if space.num_motors and space.num_thrusters:
            return task.id
    return cls.tasks(cls.Options(sizes=("S",)))[0].id


class PlayProcess:
    """`deepphy play ... --port 0` in a subprocess; its URL read from its first line."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "deepphy.cli", "play", *args, "--port", "0"],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        found = {}
        reader = threading.Thread(target=lambda: found.update(line=self.proc.stdout.readline()), daemon=True)
        reader.start()
        reader.join(120)
        match = re.search(r"http://127\.0\.0\.1:\d+/", found.get("line", ""))
        if not match:
            self.kill()
            raise AssertionError(f"deepphy play did not start: {found.get('line')!r}")
        self.url = match.group(0)

    def kill(self) -> None:
        self.proc.kill()  # as a crash would: no clean-up
        self.proc.wait(30)


# -- parity: the page shows a person what the model is shown, no more ----------------------------

# What the page shows of the decision waiting: every part of the prompt in the prompt's order
# (texts, and images by the sha256 of the bytes the page loaded), the system text, and every
# picture anywhere on the page (none may be beyond the prompt's).
PAGE_PROMPT = """async () => {
  const sha = async (url) => { const bytes = await (await fetch(url)).arrayBuffer();
    return [...new Uint8Array(await crypto.subtle.digest("SHA-256", bytes))].map(b => b.toString(16).padStart(2, "0")).join(""); };
  const parts = [];
  for (const node of document.querySelectorAll("#decision [data-part]")) {
    parts.push([Number(node.dataset.part), node.tagName === "IMG" ? {image: await sha(node.src)} : {text: node.textContent}]);
  }
  const shown = [...document.images].filter(i => i.getAttribute("src") && i.offsetParent !== null && !i.closest("[hidden]"));
  return {key: state.decision.key, system: document.querySelector("#system").textContent, parts,
          images: await Promise.all(shown.map(i => sha(i.src)))};
}"""


def parity_case(env: str) -> tuple[RunConfig, object, list[str]]:
    """A play of `env` with history in its prompts: two attempts where there are several,
    several decisions where an attempt has them."""
    if env == "phyre":
        task, solution = phyre_solution()
        return RunConfig(env="phyre", model="human:tester", runs=1, tasks=[task], max_attempts=2), drive_phyre, \
            ["Cell: 1, Radius: 1", solution]
    if env == "iphyre":
        return RunConfig(env="iphyre", model="human:tester", runs=1, tasks=["support"], max_attempts=2), drive_iphyre, \
            ['[{"time": 0.5, "index": 0}]', '[{"time": 2.0, "index": 1}]']
    if env == "angrybirds":
        level, plan = angrybirds_plan()
        return RunConfig(env="angrybirds", model="human:tester", runs=1, tasks=[level]), drive_angrybirds, plan
    if env == "cuttherope":
        level, plan = cuttherope_plan()
        return RunConfig(env="cuttherope", model="human:tester", runs=1, tasks=[level]), drive_cuttherope, plan
    if env == "pooltool":
        shots = [POOL_SHOTS[k % len(POOL_SHOTS)] for k in range(get_spec("pooltool").max_steps)]
        return RunConfig(env="pooltool", model="human:tester", runs=1, tasks=["rack_000"]), drive_pooltool, shots
    level = kinetix_level()
    cls = get_spec("kinetix").load()
    space = cls().reset(next(t for t in cls.tasks(cls.Options()) if t.id == level)).action_space
    vector = json.dumps([1] * space.num_motors + [1] * space.num_thrusters)
    return RunConfig(env="kinetix", model="human:tester", runs=1, tasks=[level]), drive_kinetix, \
        [vector] * get_spec("kinetix").max_steps


@pytest.mark.parametrize("env", [pytest.param(e, marks=[pytest.mark.slow] if e in ("kinetix", "pooltool") else [])
                                 for e in ("phyre", "iphyre", "angrybirds", "cuttherope", "pooltool", "kinetix")])
def test_the_page_shows_a_person_what_the_model_is_shown(env, play, open_page, tmp_path):
    """Before every decision the page shows exactly the prompt the model would get: its system
    text, and every part of its user message in order (images compared by the sha256 of the
    bytes the page shows with the run directory's stored prompt), and no picture beyond them
    (no key frame of a decision before the next prompt has it, as a model gets it)."""
    config, drive, texts = parity_case(env)
    server = play(config, tmp_path / "person")
    page = open_page(server.url)
    shown: dict[str, dict] = {}
    wait_for_decision(page)
    while page.get_attribute("#status", "data-state") != "finished":
        assert len(shown) < len(texts), f"the play goes on after the {len(texts)} actions given"
        seen = page.evaluate(PAGE_PROMPT)
        shown[seen["key"]] = seen
        set_action(page, drive, texts[len(shown) - 1])
        act(page)
    records = read_records(tmp_path / "person")
    decisions = [(r, s) for r in records for s in r.steps]
    assert len(decisions) == len(shown) and len(shown) >= 2
    prompts = []  # (where, what the page showed, the stored system text, the stored user parts)
    for record, step in decisions:
        logged = episode_prompts(tmp_path / "person", record.task, record.run)
        [seen] = [v for k, v in shown.items() if k == f"{record.task}|{record.run}|{record.attempt}|{step.step}|{step.prompt}"]
        system, user = logged[step.prompt]
        stored = [{"image": stored_image(p)[0]} if stored_image(p) else {"text": p} for p in user["content"]]
        prompts.append((f"attempt {record.attempt} decision {step.step}", seen, system, stored))
    extra = {where: len(set(seen["images"]) - {p["image"] for p in stored if "image" in p})
             for where, seen, _, stored in prompts}
    assert not any(extra.values()), f"pictures beyond the prompt's on the page: {extra}"
    for where, seen, system, stored in prompts:
        assert sorted(seen["images"]) == sorted(p["image"] for p in stored if "image" in p), where
        assert seen["system"] == "\n\n".join(system["content"]), where
        assert [p for _, p in sorted(seen["parts"], key=lambda x: x[0])] == stored, where
    sizes = [len(v["parts"]) for v in shown.values()]
    # later prompts carry history (earlier decisions or attempts), and the page shows it;
    # Pooltool's prompt is the table as it is now, with no history (as the paper's)
    assert max(sizes) > sizes[0] or env == "pooltool"


@pytest.mark.parametrize("width", [390, 1280])
def test_the_play_page_holds_at_a_phones_and_a_laptops_width(play, open_page, screenshots, tmp_path, width):
    """No horizontal scroll at 390 px or 1280 px; the controls stay in view on a laptop when the
    history has grown (beside the observation, sticky), and come before the history on a
    phone; no action is written before the person sets one (a stray Act spends nothing)."""
    config = RunConfig(env="iphyre", model="human:tester", runs=1, tasks=["support"], max_attempts=2)
    server = play(config, tmp_path / "person")
    page = open_page(server.url)
    page.set_viewport_size({"width": width, "height": 844})
    wait_for_decision(page)
    assert page.input_value("#action") == "" and page.is_disabled("#submit")  # the empty plan is not pre-filled
    set_action(page, drive_iphyre, '[{"time": 0.5, "index": 0}]')
    act(page)  # attempt 2: the history holds attempt 1 with its pictures
    page.wait_for_selector("#history:not([hidden]) img")
    assert page.input_value("#action") == "" and page.is_disabled("#submit")
    page.evaluate("() => window.scrollTo(0, 0)")
    assert page.evaluate("document.documentElement.scrollWidth") <= width
    box = page.locator("#submit").bounding_box()
    controls, history = page.locator("#controls").bounding_box(), page.locator("#history").bounding_box()
    if width >= 1000:
        assert box["y"] + box["height"] <= 844  # in view without scrolling
        page.evaluate("() => window.scrollTo(0, document.body.scrollHeight)")  # and still there at the page's end
        box = page.locator("#submit").bounding_box()
        assert 0 <= box["y"] and box["y"] + box["height"] <= 844
    else:
        assert controls["y"] < history["y"]  # the history does not push the controls down
    page.click("[data-control=no-removal]")  # an empty plan is a choice of its own
    page.wait_for_function("() => document.querySelector('#check').textContent === '✓ []'")
    screenshot(page, screenshots / f"play_iphyre_{width}.png")


def test_closing_the_page_or_stopping_the_server_mid_level_loses_nothing(open_page, tmp_path):
    level, plan = cuttherope_plan()
    assert len(plan) >= 3
    out = tmp_path / "person"
    server = PlayProcess("--env", "cuttherope", "--tasks", level, "--player", "ana", "--out", str(out))
    try:
        page = open_page(server.url)
        wait_for_decision(page)
        written = [set_action(page, drive_cuttherope, plan[0])]
        act(page)
        waiting = decision(page)
        page.close()  # the page closed in the middle of the level
        page = open_page(server.url)
        wait_for_decision(page)
        assert decision(page)["key"] == waiting["key"] and waiting["step"] == 2  # the same decision waits
        assert page.text_content("#last code") == written[0]  # and the action the first one took is named
        written.append(set_action(page, drive_cuttherope, plan[1]))
        act(page)
        third = decision(page)["key"]
        page.close()
    finally:
        server.kill()  # the server stopped in the middle of the level: no record of the attempt yet
    assert read_records(out) == []
    assert len((out / JOURNAL).read_text().splitlines()) == 2

    server = PlayProcess("--out", str(out))  # resumes with the run directory's options
    try:
        page = open_page(server.url)
        wait_for_decision(page)
        assert decision(page)["key"] == third  # the same decision, the two before it kept
        while page.get_attribute("#status", "data-state") != "finished":
            written.append(set_action(page, drive_cuttherope, plan[len(written)]))
            act(page)
        page.close()
    finally:
        server.kill()
    [record] = read_records(out)
    assert record.success and record.model == "human:ana"
    journal = [json.loads(line) for line in (out / JOURNAL).read_text().splitlines()]
    assert record.timing.decision_s == [a["seconds"] for a in journal]  # the person's times, across the stop
    config = RunConfig(env="cuttherope", model="human:ana", runs=1, tasks=[level])
    check_equal_to_model_replies(config, out, tmp_path, written)


def test_dashboard_shows_a_persons_run_beside_a_models_and_replays_both(ray_cluster, tmp_path_factory, open_page,
                                                                         screenshots, tmp_path):
    """A person's run is one more run on the dashboard; any attempt there, a model's or a
    person's, can be watched again as an animation of the world."""
    from dashboard_support import IPHYRE_TASKS, mock_run
    from test_dashboard_browser import DashboardProcess, card_values, run_id_of

    with ThreadPoolExecutor(1) as pool:  # evaluate() runs its own event loop: not in Playwright's thread
        model = pool.submit(mock_run, tmp_path_factory).result()
    config = RunConfig(env="iphyre", model="human:tester", runs=1, tasks=IPHYRE_TASKS[:2], max_attempts=2)
    person = tmp_path / "person"
    records = person_run(config, person, lambda *key: '[{"time": 1.0, "index": 0}]')
    server = DashboardProcess(str(model), str(person))
    try:
        page = open_page(server.url)
        page.wait_for_function("document.querySelectorAll('.card').length === 2")
        assert "human:tester" in page.text_content(f'.card[data-run="{run_id_of(page, person)}"]')
        assert card_values(page, run_id_of(page, person))["attempts"] == str(len(records))
        # the person's time to decide, labelled as a person's: median per decision and per task, and in all
        from deepphy.metrics.report import report_of

        human = report_of(person).to_json()["human_time"]
        values = card_values(page, run_id_of(page, person))
        assert float(values["human_median_decision_s"]) == pytest.approx(human["median_decision_s"])
        assert float(values["human_median_task_s"]) == pytest.approx(human["median_task_s"])
        assert float(values["human_total_s"]) == pytest.approx(human["total_s"])
        assert "human_total_s" not in card_values(page, run_id_of(page, model))  # a model's latency is no person's time
        for run_dir, name in ((model, "model"), (person, "person")):
            page.select_option("#run-select", run_id_of(page, run_dir))
            task = read_records(run_dir)[0].task
            page.click(f'#grid .cell[data-task="{task}"][data-r="0"]')
            page.wait_for_selector('#episode details.attempt[data-attempt="1"] a.replay')
            page.eval_on_selector('#episode details.attempt[data-attempt="1"]', "d => { d.open = true; }")
            line = page.text_content('#episode details.attempt[data-attempt="1"] .attempt-body > .field')
            assert ("human time to decide" in line) == (name == "person") and ("model" in line) == (name == "model")
            with page.context.expect_page() as opened:
                page.click('#episode details.attempt[data-attempt="1"] a.replay')
            replay = opened.value
            replay.wait_for_selector("#player:not([hidden])", timeout=120_000)
            assert int(replay.get_attribute("#player", "data-pictures")) > 100  # 15 s of I-PHYRE at 12 per s
            assert "equals the record" in replay.text_content("#note")
            replay.wait_for_function("() => Number(document.querySelector('#player').dataset.frame) >= 5")
            replay.screenshot(path=str(screenshots / f"dashboard_replay_{name}.png"))
            replay.close()
            page.keyboard.press("Escape")
        page.close()
    finally:
        server.close()
