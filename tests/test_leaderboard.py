"""`deepphy leaderboard`: the master table across run directories of several models and
environments. Every figure must be the one `deepphy report` gives for the same directory."""

import json
import shutil

import pytest

from dashboard_support import copy_run, synthetic_run
from deepphy.cli import main
from deepphy.metrics.leaderboard import leaderboard, render_csv, render_latex, render_markdown, render_text
from deepphy.metrics.report import report_of

KINETIX = ["s_h0_weak_thrust", "s_h1_thrust_over_ball", "m_arm_hard", "m_arm_left", "l_car_launch", "l_car_swing_around"]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """A suite-like root: <model>/<env setting>/<format>, two models, synthetic runs."""
    root = tmp_path_factory.mktemp("board")
    for model, p in [("mock", 0.2), ("gpt-4o", 0.6)]:
        synthetic_run(root / model / "kinetix" / "vla", tasks=KINETIX, runs=3, model=model, p_success=p)
        synthetic_run(root / model / "kinetix-plain" / "vla", tasks=KINETIX, runs=3, model=model, p_success=p,
                      env_options={"annotate": False})
        synthetic_run(root / model / "angrybirds" / "vla", env="angrybirds", limit=6, stars=True, model=model,
                      p_success=p)
        synthetic_run(root / model / "phyre" / "vla", env="phyre", limit=6, max_steps=1, model=model, p_success=p)
    synthetic_run(root / "mock" / "phyre" / "wm", env="phyre", limit=6, max_steps=1, fmt="wm", p_success=0.3)
    return root


def _board(paths):
    return leaderboard([report_of(p) for p in paths], [str(p) for p in paths])


def _runs(root):
    return sorted(p.parent for p in root.rglob("config.json"))


def test_rows_are_settings_and_columns_the_environments_headlines(root):
    board = _board(_runs(root))
    assert [board.row_label(i) for i in range(len(board.rows))] == ["gpt-4o VLA", "mock VLA", "mock WM"]
    assert [g.title for g in board.groups] == ["Angry Birds", "Kinetix", "Kinetix annotate=False", "PHYRE-B"]
    assert [[c.header for c in g.columns] for g in board.groups] == [
        ["n", "Succ", "Stars"], ["n", "S", "M", "L", "Succ"], ["n", "S", "M", "L", "Succ"],
        ["n", "Succ@10", "Pass@5", "AUCCESS"]]
    # each figure is the report's of that directory
    for (r, g), cells in board.cells.items():
        report = report_of(cells[0].run_dir)
        mean = report.overall.mean
        k = report.max_attempts
        expected = {"Succ": mean.success_at[0], f"Succ@{k}": mean.success_at[k - 1],
                    "AUCCESS": mean.auccess, "Stars": None if mean.stars is None else mean.stars.total,
                    # the paper's Pass@5 needs 5 runs: "-" with fewer, never a number made up
                    "Pass@5": report.overall.pass_at[4] if report.runs >= 5 else None,
                    **{size: sec.mean.success_at[0] for size, sec in (report.groups or {}).items()}}
        for column, cell in zip(board.groups[g].columns, cells):
            if column.header == "n":  # the row's tasks x runs, in words
                assert cell.text == f"{report.overall.tasks}x{report.runs}" and cell.mean is None
                continue
            assert cell.mean == pytest.approx(expected[column.header]), (cells[0].run_dir, column.header)
    # a setting without a run of an environment shows "-"
    wm = board.rows.index(("mock", "wm"))
    assert [c.text for c in board.row_cells(wm)][:3] == ["-", "-", "-"]


def test_the_best_of_each_column_is_marked(root):
    board = _board(_runs(root))
    for g, group in enumerate(board.groups):
        for c in range(len(group.columns)):
            cells = [board.cells[(r, g)][c] for r in range(len(board.rows)) if (r, g) in board.cells]
            cells = [x for x in cells if x.mean is not None]  # "-": no figure to rank
            if not cells:
                continue
            top = max(x.mean for x in cells)
            differ = len({x.mean for x in cells}) > 1  # all equal: none marked
            assert [x.best for x in cells] == [differ and x.mean == top for x in cells]
    text = render_text(board)
    assert "*" in text and "best of the column" in text
    assert "**" in render_markdown(board) and r"\textbf{" in render_latex(board)


