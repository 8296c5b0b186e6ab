"""The paper's figures, drawn from reports (`deepphy.metrics.report.report_of`).

Each `draw_*` function draws on a matplotlib Axes and returns the data it drew, so a test
can check the figure against the report it came from. Which figures apply is read from
the reports themselves, per environment: attempts K > 1 -> cumulative bars; several
decisions per attempt -> success by decision (shot, action); task groups -> success per
group (Kinetix's sizes, PHYRE's setups); a boolean `annotate` option with both values ->
dumbbell; `stars` -> star bars; and across environments, both prompt formats of one
setting -> VLA-vs-WM scatter. Across settings, the leaderboard (`draw_leaderboard`) is the
master table `deepphy leaderboard` prints, as a figure: a panel per environment setting.
Matplotlib is used through `Figure` objects only (no pyplot, no global backend).

Made for papers: every figure is written twice, for one column (3.3 in wide, `<stem>-1col`)
and for two (7 in, `<stem>`), every text at least MIN_FONT_PT at that size, legends under
the axes; every setting is labelled with its n (tasks x runs; the episodes done where not
all are), and nothing ranks settings of other tasks or runs (the leaderboard's marks are
the table's).
"""

from __future__ import annotations

import json
import math
import textwrap
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any, Sequence

import matplotlib
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

from deepphy.envs import get_env_class, get_spec
from deepphy.metrics.leaderboard import Leaderboard
from deepphy.metrics.report import Report

CHECKPOINTS = (1, 4, 7, 10)  # the attempts after which the cumulative bars show the gain
ABLATION_OPTION = "annotate"  # the boolean environment option of the annotation ablation
FORMATS = ("vla", "wm")
# Okabe & Ito's colour-blind safe palette (settings, environments)
COLORS = ["#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442", "#000000"]
SEGMENT_COLORS = ["#08306b", "#2171b5", "#6baed6", "#c6dbef"]  # attempt 1, then the gains (dark to light)
MIN_SLOTS = 3  # a figure is at least this many bar slots wide: one setting's bar does not fill it
DPI = 300
WIDTHS = {"": 7.0, "-1col": 3.3}  # file-name suffix -> inches: a two-column and a one-column figure
MIN_FONT_PT = 7  # no text smaller at print size
STYLE = {"font.size": 8, "axes.titlesize": 8, "axes.labelsize": 8, "xtick.labelsize": 7, "ytick.labelsize": 7,
         "legend.fontsize": 7, "legend.title_fontsize": 7, "figure.titlesize": 9, "pdf.fonttype": 42,
         "ps.fonttype": 42, "axes.linewidth": 0.6, "lines.linewidth": 1.2}
ANNOTATION_PT = 7
CHAR_EM = 0.6  # a character's width in ems (DejaVu Sans, on average): how long a label runs


def _mean(report: Report, section: str | None = None) -> tuple[Any, Any]:
    sec = report.overall if section is None else report.groups[section]
    return sec.mean, sec.std


def _options_key(report: Report, *drop: str) -> str:
    return json.dumps({k: v for k, v in sorted(report.env_options.items()) if k not in drop})


def labels(reports: Sequence[Report]) -> list[str]:
    """Each report's setting, numbered where two reports share one."""
    names = [r.setting for r in reports]
    repeated = {n for n, c in Counter(names).items() if c > 1}
    seen: Counter = Counter()
    out = []
    for n in names:
        seen[n] += 1
        out.append(f"{n} ({seen[n]})" if n in repeated else n)
    return out


def sized(reports: Sequence[Report], sep: str = " ") -> list[str]:
    """Each report's label (`labels`) with its n: "mock VLA (n=40x3)"; `sep` before the n."""
    return [f"{name}{sep}(n={r.sample_size()})" for name, r in zip(labels(reports), reports)]


def _style(ax: Axes, grid_axis: str = "y") -> None:
    """What every figure shares: no top/right frame, a light grid behind the data."""
    ax.spines[["top", "right"]].set_visible(False)
    ax.grid(axis=grid_axis, color="#e5e7eb", linewidth=0.6)
    ax.set_axisbelow(True)
    ax.tick_params(labelsize=MIN_FONT_PT, width=0.6, length=2.5)


def _narrow(ax: Axes) -> bool:
    return ax.figure.get_figwidth() < 4.5


