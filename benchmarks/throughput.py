"""Attempts per second: the full Ray pipeline with MOCK vs a plain single-process loop.

The plain loop runs the very same attempt protocol (`deepphy.protocol.run_attempt`: the
prompts, MOCK's decisions, parsing, the environment calls, the records) in one process,
one attempt after another, with prompts and key frames kept in memory instead of a run
directory.

    uv run python benchmarks/throughput.py [--env iphyre] [--runs 3] [--limit N]
"""

from __future__ import annotations

import argparse
import asyncio
import sys
import tempfile
import time

from deepphy.agents import MockModel
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.protocol import LocalEnv, MemoryArtifacts, run_attempt
from deepphy.runner import ensure_ray, evaluate, resolve
from deepphy.runs.records import episode_finished
from deepphy.runs.store import read_records


async def plain_loop(config: RunConfig) -> tuple[int, float]:
    spec, tasks, k_max = resolve(config)
    env_cls = spec.load()
    env = LocalEnv(env_cls(env_cls.Options(**config.env_options)))
    prompt, model, artifacts = spec.load_prompt(), MockModel(), MemoryArtifacts()
    attempts = 0
    start = time.perf_counter()
    for run in range(config.runs):
        for task in tasks:
            records = []
            while not episode_finished(records, k_max):
                records.append(await run_attempt(spec, prompt, config, task, run, len(records) + 1, records,
                                                 env, model, artifacts))
            attempts += len(records)
    return attempts, time.perf_counter() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="iphyre")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--limit", type=int)
    p.add_argument("--num-cpus", type=int, default=2)
    args = p.parse_args()
    config = RunConfig(env=args.env, runs=args.runs, limit=args.limit)

    attempts, seconds = asyncio.run(plain_loop(config))
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
