"""The master table across run directories (`deepphy leaderboard`): a row per model x
prompt format, a column group per environment setting (the environment and its options,
so Kinetix with and without annotation are two groups) holding that environment's headline
figures, mean±std over runs, the best of each column marked.

Every figure is read from the reports `deepphy report` prints (`report_of`); which figures
are headlines follows the environment's `ReportSpec`: success within K attempts (within
the game for the one-attempt environments), AUCCESS where the spec has it, success per
task group where `leaderboard_groups` is set, stars where the spec has them. A run with
unfinished episodes is shown as unfinished (episodes done/total), never averaged in.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Collection, Sequence

from deepphy.envs import get_spec, specs
from deepphy.metrics.registry import BoardColumn, by_place, count_cell, percent_cell
from deepphy.metrics.report import (
    LATEX_PREAMBLE, LATEX_WIDTH, Report, build_report, latex_escape, mixed_task_sets, paper_setting,
)
from deepphy.plan import plan
from deepphy.runs.manifest import has_manifest, read_manifest

BEST = "*"  # after the best value of a column (text, Markdown, CSV); LaTeX sets it in bold
UNRANKED = "\u2020"  # after a value left out of its column's ranking (other tasks, runs or attempts)


class LeaderboardError(ValueError):
    """Run directories that do not make one table. The message is for the user."""


@dataclass
class Cell:
    mean: float | None = None
    std: float | None = None
    text: str = "-"  # "-": no run of this setting
    best: bool = False
    unfinished: str | None = None  # "done/total" episodes, when the run is not complete
    run_dir: str | None = None
    n: str | None = None  # the row's tasks x runs ("40x3")
    unranked: bool = False  # left out of the column's ranking: other tasks, runs or attempts than those ranked


@dataclass
class Group:
    """The columns of one environment setting."""

    env: str
    options: dict[str, Any]
    title: str
    columns: list[BoardColumn] = field(default_factory=list)
    reports: list[Report] = field(default_factory=list)


@dataclass
class Leaderboard:
    groups: list[Group]
    rows: list[tuple[str, str]]  # (model, format); a user's agent's model: `row_model`
    cells: dict[tuple[int, int], list[Cell]]  # (row, group) -> a cell per column
    notes: list[str]
    agents: dict[str, dict[str, Any]] = field(default_factory=dict)  # row model -> its user's agent (AgentSpec)

    def row_label(self, i: int) -> str:
        model, fmt = self.rows[i]
        return f"{model} {fmt.upper()}"

    def row_cells(self, i: int) -> list[Cell]:
        return [c for g in range(len(self.groups)) for c in self.cells.get((i, g), _missing(self.groups[g]))]

    def keys(self) -> list[str]:
        return list(dict.fromkeys(c.key for g in self.groups for c in g.columns))


def row_model(report: Report) -> str:
    """A row's model: the run's, and for a user's agent (named by its entry point and
    arguments) its package and version too: two versions of an agent are two rows."""
    if report.agent is None:
        return report.model
    return f"{report.model} ({report.agent.label})"


def _missing(group: Group) -> list[Cell]:
    return [Cell() for _ in group.columns]


N_COLUMN = BoardColumn("n", "n: tasks x runs of the row's run (rows of other n are not ranked against each other)",
                       None, percent=False, ranked=False, text=lambda r: r.sample_size())


def comparability(report: Report) -> tuple[str, int, int]:
    """What two rows of one environment setting must share to be ranked against each other:
    the task set, the runs and the attempts per task."""
    return report.task_set, report.runs, report.max_attempts


def headline_columns(reports: Sequence[Report]) -> list[BoardColumn]:
    """An environment setting's headline figures (each metric's, in their places), after its n."""
    return [N_COLUMN, *(c for m in by_place() if m.headline is not None for c in m.headline(reports))]


def _setting_title(env: str, options: dict[str, Any]) -> str:
    title = get_spec(env).title
    return title + "".join(f" {k}={v}" for k, v in sorted(options.items()))


def leaderboard(reports: Sequence[Report], run_dirs: Sequence[str | Path] | None = None) -> Leaderboard:
    """The table of these reports (`run_dirs[i]` made `reports[i]`). Two reports of one row
    and one environment setting are an error: the table would have to pick one. A column's
    best is marked among rows of one task set, runs and attempts (`comparability`): those of
    the most rows; the others are marked unranked, and a note names them."""
    run_dirs = [str(d) for d in run_dirs] if run_dirs is not None else [None] * len(reports)
    groups: dict[tuple[str, str], Group] = {}
    rows: dict[tuple[str, str], int] = {}
    placed: dict[tuple[int, int], tuple[Report, str | None]] = {}
    agents: dict[str, dict[str, Any]] = {}
    for report, run_dir in zip(reports, run_dirs):
        options = report.options
        gkey = (report.env, json.dumps(options, sort_keys=True))
        if gkey not in groups:
            groups[gkey] = Group(report.env, options, _setting_title(report.env, options))
        group = groups[gkey]
        g = list(groups).index(gkey)
        r = rows.setdefault((row_model(report), report.format), len(rows))
        if report.agent is not None:
            agents[row_model(report)] = report.agent.model_dump(mode="json")
        if (r, g) in placed:
            raise LeaderboardError(f"two runs of {row_model(report)} {report.format.upper()} on {group.title}: "
                                   f"{placed[(r, g)][1]} and {run_dir}; give one of them")
        placed[(r, g)] = (report, run_dir)
        group.reports.append(report)
    for group in groups.values():
        group.columns = headline_columns(group.reports)
    cells: dict[tuple[int, int], list[Cell]] = {}
    for (r, g), (report, run_dir) in placed.items():
        columns = list(groups.values())[g].columns
        done, total = report.episodes_done()
        n = report.sample_size()
        if done < total:
            cells[(r, g)] = [Cell(text=n if c.text else f"unfinished {done}/{total}" if i == 1 else "",
                                  unfinished=f"{done}/{total}", run_dir=run_dir, n=n) for i, c in enumerate(columns)]
            continue
        cells[(r, g)] = []
        for column in columns:
            if column.text is not None:
                cells[(r, g)].append(Cell(text=column.text(report), run_dir=run_dir, n=n))
                continue
            m, s = column.figure(report)
            text = percent_cell(m, s) if column.percent else count_cell(m, s)
            cells[(r, g)].append(Cell(m, s, text, run_dir=run_dir, n=n))
    notes = []
    for g, group in enumerate(groups.values()):  # the best finished value of each column, among comparable rows
        in_group = {r: placed[(r, g)][0] for r in range(len(rows)) if (r, g) in placed}
        unranked: set[int] = set()
        for c, column in enumerate(group.columns):
            if not column.ranked:
                continue
            scored = [(r, cells[(r, g)][c]) for r in in_group
                      if cells[(r, g)][c].unfinished is None and cells[(r, g)][c].mean is not None]
            classes: dict[tuple, list[tuple[int, Cell]]] = {}
            for r, cell in scored:
                classes.setdefault(comparability(in_group[r]), []).append((r, cell))
            if not classes:
                continue
            # the class of the most rows (on a tie, the most tasks x runs) is ranked
            size = lambda k: in_group[classes[k][0][0]].overall.tasks * k[1]  # noqa: E731 - tasks x runs
            ranked_key = max(classes, key=lambda k: (len(classes[k]), size(k)))
            ranked = classes[ranked_key]
            for key, members in classes.items():
                if key != ranked_key:
                    for r, cell in members:
                        cell.unranked = True
                        unranked.add(r)
            if len({cell.mean for _, cell in ranked}) > 1:  # all equal: nothing is best
                top = max(cell.mean for _, cell in ranked)
                for _, cell in ranked:
                    cell.best = cell.mean == top
        if unranked:
            names = ", ".join(f"{m} {f.upper()} (n={in_group[r].sample_size()})"
                              for (m, f), r in rows.items() if r in unranked)
            notes.append(f"{group.title}: not ranked against the other rows (other tasks, runs or attempts): {names}")
    notes += [f"{group.title}: {note}" for group in groups.values() if (note := mixed_task_sets(group.reports))]
    notes += [f"{group.title}: {group.reports[0].paper_setting}" for group in groups.values()
              if group.reports[0].paper_setting != paper_setting([])]
    # columns in the registry's order of environments, the default options first; rows as given
    envs, keys = list(specs()), list(groups)
    by_column = sorted(range(len(groups)), key=lambda g: (envs.index(keys[g][0]), keys[g][1] != "{}", keys[g][1]))
    cells = {(r, by_column.index(g)): c for (r, g), c in cells.items()}
    return Leaderboard([list(groups.values())[g] for g in by_column], sorted(rows, key=rows.get), cells, notes, agents)


def not_started(root: Path, started: Collection[Path],
                known: dict[str, Report] | None = None) -> dict[Path, Report]:
    """The cells a suite manifest in `root` lists whose run directory is not among `started`
    (resolved paths), each as the report of a run with no record yet: on the board they are
    `unfinished 0/t`. {} where `root` holds no manifest; RunDirError for a bad one. `known`:
    such reports by their config's JSON, reused and added to (a live view asks every second)."""
    if not has_manifest(root):
        return {}
    known = {} if known is None else known
    out = {}
    for cell in read_manifest(root):
        path = (root / cell.dir).resolve()
        if path in started:
            continue
        key = cell.config.model_dump_json()
        if key not in known:
            the_plan = plan(cell.config)
            known[key] = build_report(cell.config, the_plan.tasks, [], the_plan.k_max)
        out[path] = known[key]
    return out


