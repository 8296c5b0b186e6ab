"""The report's metrics, declared once.

A `Metric` says what one figure of the report is: its key and type, how it is computed
(from the episodes of one run, of a section's runs together, or of the whole run
directory), which runs have it, where its columns stand, and how the report's table
(text, Markdown, CSV, LaTeX) and the leaderboard show it. The report (`build_report`), its
renderers, the leaderboard and the dashboard read this registry; none names a metric of
its own. A new metric is one declaration plus its computation:

    register_metric(Metric("median_attempts", Number | None, lambda given: ..., table=...))

Its key becomes a field of the report's typed models (deepphy.metrics.report), its value
in `deepphy report --json`, its columns in the tables. The built-in metrics below are in
the order their keys appear in a report's JSON; `place` orders their columns.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any, Callable, Literal, Optional, Sequence, Union

from pydantic import BaseModel, ConfigDict

from deepphy.config import RunConfig, is_human
from deepphy.envs import EnvSpec
from deepphy.metrics import figures as F
from deepphy.runs.records import AttemptRecord, episode_finished

if TYPE_CHECKING:  # the annotations' models; at run time the report imports this registry, not the reverse
    from deepphy.metrics.report import Report, Section

# A figure's number: an int stays an int (a count), a float a float (a rate, or a mean over
# runs), so the report's JSON writes each as it was computed.
Number = Union[int, float]
Scope = Literal["run", "section", "report"]


@dataclass(frozen=True)
class Given:
    """What a metric is computed from. Scope "run": one run's episodes of a section (all
    tasks, or one task group); "section": the section's episodes of every run; "report":
    the run directory's episodes and records."""

    config: RunConfig
    spec: EnvSpec
    k_max: int
    tasks: int  # the tasks the figure is over (in a partial report: those finished)
    episodes: Sequence[F.Episode]
    section_records: Sequence[AttemptRecord]  # the records of the section (every run)
    run: int | None = None  # scope "run": which

    @cached_property
    def records(self) -> list[AttemptRecord]:
        """The records of these episodes (scope "run": of this run alone)."""
        return [r for r in self.section_records if self.run is None or r.run == self.run]


@dataclass(frozen=True)
class TableColumns:
    """A group of columns of the report's table that belong together (a split table breaks
    only between groups)."""

    headers: list[str]
    key: list[str]  # what the columns are, for the key under the table
    cells: Callable[["Report", "Section"], list[str]]  # a row's cells: one report's section


@dataclass(frozen=True)
class BoardColumn:
    """A column of the leaderboard."""

    header: str
    key: str  # what the column is, for the key under the table
    figure: Callable[["Report"], tuple[float | None, float | None]] | None  # report -> (mean, std)
    percent: bool = True  # else a count
    ranked: bool = True  # its best value is marked (a score; not n, not a person's time)
    text: Callable[["Report"], str] | None = None  # a column of words (n), not of figures


@dataclass(frozen=True)
class Metric:
    key: str  # its key in the report (a field of the typed report)
    type: Any  # its value's type: a run's, and its mean's and std's over runs
    compute: Callable[[Given], Any]
    scope: Scope = "run"  # per run (then averaged over runs), across a section's runs, or per run directory
    applies: Callable[[Given], bool] = lambda given: True  # whether a report of this set-up has it
    place: float = 100.0  # where its columns stand in the report's table and on the leaderboard
    table: Callable[[Sequence["Report"]], TableColumns | None] | None = None  # its columns in the report's table
    headline: Callable[[Sequence["Report"]], list[BoardColumn]] | None = None  # its columns on the leaderboard
    total: bool = False  # a count the progress views sum over runs (the dashboard's totals)


_registry: dict[str, Metric] = {}
_version = [0]  # bumped on every change: the report's models are rebuilt for it


def register_metric(metric: Metric) -> Metric:
    """Add a metric (after the built-in ones). Its key must be new."""
    if metric.key in _registry or metric.key in RESERVED:
        raise ValueError(f"a report already has a figure {metric.key!r}")
    _registry[metric.key] = metric
    _version[0] += 1
    return metric


def unregister_metric(key: str) -> None:
    if _registry.pop(key, None) is not None:
        _version[0] += 1


