"""The README's MOCK figures, regenerated from the code: runs (or resumes) a baseline over
every environment's evaluation set and prints the figures the README quotes, with the
wall time of each run, so the README cannot drift from what the code produces. Beside
MOCK it runs and prints every shortcut baseline the environment declares
(deepphy/envs/shortcuts.py: `shortcut-<name>`, same seed; one run where the shortcut draws
nothing, since every run is then the first's). Runs are in-process (no Ray: the same
protocol and records, one process).

    uv run python benchmarks/mock_figures.py [--envs iphyre,phyre] [--model mock] [--runs 3]
                                             [--env-option pooltool:rules=reference] [--no-shortcuts]

Run directories go to runs/figures/<env>-<model>[-<options>] and are resumed if present.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

from deepphy.envs import get_spec, specs
from deepphy.envs.shortcuts import PREFIX, shortcuts
from deepphy.metrics.report import report_of


def pm(mean, std, pct=True, digits=1) -> str:
    if mean is None:
        return "-"
    scale = 100 if pct else 1
    return f"{scale * mean:.{digits}f}" + (f" ± {scale * std:.{digits}f}" if std else "") + (" %" if pct else "")


def summary(report: dict) -> str:
    m, s = report["overall"]["mean"], report["overall"]["std"]
    k = report["max_attempts"]
    parts = [f"success within {k} attempt{'s' if k > 1 else ''} {pm(m['success_at'][-1], s['success_at'][-1])}"]
    if k > 1:
        parts.append(f"at attempt 1 {pm(m['success_at'][0], s['success_at'][0])}")
        parts.append(f"{pm(m['avg_attempts'], s['avg_attempts'], pct=False, digits=2)} attempts when solved")
    if "avg_steps" in m:
        parts.append(f"{pm(m['avg_steps'], s['avg_steps'], pct=False, digits=2)} {report['step_noun']}s when solved")
    if "auccess" in m:
        parts.append(f"AUCCESS {pm(m['auccess'], s['auccess'])}")
    if "stars" in m:
        st, sd = m["stars"], s["stars"]
        parts.append(f"stars {pm(st['total'], sd['total'], pct=False)} ({pm(st['mean_all'], sd['mean_all'], pct=False, digits=2)}"
                     f" per level, {pm(st['mean_completed'], sd['mean_completed'], pct=False, digits=2)} per completed level)")
    parts.append(f"invalid attempts {pm(m['invalid_attempts'], s['invalid_attempts'], pct=False)} per run")
    groups = report.get("groups", {})
    if groups:
        parts.append("by group: " + ", ".join(
            f"{g} {pm(sec['mean']['success_at'][-1], sec['std']['success_at'][-1])}" for g, sec in groups.items()))
    return "; ".join(parts)


def figures(env: str, model: str, args, options: list[str], runs: int) -> None:
    """Run (or resume) `model` on `env` and print its figures."""
    name = "-".join([env, model, *[o.replace("=", "_") for o in options]])
    out = Path(args.root) / name
    cmd = [sys.executable, "-m", "deepphy.cli", "run", "--env", env, "--model", model, "--runs",
           str(runs), "--seed", str(args.seed), "--out", str(out), "--no-progress", "--in-process"]
    for o in options:
        cmd += ["--env-option", o]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        print(f"{name}: the run did not complete ({done.stderr.strip().splitlines()[-1:]}); run again to resume")
        return
    report = report_of(out).to_json()
    print(f"{name} ({runs} runs, {sum(r['attempts'] for r in report['overall']['per_run'])} attempts, "
          f"{wall / 60:.1f} min wall): {summary(report)}", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", default=",".join(specs()), help="comma-separated; default: every environment")
    ap.add_argument("--model", default="mock", help="mock (the reference baseline) or mock-uniform")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--env-option", action="append", default=[], metavar="ENV:KEY=VALUE")
    ap.add_argument("--root", default="runs/figures")
    ap.add_argument("--no-shortcuts", action="store_true", help="only --model, not the shortcut baselines")
    args = ap.parse_args()
    for env in [e for e in args.envs.split(",") if e]:
        options = [o.split(":", 1)[1] for o in args.env_option if o.startswith(env + ":")]
        figures(env, args.model, args, options, args.runs)
        if not args.no_shortcuts:
            for name, short in shortcuts(get_spec(env)).items():
                # a shortcut that draws nothing plays every run as its first: one run is all of them
                figures(env, PREFIX + name, args, options, args.runs if short.draws else 1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
