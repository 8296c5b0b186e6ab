"""Attempts per second: the full Ray pipeline with MOCK vs a plain single-process loop.

The plain loop makes the same environment calls (reset, parse, step) and the same MOCK
decisions, with prompts built, but no Ray, no run store and no key-frame files.

    uv run python benchmarks/throughput.py [--env iphyre] [--runs 3] [--limit N]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time

from deepphy.config import RunConfig, RuntimeOptions
from deepphy.models import RequestContext
from deepphy.models.mock import mock_action_text
from deepphy.prompts import PastAttempt, build_messages, get_prompt, split_reply
from deepphy.runner import ensure_ray, evaluate, resolve
from deepphy.runs.store import read_records


def plain_loop(config: RunConfig) -> tuple[int, float]:
    env_cls, tasks, k_max = resolve(config)
    env = env_cls(env_cls.Options(**config.env_options))
    prompt = get_prompt(config.env)
    attempts = 0
    start = time.perf_counter()
    for run in range(config.runs):
        for task in tasks:
            history: list[PastAttempt] = []
            tried: list[str] = []
            for attempt in range(1, k_max + 1):
                obs = env.reset(task)
                for step in range(1, env_cls.max_steps + 1):
                    build_messages(prompt, config.format, task, obs, history)
                    ctx = RequestContext(env=config.env, task_id=task.id, run=run, attempt=attempt, step=step,
                                         seed=config.seed, format=config.format,
                                         action_space=obs.action_space.model_dump(mode="json"), tried=tried)
                    _, text = split_reply(config.format, mock_action_text(ctx))
                    action = obs.action_space.parse(text)
                    result = env.step(action)
                    tried.append(obs.action_space.format(action))
                    if result.done or result.observation is None:
                        break
                    obs = result.observation
                attempts += 1
                if result.success:
                    break
                history.append(PastAttempt(attempt=attempt, actions=tried[-1:], outcome=result.feedback,
                                           key_frames=result.key_frames))
    return attempts, time.perf_counter() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="iphyre")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--limit", type=int)
    p.add_argument("--num-cpus", type=int, default=2)
    args = p.parse_args()
    config = RunConfig(env=args.env, runs=args.runs, limit=args.limit)

    attempts, seconds = plain_loop(config)
    print(f"plain loop (1 process):   {attempts} attempts in {seconds:6.1f} s = {attempts / seconds:7.1f} attempts/s")

    runtime = RuntimeOptions(num_cpus=args.num_cpus, progress=False)
    t0 = time.perf_counter()
    ensure_ray(runtime)
    ray_start = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        evaluate(config, out, runtime)
        wall = time.perf_counter() - t0
        records = read_records(out)
        busy = max(r.timing.finished for r in records) - min(r.timing.started for r in records)
    n = len(records)
    assert n == attempts, f"pipeline made {n} attempts, plain loop {attempts}: outcomes differ"
    print(f"Ray pipeline ({args.num_cpus} CPUs):   {n} attempts in {wall:6.1f} s = {n / wall:7.1f} attempts/s "
          f"(incl. actor start; {n / busy:.1f}/s first-to-last attempt; Ray start {ray_start:.1f} s not counted)")
    print(f"ratio pipeline/plain: {(n / wall) / (attempts / seconds):.2f}x (steady state {(n / busy) / (attempts / seconds):.2f}x)")


if __name__ == "__main__":
    sys.exit(main())