def metrics(scope: Scope | None = None) -> list[Metric]:
    """The registered metrics (of one scope), in their declaration order."""
    return [m for m in _registry.values() if scope is None or m.scope == scope]


def by_place() -> list[Metric]:
    """The metrics in the order their columns stand."""
    return sorted(_registry.values(), key=lambda m: m.place)


def version() -> int:
    return _version[0]


# A report's own fields, not metrics (deepphy.metrics.report).
RESERVED = {"run", "per_run", "mean", "std", "finished", "overall", "groups", "partial", "agent"}


# -- the cells of tables --------------------------------------------------------------------


def percent_cell(m: float | None, s: float | None) -> str:
    if m is None:
        return "-"
    return f"{100 * m:.1f}" + (f"±{100 * s:.1f}" if s else "")


def number_cell(m: float | None, s: float | None, digits: int = 2) -> str:
    if m is None:
        return "-"
    return f"{m:.{digits}f}" + (f"±{s:.{digits}f}" if s else "")


def count_cell(m: float | None, s: float | None) -> str:
    """A count: an integer, or the mean over runs with one decimal where it is not one."""
    if m is None:
        return "-"
    return (f"{m:.0f}" if float(m).is_integer() else f"{m:.1f}") + (f"±{s:.1f}" if s else "")


# -- the built-in metrics ---------------------------------------------------------------------


class Stars(BaseModel):
    """The games' stars (per run; the mean and std over runs have the same shape)."""

    model_config = ConfigDict(extra="forbid")

    total: Number
    mean_all: Number  # over all tasks (unfinished count 0)
    mean_completed: Optional[Number]  # over solved tasks
    levels_with: dict[str, Number]  # stars ("0".."3") -> solved tasks with exactly that many


class Predictions(BaseModel):
    """WM predicted outcomes against what happened."""

    model_config = ConfigDict(extra="forbid")

    decisions: Number
    stated: Number
    accuracy: Optional[Number]
    predicted_success_failed: Optional[Number]
    confusion: dict[str, dict[str, Number]]  # predicted -> actual -> decisions


class HumanTime(BaseModel):
    """A person's time to decide (`timing.decision_s`: the page's clock from the prompt shown
    to the answer given; simulation not counted)."""

    model_config = ConfigDict(extra="forbid")

    decisions: int
    tasks: int  # finished episodes
    median_decision_s: Optional[Number]
    median_task_s: Optional[Number]  # all the decisions of a finished episode
    total_s: Number


def _solved(g: Given) -> int:
    return sum(e.solved for e in g.episodes)


def _finished(g: Given) -> int:
    return sum(1 for e in g.episodes if e.finished)


def _total(name: str) -> Callable[[Given], Number]:
    return lambda g: F.totals(g.episodes)[name]


def _stars(g: Given) -> dict[str, Any]:
    s = F.stars(g.episodes, g.tasks)
    return {"total": s.total, "mean_all": s.mean_all, "mean_completed": s.mean_completed,
            "levels_with": {str(k): v for k, v in s.levels_with.items()}}


def _predictions(g: Given) -> dict[str, Any]:
    p = F.prediction_scores(g.records)
    return {"decisions": p.decisions, "stated": p.stated, "accuracy": p.accuracy,
            "predicted_success_failed": p.predicted_success_failed, "confusion": p.confusion}


def _human_time(g: Given) -> dict[str, Any]:
    per_decision = [s for r in g.records for s in r.timing.decision_s]
    episodes: dict[tuple[str, int], list[AttemptRecord]] = {}
    for r in g.records:
        episodes.setdefault((r.task, r.run), []).append(r)
    per_task = [sum(s for r in rs for s in r.timing.decision_s) for rs in episodes.values()
                if episode_finished(rs, g.k_max)]
    return {"decisions": len(per_decision), "tasks": len(per_task),
            "median_decision_s": statistics.median(per_decision) if per_decision else None,
            "median_task_s": statistics.median(per_task) if per_task else None,
            "total_s": sum(per_decision)}