def _legend(ax: Axes, handles=None, labels_=None, title: str | None = None) -> None:
    """The figure's legend, under the axes (a one-column figure has no room beside them)."""
    if handles is None:
        handles, labels_ = ax.get_legend_handles_labels()
    if not handles:
        return
    fits = int(ax.figure.get_figwidth() * 72 / (MIN_FONT_PT * CHAR_EM)) - 6  # characters on a line of the figure
    labels_ = [textwrap.fill(str(x), fits) for x in labels_]
    longest = max(len(line) for x in labels_ for line in x.split("\n"))
    per_row = max(1, min(len(handles), fits // (longest + 6)))
    if title:
        title = textwrap.fill(title, fits)
    ax.figure.legend(handles, labels_, loc="outside lower center", ncols=per_row, frameon=False, title=title)


def _ylabel(ax: Axes, text: str) -> None:
    """A y label on as many lines as the axes' height needs (a one-column figure is short)."""
    fits = int((ax.figure.get_figheight() - 1.2) * 72 / (STYLE["axes.labelsize"] * CHAR_EM))
    ax.set_ylabel(textwrap.fill(text, max(12, fits)))


def _ticks(ax: Axes, positions: Sequence[float], names: Sequence[str]) -> None:
    """x tick labels that fit: turned when they would run into each other."""
    width = ax.figure.get_figwidth() * 0.85 / max(1, len(names))  # inches per label
    longest = max((max(len(line) for line in n.split("\n")) for n in names), default=0)
    turn = longest * MIN_FONT_PT * CHAR_EM / 72 > width
    ax.set_xticks(list(positions), list(names), rotation=30 if turn else 0, ha="right" if turn else "center",
                  rotation_mode="anchor" if turn else "default")


def _percent_limits(top: float) -> float:
    """The upper end of a percent axis holding `top` percent: 100 for high values, else a
    round number above it (at least 10, so all-zero data still get a readable 0-10 axis)."""
    if top > 75:
        return 100.0
    return float(max(10, 10 * math.ceil(top * 1.15 / 10)))


def _clipped(values: Sequence[float], errs: Sequence[float], top: float | None = 1.0) -> list[list[float]]:
    """Error bars (mean ± std) cut at 0 and at `top`: no bar reaches below 0 % or above 100 %."""
    return [[min(e, v) for v, e in zip(values, errs)],
            [e if top is None else min(e, top - v) for v, e in zip(values, errs)]]


def _slot_limits(ax: Axes, n: int) -> None:
    """x limits for n slots at 0..n-1, centred in at least MIN_SLOTS slots."""
    pad = (max(n, MIN_SLOTS) - n) / 2
    ax.set_xlim(-0.5 - pad, n - 0.5 + pad)


# -- cumulative success (in-advance environments, K > 1) --------------------------------


def draw_cumulative_bars(ax: Axes, reports: Sequence[Report], checkpoints: Sequence[int] = CHECKPOINTS) -> dict[str, Any]:
    """Stacked bars, one per setting: success within attempt c1, then the gain up to each
    later checkpoint, with the std over runs of the last; the average attempts (over
    solved tasks) written above each bar."""
    drawn: dict[str, Any] = {"labels": labels(reports), "checkpoints": [], "success": [], "segments": [],
                             "avg_attempts": []}
    top = 0.0
    for i, r in enumerate(reports):
        m, s = _mean(r)
        cps = [c for c in checkpoints if c <= r.max_attempts]
        success = [m.success_at[c - 1] for c in cps]
        segments = [success[0]] + [b - a for a, b in zip(success, success[1:])]
        bottom = 0.0
        for j, (c, seg) in enumerate(zip(cps, segments)):
            ax.bar(i, 100 * seg, bottom=100 * bottom, width=0.6, color=SEGMENT_COLORS[j % len(SEGMENT_COLORS)],
                   edgecolor="white", linewidth=0.5,
                   label=(f"attempt {c}" if j == 0 else f"attempts {cps[j - 1] + 1}-{c}") if i == 0 else None)
            bottom += seg
        (low,), (high,) = _clipped([success[-1]], [s.success_at[cps[-1] - 1] or 0])
        ax.errorbar(i, 100 * success[-1], yerr=[[100 * low], [100 * high]], color="black", capsize=3, linewidth=1)
        avg = m.avg_attempts
        ax.annotate("-" if avg is None else f"{avg:.2f}", (i, 100 * (success[-1] + high)), xytext=(0, 3),
                    textcoords="offset points", ha="center", fontsize=ANNOTATION_PT)
        top = max(top, 100 * (success[-1] + high))
        drawn["checkpoints"].append(cps)
        drawn["success"].append(success)
        drawn["segments"].append(segments)
        drawn["avg_attempts"].append(avg)
    _style(ax)
    drawn["n"] = [r.sample_size() for r in reports]
    _ticks(ax, range(len(reports)), sized(reports, "\n"))
    _slot_limits(ax, len(reports))
    ax.set_ylim(0, _percent_limits(top * 1.1))
    ax.set_ylabel("tasks solved (%)")
    _legend(ax, title="solved within (above a bar: average attempts of the solved tasks)")
    return drawn


# -- success against attempts (in-advance environments, K > 1) ------------------------------


def draw_success_by_attempt(ax: Axes, reports: Sequence[Report]) -> dict[str, Any]:
    """Success within k attempts, k = 1..K (the paper's Att.k), a line per setting: mean ±
    std over runs (band)."""
    drawn: dict[str, Any] = {"series": []}
    names = sized(reports)
    k_max = max(r.max_attempts for r in reports)
    top = 0.0
    for i, r in enumerate(reports):
        m, s = _mean(r)
        y, err = m.success_at, [e or 0 for e in s.success_at]
        ks = list(range(1, len(y) + 1))
        color = COLORS[i % len(COLORS)]
        ax.fill_between(ks, [100 * max(0, a - e) for a, e in zip(y, err)], [100 * min(1, a + e) for a, e in zip(y, err)],
                        color=color, alpha=0.15, linewidth=0)
        ax.plot(ks, [100 * v for v in y], color=color, marker="o", markersize=2.5, label=names[i], clip_on=False)
        top = max([top] + [100 * (a + e) for a, e in zip(y, err)])
        drawn["series"].append({"label": labels(reports)[i], "n": r.sample_size(), "attempts": ks, "success": y,
                                "std": s.success_at})
    _style(ax, "both")
    ax.set_xticks(range(1, k_max + 1))
    ax.set_xlim(0.7, k_max + 0.3)
    ax.set_ylim(0, _percent_limits(top))
    ax.set_xlabel("attempts (k)")
    _ylabel(ax, "tasks solved within k attempts (%)")
    _legend(ax)
    return drawn


# -- on the fly: success by decision (shot, action) --------------------------------------


def draw_success_by_step(ax: Axes, reports: Sequence[Report]) -> dict[str, Any]:
    """Success within k decisions, k = 1..max, mean (line) ± std over runs (band); ticks at
    the report's checkpoints (Pooltool's shots 1, 3, 6, ...), else at every decision."""
    drawn: dict[str, Any] = {"series": []}
    stepped = [r for r in reports if r.overall.mean.success_by_step is not None]
    names = sized(stepped)
    checkpoints = next((list(map(int, r.overall.mean.success_within_steps)) for r in stepped
                        if r.overall.mean.success_within_steps is not None), None)
    n_steps = max([len(r.overall.mean.success_by_step) for r in stepped] + [1])
    marked = checkpoints or list(range(1, n_steps + 1))  # the table's points: marked and labelled
    top = 0.0
    for i, r in enumerate(stepped):
        m, s = _mean(r)
        y = m.success_by_step
        err = [e or 0 for e in s.success_by_step]
        ks = list(range(1, len(y) + 1))
        avg = m.avg_steps
        color = COLORS[i % len(COLORS)]
        label = names[i] + (f", avg {avg:.1f} {r.step_noun}s when solved" if avg is not None else "")
        ax.fill_between(ks, [100 * max(0, a - e) for a, e in zip(y, err)], [100 * min(1, a + e) for a, e in zip(y, err)],
                        color=color, alpha=0.15, linewidth=0)
        ax.plot(ks, [100 * v for v in y], color=color, label=label, marker="o", markersize=2.5,
                markevery=[k - 1 for k in marked if k <= len(y)])
        top = max([top] + [100 * (a + e) for a, e in zip(y, err)])
        drawn["series"].append({"label": labels(stepped)[i], "n": r.sample_size(), "steps": ks, "success": y,
                                "std": s.success_by_step, "avg_steps": avg})
    noun = stepped[0].step_noun if stepped else "step"
    drawn["ticks"] = marked
    _style(ax, "y")
    ax.set_xticks(marked)
    ax.set_xticks(range(1, n_steps + 1), minor=True)  # every decision, unlabelled
    ax.set_xlim(0.5, n_steps + 0.5)
    ax.set_ylim(0, _percent_limits(top))
    ax.set_xlabel(f"{noun}s (k)")
    _ylabel(ax, f"tasks solved within k {noun}s (%)")
    _legend(ax)
    return drawn


# -- per task group (Kinetix's sizes, PHYRE's setups) --------------------------------------


def group_order(report: Report) -> list[str]:
    """The report's groups in the order the environment lists its tasks (e.g. S, M, L)."""
    return list(report.groups or {})


def draw_group_bars(ax: Axes, reports: Sequence[Report]) -> dict[str, Any]:
    """Per task group and overall: tasks solved within K attempts (Pass@K), a bar per
    setting with the std over runs."""
    grouped = [r for r in reports if r.groups]
    names = labels(grouped)
    shown_names = sized(grouped)
    groups = list(dict.fromkeys(g for r in grouped for g in group_order(r))) + ["all"]
    width = min(0.8 / max(1, len(grouped)), 0.3)
    drawn: dict[str, Any] = {"groups": groups, "bars": []}
    top = 0.0
    for i, r in enumerate(grouped):
        values, errs = [], []
        for g in groups:
            sec = r.overall if g == "all" else r.groups.get(g)
            values.append(None if sec is None else sec.mean.success_at[-1])
            errs.append(0.0 if sec is None else sec.std.success_at[-1] or 0.0)
        xs = [j + (i - (len(grouped) - 1) / 2) * width for j in range(len(groups))]
        low, high = _clipped([v or 0 for v in values], errs)
        ax.bar(xs, [100 * (v or 0) for v in values], width=width * 0.92, color=COLORS[i % len(COLORS)],
               yerr=[[100 * e for e in low], [100 * e for e in high]], capsize=1.5, error_kw={"linewidth": 0.6},
               label=shown_names[i])
        top = max([top] + [100 * ((v or 0) + e) for v, e in zip(values, high)])
        drawn["bars"].append({"label": names[i], "n": r.sample_size(), "success": values, "std": errs})
    _style(ax)
    _ticks(ax, range(len(groups)), groups)
    ax.axvline(len(groups) - 1.5, color="#9ca3af", linewidth=0.8, linestyle=":")  # the groups | all
    _slot_limits(ax, len(groups))
    ax.set_ylim(0, _percent_limits(top))
    noun = grouped[0].group_noun if grouped else "group"
    k = max((r.max_attempts for r in grouped), default=1)
    ax.set_xlabel(noun)
    _ylabel(ax, "tasks solved (%)" if k == 1 else f"tasks solved within {k} attempts (%)")
    _legend(ax)
    return drawn


# -- VLA vs WM ----------------------------------------------------------------------------


def _setting_key(r: Report, *drop: str) -> tuple:
    """What must agree for two reports to be one comparison (everything but `drop`)."""
    facts = {"env": r.env, "model": r.model, "format": r.format, "runs": r.runs, "seed": r.seed,
             "k": r.max_attempts, "tasks": r.task_set}
    return tuple(v for k, v in facts.items() if k not in drop) + (_options_key(r, *drop),)


def vla_wm_pairs(reports: Sequence[Report]) -> list[tuple[Report, Report]]:
    """(VLA report, WM report) of each setting evaluated in both formats (several of one
    setting pair up in the order given)."""
    by_key: dict[tuple, dict[str, list[Report]]] = defaultdict(lambda: defaultdict(list))
    for r in reports:
        by_key[_setting_key(r, "format")][r.format].append(r)
    return [pair for f in by_key.values() for pair in zip(*(f[x] for x in FORMATS))]


def pass_at(report: Report, k: int) -> tuple[float, int]:
    """(Pass@k', k') with k' = k, or the report's runs where it has fewer."""
    values = report.overall.pass_at
    kk = min(k, len(values))
    return values[kk - 1], kk


def draw_vla_wm_scatter(ax: Axes, reports: Sequence[Report], k: int | None = None) -> dict[str, Any]:
    """WM against VLA at Pass@k, the paper's figure: k as given, else the environment's own
    (the paper's: PHYRE 5, I-PHYRE 3; else its runs). A setting with fewer runs than k is drawn
    at the Pass@ its runs allow and labelled so, never at an invented Pass@k."""
    drawn: dict[str, Any] = {"points": [], "notes": []}
    pairs = vla_wm_pairs(reports)
    envs = list(dict.fromkeys(vla.env for vla, _ in pairs))
    titles = {vla.env: vla.title for vla, _ in pairs}
    for vla, wm in pairs:
        want = k or get_spec(vla.env).report.pass_k or vla.runs
        (x, kx), (y, ky) = pass_at(vla, want), pass_at(wm, want)
        kk = min(kx, ky)
        if kk != kx or kk != ky:  # compare like with like
            (x, _), (y, _) = pass_at(vla, kk), pass_at(wm, kk)
        color = COLORS[envs.index(vla.env) % len(COLORS)]
        ax.scatter(100 * x, 100 * y, color=color, s=16, zorder=3)
        options = ",".join(f"{a}={b}" for a, b in sorted(vla.env_options.items()))
        n = vla.sample_size() if vla.sample_size() == wm.sample_size() else f"{vla.sample_size()} / {wm.sample_size()}"
        ax.annotate(vla.model + (f" {options}" if options else "") + f"\nPass@{kk}, n={n}", (100 * x, 100 * y),
                    fontsize=ANNOTATION_PT, xytext=(3, 3), textcoords="offset points")
        drawn["points"].append({"env": vla.env, "model": vla.model, "env_options": vla.env_options,
                                "k": kk, "vla": x, "wm": y, "n": n})
        if kk < want:
            drawn["notes"].append(f"{vla.title} {vla.model}: {min(vla.runs, wm.runs)} run(s), fewer than "
                                  f"Pass@{want} needs: drawn at Pass@{kk}")
    top = _percent_limits(max([100.0 * max(p["vla"], p["wm"]) for p in drawn["points"]] + [0.0]))
    ax.plot([0, top], [0, top], "--", color="#9ca3af", linewidth=1, zorder=1)
    _style(ax, "both")
    ax.set_xlim(0, top)
    ax.set_ylim(0, top)
    ax.set_aspect("equal")
    ax.set_xlabel("VLA: Pass@k, solved in at least one of k runs (%)")
    ax.set_ylabel("WM: Pass@k (%)")
    for i, env in enumerate(envs):
        ax.scatter([], [], color=COLORS[i % len(COLORS)], label=titles[env])
    _legend(ax)
    return drawn


# -- annotation ablation ------------------------------------------------------------------


def _option_default(env: str, option: str) -> Any:
    field = get_env_class(env).Options.model_fields.get(option)
    return None if field is None else field.default


def ablation_pairs(reports: Sequence[Report], option: str = ABLATION_OPTION) -> list[tuple[Report, Report]]:
    """(with, without) reports of one env/model/format/other options, where the
    environment's boolean `option` is true in one and false in the other."""
    by_key: dict[tuple, dict[bool, list[Report]]] = defaultdict(lambda: defaultdict(list))
    for r in reports:
        default = _option_default(r.env, option)
        if isinstance(default, bool):
            by_key[_setting_key(r, option)][bool(r.env_options.get(option, default))].append(r)
    return [pair for v in by_key.values() for pair in zip(v[True], v[False])]


def draw_ablation_dumbbell(ax: Axes, reports: Sequence[Report], option: str = ABLATION_OPTION) -> dict[str, Any]:
    """Per setting and task group (size), then overall: success with and without the
    option, joined by a line."""
    drawn: dict[str, Any] = {"rows": []}
    for with_, without in ablation_pairs(reports, option):
        for g in group_order(with_) + [None]:
            a = _mean(with_, g)[0].success_at[-1]
            b = _mean(without, g)[0].success_at[-1]
            sec_w = with_.groups[g] if g else None
            n = with_.sample_size(sec_w)
            drawn["rows"].append({"label": f"{with_.model} {with_.format.upper()} · {g or 'all'} (n={n})",
                                  "group": g, "with": a, "without": b, "n": n})
    for y, row in enumerate(drawn["rows"]):
        ax.plot([100 * row["without"], 100 * row["with"]], [y, y], color="#9ca3af", zorder=1)
        # a ring and a dot: both stay visible when the two values are equal
        ax.scatter(100 * row["with"], y, s=40, facecolors="none", edgecolors=COLORS[0], linewidths=1.2, zorder=2,
                   label=f"{option}=true" if y == 0 else None)
        ax.scatter(100 * row["without"], y, s=12, color=COLORS[5], zorder=3,
                   label=f"{option}=false" if y == 0 else None)
    _style(ax, "x")
    ax.set_yticks(range(len(drawn["rows"])), [r["label"] for r in drawn["rows"]])
    ax.invert_yaxis()
    ax.margins(y=0.15)
    top = _percent_limits(max([100 * max(r["with"], r["without"]) for r in drawn["rows"]] + [0.0]))
    ax.set_xlim(-0.02 * top, top * 1.02)
    k = max((r.max_attempts for r in reports), default=1)
    ax.set_xlabel("tasks solved (%)" if k == 1 else f"tasks solved within {k} attempts (%)")
    _legend(ax)
    return drawn


# -- stars (games) ------------------------------------------------------------------------


STAR_COLORS = ["#d1d5db", "#fde68a", "#fbbf24", "#d97706", "#92400e"]  # not won, then won with 0..3 stars


def draw_star_bars(ax: Axes, reports: Sequence[Report]) -> dict[str, Any]:
    """Per setting, a bar of all its levels (100 %): the share not won, then won with 0
    (where any were), 1, 2 and 3 stars, mean over runs, each share written where it fits;
    the stars per level after the bar."""
    starred = [r for r in reports if r.overall.mean.stars is not None]
    names = labels(starred)
    zero = any(x.stars.levels_with.get("0") for r in starred for x in r.overall.per_run)
    counts = (["0"] if zero else []) + ["1", "2", "3"]
    drawn: dict[str, Any] = {"stars": counts, "labels": names, "n": [r.sample_size() for r in starred],
                             "levels_with": [], "std": [], "shares": [], "not_won": [], "mean_all": [],
                             "mean_completed": []}
    segments = ["not won"] + [f"won, {c} star{'' if c == '1' else 's'}" for c in counts]
    colors = [STAR_COLORS[0]] + STAR_COLORS[-len(counts):]
    for i, r in enumerate(starred):
        st, sd = r.overall.mean.stars, r.overall.std.stars
        tasks = r.overall.tasks
        values = [st.levels_with[c] for c in counts]
        shares = [v / tasks if tasks else 0.0 for v in values]
        not_won = max(0.0, 1.0 - sum(shares))
        left = 0.0
        for j, share in enumerate([not_won, *shares]):
            ax.barh(i, 100 * share, left=100 * left, height=0.6, color=colors[j], edgecolor="white", linewidth=0.4,
                    label=segments[j] if i == 0 else None)
            if share >= 0.09:
                ax.text(100 * (left + share / 2), i, f"{100 * share:.0f}%", ha="center", va="center",
                        fontsize=ANNOTATION_PT, color="#111827" if j < 3 else "white")
            left += share
        ax.text(101, i, f"{st.mean_all:.2f}\u2605/level", va="center", ha="left", fontsize=ANNOTATION_PT)
        drawn["levels_with"].append(values)
        drawn["std"].append([sd.levels_with[c] or 0 for c in counts])
        drawn["shares"].append(shares)
        drawn["not_won"].append(not_won)
        drawn["mean_all"].append(st.mean_all)
        drawn["mean_completed"].append(st.mean_completed)
    _style(ax, "x")
    ax.set_yticks(range(len(starred)), sized(starred, "\n"))
    ax.invert_yaxis()
    ax.set_ylim(len(starred) - 0.5 + max(0, 2 - len(starred)) * 0.5, -0.5 - max(0, 2 - len(starred)) * 0.5)
    ax.set_xlim(0, 100)
    ax.set_xticks(range(0, 101, 20))
    ax.set_xlabel("levels (%, mean over runs)")
    _legend(ax)
    return drawn


# -- the leaderboard (across environments) -----------------------------------------------

UNFINISHED_HATCH = "////"
BEST_MARK = "\u2605"  # above the best bar of a column (the table's "*")
UNRANKED_MARK = "\u2020"  # above a bar left out of its column's ranking (the table's)


def leaderboard_panels(board: Leaderboard) -> list[tuple[str, int, list[int], bool]]:
    """(title, group, column indices, percent) of each panel: an environment setting's
    percent figures on one axis, its counts (stars) on a panel of their own."""
    panels = []
    for g, group in enumerate(board.groups):
        for percent in (True, False):
            columns = [c for c, col in enumerate(group.columns) if col.percent == percent and col.ranked]
            if columns:
                title = group.title if percent else ", ".join([group.title] + [group.columns[c].header for c in columns])
                panels.append((title, g, columns, percent))
    return panels


def draw_leaderboard(fig: Figure, board: Leaderboard) -> dict[str, Any]:
    """A panel per environment setting (`leaderboard_panels`): its headline figures side by
    side, a bar per model x format, mean ± std over runs. The best of a column carries a
    star; an unfinished run is a hatched, empty slot with its episodes done/total (never a
    bar); a setting without a run of that environment says "no run"."""
    panels = leaderboard_panels(board)
    ncols = _leaderboard_columns(fig.get_figwidth(), len(panels))
    axes = fig.subplots(math.ceil(len(panels) / ncols), ncols, squeeze=False).ravel()
    labels_ = [board.row_label(i) for i in range(len(board.rows))]
    width = min(0.8 / max(1, len(board.rows)), 0.3)
    drawn: dict[str, Any] = {"rows": labels_, "panels": []}
    for ax, (title, g, columns, percent) in zip(axes, panels):
        scale = 100.0 if percent else 1.0
        cells = [[board.cells[(r, g)][c] if (r, g) in board.cells else None for c in columns]
                 for r in range(len(board.rows))]
        finished = [(x.mean, x.std or 0.0) for row in cells for x in row if x and x.unfinished is None and x.mean is not None]
        top = max([scale * (m + s) for m, s in finished] + [0.0])
        ymax = _percent_limits(top * 1.1) if percent else max(1.0, 1.2 * top)
        panel = {"title": title, "columns": [board.groups[g].columns[c].header for c in columns], "bars": []}
        for r, row in enumerate(cells):
            xs = [j + (r - (len(board.rows) - 1) / 2) * width for j in range(len(columns))]
            values = [x.mean if x and x.unfinished is None else None for x in row]
            errs = [(x.std or 0.0) if x and x.unfinished is None else 0.0 for x in row]
            shown = [(x_, v, e) for x_, v, e in zip(xs, values, errs) if v is not None]
            if shown:
                sx, sv, se = zip(*shown)
                low, high = _clipped(sv, se, 1.0 if percent else None)
                ax.bar(sx, [scale * v for v in sv], width=width * 0.92, color=COLORS[r % len(COLORS)],
                       yerr=[[scale * e for e in low], [scale * e for e in high]], capsize=2,
                       error_kw={"linewidth": 0.8})
                for x_, v, h, cell in zip(sx, sv, high, [x for x in row if x and x.unfinished is None and x.mean is not None]):
                    if cell.best or cell.unranked:
                        ax.annotate(BEST_MARK if cell.best else UNRANKED_MARK, (x_, scale * (v + h)), xytext=(0, 1),
                                    textcoords="offset points", ha="center", va="bottom", fontsize=ANNOTATION_PT)
            for x_, cell in zip(xs, row):
                if cell is None or (cell.unfinished is None and cell.mean is None):  # told apart from a 0 % bar
                    ax.text(x_, 0, "no run" if cell is None else "n/a", rotation=90, ha="center", va="bottom",
                            fontsize=MIN_FONT_PT, color="#4b5563")
                elif cell.unfinished is not None:
                    ax.bar(x_, ymax, width=width * 0.92, facecolor="none", edgecolor="#9ca3af",
                           hatch=UNFINISHED_HATCH, linewidth=0.6)
                    ax.text(x_, ymax * 0.5, f"unfinished {cell.unfinished}", rotation=90, ha="center",
                            va="center", fontsize=MIN_FONT_PT, color="#374151",
                            bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.5})
            panel["bars"].append({"row": labels_[r], "mean": values, "std": errs,
                                  "best": [bool(x and x.best) for x in row],
                                  "unfinished": [x.unfinished if x else None for x in row],
                                  # no run, or no figure (e.g. Pass@5 of a run of 3)
                                  "missing": [x is None or (x.unfinished is None and x.mean is None) for x in row]})
        # n: every row's tasks x runs, said once where they share one
        sizes = {labels_[r]: next((x.n for x in row if x and x.n), None) for r, row in enumerate(cells)}
        sizes = {k: v for k, v in sizes.items() if v}
        shared = set(sizes.values())
        n_line = (f"n={shared.pop()}" if len(shared) == 1 else
                  "n: " + ", ".join(f"{k} {v}" for k, v in sizes.items()))
        panel["n"] = sizes
        _style(ax)
        fits = int(fig.get_figwidth() / ncols * 72 / ((MIN_FONT_PT + 1) * CHAR_EM)) - 4  # characters across a panel
        ax.set_title(textwrap.fill(title, fits) + (f"\n{textwrap.fill(n_line, fits)}" if sizes else ""),
                     fontsize=MIN_FONT_PT + 1)
        ax.set_xticks(range(len(columns)), panel["columns"])
        ax.set_xlim(-0.5 - max(0, 1 - len(columns)) / 2, len(columns) - 0.5 + max(0, 1 - len(columns)) / 2)
        ax.set_ylim(0, ymax * 1.1)  # room for a mark above the tallest bar
        if percent:
            ax.set_yticks([t for t in ax.get_yticks() if 0 <= t <= ymax])
        else:
            ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylabel("%" if percent else "per run")
        drawn["panels"].append(panel)
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    handles = [Patch(color=COLORS[r % len(COLORS)], label=label) for r, label in enumerate(labels_)]
    handles.append(Patch(facecolor="none", edgecolor="#9ca3af", hatch=UNFINISHED_HATCH,
                         label="unfinished (episodes done/total)"))
    per_row = 2 if fig.get_figwidth() < 4.5 else 4
    fits = int(fig.get_figwidth() * 72 / (MIN_FONT_PT * CHAR_EM)) - 6
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), per_row), frameon=False,
               title=textwrap.fill(f"mean \u00b1 std over runs; {BEST_MARK} best of the column among rows of one n; "
                                   f"{UNRANKED_MARK} not ranked (other n)", fits))
    return drawn


