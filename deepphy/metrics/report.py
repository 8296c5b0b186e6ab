"""The paper-style report of a run directory: figures per run, mean and std over runs,
overall and per task group, rendered as text, JSON, CSV, Markdown or LaTeX."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import re
import statistics
from collections import defaultdict
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from deepphy.config import RunConfig, is_human
from deepphy.envs import EnvSpec, Task, get_spec
from deepphy.metrics import figures as F
from deepphy.plan import plan
from deepphy.runs.records import AttemptRecord, episode_finished
from deepphy.runs.store import check_records, read_config, read_records

TEXT_WIDTH = 120  # characters: a wider text table is split into blocks of column groups
LATEX_WIDTH = 80  # characters of plain cell text per LaTeX block (~ an article's \linewidth at 10 pt)
LATEX_PREAMBLE = r"\usepackage{booktabs}\usepackage{graphicx}"


def _run_figures(eps: list[F.Episode], n_tasks: int, k_max: int, spec: EnvSpec, run: int,
                 wm_records: list[AttemptRecord] | None) -> dict[str, Any]:
    figures = spec.report
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
    if spec.max_steps > 1:  # the whole curve (figures), and the protocol's checkpoints (tables)
        out["success_by_step"] = [F.success_within_steps(eps, k, n_tasks) for k in range(1, spec.max_steps + 1)]
        out["avg_steps"] = F.average_steps(eps)
    if figures.step_checkpoints:
        out["success_within_steps"] = {str(k): F.success_within_steps(eps, k, n_tasks) for k in figures.step_checkpoints}
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


def _section(eps: list[F.Episode], tasks: Sequence[Task], runs: int, k_max: int, spec: EnvSpec,
             wm_records: list[AttemptRecord] | None, finished_only: bool = False) -> dict[str, Any]:
    """Figures per run, then mean and std. `wm_records`: the records to score WM predictions on.
    `finished_only`: every figure over the finished episodes alone (a run in progress: its
    unfinished episodes are left out, not counted as unsolved); Pass@k over the tasks whose
    runs have all finished."""
    by_run: dict[int, list[F.Episode]] = defaultdict(list)
    for e in eps:
        by_run[e.run].append(e)
    wanted = {t.id for t in tasks}
    finished = sum(e.finished for e in eps)
    if finished_only:
        by_run = defaultdict(list, {r: [e for e in x if e.finished] for r, x in by_run.items()})
        done_runs: dict[str, int] = defaultdict(int)
        for e in eps:
            done_runs[e.task] += e.finished
        complete = {t for t, n in done_runs.items() if n >= runs}
        pass_eps, pass_n = [e for e in eps if e.task in complete], len(complete)
    else:
        pass_eps, pass_n = eps, len(tasks)
    per_run = [
        _run_figures(by_run.get(r, []), len(by_run.get(r, [])) if finished_only else len(tasks), k_max, spec, r,
                     None if wm_records is None else [x for x in wm_records if x.run == r and x.task in wanted])
        for r in range(runs)
    ]
    mean, std = _mean_std(per_run)
    # Across runs, not per run: Pass@k for k = 1..runs (the paper's tables' Pass@K)
    pass_at = [F.pass_at(pass_eps, k, runs, pass_n) for k in range(1, runs + 1)]
    return {"tasks": len(tasks), "finished": finished, "per_run": per_run, "mean": mean, "std": std,
            "pass_at": pass_at}


def task_set_digest(tasks: Sequence[Task]) -> str:
    """Equal for two runs exactly when they evaluate the same tasks (in any order)."""
    return hashlib.sha256("\n".join(sorted(t.id for t in tasks)).encode()).hexdigest()[:16]


def departures(config: RunConfig) -> list[str]:
    """How a run's set-up departs from the paper's (docs/comparability.md): its prompts and
    the environment options set otherwise than the paper did. Empty: the paper's set-up."""
    cls = get_spec(config.env).load()
    out = [] if config.prompts == "paper" else [f"prompts={config.prompts}"]
    return out + cls.Options.departures_from_paper(config.env_options)