def _attempt_columns(reports: Sequence[Report]) -> TableColumns:
    k_max = max(r.max_attempts for r in reports)
    if k_max == 1:
        return TableColumns(["Success"], ["Success: tasks solved (%)"],
                            lambda r, sec: [percent_cell(sec.mean.success_at[0], sec.std.success_at[0])])
    return TableColumns(
        [f"Att.{k}" for k in range(1, k_max + 1)] + ["AvgAtt"],
        ["Att.k: tasks solved within k attempts (%)", "AvgAtt: attempts used by the solved tasks"],
        lambda r, sec: [percent_cell(sec.mean.success_at[i], sec.std.success_at[i]) if i < r.max_attempts else ""
                        for i in range(k_max)] + [number_cell(sec.mean.avg_attempts, sec.std.avg_attempts)])


def _pass_columns(reports: Sequence[Report]) -> TableColumns | None:
    runs, k_max = max(r.runs for r in reports), max(r.max_attempts for r in reports)
    if runs < 2 or k_max < 2:  # beside Att.k, as the paper's tables; one run: Pass@1 is Att.K
        return None
    return TableColumns(
        [f"Pass@{k}" for k in range(1, runs + 1)],
        ["Pass@k: tasks solved within the attempt budget in at least one of k runs (%, the paper's Pass@k)"],
        lambda r, sec: [percent_cell(sec.pass_at[k], None) if k < len(sec.pass_at or []) else "-"
                        for k in range(runs)])


def _step_columns(reports: Sequence[Report]) -> TableColumns | None:
    checkpoints = next((list(r.overall.mean.success_within_steps) for r in reports
                        if r.overall.mean.success_within_steps is not None), None)
    if not checkpoints:
        return None
    noun = reports[0].step_noun
    cap = noun.capitalize()

    def cells(r: Report, sec: Section) -> list[str]:
        within = sec.mean.success_within_steps or {}
        return ([percent_cell(within[c], sec.std.success_within_steps[c]) if c in within else "-"
                 for c in checkpoints] + [number_cell(sec.mean.avg_steps, sec.std.avg_steps)])

    return TableColumns([f"{cap}{k}" for k in checkpoints] + [f"Avg{cap}s"],
                        [f"{cap}k: tasks solved within k {noun}s (%)", f"Avg{cap}s: {noun}s used by the solved tasks"],
                        cells)


def _outcome_columns(reports: Sequence[Report]) -> TableColumns:
    auccess = any(r.overall.mean.auccess is not None for r in reports)
    return TableColumns(
        ["Solved", "Invalid"] + (["AUCCESS"] if auccess else []),
        ["Solved: tasks solved", "Invalid: attempts that ended on an invalid action"]
        + (["AUCCESS: PHYRE's area under the success curve, invalid attempts not counted (%)"] if auccess else []),
        lambda r, sec: [count_cell(sec.mean.solved, sec.std.solved),
                        count_cell(sec.mean.invalid_attempts, sec.std.invalid_attempts)]
        + ([percent_cell(sec.mean.auccess, sec.std.auccess)] if auccess else []))


def _star_columns(reports: Sequence[Report]) -> TableColumns | None:
    if not any(r.overall.mean.stars is not None for r in reports):
        return None
    zero = any(x.stars.levels_with.get("0") for r in reports for x in r.overall.per_run if x.stars is not None)
    counts = (["0"] if zero else []) + ["1", "2", "3"]  # 0-star wins exist

    def cells(r: Report, sec: Section) -> list[str]:
        st, sd = sec.mean.stars, sec.std.stars
        if st is None:
            return ["-"] * (3 + len(counts))
        return ([count_cell(st.total, sd.total), number_cell(st.mean_all, sd.mean_all),
                 number_cell(st.mean_completed, sd.mean_completed)]
                + [count_cell(st.levels_with[c], sd.levels_with[c]) for c in counts])

    return TableColumns(["Stars", "Stars/lvl", "Stars/won"] + [f"{c}*" for c in counts],
                        ["Stars: stars earned", "Stars/lvl: stars per level", "Stars/won: stars per level won",
                         "n*: levels won with n stars"], cells)


