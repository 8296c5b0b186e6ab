"""A new metric is one declaration plus its computation (deepphy.metrics.registry): registered
from this test module, without editing deepphy's files, it is a field of the typed report, a
key of `deepphy report --json`, a column of the report's tables and of the leaderboard."""

from __future__ import annotations

import statistics

import pytest

from deepphy.config import RunConfig
from deepphy.envs import Task
from deepphy.metrics import registry as R
from deepphy.metrics.leaderboard import leaderboard, render_text as board_text
from deepphy.metrics.report import build_report, render_csv, render_latex, render_text, table
from test_metrics import episode_records


def _median_attempts(given: R.Given) -> float | None:
    """The median attempt of first success over the solved tasks: a toy figure."""
    firsts = [e.solved_at for e in given.episodes if e.solved]
    return statistics.median(firsts) if firsts else None


TOY = R.Metric(
    "median_attempts", float, _median_attempts, place=35,
    table=lambda reports: R.TableColumns(["MedAtt"], ["MedAtt: median attempt of first success"],
                                         lambda r, sec: [R.number_cell(sec.mean.median_attempts,
                                                                       sec.std.median_attempts)]),
    headline=lambda reports: [R.BoardColumn("MedAtt", "MedAtt: median attempt of first success",
                                            lambda r: (r.overall.mean.median_attempts, r.overall.std.median_attempts),
                                            percent=False, ranked=False)])


@pytest.fixture
def toy_metric():
    R.register_metric(TOY)
    yield TOY
    R.unregister_metric(TOY.key)


def report(runs_solved_at: list[list[int | None]]):
    tasks = [Task(env="iphyre", id=t) for t in "abc"]
    records = [r for run, solved in enumerate(runs_solved_at) for t, at in zip("abc", solved)
               for r in episode_records(t, run, at)]
    return build_report(RunConfig(env="iphyre", runs=len(runs_solved_at)), tasks, records, k_max=10)


def test_a_metric_registered_outside_deepphy_is_in_the_report_its_json_and_its_tables(toy_metric):
    rep = report([[1, 3, None], [2, 6, 10]])
    assert [r.median_attempts for r in rep.overall.per_run] == [2.0, 6.0]  # the typed field, per run
    assert rep.overall.mean.median_attempts == 4.0 and rep.overall.std.median_attempts == pytest.approx(2 ** 0.5 * 2)
    assert rep.to_json()["overall"]["per_run"][1]["median_attempts"] == 6.0
    header, rows = table([rep])
    assert header.index("MedAtt") > header.index("Att.10")  # its place: after the attempts' columns
    assert rows[0][header.index("MedAtt")] == "4.00±2.83"
    for render in (render_text, render_csv, render_latex):
        assert "MedAtt" in render(rep)
    board = leaderboard([rep])
    assert "MedAtt" in board_text(board)


def test_without_it_nothing_of_it_remains_and_keys_are_checked():
    rep = report([[1, 3, None]])
    assert "median_attempts" not in rep.to_json()["overall"]["per_run"][0]
    assert "MedAtt" not in render_text(rep)
    with pytest.raises(ValueError, match="already has a figure 'success_at'"):
        R.register_metric(R.Metric("success_at", float, _median_attempts))
    with pytest.raises(ValueError, match="already has a figure 'mean'"):
        R.register_metric(R.Metric("mean", float, _median_attempts))
