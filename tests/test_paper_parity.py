"""By default a model gets the information the DeepPHY paper's prompts gave it, no more, no less
(docs/comparability.md, from the team's note on the paper's prompts): no numeric state (positions,
velocities, distances, sizes in pixels, physical constants, time limits) beyond what the paper
gave, the paper's retry instructions after a failure, and no image promised that is not sent.
`state_text=true` is the opt-in richer text; the test shows it is what the check catches."""

from __future__ import annotations

import asyncio
import json
import re

import pytest

from deepphy.agents import make_agent
from deepphy.config import RunConfig
from deepphy.envs import get_spec
from deepphy.prompts.base import RETRY
from deepphy.protocol import LocalEnv, MemoryArtifacts, run_episode

# What the paper gave in numbers, per environment (besides attempt and step numbers, block
# indices, cells and radius levels, which are small integers): PHYRE's radius levels as
# shares of the width (1/128 .. 1/8); I-PHYRE's time window (0.0 to 15 s); Kinetix's goal
# distances (pixels); Pooltool's ball numbers (1 to 9). Cut the Rope's are our protocol's own
# mechanics, which the paper's real-time game had no need to state: the range `sleep` accepts,
# the 0.25 s the world runs after each action so that its first consequence shows, the 10 s it
# runs on at the end; and the level's number (b1_l01). Angry Birds': the paper's angle
# convention (0 to 90, 45 diagonal), the score as the game displays it, the level's number.
ALLOWED_PHRASES = {
    "phyre": [r"1/128", r"1/8\b", r"\b5 ?x ?5 grid"],
    "iphyre": [r"\b0\.0 to less than 15\b", r"\(15 s\)"],
    "kinetix": [r"(?i)goal distance[^\n]*?\d+ px", r"\(was \d+ px\)", r"last \d+"],
    "pooltool": [],
    "angrybirds": [r"\bfrom\s+0\s+to\s+90\b", r"\b45\s+diagonally", r"\b90\s+straight\s+up", r"(?i)score(?:\s+so\s+far)?:?\s+\d+",
                   r"\(\+\d+\)", r"\bs\d_l\d\d\b"],
    "cuttherope": [r"\b0\.1\s+to\s+10\s+seconds", r"sleep\(0\.1\.\.10\)", r"runs\s+for\s+0\.25\s+s", r"(?:up\s+to|at\s+most)\s+10\s+s\b",
                   r"\bb\d_l\d\d\b"],
}
SMALL = {str(k) for k in range(26)}  # indices, cells, radius levels, attempt and step numbers
UNIT = re.compile(r"\d+(?:\.\d+)?\s*(?:px|pixels?|m/s|metres|meters|seconds?|s\b|px/s|%|x\b|degrees)")
NUMBER = re.compile(r"\d+(?:\.\d+)?")
ENVS = list(ALLOWED_PHRASES)


def prompts(env: str, fmt: str, options: dict, n_tasks: int = 2) -> list[tuple[str, list[dict], list[str]]]:
    """(text of the prompt's text parts, its raw content, the actions taken in the episode) for
    every distinct prompt of MOCK's first episodes (a first request, requests after earlier
    decisions, and after a failed attempt: two attempts each)."""
    spec = get_spec(env)
    cls = spec.load()
    opts = cls.Options(**options)
    out = []
    for task in cls.tasks(opts)[:n_tasks]:
        config = RunConfig(env=env, model="mock", format=fmt, env_options=options, max_attempts=2)
        artifacts = MemoryArtifacts()
        records = asyncio.run(run_episode(spec, spec.load_prompt(), config, task, 0, 2, LocalEnv(cls(opts)),
                                          make_agent("mock"), artifacts))
        actions = [s.action_text or s.raw_output for r in records for s in r.steps]
        for digest in dict.fromkeys(s.prompt for r in records for s in r.steps):
            messages = json.loads(artifacts.prompts[digest])
            text = "\n".join(c for m in messages for c in m["content"] if isinstance(c, str))
            out.append((text, messages, actions))
    return out