def _prediction_columns(reports: Sequence[Report]) -> TableColumns | None:
    if not any(r.overall.mean.wm is not None for r in reports):
        return None

    def cells(r: Report, sec: Section) -> list[str]:
        w, wsd = sec.mean.wm, sec.std.wm
        return ["-", "-"] if w is None else [percent_cell(w.accuracy, wsd.accuracy),
                                             percent_cell(w.predicted_success_failed, wsd.predicted_success_failed)]

    return TableColumns(["PredAcc", "PredS->F"], ["PredAcc: WM outcome predictions that came true (%)",
                                                  "PredS->F: predicted successes that failed (%)"], cells)


def _error_columns(reports: Sequence[Report]) -> TableColumns | None:
    if not any(x.model_errors or x.retries for r in reports for x in r.overall.per_run):
        return None
    return TableColumns(["ModelErr", "Retries"],
                        ["ModelErr: model requests that failed for good", "Retries: model request retries"],
                        lambda r, sec: [count_cell(sec.mean.model_errors, sec.std.model_errors),
                                        count_cell(sec.mean.retries, sec.std.retries)])


def _human_columns(reports: Sequence[Report]) -> TableColumns | None:
    if not any(r.human_time is not None for r in reports):  # a person's time to decide: never a model's latency
        return None

    def cells(r: Report, sec: Section) -> list[str]:
        h = r.human_time
        if h is None or sec is not r.overall:
            return ["-", "-", "-"]
        return [number_cell(h.median_decision_s, None, 1), number_cell(h.median_task_s, None, 1),
                number_cell(h.total_s / 60, None, 1)]

    return TableColumns(["Human s/dec", "Human s/task", "Human min"],
                        ["Human s/dec, s/task: a person's time to decide (the page's clock, simulation not "
                         "counted), median per decision and per finished task", "Human min: the person's time in all"],
                        cells)


def _usage_columns(reports: Sequence[Report]) -> TableColumns | None:
    if not any(x.cost_usd or x.input_tokens for r in reports for x in r.overall.per_run):
        return None
    return TableColumns(["TokensIn", "TokensOut", "Cost$"],
                        ["TokensIn/TokensOut: tokens sent and received", "Cost$: model cost (US dollars)"],
                        lambda r, sec: [number_cell(sec.mean.input_tokens, sec.std.input_tokens, 0),
                                        number_cell(sec.mean.output_tokens, sec.std.output_tokens, 0),
                                        number_cell(sec.mean.cost_usd, sec.std.cost_usd, 4)])


def _success_headline(reports: Sequence[Report]) -> list[BoardColumn]:
    """Success within K attempts (within the game for the one-attempt environments), and per
    task group where the environment's spec asks for it (Kinetix S/M/L)."""
    first = reports[0]
    spec, k = first.spec, first.max_attempts
    columns = []
    if spec.report.leaderboard_groups:
        for g in first.groups or {}:
            columns.append(BoardColumn(g, f"{g}: tasks of {spec.report.group_noun} {g} solved (%)",
                                       lambda r, g=g: (r.groups[g].mean.success_at[k - 1],
                                                       r.groups[g].std.success_at[k - 1])))
    if k > 1:
        header, key = f"Succ@{k}", f"Succ@{k}: tasks solved within {k} attempts (%)"
    else:
        header, key = "Succ", "Succ: tasks solved in their one attempt (all its decisions, shots or actions) (%)"
    return [*columns, BoardColumn(header, key, lambda r: (r.overall.mean.success_at[k - 1],
                                                          r.overall.std.success_at[k - 1]))]


def _pass_headline(reports: Sequence[Report]) -> list[BoardColumn]:
    p = reports[0].spec.report.pass_k  # the paper's headline Pass@k (PHYRE 5, I-PHYRE 3)
    if not p:
        return []
    return [BoardColumn(
        f"Pass@{p}", f"Pass@{p}: tasks solved within the attempt budget in at least one of {p} runs (%; the paper's "
        f"Pass@{p}; - with fewer than {p} runs)",
        lambda r: (r.overall.pass_at[p - 1] if len(r.overall.pass_at or []) >= p else None, None))]


def _auccess_headline(reports: Sequence[Report]) -> list[BoardColumn]:
    if not reports[0].spec.report.auccess:
        return []
    return [BoardColumn("AUCCESS", "AUCCESS: PHYRE's area under the success curve (%)",
                        lambda r: (r.overall.mean.auccess, r.overall.std.auccess))]