def test_unfinished_runs_are_marked_and_never_averaged_or_best(root, tmp_path):
    src = root / "gpt-4o" / "phyre" / "vla"
    copy_run(src, tmp_path / "cut", lines=5)  # PHYRE: at most 10 attempts per episode, so some are open
    paths = [root / "mock" / "phyre" / "vla", tmp_path / "cut"]
    board = _board(paths)
    cut = board.cells[(1, 0)]
    done = sum(x.tasks - x.unfinished for x in report_of(tmp_path / "cut").overall.per_run)
    assert cut[1].unfinished == f"{done}/12" and cut[1].text == f"unfinished {done}/12"
    assert cut[0].text == f"6x2 ({done} done)"  # n: tasks x runs, and the episodes done
    assert all(c.mean is None and not c.best for c in cut)
    assert not any(c.best for c in board.cells[(0, 0)])  # one finished row: nothing to compare


def test_rows_of_other_tasks_or_runs_are_not_ranked_against_the_others(root, tmp_path):
    """A run of one task (a person's, say) is never the best against runs of six: the column
    is ranked among the rows of one task set, runs and attempts (those of the most rows), the
    other rows are marked and named in a note, and every row states its n."""
    paths = [root / model / "phyre" / "vla" for model in ("mock", "gpt-4o")]
    report = report_of(paths[0])
    one = synthetic_run(tmp_path / "one", env="phyre", limit=1, max_steps=1,
                        model="human:ana", p_success=1.0, runs=1)
    board = _board([*paths, one])
    rows = {board.row_label(i): board.row_cells(i) for i in range(len(board.rows))}
    succ = [c.header for c in board.groups[0].columns].index("Succ@10")
    assert rows["human:ana VLA"][succ].mean == 1.0 and not rows["human:ana VLA"][succ].best
    assert rows["human:ana VLA"][succ].unranked and rows["human:ana VLA"][0].text == "1x1"
    assert any(rows[m][succ].best for m in ("mock VLA", "gpt-4o VLA"))  # the comparable rows are still ranked
    assert not any(rows[m][succ].unranked for m in ("mock VLA", "gpt-4o VLA"))
    assert any("not ranked against the other rows" in n and "human:ana VLA (n=1x1)" in n for n in board.notes)
    assert "100.0\u2020" in render_text(board) and report.overall.tasks == 6


def test_two_runs_of_one_cell_are_refused(root, tmp_path):
    synthetic_run(tmp_path / "again", env="phyre", limit=6, max_steps=1, seed=1)
    with pytest.raises(ValueError, match="two runs of mock VLA on PHYRE-B"):
        _board([root / "mock" / "phyre" / "vla", tmp_path / "again"])


