"""The paper's figures, drawn from reports (`deepphy.metrics.report.report_of`).

Each `draw_*` function draws on a matplotlib Axes and returns the data it drew, so a test
can check the figure against the report it came from. Which figures apply is read from
the reports themselves: attempts K > 1 -> cumulative bars; both prompt formats of one
setting -> VLA-vs-WM scatter; a boolean `annotate` option with both values -> dumbbell;
`success_within_steps` -> success by shot; `stars` -> star bars.
Matplotlib is used through `Figure` objects only (no pyplot, no global backend).
"""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path
from typing import Any, Sequence

from matplotlib.axes import Axes
from matplotlib.figure import Figure

from deepphy.metrics.report import setting

Report = dict[str, Any]

CHECKPOINTS = (1, 4, 7, 10)  # the attempts after which the cumulative bars show the gain
ABLATION_OPTION = "annotate"  # the boolean environment option of the annotation ablation
FORMATS = ("vla", "wm")
COLORS = ["#2563eb", "#dc2626", "#16a34a", "#9333ea", "#ea580c", "#0891b2", "#ca8a04", "#db2777"]
SEGMENT_COLORS = ["#1e3a8a", "#2563eb", "#60a5fa", "#bfdbfe"]


def _mean(report: Report, section: str | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
    sec = report["overall"] if section is None else report["groups"][section]
    return sec["mean"], sec["std"]


def _options_key(report: Report, *drop: str) -> str:
    return json.dumps({k: v for k, v in sorted(report["env_options"].items()) if k not in drop})


# -- cumulative success (in-advance environments, K > 1) --------------------------------


def draw_cumulative_bars(ax: Axes, reports: Sequence[Report], checkpoints: Sequence[int] = CHECKPOINTS) -> dict[str, Any]:
    """Stacked bars, one per setting: success within attempt c1, then the gain up to each
    later checkpoint; average attempts (over solved tasks) as points on a second axis."""
    drawn: dict[str, Any] = {"labels": [], "checkpoints": [], "success": [], "segments": [], "avg_attempts": []}
    for i, r in enumerate(reports):
        m, s = _mean(r)
        cps = [c for c in checkpoints if c <= r["max_attempts"]]
        success = [m["success_at"][c - 1] for c in cps]
        segments = [success[0]] + [b - a for a, b in zip(success, success[1:])]
        bottom = 0.0
        for j, (c, seg) in enumerate(zip(cps, segments)):
            ax.bar(i, 100 * seg, bottom=100 * bottom, width=0.6, color=SEGMENT_COLORS[j % len(SEGMENT_COLORS)],
                   label=(f"attempt {c}" if j == 0 else f"gain by attempt {c}") if i == 0 else None)
            bottom += seg
        ax.errorbar(i, 100 * success[-1], yerr=100 * (s["success_at"][cps[-1] - 1] or 0), color="black", capsize=3)
        drawn["labels"].append(setting(r))
        drawn["checkpoints"].append(cps)
        drawn["success"].append(success)
        drawn["segments"].append(segments)
        drawn["avg_attempts"].append(m["avg_attempts"])
    ax.set_xticks(range(len(reports)), drawn["labels"], rotation=20, ha="right")
    ax.set_ylabel("tasks solved (%)")
    twin = ax.twinx()
    xs = [i for i, a in enumerate(drawn["avg_attempts"]) if a is not None]
    twin.plot(xs, [drawn["avg_attempts"][i] for i in xs], "D", color="#ea580c", label="average attempts (solved)")
    twin.set_ylabel("average attempts")
    twin.set_ylim(0, max(max(r["max_attempts"] for r in reports), 1) + 0.5)
    handles, labels = ax.get_legend_handles_labels()
    h2, l2 = twin.get_legend_handles_labels()
    ax.legend(handles + h2, labels + l2, fontsize=8, loc="upper left", bbox_to_anchor=(1.12, 1.0))
    return drawn


# -- VLA vs WM ----------------------------------------------------------------------------


def _setting_key(r: Report, *drop: str) -> tuple:
    """What must agree for two reports to be one comparison (everything but `drop`)."""
    facts = {"env": r["env"], "model": r["model"], "format": r["format"], "runs": r["runs"], "seed": r["seed"],
             "k": r["max_attempts"], "tasks": r["overall"]["tasks"]}
    return tuple(v for k, v in facts.items() if k not in drop) + (_options_key(r, *drop),)


def vla_wm_pairs(reports: Sequence[Report]) -> list[tuple[Report, Report]]:
    """(VLA report, WM report) of each setting evaluated in both formats (several of one
    setting pair up in the order given)."""
    by_key: dict[tuple, dict[str, list[Report]]] = defaultdict(lambda: defaultdict(list))
    for r in reports:
        by_key[_setting_key(r, "format")][r["format"]].append(r)
    return [pair for f in by_key.values() for pair in zip(*(f[x] for x in FORMATS))]


def draw_vla_wm_scatter(ax: Axes, reports: Sequence[Report], k: int | None = None) -> dict[str, Any]:
    """WM against VLA success at Pass@k (default: each environment's K), with the diagonal."""
    drawn: dict[str, Any] = {"points": []}
    envs = sorted({vla["env"] for vla, _ in vla_wm_pairs(reports)})
    for vla, wm in vla_wm_pairs(reports):
        kk = min(k or vla["max_attempts"], vla["max_attempts"], wm["max_attempts"])
        x, y = _mean(vla)[0]["success_at"][kk - 1], _mean(wm)[0]["success_at"][kk - 1]
        color = COLORS[envs.index(vla["env"]) % len(COLORS)]
        ax.scatter(100 * x, 100 * y, color=color, s=40, zorder=3)
        options = ",".join(f"{a}={b}" for a, b in sorted(vla["env_options"].items()))
        name = f"{vla['env']} {vla['model']}" + (f" {options}" if options else "")
        ax.annotate(name, (100 * x, 100 * y), fontsize=7, xytext=(4, 4), textcoords="offset points")
        drawn["points"].append({"env": vla["env"], "model": vla["model"], "env_options": vla["env_options"],
                                "k": kk, "vla": x, "wm": y})
    top = max([100.0 * max(p["vla"], p["wm"]) for p in drawn["points"]] + [10.0])
    top = min(100.0, 10 * (int(top // 10) + 1))
    ax.plot([0, top], [0, top], "--", color="#9ca3af", zorder=1)
    ax.set_xlim(0, top)
    ax.set_ylim(0, top)
    ax.set_aspect("equal")
    ax.set_xlabel("VLA: tasks solved within K attempts (%)")
    ax.set_ylabel("WM: tasks solved within K attempts (%)")
    for i, env in enumerate(envs):
        ax.scatter([], [], color=COLORS[i % len(COLORS)], label=env)
    ax.legend(fontsize=8, loc="upper left")
    return drawn


# -- annotation ablation ------------------------------------------------------------------


def _option_default(env: str, option: str) -> Any:
    from deepphy.envs import get_env_class

    field = get_env_class(env).Options.model_fields.get(option)
    return None if field is None else field.default


def ablation_pairs(reports: Sequence[Report], option: str = ABLATION_OPTION) -> list[tuple[Report, Report]]:
    """(with, without) reports of one env/model/format/other options, where the
    environment's boolean `option` is true in one and false in the other."""
    by_key: dict[tuple, dict[bool, list[Report]]] = defaultdict(lambda: defaultdict(list))
    for r in reports:
        default = _option_default(r["env"], option)
        if isinstance(default, bool):
            by_key[_setting_key(r, option)][bool(r["env_options"].get(option, default))].append(r)
    return [pair for v in by_key.values() for pair in zip(v[True], v[False])]


def group_order(report: Report) -> list[str]:
    """The report's groups in the order the environment lists its tasks (e.g. S, M, L)."""
    from deepphy.envs import get_env_class

    groups = list(report.get("groups", {}))
    if not groups:
        return []
    cls = get_env_class(report["env"])
    seen = list(dict.fromkeys(t.group for t in cls.tasks(cls.Options(**report["env_options"]))))
    return sorted(groups, key=lambda g: seen.index(g) if g in seen else len(seen))


def draw_ablation_dumbbell(ax: Axes, reports: Sequence[Report], option: str = ABLATION_OPTION) -> dict[str, Any]:
    """Per setting and task group (size): success with and without the option, joined by a line."""
    drawn: dict[str, Any] = {"rows": []}
    for with_, without in ablation_pairs(reports, option):
        groups = group_order(with_) or [None]
        for g in groups:
            a = _mean(with_, g)[0]["success_at"][-1]
            b = _mean(without, g)[0]["success_at"][-1]
            drawn["rows"].append({"label": f"{with_['model']} {with_['format'].upper()} · {g or 'all'}",
                                  "group": g, "with": a, "without": b})
    for y, row in enumerate(drawn["rows"]):
        ax.plot([100 * row["without"], 100 * row["with"]], [y, y], color="#9ca3af", zorder=1)
        # a ring and a dot: both stay visible when the two values are equal
        ax.scatter(100 * row["with"], y, s=110, facecolors="none", edgecolors="#2563eb", linewidths=2, zorder=2,
                   label=f"{option}=true" if y == 0 else None)
        ax.scatter(100 * row["without"], y, s=30, color="#dc2626", zorder=3, label=f"{option}=false" if y == 0 else None)
    ax.set_yticks(range(len(drawn["rows"])), [r["label"] for r in drawn["rows"]])
    ax.invert_yaxis()
    ax.margins(y=0.15)
    ax.set_xlabel("tasks solved (%)")
    ax.set_xlim(-2, 102)
    ax.legend(fontsize=8)
    return drawn


# -- on-the-fly: success by shot --------------------------------------------------------


def draw_success_by_shot(ax: Axes, reports: Sequence[Report]) -> dict[str, Any]:
    """Success within k decisions (the report's checkpoints), mean ± std over runs."""
    drawn: dict[str, Any] = {"series": []}
    shots = [r for r in reports if "success_within_steps" in r["overall"]["mean"]]
    for i, r in enumerate(shots):
        m, s = _mean(r)
        ks = list(m["success_within_steps"])
        y = [m["success_within_steps"][k] for k in ks]
        err = [s["success_within_steps"][k] or 0 for k in ks]
        avg = m.get("avg_steps")
        label = setting(r) + (f" (avg {avg:.1f} when solved)" if avg is not None else "")
        ax.errorbar([int(k) for k in ks], [100 * v for v in y], yerr=[100 * e for e in err], marker="o",
                    capsize=3, color=COLORS[i % len(COLORS)], label=label)
        drawn["series"].append({"label": setting(r), "shots": [int(k) for k in ks], "success": y, "avg_steps": avg})
    ax.set_xlabel("shots")
    ax.set_ylabel("games won within k shots (%)")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8)
    return drawn


# -- stars (games) ------------------------------------------------------------------------


def draw_star_bars(ax: Axes, reports: Sequence[Report]) -> dict[str, Any]:
    """Per setting: levels finished with 1, 2 and 3 stars (mean over runs), side by side."""
    drawn: dict[str, Any] = {"labels": [], "levels_with": [], "mean_all": [], "mean_completed": []}
    starred = [r for r in reports if "stars" in r["overall"]["mean"]]
    width = 0.8 / max(1, len(starred))
    for i, r in enumerate(starred):
        st = _mean(r)[0]["stars"]
        counts = [st["levels_with"][c] for c in ("1", "2", "3")]
        ax.bar([j + i * width for j in range(3)], counts, width=width, color=COLORS[i % len(COLORS)],
               label=f"{setting(r)} (mean {st['mean_all']:.2f} ★/level)")
        drawn["labels"].append(setting(r))
        drawn["levels_with"].append(counts)
        drawn["mean_all"].append(st["mean_all"])
        drawn["mean_completed"].append(st["mean_completed"])
    ax.set_xticks([j + 0.4 - width / 2 for j in range(3)], ["1 star", "2 stars", "3 stars"])
    ax.set_ylabel("levels (mean over runs)")
    ax.legend(fontsize=8)
    return drawn


# -- all figures --------------------------------------------------------------------------


def figures_for(reports: Sequence[Report]) -> list[tuple[str, str, Any, list[Report]]]:
    """(file stem, title, draw function, reports) of every figure these reports support."""
    out = []
    by_env: dict[str, list[Report]] = defaultdict(list)
    for r in reports:
        by_env[r["env"]].append(r)
    for env, rs in by_env.items():
        multi = [r for r in rs if r["max_attempts"] > 1]
        if multi:
            out.append((f"cumulative_{env}", f"{env}: cumulative success by attempt", draw_cumulative_bars, multi))
        if ablation_pairs(rs):
            out.append((f"{ABLATION_OPTION}_{env}", f"{env}: with and without {ABLATION_OPTION}",
                        draw_ablation_dumbbell, rs))
        shots = [r for r in rs if "success_within_steps" in r["overall"]["mean"]]
        if shots:
            out.append((f"by_shot_{env}", f"{env}: success by shot", draw_success_by_shot, shots))
        stars = [r for r in rs if "stars" in r["overall"]["mean"]]
        if stars:
            out.append((f"stars_{env}", f"{env}: stars", draw_star_bars, stars))
    if vla_wm_pairs(reports):
        out.append(("vla_vs_wm", "VLA vs WM (Pass@K)", draw_vla_wm_scatter, list(reports)))
    return out


def plot_all(reports: Sequence[Report], out: str | Path) -> list[Path]:
    """Write every applicable figure as PNG and PDF, and the drawn data as figures.json."""
    figures = figures_for(reports)
    if not figures:
        return []
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    data: dict[str, Any] = {}
    for stem, title, draw, rs in figures:
        fig = Figure(figsize=(7.5, 4.5) if draw is not draw_vla_wm_scatter else (5.5, 5.5), layout="constrained")
        ax = fig.add_subplot()
        data[stem] = draw(ax, rs)
        ax.set_title(title)
        for suffix in ("png", "pdf"):
            path = out / f"{stem}.{suffix}"
            fig.savefig(path, dpi=150)
            written.append(path)
    (out / "figures.json").write_text(json.dumps(data, indent=1))
    return [*written, out / "figures.json"]