def human_time(records: Sequence[AttemptRecord], k_max: int) -> dict[str, Any]:
    """A person's time to decide (`timing.decision_s`: the page's clock from the prompt shown
    to the answer given; simulation not counted): per decision and per task (all the
    decisions of a finished episode), median, and in total."""
    per_decision = [s for r in records for s in r.timing.decision_s]
    episodes: dict[tuple[str, int], list[AttemptRecord]] = defaultdict(list)
    for r in records:
        episodes[(r.task, r.run)].append(r)
    per_task = [sum(s for r in rs for s in r.timing.decision_s) for rs in episodes.values()
                if episode_finished(rs, k_max)]
    return {"decisions": len(per_decision), "tasks": len(per_task),
            "median_decision_s": statistics.median(per_decision) if per_decision else None,
            "median_task_s": statistics.median(per_task) if per_task else None,
            "total_s": sum(per_decision)}


def build_report(config: RunConfig, tasks: Sequence[Task], records: Sequence[AttemptRecord], k_max: int,
                 finished_only: bool = False) -> dict[str, Any]:
    """The report of a run's records. `finished_only`: the figures over finished episodes
    alone (a live view's partial estimate; `partial` in the report says so)."""
    spec = get_spec(config.env)
    wanted = {t.id for t in tasks}
    records = [r for r in records if r.task in wanted and r.run < config.runs]
    eps = [e for e in F.episodes(records, k_max) if e.task in wanted and e.run < config.runs]
    wm = list(records) if config.format.value == "wm" else None
    if wm is not None and finished_only:
        done = {(e.task, e.run) for e in eps if e.finished}
        wm = [r for r in wm if (r.task, r.run) in done]
    report: dict[str, Any] = {
        "env": config.env,
        "title": spec.title,
        "model": config.model,
        "format": config.format.value,
        "runs": config.runs,
        "seed": config.seed,
        "max_attempts": k_max,
        "max_steps": spec.max_steps,
        "step_noun": spec.report.step_noun,
        "group_noun": spec.report.group_noun,
        "env_options": config.env_options,
        "prompts": config.prompts,
        "departures": departures(config),
        "task_set": task_set_digest(tasks),
        "overall": _section(eps, tasks, config.runs, k_max, spec, wm, finished_only),
    }
    if config.agent is not None:  # a user's agent: its entry point, arguments and package version
        report["agent"] = config.agent.model_dump(mode="json")
    if finished_only:
        report["partial"] = True
    if is_human(config.model):
        report["human_time"] = human_time(records, k_max)
    groups = list(dict.fromkeys(t.group for t in tasks if t.group))  # in the environment's order (S, M, L)
    if len(groups) > 1:
        report["groups"] = {
            g: _section([e for e in eps if e.group == g], [t for t in tasks if t.group == g], config.runs, k_max,
                        spec, wm, finished_only)
            for g in groups
        }
    return report


def episodes_done(report: dict[str, Any], section: dict[str, Any] | None = None) -> tuple[int, int]:
    """(finished episodes, all episodes: tasks x runs) of a report's section (overall by default)."""
    sec = report["overall"] if section is None else section
    total = sec["tasks"] * report["runs"]
    if "finished" in sec:
        return sec["finished"], total
    return total - sum(r["unfinished"] for r in sec["per_run"]), total  # a report made before `finished`


def sample_size(report: dict[str, Any], section: dict[str, Any] | None = None) -> str:
    """n of a row: tasks x runs, and the episodes finished where not all are ("40x3", "40x3 (31 done)")."""
    sec = report["overall"] if section is None else section
    done, total = episodes_done(report, sec)
    return f"{sec['tasks']}x{report['runs']}" + ("" if done == total else f" ({done} done)")


def report_of(run_dir) -> dict[str, Any]:
    """The report of one run directory, as `deepphy report --json` prints it."""
    the_plan = plan(read_config(run_dir))
    records = read_records(run_dir)
    check_records(run_dir, records, the_plan.k_max, frames=False)  # a duplicated or missing attempt would skew every figure
    return build_report(the_plan.config, the_plan.tasks, records, the_plan.k_max)


def mixed_task_sets(reports: Sequence[dict[str, Any]]) -> str | None:
    """A warning when reports to be compared evaluate different task sets, else None."""
    if len({r["task_set"] for r in reports}) < 2:
        return None
    sizes = {r["overall"]["tasks"] for r in reports}
    which = (f"n={sizes.pop()} each, other tasks" if len(sizes) == 1
             else ", ".join(f"{setting(r)}: n={r['overall']['tasks']}" for r in reports))
    return f"these runs evaluate different task sets ({which}): their rows are not comparable"


