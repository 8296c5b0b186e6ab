"""Two endpoints held at their rate limits by one interleaved suite: the local model
server (MOCK's answers over HTTP) on two ports, each answering after `--latency` s;
endpoint `a` allows `--rpm-a` requests/min, endpoint `b` `--rpm-b`, shared by two models
(`b1`, `b2`: one limiter key), so both endpoints have work for about as long. The suite:
I-PHYRE (`--limit` games), VLA and WM, 1 run, models a, b1, b2 (6 cells at once).

Prints each endpoint's requests in the trailing 60 s window against its limit every 10 s
(arrival times at the server, so what a provider would see), the most in any 60 s window
(never over the limit), and the share of windows from the first minute to the endpoint's
tail (its last cell's last episodes, when fewer are left than keep it busy) at >= 95 %.

    uv run python benchmarks/suite_endpoints.py [--limit 30] [--rpm-a 120] [--rpm-b 300] [--latency 1]
"""

from __future__ import annotations

import argparse
import bisect
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from deepphy.config import RuntimeOptions
from deepphy.runs.store import read_records
from deepphy.suite import Suite, run_suite
from deepphy.testing.model_server import ServerConfig, ServerThread

WINDOW_S = 60.0


def in_window(arrivals: list[float], end: float) -> int:
    """Arrivals in (end - 60 s, end]."""
    return bisect.bisect_right(arrivals, end) - bisect.bisect_right(arrivals, end - WINDOW_S)


def most_in_any_window(arrivals: list[float]) -> int:
    """The most arrivals in any 60 s window (windows ending at an arrival hold the maxima)."""
    return max((in_window(arrivals, t) for t in arrivals), default=0)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--limit", type=int, default=30, help="I-PHYRE games per cell")
    p.add_argument("--rpm-a", type=float, default=120)
    p.add_argument("--rpm-b", type=float, default=300)
    p.add_argument("--latency", type=float, default=1.0)
    args = p.parse_args()
    print("load before:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip(), flush=True)
    limits = {"a": args.rpm_a, "b": args.rpm_b}
    with ServerThread(ServerConfig(latency_s=args.latency)) as server_a, \
            ServerThread(ServerConfig(latency_s=args.latency)) as server_b, \
            tempfile.TemporaryDirectory(prefix="deepphy-endpoints-") as tmp:
        servers = {"a": server_a, "b": server_b}
        entry = lambda name, key: {  # noqa: E731
            "name": name, "provider": "openai", "model": "deepphy-mock", "base_url": servers[key].url + "/v1",
            "send_context": True, "timeouts": {"request_s": 30},
            "rate_limits": {"requests_per_min": limits[key], "key": f"bench-{key}"}}
        models = Path(tmp) / "models.yaml"
        models.write_text(yaml.safe_dump({"models": [entry("a", "a"), entry("b1", "b"), entry("b2", "b")]}))
        suite = Suite.model_validate({"name": "endpoints", "envs": [{"env": "iphyre", "limit": args.limit}],
                                      "formats": ["vla", "wm"], "runs": 1, "seed": 0, "models": ["a", "b1", "b2"]})
        runtime = RuntimeOptions(models_file=str(models))
        start = time.perf_counter()
        outcomes = run_suite(suite, Path(tmp) / "root", runtime, stream=sys.stderr)
        wall = time.perf_counter() - start
        arrivals = {k: sorted(s.stats()["arrivals"]) for k, s in servers.items()}
        requests = {k: sum(len(r.steps) for o in outcomes if o.cell.config.model.startswith(k)
                           for r in read_records(Path(tmp) / "root" / o.cell.dir)) for k in servers}
    print("load after: ", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip())
    assert all(o.done == o.total for o in outcomes), "the suite is incomplete"
    t0 = min(a[0] for a in arrivals.values())
    print(f"\nsuite: {len(outcomes)} cells, {wall:.0f} s; latency {args.latency:g} s per request")
    print("t (s)  " + "  ".join(f"{k}: in last 60 s / limit" for k in servers))
    end = max(a[-1] for a in arrivals.values())
    for t in range(10, int(end - t0) + 11, 10):
        print(f"{t:5d}  " + "  ".join(
            f"{in_window(arrivals[k], t0 + t):5d}/{limits[k]:g} ({100 * in_window(arrivals[k], t0 + t) / limits[k]:5.1f} %)"
            .ljust(len(f"{k}: in last 60 s / limit")) for k in servers))
    for k, times in arrivals.items():
        # The tail: from the last window ending at the endpoint's final arrival backwards, the
        # windows where too few episodes were left to keep it busy. Windows from the first
        # minute on, every 1 s, until the endpoint's last arrival.
        ends = [times[0] + WINDOW_S + i for i in range(int(times[-1] - times[0] - WINDOW_S) + 1)]
        held = [in_window(times, t) / limits[k] for t in ends]
        full = [u >= 0.95 for u in held]
        tail = len(full) - (max(i for i, ok in enumerate(full) if ok) + 1 if any(full) else 0)
        first_miss = next((i for i, ok in enumerate(full) if not ok), None)
        print(f"endpoint {k}: {len(times)} arrivals ({requests[k]} recorded requests) over "
              f"{times[-1] - times[0]:.0f} s; most in any 60 s window {most_in_any_window(times)} (limit "
              f"{limits[k]:g}); windows from the first minute at >= 95 %: {sum(full)}/{len(full)}, first below: "
              f"{'none' if first_miss is None else f'+{60 + first_miss} s'}, tail (final windows below) {tail} s; "
              f"lowest before the tail {min(held[:len(held) - tail], default=0) * 100:.1f} %")


if __name__ == "__main__":
    main()
