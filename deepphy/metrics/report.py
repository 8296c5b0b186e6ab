"""The paper-style report of a run directory: figures per run, mean and std over runs,
overall and per task group, rendered as text, JSON, CSV or Markdown."""

from __future__ import annotations

import csv
import io
import json
from collections import defaultdict
from typing import Any, Sequence

from deepphy.config import RunConfig
from deepphy.envs import ReportSpec, Task, get_spec
from deepphy.metrics import figures as F
from deepphy.runs.records import AttemptRecord


def _run_figures(eps: list[F.Episode], n_tasks: int, k_max: int, figures: ReportSpec, run: int,
                 wm_records: list[AttemptRecord] | None) -> dict[str, Any]:
    finished = [e for e in eps if e.finished]
    solved = sum(e.solved for e in eps)
    out: dict[str, Any] = {
        "run": run,
        "tasks": n_tasks,
        "solved": solved,
        "unsolved": len(finished) - solved,
        "unfinished": n_tasks - len(finished),
        "success_at": [F.success_at(eps, k, n_tasks) for k in range(1, k_max + 1)],
        "avg_attempts": F.average_attempts(eps),
        **F.totals(eps),
    }
    if figures.step_checkpoints:
        out["success_within_steps"] = {str(k): F.success_within_steps(eps, k, n_tasks) for k in figures.step_checkpoints}
        out["avg_steps"] = F.average_steps(eps)
    if figures.auccess:
        out["auccess"] = F.auccess(eps, n_tasks)
    if wm_records is not None:
        p = F.prediction_scores(wm_records)
        out["wm"] = {"decisions": p.decisions, "stated": p.stated, "accuracy": p.accuracy,
                     "predicted_success_failed": p.predicted_success_failed, "confusion": p.confusion}
    if figures.stars:
        s = F.stars(eps, n_tasks)
        out["stars"] = {
            "total": s.total,
            "mean_all": s.mean_all,
            "mean_completed": s.mean_completed,
            "levels_with": {str(k): v for k, v in s.levels_with.items()},
        }
    return out