def numeric_state(env: str, text: str, actions: list[str]) -> list[str]:
    """The numbers in a prompt's text that the paper's prompt did not give."""
    for action in sorted(actions, key=len, reverse=True):  # the model's own actions, quoted back
        text = text.replace(action, " ")
    text = re.sub(r"Reply with the action only.*?\n.*?\n|Action: .*", " ", text)  # the example action
    text = re.sub(r"\bM\d+|\bT\d+|\bP\d+|\d+-ball", " ", text)  # labels
    for phrase in ALLOWED_PHRASES[env]:
        text = re.sub(phrase, " ", text)
    found = [m.group(0) for m in UNIT.finditer(text)]
    found += [n for n in NUMBER.findall(text) if n not in SMALL and n != "0.0"]
    return found


@pytest.mark.parametrize("fmt", ["vla", "wm"])
@pytest.mark.parametrize("env", ENVS)
def test_default_prompts_carry_no_numeric_state_beyond_the_papers(env, fmt):
    seen = prompts(env, fmt, {})
    assert len(seen) >= 2
    for text, _, actions in seen:
        assert numeric_state(env, text, actions) == [], text


@pytest.mark.parametrize("env", ENVS)
def test_state_text_is_the_richer_text_the_check_catches(env):
    richer = [n for text, _, actions in prompts(env, "vla", {"state_text": True}) for n in numeric_state(env, text, actions)]
    assert richer, f"{env}: state_text=true gave no number beyond the paper's"


@pytest.mark.parametrize("env", ENVS)
def test_after_a_failure_the_prompt_gives_the_papers_retry_instructions(env):
    after = [text for text, _, _ in prompts(env, "vla", {}, n_tasks=5)  # some tasks MOCK solves at once
             if "previous 1 attempt(s) at this task failed" in text]
    assert after, "no prompt after a failed attempt"
    for text in after:
        assert RETRY in text and "do not repeat an action that already failed" in text
    if env == "phyre":
        assert all("Never reuse a cell and radius pair you have already tried" in t for t in after)
    if env == "iphyre":
        assert all("Diagnose the failure: timing" in t and "revise your strategy" in t for t in after)


# What a prompt's words promise to show, and how to see that it does.
PROMISES = {
    r"\bthe annotated image\b": lambda names, history: "annotated" in names,
    r"\bthe second image\b": lambda names, history: len(names) >= 2,
    r"pictures? of (?:earlier|the previous|your failures)": lambda names, history: history > 0,
}


@pytest.mark.parametrize("env", ENVS)
def test_no_prompt_promises_an_image_it_does_not_send(env):
    for options in ({}, {"state_text": True}):
        for text, messages, _ in prompts(env, "vla", options):
            user = messages[-1]["content"]
            current = user.index("Current observation:")
            names = [c["name"] for c in user[current:] if isinstance(c, dict)]
            history = sum(isinstance(c, dict) for c in user[:current])
            for promise, kept in PROMISES.items():
                if re.search(promise, text):
                    assert kept(names, history), f"{env} {options}: the prompt says {promise!r} but sends {names}"
            for i, part in enumerate(user):  # every image is introduced by a text
                if isinstance(part, dict):
                    assert i > 0 and isinstance(user[i - 1], str), f"{env}: image {part['name']} has no words before it"


def test_a_run_made_before_parity_is_read_labelled_and_never_resumed(tmp_path, deepphy_cmd):
    """Its config.json names no prompts: report and leaderboard read it as made with the earlier
    prompts (a setting of its own, said in the header); a resume is refused in one line."""
    import subprocess

    from dashboard_support import synthetic_run

    from deepphy.metrics.report import render_text, report_of

    old = synthetic_run(tmp_path / "old", env="iphyre", limit=2, runs=1)
    config = json.loads((old / "config.json").read_text())
    assert config.pop("prompts") == "paper"
    (old / "config.json").write_text(json.dumps(config))
    report = report_of(old)
    assert report.prompts == "before-parity" and report.departures == ["prompts=before-parity"]
    assert "departs from the paper: prompts=before-parity" in render_text(report).splitlines()[0]
    proc = subprocess.run([*deepphy_cmd, "run", "--env", "iphyre", "--limit", "2", "--runs", "1", "--out", str(old)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "was made with deepphy's prompts from before-parity and cannot be resumed" in proc.stderr
