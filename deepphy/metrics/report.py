"""The paper-style report of a run directory: figures per run, mean and std over runs,
overall and per task group, as typed models (`Report`, `Section`, a run's figures) and
rendered as text, JSON, CSV, Markdown or LaTeX.

Which figures a report holds, and how its table shows them, is the metric registry's
(deepphy.metrics.registry): the models below get a field per registered metric.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import re
from collections import defaultdict
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any, Optional, Sequence

from pydantic import BaseModel, ConfigDict, create_model

from deepphy.config import AgentSpec, RunConfig
from deepphy.envs import EnvSpec, Task, get_spec
from deepphy.metrics import figures as F
from deepphy.metrics import registry as R
from deepphy.metrics.registry import Given, TableColumns, count_cell
from deepphy.plan import plan
from deepphy.runs.records import AttemptRecord
from deepphy.runs.store import check_records, read_config, read_records

TEXT_WIDTH = 120  # characters: a wider text table is split into blocks of column groups
LATEX_WIDTH = 80  # characters of plain cell text per LaTeX block (~ an article's \linewidth at 10 pt)
LATEX_PREAMBLE = r"\usepackage{booktabs}\usepackage{graphicx}"


# -- the typed report -------------------------------------------------------------------
# Each model's fields in the order of the report's JSON; the metrics' fields are added to
# them by `models()`, in the registry's order, so only the figures a report holds are set
# (and written: `Report.to_json`).


class Figures(BaseModel):
    """The figures of one run, or their mean or std over runs (a field per run metric)."""

    model_config = ConfigDict(extra="forbid")


class RunFigures(BaseModel):
    """One run's figures (a field per run metric, after `run`)."""

    model_config = ConfigDict(extra="forbid")

    run: int


class Section(BaseModel):
    """The figures of the report's tasks, or of one task group (then a field per section metric)."""

    model_config = ConfigDict(extra="forbid")

    tasks: int
    finished: int  # episodes
    per_run: list[RunFigures]
    mean: Figures
    std: Figures

    @property
    def episodes_total(self) -> int:
        return self.tasks * len(self.per_run)


class Report(BaseModel):
    """One run directory's report (then a field per report metric, and the task groups')."""

    model_config = ConfigDict(extra="forbid")

    env: str
    title: str
    model: str
    format: str
    runs: int
    seed: int
    max_attempts: int
    max_steps: int
    step_noun: str
    group_noun: str
    env_options: dict[str, Any]
    prompts: str
    departures: list[str]  # how the set-up departs from the paper's; empty: the paper's
    task_set: str
    overall: Section
    agent: Optional[AgentSpec] = None  # a user's agent: its entry point, arguments and package version
    partial: bool = False  # the figures are over the finished episodes alone (a live view's estimate)

    @property
    def spec(self) -> EnvSpec:
        return get_spec(self.env)

    @property
    def sections(self) -> list[tuple[str, Section]]:
        """("all", overall), then each task group's, in the environment's order."""
        return [("all", self.overall), *(getattr(self, "groups", None) or {}).items()]

    @property
    def setting(self) -> str:
        """What distinguishes one run directory's rows from another's in a combined table."""
        return setting_label(self.model, self.format, self.env_options, self.prompts)

    @property
    def options(self) -> dict[str, Any]:
        """The environment options and, where they are not the paper's, the prompts: what makes
        an environment setting (reports of one setting compare; others are never mixed)."""
        return setting_options(self.env_options, self.prompts)

    @property
    def paper_setting(self) -> str:
        """The report's set-up in words: the paper's, or how it departs from it."""
        return paper_setting(self.departures)

    def episodes_done(self, section: Section | None = None) -> tuple[int, int]:
        """(finished episodes, all episodes: tasks x runs) of a section (overall by default)."""
        sec = self.overall if section is None else section
        return sec.finished, sec.tasks * self.runs

    def sample_size(self, section: Section | None = None) -> str:
        """n of a row: tasks x runs, and the episodes finished where not all are ("40x3", "40x3 (31 done)")."""
        sec = self.overall if section is None else section
        done, total = self.episodes_done(sec)
        return f"{sec.tasks}x{self.runs}" + ("" if done == total else f" ({done} done)")

    def to_json(self) -> dict[str, Any]:
        """The report as `deepphy report --json` writes it: the figures it holds, nothing unset."""
        return self.model_dump(exclude_unset=True)


_models: dict[int, SimpleNamespace] = {}


def models() -> SimpleNamespace:
    """The report's models with a field per registered metric (Figures, RunFigures, Section,
    Report): made again when the registry changes."""
    version = R.version()
    if version not in _models:
        def fields(scope: R.Scope) -> dict[str, Any]:
            return {m.key: (Optional[m.type], None) for m in R.metrics(scope)}

        figures = create_model("Figures", __base__=Figures, **fields("run"))
        run_figures = create_model("RunFigures", __base__=RunFigures, **fields("run"))
        section = create_model("Section", __base__=Section, per_run=(list[run_figures], ...), mean=(figures, ...),
                               std=(figures, ...), **fields("section"))
        report = create_model("Report", __base__=Report, overall=(section, ...), **fields("report"),
                              groups=(Optional[dict[str, section]], None))
        _models.clear()
        _models[version] = SimpleNamespace(Figures=figures, RunFigures=run_figures, Section=section, Report=report)
    return _models[version]