def test_cli_takes_a_root_and_plain_run_directories_of_different_environments(root, capsys):
    assert main(["leaderboard", str(root), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert len(data["rows"]) == 3 and len(data["columns"]) == 17
    # plain run directories of different environments: `report` refuses them, the leaderboard takes them
    dirs = [str(root / "mock" / "phyre" / "vla"), str(root / "gpt-4o" / "angrybirds" / "vla")]
    assert main(["report", *dirs]) == 2
    assert "one environment" in capsys.readouterr().err
    assert main(["leaderboard", *dirs, "--csv"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == ("setting,Angry Birds n,Angry Birds Succ,Angry Birds Stars,PHYRE-B n,PHYRE-B Succ@10,"
                        "PHYRE-B Pass@5,PHYRE-B AUCCESS")
    assert lines[1].startswith("mock VLA,-,-,-,6x2,") and lines[2].startswith("gpt-4o VLA,6x2,")
    assert render_csv(_board(dirs)).splitlines()[0] == lines[0]


def test_cli_errors_are_one_line(tmp_path, capsys):
    assert main(["leaderboard", str(tmp_path / "missing")]) == 2
    assert "is not a directory" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert main(["leaderboard", str(tmp_path / "empty")]) == 2
    assert "holds no run directory" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("pdflatex") is None,
                    reason="needs pdflatex with booktabs (Debian: texlive-latex-base texlive-latex-recommended)")
def test_latex_leaderboard_compiles_and_fits_the_page(root, tmp_path):
    from test_plots import _pdflatex

    log = _pdflatex(render_latex(_board(_runs(root))), tmp_path)
    assert "Overfull \\hbox" not in log and "Missing character" not in log
    assert (tmp_path / "table.pdf").read_bytes()[:5] == b"%PDF-"


def _suite_root(root, dest):
    """`root` as a suite root: its runs, gpt-4o's PHYRE run cut short (unfinished), and a
    manifest cell (I-PHYRE) with no run directory yet."""
    from deepphy.config import RunConfig
    from deepphy.runs.store import read_config

    shutil.copytree(root, dest, ignore=shutil.ignore_patterns("gpt-4o"))
    for run in (root / "gpt-4o").iterdir():
        if run.name != "phyre":
            shutil.copytree(run, dest / "gpt-4o" / run.name)
    copy_run(root / "gpt-4o" / "phyre" / "vla", dest / "gpt-4o" / "phyre" / "vla", lines=5)
    cells = [{"dir": str(p.parent.relative_to(dest)), "config": read_config(p.parent).model_dump(mode="json")}
             for p in sorted(dest.rglob("config.json"))]
    waiting = RunConfig(env="iphyre", model="mock", runs=3, limit=4)
    cells.append({"dir": "mock/iphyre/vla", "config": waiting.model_dump(mode="json")})
    (dest / "suite.json").write_text(json.dumps({"suite": "test", "description": "", "cells": cells}))
    return dest


def test_plot_of_a_suite_root_draws_the_leaderboard(root, tmp_path, capsys):
    suite = _suite_root(root, tmp_path / "suite")
    assert main(["plot", str(suite), "--out", str(tmp_path / "fig")]) == 0
    written = capsys.readouterr().out.split()
    assert str(tmp_path / "fig" / "leaderboard.png") in written and str(tmp_path / "fig" / "leaderboard.pdf") in written
    assert (tmp_path / "fig" / "leaderboard.pdf").read_bytes()[:5] == b"%PDF-"
    drawn = json.loads((tmp_path / "fig" / "figures.json").read_text())["leaderboard"]
    assert main(["leaderboard", str(suite), "--json"]) == 0
    table = json.loads(capsys.readouterr().out)
    assert drawn["rows"] == [f"{r['model']} {r['format'].upper()}" for r in table["rows"]]
    # a panel per setting's percent figures, the stars on their own; every bar the table's figure
    assert [p["title"] for p in drawn["panels"]] == [
        "Angry Birds", "Angry Birds, Stars", "I-PHYRE", "Kinetix", "Kinetix annotate=False", "PHYRE-B"]
    where = {(c["title"], c["header"]): j for j, c in enumerate(table["columns"])}
    group = {"Angry Birds, Stars": "Angry Birds"}
    for panel in drawn["panels"]:
        for r, bars in enumerate(panel["bars"]):
            for k, header in enumerate(panel["columns"]):
                cell = table["rows"][r]["cells"][where[(group.get(panel["title"], panel["title"]), header)]]
                unfinished = cell["unfinished"]
                assert bars["unfinished"][k] == unfinished
                assert bars["mean"][k] == (None if unfinished else cell["mean"])
                assert bars["best"][k] == cell["best"]
                assert bars["missing"][k] == (cell["text"] == "-")
    phyre = drawn["panels"][-1]["bars"]
    assert phyre[0]["row"] == "gpt-4o VLA" and phyre[0]["unfinished"][0] and phyre[0]["mean"] == [None, None, None]
    iphyre = drawn["panels"][2]["bars"]  # the cell the manifest lists and nobody started
    assert [(b["unfinished"], b["missing"]) for b in iphyre] == [([None, None], [True, True]),
                                                                  (["0/12", "0/12"], [False, False]),
                                                                  ([None, None], [True, True])]


def test_leaderboard_figure_marks_what_the_table_marks(root):
    from matplotlib.figure import Figure

    from deepphy.plots import BEST_MARK, draw_leaderboard

    board = _board(_runs(root))
    fig = Figure()
    drawn = draw_leaderboard(fig, board)
    stars_drawn = sum(t.get_text() == BEST_MARK for ax in fig.axes for t in ax.texts)
    assert stars_drawn == sum(c.best for cells in board.cells.values() for c in cells) > 0
    no_run = sum(t.get_text() in ("no run", "n/a") for ax in fig.axes for t in ax.texts)  # n/a: Pass@5 of 3 runs
    assert no_run == sum(m for p in drawn["panels"] for b in p["bars"] for m in b["missing"]) > 0