# -- rendering --------------------------------------------------------------------------


def _pct(m: float | None, s: float | None) -> str:
    if m is None:
        return "-"
    return f"{100 * m:.1f}" + (f"±{100 * s:.1f}" if s else "")


def _num(m: float | None, s: float | None, digits: int = 2) -> str:
    if m is None:
        return "-"
    return f"{m:.{digits}f}" + (f"±{s:.{digits}f}" if s else "")


def _count(m: float | None, s: float | None) -> str:
    """A count: an integer, or the mean over runs with one decimal where it is not one."""
    if m is None:
        return "-"
    return (f"{m:.0f}" if float(m).is_integer() else f"{m:.1f}") + (f"±{s:.1f}" if s else "")


def setting(report: dict[str, Any]) -> str:
    """What distinguishes one run directory's rows from another's in a combined table."""
    options = ",".join(f"{k}={v}" for k, v in sorted(options_of(report).items()))
    return f"{report['model']} {report['format'].upper()}" + (f" {options}" if options else "")


def options_of(report: dict[str, Any]) -> dict[str, Any]:
    """The environment options and, where they are not the paper's, the prompts: what makes
    an environment setting (reports of one setting compare; others are never mixed)."""
    prompts = report.get("prompts", "before-parity")
    return {**report["env_options"], **({} if prompts == "paper" else {"prompts": prompts})}


def paper_setting(report: dict[str, Any]) -> str:
    """The report's set-up in words: the paper's, or how it departs from it."""
    away = report.get("departures")
    if away is None:  # a report made before reports said so
        away = [f"prompts={report.get('prompts', 'before-parity')}"]
    return "the paper's set-up" if not away else f"departs from the paper: {', '.join(away)}"


@dataclass(frozen=True)
class _Columns:
    """A group of columns that belong together (split tables break only between groups)."""

    headers: list[str]
    key: list[str]  # what each column is, for the key under the table
    cells: Callable[[dict[str, Any], dict[str, Any], dict[str, Any]], list[str]]  # (report, mean, std) -> cells
    across_runs: Callable[[dict[str, Any], dict[str, Any]], list[str]] | None = None  # (report, section) -> cells

    def row(self, report: dict[str, Any], section: dict[str, Any]) -> list[str]:
        if self.across_runs is not None:
            return self.across_runs(report, section)
        return self.cells(report, section["mean"], section["std"])


