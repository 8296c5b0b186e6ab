"""Run directories for the dashboard, plot and export tests.

`mock_run` makes a real one (MOCK on the real I-PHYRE through the real pipeline).
`synthetic_run` writes one through the real RunStore without simulating: seeded random
outcomes with several decisions per attempt, prompts with image placeholders and key
frames, so that multi-decision environments, option ablations and stars can be tested
without minutes of physics. Figures are always compared with `report_of` of the same
directory, never with numbers written here.
"""

from __future__ import annotations

import hashlib
import json
import random
import shutil
from pathlib import Path

import cv2
import numpy as np

from deepphy.config import RunConfig, RuntimeOptions
from deepphy.plan import plan
from deepphy.runner import evaluate
from deepphy.runs.records import AttemptRecord, KeyFrame, ModelStats, StepRecord, Timing
from deepphy.runs.store import ATTEMPTS, PROMPTS, RunStore, prompt_log

IPHYRE_TASKS = ["support", "hinder", "direction", "hole", "spring_flick", "multi_ball_lever"]


def mock_run(tmp_path_factory, fmt: str = "vla") -> Path:
    """A real MOCK evaluation of a few I-PHYRE games (needs a Ray runtime), made once per
    test session and shared by the test modules: treat it as read-only."""
    out = tmp_path_factory.getbasetemp() / f"shared-mock-iphyre-{fmt}"
    if not out.exists():  # renamed into place only once complete
        partial = tmp_path_factory.mktemp(f"mock-iphyre-{fmt}")
        config = RunConfig(env="iphyre", model="mock", format=fmt, runs=2, seed=3, tasks=IPHYRE_TASKS)
        outcome = evaluate(config, partial, RuntimeOptions(progress=False, env_workers=2))
        assert outcome.complete
        partial.rename(out)
    return out


def _png(seed: int) -> bytes:
    image = np.full((24, 32, 3), 255, np.uint8)
    cv2.circle(image, (8 + seed % 16, 12), 5, (0, 0, 200), -1)
    return cv2.imencode(".png", image)[1].tobytes()


def synthetic_run(out: Path, env: str = "kinetix", *, runs: int = 2, seed: int = 0, fmt: str = "vla",
                  env_options: dict | None = None, tasks: list[str] | None = None, limit: int | None = None,
                  max_steps: int = 4, p_success: float = 0.3, stars: bool = False, model: str = "mock") -> Path:
    config = RunConfig(env=env, model=model, runs=runs, seed=seed, format=fmt, env_options=env_options or {},
                       tasks=tasks, limit=limit)
    the_plan = plan(config)
    task_list, k_max = the_plan.tasks, the_plan.k_max
    rng = random.Random(f"{env}-{seed}-{json.dumps(env_options, sort_keys=True)}" + ("" if model == "mock" else model))
    with RunStore.create_or_resume(out, config) as store:
        for run in range(runs):
            for task in task_list:
                history: list[KeyFrame] = []
                for attempt in range(1, k_max + 1):
                    steps, frames = [], []
                    n_steps = rng.randint(1, max_steps)
                    invalid = None
                    for step in range(1, n_steps + 1):
                        shown = [f"<image {Path(f.path).name}: {f.caption}>" for f in history[-2:]]
                        messages = [
                            {"role": "system", "content": [f"Rules of {env} for {task.id}."]},
                            {"role": "user", "content": [*shown, "Current observation:",
                                                         "<image scene: The scene now.>", f"Decision {step}:"]},
                        ]
                        text = json.dumps(messages, indent=1)
                        digest = hashlib.sha256(text.encode()).hexdigest()[:20]
                        # The prompt as runs before content-addressed images stored it (placeholders).
                        (Path(out) / "prompts" / f"{digest}.json").write_text(text)
                        value = rng.randint(0, 2)
                        if rng.random() < 0.08:
                            invalid = "unparseable action: not a list"
                            steps.append(StepRecord(step=step, prompt=digest, raw_output="no idea",
                                                    prediction="it falls" if fmt == "wm" else None,
                                                    invalid_reason=invalid))
                            break
                        rel = store.write_frame(task.id, run, attempt, f"s{step}_after", _png(rng.randint(0, 99)))
                        frames.append(KeyFrame(path=rel, caption=f"step {step}, the scene after the decision"))
                        steps.append(StepRecord(
                            step=step, prompt=digest, raw_output=f"[{value}]",
                            prediction="it falls" if fmt == "wm" else None, action={"controls": [value]},
                            action_text=f"[{value}]", feedback=f"decision {step} applied", info={"distance": step * 1.5}))
                    success = invalid is None and rng.random() < p_success
                    usage = {"input_tokens": 100 * len(steps), "output_tokens": 5 * len(steps),
                             "cost_usd": 0.001 * len(steps)}
                    store.append(AttemptRecord(
                        env=env, task=task.id, group=task.group, run=run, attempt=attempt, model=config.model,
                        format=fmt, seed=seed, steps=steps, success=success, invalid_reason=invalid,
                        stars=rng.randint(1, 3) if stars and success else (0 if stars else None),
                        key_frames=frames, feedback="solved." if success else "failed.",
                        timing=Timing(started=1.0e9 + attempt, finished=1.0e9 + attempt + 0.5),
                        model_stats=ModelStats.model_validate({"usage": usage, "retries": rng.randint(0, 1)}),
                    ))
                    history += frames
                    if success:
                        break
    return out


def copy_run(src, dest, lines: int, torn: int = 0):
    """A copy of a run directory whose log holds only its first `lines` records (and
    `torn` bytes of the next, as a writer in the middle of a line leaves it)."""
    shutil.copytree(src, dest, ignore=shutil.ignore_patterns(ATTEMPTS, ".lock"))
    log = (src / ATTEMPTS).read_bytes().split(b"\n")
    (dest / ATTEMPTS).write_bytes(b"".join(line + b"\n" for line in log[:lines]) + log[lines][:torn])
    return log[:-1]


def append(dest, lines: list[bytes]):
    with open(dest / ATTEMPTS, "ab") as f:
        f.write(b"".join(line + b"\n" for line in lines))


def to_old_layout(run: Path) -> None:
    """Store a run directory's prompts as runs before the episode logs did: a file
    prompts/<digest>.json per distinct prompt, and no logs."""
    for log in sorted((run / PROMPTS).glob("*/*.jsonl")):
        for line in log.read_bytes().splitlines():
            entry = json.loads(line)
            (run / PROMPTS / f"{entry['digest']}.json").write_text(json.dumps(entry["messages"]))
        log.unlink()
    for task in (run / PROMPTS).iterdir():
        if task.is_dir():
            task.rmdir()


def rewrite_prompt(run: Path, task: str, run_number: int, digest: str, text: str) -> None:
    """Replace the line of prompt `digest` in the log of episode (task, run_number) with
    `text`, as someone editing the run directory would."""
    log = run / prompt_log(task, run_number)
    lines = log.read_text().splitlines()
    lines[next(i for i, line in enumerate(lines) if json.loads(line)["digest"] == digest)] = text
    log.write_text("\n".join(lines) + "\n")