# -- building it ------------------------------------------------------------------------


def _computed(scope: R.Scope, given: Given) -> dict[str, Any]:
    """The figures of every metric of `scope` that applies, by key, in the registry's order."""
    return {m.key: m.compute(given) for m in R.metrics(scope) if m.applies(given)}


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


def _section(config: RunConfig, spec: EnvSpec, eps: list[F.Episode], tasks: Sequence[Task], k_max: int,
             records: list[AttemptRecord], finished_only: bool = False) -> dict[str, Any]:
    """Figures per run, then mean and std, then the figures across runs. `records`: the
    section's records (of finished episodes alone when `finished_only`). `finished_only`:
    every figure over the finished episodes alone (a run in progress: its unfinished
    episodes are left out, not counted as unsolved); Pass@k over the tasks whose runs have
    all finished."""
    runs = config.runs
    by_run: dict[int, list[F.Episode]] = defaultdict(list)
    for e in eps:
        by_run[e.run].append(e)
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
    per_run = []
    for r in range(runs):
        run_eps = by_run.get(r, [])
        given = Given(config, spec, k_max, len(run_eps) if finished_only else len(tasks), run_eps, records, run=r)
        per_run.append({"run": r, **_computed("run", given)})
    mean, std = _mean_std(per_run)
    across = _computed("section", Given(config, spec, k_max, pass_n, pass_eps, records))
    return {"tasks": len(tasks), "finished": finished, "per_run": per_run, "mean": mean, "std": std, **across}


def task_set_digest(tasks: Sequence[Task]) -> str:
    """Equal for two runs exactly when they evaluate the same tasks (in any order)."""
    return hashlib.sha256("\n".join(sorted(t.id for t in tasks)).encode()).hexdigest()[:16]


def departures(config: RunConfig) -> list[str]:
    """How a run's set-up departs from the paper's (docs/comparability.md): its prompts and
    the environment options set otherwise than the paper did. Empty: the paper's set-up."""
    cls = get_spec(config.env).load()
    out = [] if config.prompts == "paper" else [f"prompts={config.prompts}"]
    return out + cls.Options.departures_from_paper(config.env_options)


def build_report(config: RunConfig, tasks: Sequence[Task], records: Sequence[AttemptRecord], k_max: int,
                 finished_only: bool = False) -> Report:
    """The report of a run's records. `finished_only`: the figures over finished episodes
    alone (a live view's partial estimate; `partial` in the report says so)."""
    spec = get_spec(config.env)
    wanted = {t.id for t in tasks}
    records = [r for r in records if r.task in wanted and r.run < config.runs]
    eps = [e for e in F.episodes(records, k_max) if e.task in wanted and e.run < config.runs]
    shown = records
    if finished_only:  # the figures' records: those of finished episodes
        done = {(e.task, e.run) for e in eps if e.finished}
        shown = [r for r in records if (r.task, r.run) in done]
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
        "overall": _section(config, spec, eps, tasks, k_max, shown, finished_only),
    }
    if config.agent is not None:
        report["agent"] = config.agent
    if finished_only:
        report["partial"] = True
    report.update(_computed("report", Given(config, spec, k_max, len(tasks), eps, records)))
    groups = list(dict.fromkeys(t.group for t in tasks if t.group))  # in the environment's order (S, M, L)
    if len(groups) > 1:
        report["groups"] = {
            g: _section(config, spec, [e for e in eps if e.group == g], [t for t in tasks if t.group == g], k_max,
                        [r for r in shown if r.task in {t.id for t in tasks if t.group == g}], finished_only)
            for g in groups
        }
    return models().Report.model_validate(report)


def report_of(run_dir) -> Report:
    """The report of one run directory, as `deepphy report --json` prints it."""
    the_plan = plan(read_config(run_dir))
    records = read_records(run_dir)
    check_records(run_dir, records, the_plan.k_max, frames=False)  # a duplicated or missing attempt would skew every figure
    return build_report(the_plan.config, the_plan.tasks, records, the_plan.k_max)


def mixed_task_sets(reports: Sequence[Report]) -> str | None:
    """A warning when reports to be compared evaluate different task sets, else None."""
    if len({r.task_set for r in reports}) < 2:
        return None
    sizes = {r.overall.tasks for r in reports}
    which = (f"n={sizes.pop()} each, other tasks" if len(sizes) == 1
             else ", ".join(f"{r.setting}: n={r.overall.tasks}" for r in reports))
    return f"these runs evaluate different task sets ({which}): their rows are not comparable"


def setting_label(model: str, format: str, env_options: dict[str, Any], prompts: str) -> str:
    """A run's setting in a combined table's rows: its model, format and options."""
    options = ",".join(f"{k}={v}" for k, v in sorted(setting_options(env_options, prompts).items()))
    return f"{model} {format.upper()}" + (f" {options}" if options else "")