def _mean_std(per_run: list[dict[str, Any]]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Mean and std over runs of every numeric figure (lists element-wise, dicts per key)."""

    def combine(values: list[Any]) -> tuple[Any, Any]:
        first = values[0]
        if isinstance(first, list):
            pairs = [combine([v[i] for v in values]) for i in range(len(first))]
            return [p[0] for p in pairs], [p[1] for p in pairs]
        if isinstance(first, dict):
            pairs = {k: combine([v[k] for v in values]) for k in first}
            return {k: p[0] for k, p in pairs.items()}, {k: p[1] for k, p in pairs.items()}
        ms = F.MeanStd.of(values)
        return ms.mean, ms.std

    keys = [k for k in per_run[0] if k != "run"]
    means, stds = {}, {}
    for k in keys:
        means[k], stds[k] = combine([r[k] for r in per_run])
    return means, stds


def _section(eps: list[F.Episode], tasks: Sequence[Task], runs: int, k_max: int, figures: ReportSpec,
             wm_records: list[AttemptRecord] | None) -> dict[str, Any]:
    """Figures per run, then mean and std. `wm_records`: the records to score WM predictions on."""
    by_run: dict[int, list[F.Episode]] = defaultdict(list)
    for e in eps:
        by_run[e.run].append(e)
    wanted = {t.id for t in tasks}
    per_run = [
        _run_figures(by_run.get(r, []), len(tasks), k_max, figures, r,
                     None if wm_records is None else [x for x in wm_records if x.run == r and x.task in wanted])
        for r in range(runs)
    ]
    mean, std = _mean_std(per_run)
    return {"tasks": len(tasks), "per_run": per_run, "mean": mean, "std": std}


def build_report(config: RunConfig, tasks: Sequence[Task], records: Sequence[AttemptRecord], k_max: int) -> dict[str, Any]:
    figures = get_spec(config.env).report
    wanted = {t.id for t in tasks}
    eps = [e for e in F.episodes(records, k_max) if e.task in wanted and e.run < config.runs]
    wm = list(records) if config.format.value == "wm" else None
    report: dict[str, Any] = {
        "env": config.env,
        "model": config.model,
        "format": config.format.value,
        "runs": config.runs,
        "seed": config.seed,
        "max_attempts": k_max,
        "step_noun": figures.step_noun,
        "env_options": config.env_options,
        "overall": _section(eps, tasks, config.runs, k_max, figures, wm),
    }
    groups = sorted({t.group for t in tasks if t.group})
    if len(groups) > 1:
        report["groups"] = {
            g: _section([e for e in eps if e.group == g], [t for t in tasks if t.group == g], config.runs, k_max,
                        figures, wm)
            for g in groups
        }
    return report


def report_of(run_dir) -> dict[str, Any]:
    """The report of one run directory, as `deepphy report --json` prints it."""
    from deepphy.runner import resolve
    from deepphy.runs.store import check_records, read_config, read_records

    config = read_config(run_dir)
    _, tasks, k_max = resolve(config)
    records = read_records(run_dir)
    check_records(run_dir, records, k_max, frames=False)  # a duplicated or missing attempt would skew every figure
    return build_report(config, tasks, records, k_max)


# -- rendering --------------------------------------------------------------------------


def _pct(m: float | None, s: float | None) -> str:
    if m is None:
        return "-"
    return f"{100 * m:.1f}" + (f"±{100 * s:.1f}" if s else "")


def _num(m: float | None, s: float | None, digits: int = 2) -> str:
    if m is None:
        return "-"
    return f"{m:.{digits}f}" + (f"±{s:.{digits}f}" if s else "")


def setting(report: dict[str, Any]) -> str:
    """What distinguishes one run directory's rows from another's in a combined table."""
    options = ",".join(f"{k}={v}" for k, v in sorted(report["env_options"].items()))
    return f"{report['model']} {report['format'].upper()}" + (f" {options}" if options else "")


def table(reports: Sequence[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    """Header and rows: per report, one row for all tasks, then one per group. Reports of
    several run directories (same environment) share one table, labelled by their setting."""
    k_max = max(r["max_attempts"] for r in reports)
    means = [r["overall"]["mean"] for r in reports]
    per_runs = [x for r in reports for x in r["overall"]["per_run"]]
    extra_steps = next((m["success_within_steps"] for m in means if "success_within_steps" in m), None)
    show_auccess = any("auccess" in m for m in means)
    show_stars = any("stars" in m for m in means)
    show_wm = any("wm" in m for m in means)
    show_errors = any(x["model_errors"] or x["retries"] for x in per_runs)
    show_cost = any(x["cost_usd"] or x["input_tokens"] for x in per_runs)
    combined = len(reports) > 1
    header = (["setting"] if combined else []) + ["group", "n"] + [f"Att.{k}" for k in range(1, k_max + 1)]
    header += ["AvgAtt", "Solved", "Invalid"]
    if extra_steps:
        noun = reports[0].get("step_noun", "step").capitalize()
        header += [f"{noun}{k}" for k in extra_steps] + [f"Avg{noun}s"]
    if show_auccess:
        header.append("AUCCESS")
    if show_stars:
        header += ["Stars", "Stars/lvl", "Stars/done", "1*", "2*", "3*"]
    if show_wm:  # WM predicted outcomes: accuracy, and how often a predicted success failed
        header += ["PredAcc", "PredS->F"]
    if show_errors:
        header += ["ModelErr", "Retries"]
    if show_cost:
        header += ["TokensIn", "TokensOut", "Cost$"]

    def row(report: dict[str, Any], name: str, sec: dict[str, Any]) -> list[str]:
        m, s = sec["mean"], sec["std"]
        k = report["max_attempts"]
        cells = ([setting(report)] if combined else []) + [name, str(sec["tasks"])]
        cells += [_pct(m["success_at"][i], s["success_at"][i]) if i < k else "" for i in range(k_max)]
        cells += [_num(m["avg_attempts"], s["avg_attempts"]), _num(m["solved"], s["solved"], 1),
                  _num(m["invalid_attempts"], s["invalid_attempts"], 1)]
        if extra_steps:
            within = m.get("success_within_steps", {})
            cells += [_pct(within[c], s["success_within_steps"][c]) if c in within else "-" for c in extra_steps]
            cells.append(_num(m.get("avg_steps"), s.get("avg_steps")))
        if show_auccess:
            cells.append(_pct(m.get("auccess"), s.get("auccess")))
        if show_stars:
            st, sd = m.get("stars"), s.get("stars")
            if st is None:
                cells += ["-"] * 6
            else:
                cells += [_num(st["total"], sd["total"], 1), _num(st["mean_all"], sd["mean_all"]),
                          _num(st["mean_completed"], sd["mean_completed"])]
                cells += [_num(st["levels_with"][c], sd["levels_with"][c], 1) for c in ("1", "2", "3")]
        if show_wm:
            wm, wsd = m.get("wm"), s.get("wm")
            cells += (["-", "-"] if wm is None else
                      [_pct(wm["accuracy"], wsd["accuracy"]), _pct(wm["predicted_success_failed"], wsd["predicted_success_failed"])])
        if show_errors:
            cells += [_num(m["model_errors"], s["model_errors"], 1), _num(m["retries"], s["retries"], 1)]
        if show_cost:
            cells += [_num(m["input_tokens"], s["input_tokens"], 0), _num(m["output_tokens"], s["output_tokens"], 0),
                      _num(m["cost_usd"], s["cost_usd"], 4)]
        return cells

    rows = []
    for report in reports:
        rows.append(row(report, "all", report["overall"]))
        rows += [row(report, g, sec) for g, sec in report.get("groups", {}).items()]
    return header, rows


def _as_list(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    return [reports] if isinstance(reports, dict) else list(reports)


def render_text(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    reports = _as_list(reports)
    header, rows = table(reports)
    widths = [max(len(header[i]), *(len(r[i]) for r in rows)) for i in range(len(header))]
    fmt = lambda cells: "  ".join(c.rjust(w) for c, w in zip(cells, widths))  # noqa: E731
    lines = []
    for report in reports:
        done = sum(r["tasks"] - r["unfinished"] for r in report["overall"]["per_run"])
        total = report["overall"]["tasks"] * report["runs"]
        lines.append(
            f"{report['env']} · {setting(report)} · {report['runs']} run(s), seed {report['seed']} · "
            f"episodes complete {done}/{total}"
        )
    lines += ["success rate (%) within k attempts, mean±std over runs", fmt(header), fmt(["-" * w for w in widths])]
    lines += [fmt(r) for r in rows]
    for report in reports:
        wm = report["overall"]["mean"].get("wm")
        if wm is not None:
            c = wm["confusion"]
            lines += [
                f"WM predicted outcomes ({setting(report)}): {_num(wm['stated'], None, 1)} of "
                f"{_num(wm['decisions'], None, 1)} decisions stated one (mean per run); decisions by prediction and result:",
                f"  predicted success: {_num(c['success']['success'], None, 1)} solved, {_num(c['success']['failure'], None, 1)} failed",
                f"  predicted failure: {_num(c['failure']['success'], None, 1)} solved, {_num(c['failure']['failure'], None, 1)} failed",
            ]
    return "\n".join(lines)


def render_markdown(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    header, rows = table(_as_list(reports))
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def render_csv(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    header, rows = table(_as_list(reports))
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


_LATEX_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
                  "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}


def _latex_cell(text: str) -> str:
    escaped = "".join(_LATEX_SPECIAL.get(c, c) for c in text)
    return escaped.replace("±", r"$\pm$").replace("*", r"$\star$")


def render_latex(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    """A booktabs `tabular` of the same table (needs \\usepackage{booktabs})."""
    header, rows = table(_as_list(reports))
    numeric = [all(_is_figure(r[i]) for r in rows) for i in range(len(header))]
    lines = [
        "% success rate (%) within k attempts, mean $\\pm$ std over runs (deepphy report --latex)",
        r"\begin{tabular}{" + "".join("r" if n else "l" for n in numeric) + "}",
        r"\toprule",
        " & ".join(_latex_cell(h) for h in header) + r" \\",
        r"\midrule",
    ]
    lines += [" & ".join(_latex_cell(c) for c in r) + r" \\" for r in rows]
    lines += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(lines)


def _is_figure(cell: str) -> bool:
    return cell in ("", "-") or cell.replace("±", "").replace(".", "").replace("-", "").isdigit()


def render_json(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    """One report as an object; several as a list."""
    return json.dumps(reports if isinstance(reports, dict) or len(reports) > 1 else reports[0], indent=2)
