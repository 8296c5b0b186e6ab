"""The environment checker: the contract every registered environment must keep (in the
spirit of Gymnasium's `check_env`). A new environment gets these checks for free: the
contract test runs `check_env` over every registered spec.

    problems = check_env(spec)        # [] when the environment keeps the contract

Rules:
- tasks: a non-empty list; ids unique, filesystem-safe and stable between calls; every
  task names this environment;
- reset is deterministic: the same task gives the same observation (images, text, action
  space), in the same instance and in a fresh one;
- the action space round-trips: `parse(format(sample())) == sample()` and
  `ActionSpace.from_json(space.model_dump()) == space`;
- the prompt's example action parses in the space, and the prompt builds in both formats;
- an attempt ends within `spec.max_steps` decisions; a step that does not end it carries
  the next observation; success is a termination, never a truncation; an invalid action
  ends the attempt unsolved;
- the same actions give the same outcome in a fresh process (outcome, feedback, info and
  key frames compared).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from typing import Any, Sequence

from deepphy.chat import PromptFormat
from deepphy.envs.base import SAFE_ID, Action, ActionSpace, EnvOptions, Environment, Observation, StepResult, Task
from deepphy.envs.spec import EnvSpec
from deepphy.prompts import build_messages
from deepphy.seeding import seeded_rng

def check_env(spec: EnvSpec, options: EnvOptions | None = None, *, tasks_checked: int = 2,
              fresh_process: bool = True) -> list[str]:
    """Every broken rule, as a sentence; [] when the environment keeps the contract.
    Resets and plays `tasks_checked` tasks (the first, the last, seeded picks between)."""
    problems: list[str] = []
    env_cls = spec.load()
    if getattr(env_cls, "spec", None) != spec:
        problems.append(f"{env_cls.__name__}.spec is not the registered spec")
    options = options if options is not None else env_cls.Options()

    tasks = env_cls.tasks(options)
    if not tasks:
        return problems + ["tasks() is empty"]
    ids = [t.id for t in tasks]
    if len(set(ids)) != len(ids):
        dupes = sorted({i for i in ids if ids.count(i) > 1})[:5]
        problems.append(f"task ids are not unique: {dupes}")
    unsafe = [i for i in ids if not SAFE_ID.match(i)][:5]
    if unsafe:
        problems.append(f"task ids are not filesystem-safe: {unsafe}")
    if [t.id for t in env_cls.tasks(options)] != ids:
        problems.append("tasks() is not stable: two calls give different ids or order")
    wrong_env = [t.id for t in tasks if t.env != spec.name][:5]
    if wrong_env:
        problems.append(f"tasks that do not name environment {spec.name!r}: {wrong_env}")

    prompt = spec.load_prompt()
    for task in _pick(tasks, tasks_checked):
        where = f"task {task.id}"
        env = env_cls(options)
        first = env.reset(task)
        if _observation_key(env.reset(task)) != _observation_key(first):
            problems.append(f"{where}: reset is not deterministic in one instance")
        if _observation_key(env_cls(options).reset(task)) != _observation_key(first):
            problems.append(f"{where}: reset differs between instances")
        problems += [f"{where}: {p}" for p in _check_space(first.action_space, seeded_rng("check", spec.name, task.id))]
        try:
            example = prompt.example(first)
            first.action_space.parse(example)
        except Exception as e:  # noqa: BLE001 - report, don't crash the checker
            problems.append(f"{where}: the prompt's example action does not parse: {type(e).__name__}: {e}")
        for fmt in PromptFormat:
            try:
                build_messages(prompt, fmt, task, first, [])
            except Exception as e:  # noqa: BLE001
                problems.append(f"{where}: the {fmt.value} prompt does not build: {type(e).__name__}: {e}")

        env.reset(task)
        actions, outcome, step_problems = play(env, first, spec.max_steps, seeded_rng("check-play", spec.name, task.id))
        problems += [f"{where}: {p}" for p in step_problems]
        if fresh_process and not step_problems:
            try:
                again = replay_in_fresh_process(spec, options, task, actions)
            except RuntimeError as e:
                problems.append(f"{where}: replay in a fresh process failed: {e}")
            else:
                if again != outcome:
                    diff = sorted(k for k in outcome if outcome.get(k) != again.get(k))
                    problems.append(f"{where}: the same actions gave a different outcome in a fresh process ({diff})")
    return problems


def _pick(tasks: Sequence[Task], n: int) -> list[Task]:
    if n >= len(tasks):
        return list(tasks)
    idx = {0, len(tasks) - 1}
    rng = seeded_rng("check-pick", len(tasks))
    while len(idx) < n:
        idx.add(int(rng.integers(len(tasks))))
    return [tasks[i] for i in sorted(idx)][:n]


def _observation_key(obs: Observation) -> tuple:
    return (tuple((i.name, i.caption, i.png) for i in obs.images), obs.text, obs.action_space.model_dump_json())


def _check_space(space: ActionSpace, rng) -> list[str]:
    problems = []
    try:
        rebuilt = ActionSpace.from_json(space.model_dump(mode="json"))
        if rebuilt != space:
            problems.append("ActionSpace.from_json(space.model_dump()) differs from the space")
    except Exception as e:  # noqa: BLE001
        problems.append(f"the action space does not rebuild from JSON: {type(e).__name__}: {e}")
    for _ in range(20):
        action = space.sample(rng)
        text = space.format(action)
        try:
            back = space.parse(text)
        except Exception as e:  # noqa: BLE001
            problems.append(f"parse(format(a)) fails for {text!r}: {type(e).__name__}: {e}")
            break
        if back != action:
            problems.append(f"parse(format(a)) != a for {text!r}: {back!r} vs {action!r}")
            break
    return problems


def play(env: Environment, obs: Observation, max_steps: int, rng) -> tuple[list[str], dict[str, Any], list[str]]:
    """Play one attempt with sampled actions from a reset environment: (the actions as
    text, the outcome, the broken rules)."""
    actions: list[str] = []
    results: list[StepResult] = []
    problems: list[str] = []
    for step in range(1, max_steps + 1):
        action = obs.action_space.sample(rng)
        actions.append(obs.action_space.format(action))
        result = env.step(action)
        results.append(result)
        if result.success and result.truncated:
            problems.append(f"step {step}: success must be a termination, not a truncation")
        if result.invalid_reason and (not result.done or result.success):
            problems.append(f"step {step}: an invalid action must end the attempt unsolved")
        if result.done:
            break
        if result.observation is None:
            problems.append(f"step {step}: the attempt goes on but no next observation was returned")
            break
        obs = result.observation
    else:
        problems.append(f"the attempt did not end within max_steps = {max_steps} decisions")
    return actions, outcome_of(results), problems


def outcome_of(results: Sequence[StepResult]) -> dict[str, Any]:
    """What must be equal when the same actions are replayed."""
    return {
        "steps": [
            {"terminated": r.terminated, "truncated": r.truncated, "success": r.success,
             "invalid_reason": r.invalid_reason, "feedback": r.feedback, "stars": r.stars, "score": r.score,
             "info": json.loads(json.dumps(r.info, default=str)),
             "key_frames": [hashlib.sha256(f.png).hexdigest() for f in r.key_frames],
             "observation": None if r.observation is None else hashlib.sha256(
                 repr(_observation_key(r.observation)).encode()).hexdigest()}
            for r in results
        ]
    }


def replay_in_fresh_process(spec: EnvSpec, options: EnvOptions, task: Task, actions: list[str],
                            timeout_s: float = 600) -> dict[str, Any]:
    """Replay `actions` (text) on `task` in a new Python process; returns its outcome."""
    payload = json.dumps({
        "spec": spec.model_dump(mode="json"), "options": options.model_dump(mode="json"),
        "task": task.model_dump(mode="json"), "actions": actions,
    })
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    proc = subprocess.run([sys.executable, "-m", "deepphy.envs.checker"], input=payload, capture_output=True,
                          text=True, timeout=timeout_s, env=env)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else f"exit {proc.returncode}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _replay_main() -> None:
    data = json.loads(sys.stdin.read())
    spec = EnvSpec.model_validate(data["spec"])
    env_cls = spec.load()
    env = env_cls(env_cls.Options.model_validate(data["options"]))
    obs = env.reset(Task.model_validate(data["task"]))
    results = []
    for text in data["actions"]:
        action: Action = obs.action_space.parse(text)
        result = env.step(action)
        results.append(result)
        if result.done or result.observation is None:
            break
        obs = result.observation
    print(json.dumps(outcome_of(results)))


if __name__ == "__main__":
    _replay_main()