# -- rendering --------------------------------------------------------------------------


def _marked(cell: Cell) -> str:
    return cell.text + (BEST if cell.best else UNRANKED if cell.unranked else "")


def _flat_header(board: Leaderboard) -> list[str]:
    return ["setting"] + [f"{g.title} {c.header}" for g in board.groups for c in g.columns]


def _key_line(board: Leaderboard) -> str:
    return " · ".join([*board.keys(), f"{BEST}: best of the column among rows of one n",
                       f"{UNRANKED}: not ranked (other tasks, runs or attempts than the rows ranked)",
                       "values: mean±std over runs",
                       "unfinished d/t: episodes complete, not averaged in",
                       "settings: the paper's set-up unless a note says how one departs from it"])


def render_text(board: Leaderboard) -> str:
    top = [""] + [g.title if i == 0 else "" for g in board.groups for i in range(len(g.columns))]
    header = ["setting"] + [c.header for g in board.groups for c in g.columns]
    rows = [[board.row_label(i)] + [_marked(c) for c in board.row_cells(i)] for i in range(len(board.rows))]
    # a group's title may be wider than its columns: widen its first column
    widths = [max(len(header[j]), *(len(r[j]) for r in rows)) for j in range(len(header))]
    j = 1
    for g in board.groups:
        span = sum(widths[j:j + len(g.columns)]) + 2 * (len(g.columns) - 1)
        if len(g.title) > span:
            widths[j + len(g.columns) - 1] += len(g.title) - span
        j += len(g.columns)
    fmt = lambda cells, just: "  ".join(  # noqa: E731
        (c.ljust(w) if k == 0 or just == "l" else c.rjust(w)) for k, (c, w) in enumerate(zip(cells, widths))).rstrip()
    lines = [fmt(top, "l"), fmt(header, "r"), fmt(["-" * w for w in widths], "r"), *(fmt(r, "r") for r in rows)]
    lines += ["", _key_line(board), *(f"note: {n}" for n in board.notes)]
    return "\n".join(lines)