def _leaderboard_columns(width: float, panels: int) -> int:
    return min(1 if width < 4.5 else 3, panels)


def _leaderboard_size(board: Leaderboard, width: float) -> tuple[float, float]:
    n = len(leaderboard_panels(board))
    ncols = _leaderboard_columns(width, n)
    legend_rows = math.ceil((len(board.rows) + 1) / (2 if width < 4.5 else 4))
    return width, 2.1 * math.ceil(n / ncols) + 0.3 + 0.16 * legend_rows


# -- all figures --------------------------------------------------------------------------


def figures_for(reports: Sequence[Report]) -> list[tuple[str, str, Any, list[Report]]]:
    """(file stem, title, draw function, reports) of every figure these reports support."""
    out = []
    by_env: dict[str, list[Report]] = defaultdict(list)
    for r in reports:
        by_env[r.env].append(r)
    for env, rs in by_env.items():
        title = rs[0].title
        multi = [r for r in rs if r.max_attempts > 1]
        if multi:
            out.append((f"cumulative_{env}", f"{title}: tasks solved by attempt", draw_cumulative_bars, multi))
            out.append((f"by_attempt_{env}", f"{title}: success against attempts", draw_success_by_attempt, multi))
        stepped = [r for r in rs if r.overall.mean.success_by_step is not None]
        if stepped:
            noun = stepped[0].step_noun
            out.append((f"by_{noun}_{env}", f"{title}: tasks solved by {noun}", draw_success_by_step, stepped))
        grouped = [r for r in rs if r.groups]
        if grouped:
            noun = grouped[0].group_noun
            out.append((f"by_{noun}_{env}", f"{title}: tasks solved by {noun}", draw_group_bars, grouped))
        if ablation_pairs(rs):
            out.append((f"{ABLATION_OPTION}_{env}", f"{title}: with and without annotations",
                        draw_ablation_dumbbell, rs))
        stars = [r for r in rs if r.overall.mean.stars is not None]
        if stars:
            out.append((f"stars_{env}", f"{title}: levels won by stars", draw_star_bars, stars))
    if vla_wm_pairs(reports):
        out.append(("vla_vs_wm", "VLA vs WM (Pass@k, the paper's figure)", draw_vla_wm_scatter, list(reports)))
    return out