def setting_options(env_options: dict[str, Any], prompts: str) -> dict[str, Any]:
    """The environment options and, where they are not the paper's, the prompts."""
    return {**env_options, **({} if prompts == "paper" else {"prompts": prompts})}


def paper_setting(departures: list[str]) -> str:
    """A set-up in words: the paper's, or how it departs from it."""
    return "the paper's set-up" if not departures else f"departs from the paper: {', '.join(departures)}"


# -- rendering --------------------------------------------------------------------------


def column_groups(reports: Sequence[Report]) -> list[TableColumns]:
    """The table's column groups for these reports: each metric's, in their places."""
    return [group for m in R.by_place() if m.table is not None and (group := m.table(reports)) is not None]


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


def _table(reports: Sequence[Report]) -> _Table:
    groups = column_groups(reports)
    combined = len(reports) > 1
    header = (["setting"] if combined else []) + ["group", "n"]
    labels = len(header)
    columns = []
    for g in groups:
        columns.append(list(range(len(header), len(header) + len(g.headers))))
        header += g.headers
    rows = []
    for report in reports:
        for name, sec in report.sections:
            rows.append(([report.setting] if combined else []) + [name, report.sample_size(sec)]
                        + [c for g in groups for c in g.cells(report, sec)])
    return _Table(header, rows, labels, columns, [k for g in groups for k in g.key])


def table(reports: Sequence[Report]) -> tuple[list[str], list[list[str]]]:
    """Header and rows: per report, one row for all tasks, then one per group. Reports of
    several run directories (same environment) share one table, labelled by their setting."""
    t = _table(reports)
    return t.header, t.rows


def table_key(reports: Sequence[Report]) -> str:
    """What the table's columns are, in one line (shown under every rendering of it)."""
    partial = any(r.partial for r in reports)
    return " · ".join([*_table(reports).keys, "n: tasks x runs (and the episodes done, where not all are)",
                       "values: mean±std over runs; counts per run"]
                      + (["partial: over the finished episodes only"] if partial else []))


def _as_list(reports: Report | Sequence[Report]) -> list[Report]:
    return [reports] if isinstance(reports, Report) else list(reports)


def render_text(reports: Report | Sequence[Report]) -> str:
    reports = _as_list(reports)
    t = _table(reports)
    lines = []
    for report in reports:
        done = sum(r.tasks - r.unfinished for r in report.overall.per_run)
        total = report.overall.tasks * report.runs
        lines.append(f"{report.title} · {report.setting} · {report.runs} run(s), seed {report.seed} · "
                     f"episodes complete {done}/{total} · {report.paper_setting}")
    note = mixed_task_sets(reports)
    if note:
        lines.append(f"note: {note}")
    for report in reports:
        done, total = report.episodes_done()
        if done < total and not report.partial:
            lines.append(f"note: {report.setting}: partial, {done} of {total} episodes finished; the unfinished count "
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
        wm = report.overall.mean.wm
        if wm is not None:
            c = wm.confusion
            lines += [
                f"WM predicted outcomes ({report.setting}): {count_cell(wm.stated, None)} of "
                f"{count_cell(wm.decisions, None)} decisions stated one (mean per run); decisions by prediction and "
                "result:",
                f"  predicted success: {count_cell(c['success']['success'], None)} solved, "
                f"{count_cell(c['success']['failure'], None)} failed",
                f"  predicted failure: {count_cell(c['failure']['success'], None)} solved, "
                f"{count_cell(c['failure']['failure'], None)} failed",
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


def render_markdown(reports: Report | Sequence[Report]) -> str:
    reports = _as_list(reports)
    header, rows = table(reports)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join([*lines, "", table_key(reports)])


def render_csv(reports: Report | Sequence[Report]) -> str:
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


def _latex_caption(reports: list[Report]) -> str:
    """Environment, setting(s), runs and seed, and the columns' key."""
    runs = "/".join(str(r) for r in dict.fromkeys(r.runs for r in reports))
    seeds = "/".join(str(r) for r in dict.fromkeys(r.seed for r in reports))
    who = "; ".join(f"{r.setting} ({r.paper_setting})" for r in reports)
    return _latex_cell(f"{reports[0].title}: {who}; {runs} run(s), seed {seeds}. {table_key(reports)}.")


def render_latex(reports: Report | Sequence[Report]) -> str:
    """A `table` float: caption (environment, model, format, runs, the columns' key), then
    the report's table as booktabs `tabular`s, split between column groups where it is
    wide and stacked in one box, scaled down (all by the same factor) to the line width
    if it is still wider. Needs `\\usepackage{booktabs}` and `\\usepackage{graphicx}`
    (LATEX_PREAMBLE)."""
    reports = _as_list(reports)
    t = _table(reports)
    label = re.sub(r"[^a-z0-9]+", "-", " ".join([reports[0].env, *(r.setting for r in reports)]).lower())
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


def render_json(reports: Report | Sequence[Report]) -> str:
    """One report as an object; several as a list."""
    reports = _as_list(reports)
    return json.dumps(reports[0].to_json() if len(reports) == 1 else [r.to_json() for r in reports], indent=2)