def render_markdown(board: Leaderboard) -> str:
    header = _flat_header(board)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(["---"] + ["--:"] * (len(header) - 1)) + "|"]
    for i in range(len(board.rows)):
        cells = [f"**{c.text}**" if c.best else _marked(c) for c in board.row_cells(i)]
        lines.append("| " + " | ".join([board.row_label(i), *cells]) + " |")
    return "\n".join([*lines, "", _key_line(board).replace(f"{BEST}: best", "bold: best"),
                      *(f"note: {n}" for n in board.notes)])


def render_csv(board: Leaderboard) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(_flat_header(board))
    for i in range(len(board.rows)):
        w.writerow([board.row_label(i), *(_marked(c) for c in board.row_cells(i))])
    return buf.getvalue()


def as_dict(board: Leaderboard) -> dict[str, Any]:
    """The board as plain data (`--json`, the dashboard's leaderboard view)."""
    return {
        "columns": [{"env": g.env, "env_options": g.options, "title": g.title, "header": c.header, "key": c.key,
                     "ranked": c.ranked} for g in board.groups for c in g.columns],
        "rows": [{"model": model, "format": fmt, **({"agent": board.agents[model]} if model in board.agents else {}),
                  "cells": [{"mean": c.mean, "std": c.std, "text": c.text, "best": c.best, "unranked": c.unranked,
                             "unfinished": c.unfinished, "run_dir": c.run_dir, "n": c.n} for c in board.row_cells(i)]}
                 for i, (model, fmt) in enumerate(board.rows)],
        "notes": board.notes,
        "key": _key_line(board),
    }