def _size(draw, reports: Sequence[Report], width: float) -> tuple[float, float]:
    """Figure size in inches at `width` (one or two columns): a height for the axes, the legend
    under them (a line per setting where they stack) and long tick labels."""
    narrow = width < 4.5
    rows = len(reports) if narrow else math.ceil(len(reports) / 2)
    legend = 0.18 * (rows + 1)
    if draw is draw_vla_wm_scatter:
        return width, min(width, 4.2) + legend
    if draw is draw_ablation_dumbbell:
        lines = sum(len(group_order(with_)) + 1 for with_, _ in ablation_pairs(reports))
        return width, 1.0 + 0.22 * lines + legend
    if draw is draw_star_bars:
        return width, 0.9 + 0.42 * len(reports) + (0.5 if narrow else 0.3)
    if draw is draw_cumulative_bars:
        return width, (2.4 if narrow else 2.6) + 0.35 + legend
    return width, (2.2 if narrow else 2.5) + legend


def plot_all(reports: Sequence[Report], out: str | Path, board: Leaderboard | None = None) -> list[Path]:
    """Write every applicable figure as PNG and PDF, two columns wide (`<stem>`) and one
    (`<stem>-1col`), and the drawn data as figures.json; with `board`, the leaderboard too
    where it compares anything (two settings or more)."""
    figures = figures_for(reports)
    compares = board is not None and (len(board.groups) > 1 or len(board.rows) > 1)
    if not figures and not compares:
        return []
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    data: dict[str, Any] = {}

    def save(stem: str, fig: Figure) -> None:
        for suffix in ("png", "pdf"):
            path = out / f"{stem}.{suffix}"
            fig.savefig(path, dpi=DPI)
            written.append(path)

    with matplotlib.rc_context(STYLE):
        for name, width in WIDTHS.items():
            if compares:
                fig = Figure(figsize=_leaderboard_size(board, width), layout="constrained")
                data["leaderboard"] = draw_leaderboard(fig, board)
                fig.suptitle("Leaderboard")
                save(f"leaderboard{name}", fig)
            for stem, title, draw, rs in figures:
                fig = Figure(figsize=_size(draw, rs, width), layout="constrained")
                ax = fig.add_subplot()
                data[stem] = draw(ax, rs)
                ax.set_title(title)
                save(f"{stem}{name}", fig)
    (out / "figures.json").write_text(json.dumps(data, indent=1))
    return [*written, out / "figures.json"]


def draw_figure(stem: str, reports: Sequence[Report], width: float, board: Leaderboard | None = None) -> Figure:
    """One figure by its stem (of `figures_for(reports)`, or "leaderboard" of `board`), drawn
    at `width` inches in the figures' style, laid out (for tests and notebooks)."""
    with matplotlib.rc_context(STYLE):
        if stem == "leaderboard":
            fig = Figure(figsize=_leaderboard_size(board, width), layout="constrained")
            FigureCanvasAgg(fig)
            draw_leaderboard(fig, board)
            fig.suptitle("Leaderboard")
        else:
            [(_, title, draw, rs)] = [f for f in figures_for(reports) if f[0] == stem]
            fig = Figure(figsize=_size(draw, rs, width), layout="constrained")
            FigureCanvasAgg(fig)
            ax = fig.add_subplot()
            draw(ax, rs)
            ax.set_title(title)
        fig.canvas.draw()  # lay out and render the text at the style's sizes
    return fig
