"""Attempts per second: the full Ray pipeline with MOCK vs a plain single-process loop.

The plain loop does the same work in one process, one attempt after another: the very
same attempt protocol (`deepphy.protocol.run_attempt`: prompts, MOCK's decisions, parsing,
the environment calls) writing the same run directory (records, prompts, key frames).
Both runs must produce the same records.

`--rounds N` repeats the measurement N times, interleaved, and prints the medians: the same
pipeline's wall time moves by 10-20 % within an hour on the 2-vCPU VM.

`--ceiling` also runs the plain loop as two processes at once, each on half of the tasks
(alternate ones): what two independent processes get from this machine, from the first's
start (after its imports) to the last's end. "2x is the limit" holds only where two cores
double the work done; on a VM whose two vCPUs share a physical core (or its caches and
memory bandwidth) two processes get less, and the pipeline cannot beat that.

    uv run python benchmarks/throughput.py [--env iphyre] [--runs 3] [--limit N] [--quick] [--ceiling] [--rounds N]
"""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing
import os
import statistics
import sys
import tempfile
import time

import ray

from deepphy.agents import make_agent
from deepphy.allocator import keep_freed_memory
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.protocol import LocalEnv, run_episode
from deepphy.plan import plan
from deepphy.ray_connect import ensure_ray
from deepphy.runner import evaluate
from deepphy.runs.store import RunStore, read_records


async def plain_loop(config: RunConfig, out: str) -> tuple[int, float]:
    the_plan = plan(config)
    spec, tasks, k_max = the_plan.spec, the_plan.tasks, the_plan.k_max
    keep_freed_memory()  # as an environment worker does
    start = time.perf_counter()
    env = LocalEnv(the_plan.make_env())
    spec.load().warm_up(the_plan.options, tasks)
    prompt, model = the_plan.prompt(), make_agent(config.model)
    attempts = 0
    with RunStore.create_or_resume(out, config) as store:
        for run in range(config.runs):
            for task in tasks:
                attempts += len(await run_episode(spec, prompt, config, task, run, k_max, env, model, store,
                                                  on_record=store.append))
    return attempts, time.perf_counter() - start


def _half(config: RunConfig, out: str) -> tuple[int, float, float]:
    """A plain loop in a child process: (attempts, its start, its end) on the epoch clock."""
    start = time.time()
    attempts, _ = asyncio.run(plain_loop(config, out))
    return attempts, start, time.time()


def two_plain_loops(config: RunConfig, scratch: str) -> tuple[int, float]:
    """The plain loop on alternate halves of the tasks, in two processes at once:
    (attempts, seconds from the first's start to the last's end)."""
    tasks = plan(config).tasks
    halves = [config.model_copy(update={"tasks": [t.id for t in tasks[i::2]], "limit": None}) for i in (0, 1)]
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        done = pool.starmap(_half, [(h, os.path.join(scratch, f"half{i}")) for i, h in enumerate(halves)])
    return sum(n for n, _, _ in done), max(end for _, _, end in done) - min(start for _, start, _ in done)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="iphyre")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--limit", type=int)
    p.add_argument("--num-cpus", type=int, default=2)
    p.add_argument("--model", default="mock", help="a random baseline (mock, mock-uniform)")
    p.add_argument("--quick", action="store_true", help="one run of the first 20 tasks (under 3 minutes)")
    p.add_argument("--ceiling", action="store_true", help="also two plain loops at once, on halves of the tasks")
    p.add_argument("--rounds", type=int, default=1, help="measurements, interleaved; medians at the end")
    args = p.parse_args()
    if args.quick:
        args.runs, args.limit = 1, args.limit or 20
    config = RunConfig(env=args.env, runs=args.runs, limit=args.limit, model=args.model)
    runtime = RuntimeOptions(num_cpus=args.num_cpus, progress=False)
    rows = []
    # Every round's directories are removed at the end, not between rounds: on an ext4 without
    # a journal, deleting thousands of files makes the next minutes' file creations dearer
    # (benchmarks/cpu_per_attempt.py).
    with tempfile.TemporaryDirectory() as scratch:
        for round_ in range(args.rounds):
            if args.rounds > 1:
                print(f"round {round_ + 1} of {args.rounds}")
            rows.append(measure(config, runtime, args.ceiling, os.path.join(scratch, str(round_))))
    if args.rounds > 1:
        median = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
        every = ", ".join(f"{r['ratio']:.2f}" for r in rows)
        print(f"medians of {args.rounds} rounds: plain {median['plain']:.1f}, pipeline {median['pipeline']:.1f} "
              f"attempts/s; ratio {median['ratio']:.2f}x (rounds: {every}), steady state {median['steady']:.2f}x"
              + (f"; of two plain loops {median['of_ceiling']:.2f} (ceiling {median['ceiling']:.2f}x)"
                 if args.ceiling else ""))


def measure(config: RunConfig, runtime: RuntimeOptions, ceiling: bool, scratch: str) -> dict[str, float]:
    """One round: the plain loop, then the pipeline (then two plain loops at once), printed;
    attempts/s and ratios returned."""
    plain_out, out = os.path.join(scratch, "plain"), os.path.join(scratch, "pipeline")
    attempts, seconds = asyncio.run(plain_loop(config, plain_out))
    plain = attempts / seconds
    print(f"plain loop (1 process):   {attempts} attempts in {seconds:6.1f} s = {plain:7.1f} attempts/s")
    t0 = time.perf_counter()
    started = ensure_ray(runtime)
    ray_start = time.perf_counter() - t0
    t0 = time.perf_counter()
    evaluate(config, out, runtime)
    wall = time.perf_counter() - t0
    if started:  # as a `deepphy run` does; the plain loops run with no Ray beside them
        ray.shutdown()
    records = read_records(out)
    busy = max(r.timing.finished for r in records) - min(r.timing.started for r in records)
    key = lambda v: (v["task"], v["run"], v["attempt"])  # noqa: E731
    same = sorted((r.deterministic_view() for r in records), key=key) == sorted(
        (r.deterministic_view() for r in read_records(plain_out)), key=key)
    n = len(records)
    assert n == attempts and same, f"pipeline made {n} attempts, plain loop {attempts}: outcomes differ"
    row = {"plain": plain, "pipeline": n / wall, "ratio": n / wall / plain, "steady": n / busy / plain}
    print(f"Ray pipeline ({runtime.num_cpus} CPUs):   {n} attempts in {wall:6.1f} s = {n / wall:7.1f} attempts/s "
          f"(incl. actor start; {n / busy:.1f}/s first-to-last attempt; Ray start {ray_start:.1f} s not counted)")
    print(f"ratio pipeline/plain: {row['ratio']:.2f}x (steady state {row['steady']:.2f}x)")
    if ceiling:
        both, both_s = two_plain_loops(config, scratch)
        assert both == attempts, f"two plain loops made {both} attempts, one {attempts}"
        row["ceiling"], row["of_ceiling"] = both / both_s / plain, n / wall / (both / both_s)
        print(f"two plain loops at once:  {both} attempts in {both_s:6.1f} s = {both / both_s:7.1f} attempts/s "
              f"= {row['ceiling']:.2f}x the plain loop: this machine's ceiling for two processes; the pipeline "
              f"reaches {row['of_ceiling']:.2f} of it")
    return row


if __name__ == "__main__":
    sys.exit(main())