def render_json(board: Leaderboard) -> str:
    return json.dumps(as_dict(board), indent=2)


def _latex_blocks(board: Leaderboard, width: int = LATEX_WIDTH) -> list[list[int]]:
    """The groups (by index) of each block of a wide table: as many as fit in `width`
    characters of plain text beside the row labels; a group wider than that is a block alone."""
    label = max(len(board.row_label(i)) for i in range(len(board.rows))) + 2 if board.rows else 8
    blocks: list[list[int]] = []
    used = width
    for g, group in enumerate(board.groups):
        cells = [board.cells[(r, g)] for r in range(len(board.rows)) if (r, g) in board.cells]
        w = max(len(group.title),
                sum(2 + max([len(c.header)] + [len(_marked(row[k])) for row in cells]) for k, c in enumerate(group.columns)))
        if blocks and used + w <= width:
            blocks[-1].append(g)
            used += w
        else:
            blocks.append([g])
            used = label + w
    return blocks


def render_latex(board: Leaderboard) -> str:
    """A `table*` float: a column group per environment setting, best values in bold,
    unranked ones with a dagger; wide tables split between groups into blocks stacked in
    one box (each repeating the row labels), scaled down to the line width only if still
    wider. Needs `\\usepackage{booktabs}` and `\\usepackage{graphicx}` (LATEX_PREAMBLE)."""
    lines = [
        f"% deepphy leaderboard --latex; preamble: {LATEX_PREAMBLE}",
        r"\begin{table*}[htbp]",
        r"\centering",
        r"\caption{" + latex_escape(" · ".join([_key_line(board).replace(f"{BEST}: best", "bold: best"),
                                                *(f"note: {n}" for n in board.notes)])) + "}",
        r"\label{tab:deepphy-leaderboard}",
        r"\resizebox{\ifdim\width>\linewidth\linewidth\else\width\fi}{!}{%",
        r"\begin{tabular}{@{}l@{}}",
    ]
    for b, groups in enumerate(_latex_blocks(board)):
        n = sum(len(board.groups[g].columns) for g in groups)
        top, rules, j = ["Setting"], [], 2
        for g in groups:
            group = board.groups[g]
            top.append(r"\multicolumn{%d}{c}{%s}" % (len(group.columns), latex_escape(group.title)))
            rules.append(r"\cmidrule(lr){%d-%d}" % (j, j + len(group.columns) - 1))
            j += len(group.columns)
        header = [""] + [latex_escape(c.header) for g in groups for c in board.groups[g].columns]
        body = []
        for i in range(len(board.rows)):
            cells = [(r"\textbf{%s}" if c.best else r"%s$^\dagger$" if c.unranked else "%s") % latex_escape(c.text)
                     for g in groups for c in board.cells.get((i, g), _missing(board.groups[g]))]
            body.append(" & ".join([latex_escape(board.row_label(i)), *cells]) + r" \\")
        lines += [
            *([r"\\ \noalign{\vskip 2ex}"] if b else []),
            r"\begin{tabular}{l" + "r" * n + "}",
            r"\toprule",
            " & ".join(top) + r" \\",
            "".join(rules),
            " & ".join(header) + r" \\",
            r"\midrule",
            *body,
            r"\bottomrule",
            r"\end{tabular}",
        ]
    return "\n".join([*lines, r"\end{tabular}}", r"\end{table*}"])