def _stars_headline(reports: Sequence[Report]) -> list[BoardColumn]:
    if not reports[0].spec.report.stars:
        return []
    return [BoardColumn("Stars", "Stars: stars earned per run",
                        lambda r: (None, None) if r.overall.mean.stars is None
                        else (r.overall.mean.stars.total, r.overall.std.stars.total), percent=False)]


def _human_headline(reports: Sequence[Report]) -> list[BoardColumn]:
    if not any(r.human_time is not None for r in reports):  # a person's rows only; a time, never ranked
        return []

    def human(name: str, scale: float = 1.0):
        def figure(r: Report) -> tuple[float | None, None]:
            value = None if r.human_time is None else getattr(r.human_time, name)
            return (None if value is None else value / scale), None
        return figure

    both = "Human s/dec, s/task: a person's time to decide, median per decision and per task"
    return [BoardColumn("Human s/dec", both, human("median_decision_s"), percent=False, ranked=False),
            BoardColumn("Human s/task", both, human("median_task_s"), percent=False, ranked=False),
            BoardColumn("Human min", "Human min: the person's time to decide in all", human("total_s", 60.0),
                        percent=False, ranked=False)]


def _many_steps(g: Given) -> bool:
    return g.spec.max_steps > 1


for _metric in [
    Metric("tasks", Number, lambda g: g.tasks),
    Metric("solved", Number, _solved, place=40, table=_outcome_columns, total=True),
    Metric("unsolved", Number, lambda g: _finished(g) - _solved(g)),
    Metric("unfinished", Number, lambda g: g.tasks - _finished(g)),
    Metric("success_at", list[Number], lambda g: [F.success_at(g.episodes, k, g.tasks) for k in range(1, g.k_max + 1)],
           place=10, table=_attempt_columns, headline=_success_headline),
    # Across runs, not per run: Pass@k for k = 1..runs (the paper's tables' Pass@K)
    Metric("pass_at", list[Optional[Number]], lambda g: [F.pass_at(g.episodes, k, g.config.runs, g.tasks)
                                                         for k in range(1, g.config.runs + 1)],
           scope="section", place=20, table=_pass_columns, headline=_pass_headline),
    Metric("avg_attempts", Optional[Number], lambda g: F.average_attempts(g.episodes)),
    Metric("attempts", Number, _total("attempts"), total=True),
    Metric("invalid_attempts", Number, _total("invalid_attempts"), total=True),
    Metric("model_errors", Number, _total("model_errors"), place=70, table=_error_columns, total=True),
    Metric("retries", Number, _total("retries"), total=True),
    Metric("input_tokens", Number, _total("input_tokens"), place=90, table=_usage_columns, total=True),
    Metric("output_tokens", Number, _total("output_tokens"), total=True),
    Metric("cost_usd", Number, _total("cost_usd"), total=True),
    # the whole curve (figures), and the protocol's checkpoints (tables)
    Metric("success_by_step", list[Number], lambda g: [F.success_within_steps(g.episodes, k, g.tasks)
                                                       for k in range(1, g.spec.max_steps + 1)], applies=_many_steps),
    Metric("avg_steps", Optional[Number], lambda g: F.average_steps(g.episodes), applies=_many_steps),
    Metric("success_within_steps", dict[str, Number],
           lambda g: {str(k): F.success_within_steps(g.episodes, k, g.tasks) for k in g.spec.report.step_checkpoints},
           applies=lambda g: bool(g.spec.report.step_checkpoints), place=30, table=_step_columns),
    Metric("auccess", Number, lambda g: F.auccess(g.episodes, g.tasks), applies=lambda g: g.spec.report.auccess,
           place=40, headline=_auccess_headline),
    Metric("wm", Predictions, _predictions, applies=lambda g: g.config.format.value == "wm", place=60,
           table=_prediction_columns),
    Metric("stars", Stars, _stars, applies=lambda g: g.spec.report.stars, place=50, table=_star_columns,
           headline=_stars_headline),
    Metric("human_time", HumanTime, _human_time, scope="report", applies=lambda g: is_human(g.config.model),
           place=80, table=_human_columns, headline=_human_headline),
]:
    register_metric(_metric)
