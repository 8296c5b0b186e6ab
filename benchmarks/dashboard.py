"""The dashboard on a PHYRE-sized run: load time, report/view/grid/episode times, and the
delay from an appended record to its Server-Sent Event while such a run is loaded.

The run is synthetic (written through the real RunStore, no simulation): 1000 PHYRE tasks
x 3 runs, each attempt solving with probability --p-success, so ~25,000-30,000 records.

    uv run python benchmarks/dashboard.py [--p-success 0.04] [--keep DIR]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import random
import statistics
import tempfile
import time
from pathlib import Path

from aiohttp.test_utils import TestClient, TestServer

from deepphy.config import RunConfig
from deepphy.dashboard.server import Dashboard, make_app
from deepphy.dashboard.source import RunSource
from deepphy.plan import plan
from deepphy.runs.records import AttemptRecord, KeyFrame, StepRecord, Timing
from deepphy.runs.store import ATTEMPTS, RunStore


def record(task, run: int, attempt: int, rng: random.Random, p: float, t: float) -> AttemptRecord:
    cell, radius = rng.randint(1, 25), rng.randint(1, 5)
    invalid = "the ball overlaps an object" if rng.random() < 0.1 else None
    text = f"Cell: {cell}, Radius: {radius}"
    return AttemptRecord(
        env="phyre", task=task.id, group=task.group, run=run, attempt=attempt, model="mock", format="vla", seed=0,
        steps=[StepRecord(step=1, prompt=f"{rng.getrandbits(80):020x}", raw_output=text, action={"cell": cell, "radius": radius},
                          action_text=text, invalid_reason=invalid, feedback="the green ball did not touch the goal")],
        success=not invalid and rng.random() < p, invalid_reason=invalid,
        key_frames=[KeyFrame(path=f"frames/{task.id}/r{run}_a{attempt}_s1_outcome.png", caption="step 1, frames")],
        feedback="failed.", timing=Timing(started=t, finished=t + 0.05, env_s=0.05))


def make_run(out: Path, p: float) -> list[AttemptRecord]:
    config = RunConfig(env="phyre", runs=3)
    the_plan = plan(config)
    tasks, k_max = the_plan.tasks, the_plan.k_max
    rng = random.Random(0)
    held_back = []
    t = time.time() - 3600
    with RunStore.create_or_resume(out, config) as store:
        for run in range(config.runs):
            for task in tasks:
                for attempt in range(1, k_max + 1):
                    r = record(task, run, attempt, rng, p, t)
                    t += 0.05
                    if run == config.runs - 1 and task in tasks[-10:]:
                        held_back.append(r)  # appended later, one at a time, while the dashboard runs
                    else:
                        store.append(r)
                    if r.success:
                        break
    return held_back


def timed(fn, *args):
    t0 = time.perf_counter()
    value = fn(*args)
    return value, time.perf_counter() - t0


async def update_delays(out: Path, held_back: list[AttemptRecord]) -> tuple[float, list[float]]:
    source = RunSource(out)
    async with TestClient(TestServer(make_app(Dashboard([source])))) as client:
        t0 = time.perf_counter()
        events = await client.get("/api/events")
        while not (await (await client.get("/api/state")).json())["runs"] or source.loading:
            await asyncio.sleep(0.05)
        loaded = time.perf_counter() - t0
        delays = []
        for r in held_back:
            before = source.version
            t0 = time.perf_counter()
            with open(out / ATTEMPTS, "a") as f:
                f.write(r.model_dump_json() + "\n")
            while True:
                line = (await asyncio.wait_for(events.content.readline(), 30)).decode()
                if line.startswith("data: ") and json.loads(line[6:]).get("run", {}).get("version", 0) > before:
                    break
            delays.append(time.perf_counter() - t0)
        events.close()
        return loaded, delays


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--p-success", type=float, default=0.04)
    ap.add_argument("--keep", help="write the run here (default: a temporary directory)")
    args = ap.parse_args()
    out = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="dash-bench-")) / "phyre"

    held_back, made = timed(make_run, out, args.p_success)
    size = (out / ATTEMPTS).stat().st_size
    source, opened = timed(RunSource, out)
    t0 = time.perf_counter()
    polls = 0
    while source.poll() or source.loading:
        polls += 1
    load = time.perf_counter() - t0
    print(f"run: {len(source.records)} records, {size / 1e6:.1f} MB log (written in {made:.1f} s)")
    print(f"open (config, task list): {opened * 1000:.0f} ms; load the log: {load:.2f} s in {polls} slices")
    def uncached(fn, *a):
        source._report, source._cells = None, {}  # noqa: SLF001 - what a change costs, not a cache hit
        return fn(*a)

    for name, fn, args_ in [("report (build_report)", source.report, ()), ("view (card, curve, table)", source.view, ()),
                            ("grid page (200 tasks x 3 runs)", source.grid, (0,)),
                            ("episode", source.episode, (source.tasks[0].id, 0))]:
        times = [timed(uncached, fn, *args_)[1] for _ in range(3)]
        print(f"{name}, uncached: {statistics.median(times) * 1000:.0f} ms")
    loaded, delays = asyncio.run(update_delays(out, held_back))
    print(f"server: first full view after {loaded:.2f} s; appended record -> SSE event: "
          f"median {statistics.median(delays) * 1000:.0f} ms, max {max(delays) * 1000:.0f} ms over {len(delays)} records")


if __name__ == "__main__":
    main()