def _column_groups(reports: Sequence[dict[str, Any]]) -> list[_Columns]:
    k_max = max(r["max_attempts"] for r in reports)
    means = [r["overall"]["mean"] for r in reports]
    per_runs = [x for r in reports for x in r["overall"]["per_run"]]
    out: list[_Columns] = []
    if k_max > 1:
        out.append(_Columns(
            [f"Att.{k}" for k in range(1, k_max + 1)] + ["AvgAtt"],
            ["Att.k: tasks solved within k attempts (%)", "AvgAtt: attempts used by the solved tasks"],
            lambda r, m, s: [_pct(m["success_at"][i], s["success_at"][i]) if i < r["max_attempts"] else ""
                             for i in range(k_max)] + [_num(m["avg_attempts"], s["avg_attempts"])]))
    else:
        out.append(_Columns(["Success"], ["Success: tasks solved (%)"],
                            lambda r, m, s: [_pct(m["success_at"][0], s["success_at"][0])]))
    runs = max(r["runs"] for r in reports)
    if runs > 1 and k_max > 1:  # beside Att.k, as the paper's tables; one run: Pass@1 is Att.K
        out.append(_Columns(
            [f"Pass@{k}" for k in range(1, runs + 1)],
            ["Pass@k: tasks solved within the attempt budget in at least one of k runs (%, the paper's Pass@k)"],
            lambda r, m, s: [], across_runs=lambda r, sec: [
                _pct(sec["pass_at"][k], None) if k < len(sec.get("pass_at", [])) else "-" for k in range(runs)]))
    checkpoints = next((list(m["success_within_steps"]) for m in means if "success_within_steps" in m), None)
    if checkpoints:
        noun = reports[0]["step_noun"]
        cap = noun.capitalize()

        def steps(r, m, s):
            within = m.get("success_within_steps", {})
            return ([_pct(within[c], s["success_within_steps"][c]) if c in within else "-" for c in checkpoints]
                    + [_num(m.get("avg_steps"), s.get("avg_steps"))])

        out.append(_Columns([f"{cap}{k}" for k in checkpoints] + [f"Avg{cap}s"],
                            [f"{cap}k: tasks solved within k {noun}s (%)", f"Avg{cap}s: {noun}s used by the solved tasks"],
                            steps))
    auccess = any("auccess" in m for m in means)
    out.append(_Columns(
        ["Solved", "Invalid"] + (["AUCCESS"] if auccess else []),
        ["Solved: tasks solved", "Invalid: attempts that ended on an invalid action"]
        + (["AUCCESS: PHYRE's area under the success curve, invalid attempts not counted (%)"] if auccess else []),
        lambda r, m, s: [_count(m["solved"], s["solved"]), _count(m["invalid_attempts"], s["invalid_attempts"])]
        + ([_pct(m.get("auccess"), s.get("auccess"))] if auccess else [])))
    if any("stars" in m for m in means):
        zero = any(x["stars"]["levels_with"].get("0") for x in per_runs if "stars" in x)  # 0-star wins exist
        counts = (["0"] if zero else []) + ["1", "2", "3"]

        def stars(r, m, s):
            st, sd = m.get("stars"), s.get("stars")
            if st is None:
                return ["-"] * (3 + len(counts))
            return ([_count(st["total"], sd["total"]), _num(st["mean_all"], sd["mean_all"]),
                     _num(st["mean_completed"], sd["mean_completed"])]
                    + [_count(st["levels_with"][c], sd["levels_with"][c]) for c in counts])

        out.append(_Columns(
            ["Stars", "Stars/lvl", "Stars/won"] + [f"{c}*" for c in counts],
            ["Stars: stars earned", "Stars/lvl: stars per level", "Stars/won: stars per level won",
             "n*: levels won with n stars"], stars))
    if any("wm" in m for m in means):  # WM predicted outcomes: accuracy, and how often a predicted success failed
        def wm(r, m, s):
            w, wsd = m.get("wm"), s.get("wm")
            return ["-", "-"] if w is None else [_pct(w["accuracy"], wsd["accuracy"]),
                                                 _pct(w["predicted_success_failed"], wsd["predicted_success_failed"])]

        out.append(_Columns(["PredAcc", "PredS->F"],
                            ["PredAcc: WM outcome predictions that came true (%)",
                             "PredS->F: predicted successes that failed (%)"], wm))
    if any(x["model_errors"] or x["retries"] for x in per_runs):
        out.append(_Columns(["ModelErr", "Retries"],
                            ["ModelErr: model requests that failed for good", "Retries: model request retries"],
                            lambda r, m, s: [_count(m["model_errors"], s["model_errors"]),
                                             _count(m["retries"], s["retries"])]))
    if any("human_time" in r for r in reports):  # a person's time to decide: never a model's latency
        def human(r, sec):
            h = r.get("human_time")
            if h is None or sec is not r["overall"]:
                return ["-", "-", "-"]
            return [_num(h["median_decision_s"], None, 1), _num(h["median_task_s"], None, 1),
                    _num(h["total_s"] / 60, None, 1)]

        out.append(_Columns(["Human s/dec", "Human s/task", "Human min"],
                            ["Human s/dec, s/task: a person's time to decide (the page's clock, simulation not "
                             "counted), median per decision and per finished task", "Human min: the person's time in all"],
                            lambda r, m, s: [], across_runs=human))
    if any(x["cost_usd"] or x["input_tokens"] for x in per_runs):
        out.append(_Columns(["TokensIn", "TokensOut", "Cost$"],
                            ["TokensIn/TokensOut: tokens sent and received", "Cost$: model cost (US dollars)"],
                            lambda r, m, s: [_num(m["input_tokens"], s["input_tokens"], 0),
                                             _num(m["output_tokens"], s["output_tokens"], 0),
                                             _num(m["cost_usd"], s["cost_usd"], 4)]))
    return out


@dataclass
class _Table:
    header: list[str]
    rows: list[list[str]]
    labels: int  # the first columns label a row (setting, group, n): every block repeats them
    groups: list[list[int]]  # the other columns' indices, by column group
    keys: list[str]  # what the columns are

    def blocks(self, width: int) -> list[list[int]]:
        """Column indices, in order, packed into blocks of at most `width` characters of
        text, each starting with the label columns. A column group stays in one block
        unless it is wider than a block on its own; then it is cut into equal parts."""
        w = [2 + max(len(h), *(len(r[i]) for r in self.rows)) for i, h in enumerate(self.header)]
        base = sum(w[: self.labels])
        units = []
        for g in self.groups:
            parts = -(-sum(w[c] for c in g) // max(1, width - base))  # ceil: the fewest parts that fit
            size = -(-len(g) // parts)
            units += [g[i : i + size] for i in range(0, len(g), size)]
        blocks: list[list[int]] = []
        used = width
        for unit in units:
            if used + sum(w[c] for c in unit) > width:
                blocks.append(list(range(self.labels)))
                used = base
            blocks[-1] += unit
            used += sum(w[c] for c in unit)
        return blocks

    def block(self, columns: list[int]) -> tuple[list[str], list[list[str]]]:
        return [self.header[c] for c in columns], [[r[c] for c in columns] for r in self.rows]


def _table(reports: Sequence[dict[str, Any]]) -> _Table:
    groups = _column_groups(reports)
    combined = len(reports) > 1
    header = (["setting"] if combined else []) + ["group", "n"]
    labels = len(header)
    columns = []
    for g in groups:
        columns.append(list(range(len(header), len(header) + len(g.headers))))
        header += g.headers
    rows = []
    for report in reports:
        for name, sec in [("all", report["overall"]), *report.get("groups", {}).items()]:
            rows.append(([setting(report)] if combined else []) + [name, sample_size(report, sec)]
                        + [c for g in groups for c in g.row(report, sec)])
    return _Table(header, rows, labels, columns, [k for g in groups for k in g.key])


def table(reports: Sequence[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    """Header and rows: per report, one row for all tasks, then one per group. Reports of
    several run directories (same environment) share one table, labelled by their setting."""
    t = _table(reports)
    return t.header, t.rows


def table_key(reports: Sequence[dict[str, Any]]) -> str:
    """What the table's columns are, in one line (shown under every rendering of it)."""
    partial = any(r.get("partial") for r in reports)
    return " · ".join([*_table(reports).keys, "n: tasks x runs (and the episodes done, where not all are)",
                       "values: mean±std over runs; counts per run"]
                      + (["partial: over the finished episodes only"] if partial else []))


def _as_list(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    return [reports] if isinstance(reports, dict) else list(reports)


def render_text(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    reports = _as_list(reports)
    t = _table(reports)
    lines = []
    for report in reports:
        done = sum(r["tasks"] - r["unfinished"] for r in report["overall"]["per_run"])
        total = report["overall"]["tasks"] * report["runs"]
        lines.append(f"{report['title']} · {setting(report)} · {report['runs']} run(s), seed {report['seed']} · "
                     f"episodes complete {done}/{total} · {paper_setting(report)}")
    note = mixed_task_sets(reports)
    if note:
        lines.append(f"note: {note}")
    for report in reports:
        done, total = episodes_done(report)
        if done < total and not report.get("partial"):
            lines.append(f"note: {setting(report)}: partial, {done} of {total} episodes finished; the unfinished count "
                         "as unsolved (their success figures can only rise)")
    for columns in t.blocks(TEXT_WIDTH):
        header, rows = t.block(columns)
        widths = [max(len(header[i]), *(len(r[i]) for r in rows)) for i in range(len(header))]
        left = [not all(_is_figure(r[i]) for r in rows) for i in range(len(header))]  # words: left-aligned
        fmt = lambda cells: "  ".join(c.ljust(w) if lj else c.rjust(w)  # noqa: E731
                                      for c, w, lj in zip(cells, widths, left)).rstrip()
        lines += ["", fmt(header), fmt(["-" * w for w in widths]), *(fmt(r) for r in rows)]
    lines += ["", *_wrap(table_key(reports).split(" · "), TEXT_WIDTH)]
    for report in reports:
        wm = report["overall"]["mean"].get("wm")
        if wm is not None:
            c = wm["confusion"]
            lines += [
                f"WM predicted outcomes ({setting(report)}): {_count(wm['stated'], None)} of "
                f"{_count(wm['decisions'], None)} decisions stated one (mean per run); decisions by prediction and result:",
                f"  predicted success: {_count(c['success']['success'], None)} solved, "
                f"{_count(c['success']['failure'], None)} failed",
                f"  predicted failure: {_count(c['failure']['success'], None)} solved, "
                f"{_count(c['failure']['failure'], None)} failed",
            ]
    return "\n".join(lines)


def _wrap(items: list[str], width: int) -> list[str]:
    """Items joined by " · " into lines of at most `width` characters, never breaking one."""
    lines: list[str] = []
    for item in items:
        if lines and len(lines[-1]) + 3 + len(item) <= width:
            lines[-1] += " · " + item
        else:
            lines.append(item)
    return lines


def render_markdown(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    reports = _as_list(reports)
    header, rows = table(reports)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join([*lines, "", table_key(reports)])


def render_csv(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    header, rows = table(_as_list(reports))
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


_LATEX_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
                  "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
                  "<": r"\textless{}", ">": r"\textgreater{}", "|": r"\textbar{}"}


def latex_escape(text: str) -> str:
    """Plain text as LaTeX (default OT1 encoding: <, > and | are not text characters there)."""
    parts = text.split("->")
    escaped = [("".join(_LATEX_SPECIAL.get(c, c) for c in p)).replace("±", r"$\pm$").replace("★", r"$\star$")
               .replace("\u2020", r"$^\dagger$") for p in parts]
    return r"$\to$".join(escaped)


def _latex_cell(text: str) -> str:
    return latex_escape(text).replace("*", r"$\star$")


def _latex_caption(reports: list[dict[str, Any]]) -> str:
    """Environment, setting(s), runs and seed, and the columns' key."""
    runs = "/".join(str(r) for r in dict.fromkeys(r["runs"] for r in reports))
    seeds = "/".join(str(r) for r in dict.fromkeys(r["seed"] for r in reports))
    who = "; ".join(f"{setting(r)} ({paper_setting(r)})" for r in reports)
    return _latex_cell(f"{reports[0]['title']}: {who}; {runs} run(s), seed {seeds}. {table_key(reports)}.")


def render_latex(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    """A `table` float: caption (environment, model, format, runs, the columns' key), then
    the report's table as booktabs `tabular`s, split between column groups where it is
    wide and stacked in one box, scaled down (all by the same factor) to the line width
    if it is still wider. Needs `\\usepackage{booktabs}` and `\\usepackage{graphicx}`
    (LATEX_PREAMBLE)."""
    reports = _as_list(reports)
    t = _table(reports)
    label = re.sub(r"[^a-z0-9]+", "-", " ".join([reports[0]["env"], *(setting(r) for r in reports)]).lower())
    lines = [
        f"% deepphy report --latex; preamble: {LATEX_PREAMBLE}",
        r"\begin{table}[htbp]",
        r"\centering",
        r"\caption{" + _latex_caption(reports) + "}",
        r"\label{tab:deepphy-" + label.strip("-") + "}",
        r"\resizebox{\ifdim\width>\linewidth\linewidth\else\width\fi}{!}{%",
        r"\begin{tabular}{@{}l@{}}",
    ]
    for n, columns in enumerate(t.blocks(LATEX_WIDTH)):
        header, rows = t.block(columns)
        numeric = [all(_is_figure(r[i]) for r in rows) for i in range(len(header))]
        lines += [
            *([r"\\ \noalign{\vskip 2ex}"] if n else []),  # \\[2ex] would not add to a row this deep
            r"\begin{tabular}{" + "".join("r" if x else "l" for x in numeric) + "}",
            r"\toprule",
            " & ".join(_latex_cell(h) for h in header) + r" \\",
            r"\midrule",
            *(" & ".join(_latex_cell(c) for c in r) + r" \\" for r in rows),
            r"\bottomrule",
            r"\end{tabular}",
        ]
    lines += [r"\end{tabular}}", r"\end{table}"]
    return "\n".join(lines)


def _is_figure(cell: str) -> bool:
    return cell in ("", "-") or cell.replace("±", "").replace(".", "").replace("-", "").isdigit()


def render_json(reports: dict[str, Any] | Sequence[dict[str, Any]]) -> str:
    """One report as an object; several as a list."""
    return json.dumps(reports if isinstance(reports, dict) or len(reports) > 1 else reports[0], indent=2)
