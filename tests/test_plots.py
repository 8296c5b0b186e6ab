"""The paper's figures (`deepphy plot`) draw exactly the report's numbers, on axes a paper
can use; `report --latex` is the report's table, and it compiles."""

import json
import re
import shutil
import subprocess

import pytest
from matplotlib.figure import Figure

from dashboard_support import mock_run, synthetic_run
from deepphy.cli import main
from deepphy.metrics.report import LATEX_PREAMBLE, render_latex, report_of, table
from deepphy.plots import (
    draw_ablation_dumbbell, draw_cumulative_bars, draw_group_bars, draw_star_bars, draw_success_by_step,
    draw_vla_wm_scatter, figures_for, plot_all,
)

KINETIX = ["s_h0_weak_thrust", "s_h1_thrust_over_ball", "m_arm_hard", "m_arm_left", "l_car_launch", "l_car_swing_around"]


@pytest.fixture(scope="module")
def dirs(ray_cluster, tmp_path_factory):
    base = tmp_path_factory.mktemp("plot-runs")
    return {
        "vla": mock_run(tmp_path_factory),
        "wm": mock_run(tmp_path_factory, fmt="wm"),
        "kinetix": synthetic_run(base / "kin-annotated", tasks=KINETIX, runs=3),
        "kinetix-plain": synthetic_run(base / "kin-plain", tasks=KINETIX, runs=3, env_options={"annotate": False}),
        "pooltool": synthetic_run(base / "pool", env="pooltool", limit=8, max_steps=15, p_success=0.5),
        "stars": synthetic_run(base / "stars", env="angrybirds", limit=8, stars=True),
    }


@pytest.fixture(scope="module")
def zero(tmp_path_factory):
    """An I-PHYRE run that solved nothing."""
    return synthetic_run(tmp_path_factory.mktemp("zero") / "run", env="iphyre", limit=4, p_success=0.0)


def _axes():
    return Figure().add_subplot()


def test_cumulative_bars_are_the_reports_success_at_1_4_7_10(dirs):
    reports = [report_of(dirs["vla"]), report_of(dirs["wm"])]
    ax = _axes()
    drawn = draw_cumulative_bars(ax, reports)
    bars = [p.get_height() for p in ax.patches]
    for i, r in enumerate(reports):
        m = r.overall.mean
        assert drawn["checkpoints"][i] == [1, 4, 7, 10]
        assert drawn["success"][i] == [m.success_at[k - 1] for k in (1, 4, 7, 10)]
        assert drawn["avg_attempts"][i] == m.avg_attempts
        assert sum(drawn["segments"][i]) == pytest.approx(m.success_at[9])
        # what is on the axes: the stacked segments, in percent
        assert bars[4 * i : 4 * i + 4] == pytest.approx([100 * s for s in drawn["segments"][i]])
    assert drawn["labels"] == ["mock VLA", "mock WM"]
    # the average attempts are written above the bars, on the one y axis (no twin axis)
    assert [t.get_text() for t in ax.texts][:2] == [f"{r.overall.mean.avg_attempts:.2f}" for r in reports]
    assert len(ax.figure.axes) == 1
    assert ax.get_ylim()[0] == 0 and ax.get_ylim()[1] in (10, 20, 30, 40, 50, 60, 70, 80, 90, 100)


def test_one_setting_bar_does_not_fill_the_figure(dirs):
    ax = _axes()
    draw_cumulative_bars(ax, [report_of(dirs["vla"])])
    lo, hi = ax.get_xlim()
    assert ax.patches[0].get_width() / (hi - lo) < 0.25


def test_all_zero_results_get_a_0_to_10_percent_axis(zero):
    report = report_of(zero)
    assert report.overall.mean.success_at[-1] == 0
    ax = _axes()
    draw_cumulative_bars(ax, [report])
    assert ax.get_ylim() == (0, 10)


def test_vla_wm_scatter_pairs_formats_at_pass_at_k(dirs):
    """The paper's figure: Pass@k (solved in at least one of k runs); I-PHYRE's k is 3, and two
    runs allow Pass@2 at most: drawn at Pass@2 and said so, no Pass@3 invented."""
    reports = [report_of(dirs[k]) for k in ("vla", "wm", "kinetix")]
    assert reports[0].runs == 2
    ax = _axes()
    drawn = draw_vla_wm_scatter(ax, reports)
    assert len(drawn["points"]) == 1  # kinetix has one format only
    p = drawn["points"][0]
    assert (p["env"], p["k"]) == ("iphyre", 2)
    assert p["vla"] == reports[0].overall.pass_at[1]
    assert p["wm"] == reports[1].overall.pass_at[1]
    assert drawn["notes"] == ["I-PHYRE mock: 2 run(s), fewer than Pass@3 needs: drawn at Pass@2"]
    assert list(ax.collections[0].get_offsets()[0]) == pytest.approx([100 * p["vla"], 100 * p["wm"]])
    one = draw_vla_wm_scatter(_axes(), reports, k=1)
    assert one["points"][0]["vla"] == pytest.approx(reports[0].overall.mean.success_at[9]) and not one["notes"]
    assert [t.get_text() for t in ax.figure.legends[0].get_texts()] == ["I-PHYRE"]  # the environment's title


def test_annotation_dumbbell_by_size(dirs):
    with_, without = report_of(dirs["kinetix"]), report_of(dirs["kinetix-plain"])
    drawn = draw_ablation_dumbbell(_axes(), [without, with_])
    assert [row["group"] for row in drawn["rows"]] == ["S", "M", "L", None]  # the environment's order, then all
    for row in drawn["rows"]:
        sec = with_.groups[row["group"]] if row["group"] else with_.overall
        plain = without.groups[row["group"]] if row["group"] else without.overall
        assert row["with"] == sec.mean.success_at[0] and row["without"] == plain.mean.success_at[0]
    assert any(row["with"] != row["without"] for row in drawn["rows"])


def test_kinetix_per_size_with_and_without_annotation(dirs):
    reports = [report_of(dirs["kinetix"]), report_of(dirs["kinetix-plain"])]
    ax = _axes()
    drawn = draw_group_bars(ax, reports)
    assert drawn["groups"] == ["S", "M", "L", "all"]
    for bars, r in zip(drawn["bars"], reports):
        assert bars["success"] == [r.groups[g].mean.success_at[0] for g in "SML"] + [r.overall.mean.success_at[0]]
    assert [b["label"] for b in drawn["bars"]] == ["mock VLA", "mock VLA annotate=False"]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["S", "M", "L", "all"] and ax.get_xlabel() == "size"
    assert [p.get_height() for p in ax.patches][:4] == pytest.approx([100 * v for v in drawn["bars"][0]["success"]])


def test_success_by_shot_has_ticks_at_the_checkpoints(dirs):
    pool = report_of(dirs["pooltool"])
    ax = _axes()
    drawn = draw_success_by_step(ax, [pool])
    m = pool.overall.mean
    series = drawn["series"][0]
    assert series["steps"] == list(range(1, 16)) and series["success"] == m.success_by_step
    for k, v in m.success_within_steps.items():  # the curve passes through the table's figures
        assert series["success"][int(k) - 1] == v
    assert series["avg_steps"] == m.avg_steps
    assert list(ax.get_xticks()) == [1, 3, 6, 9, 12, 15] == drawn["ticks"]
    assert ax.get_xlabel() == "shots (k)"
    kinetix = draw_success_by_step(_axes(), [report_of(dirs["kinetix"])])
    assert kinetix["ticks"] == list(range(1, 17))  # no checkpoints: every decision


def test_star_bars(dirs):
    """A bar of all the levels per setting: the share not won, then won with 1, 2 and 3 stars
    (0 where any were), the report's mean over runs; the shares add up to 100 %."""
    stars = report_of(dirs["stars"])
    ax = _axes()
    drawn = draw_star_bars(ax, [stars])
    st = stars.overall.mean.stars
    tasks = stars.overall.tasks
    assert drawn["levels_with"][0] == [st.levels_with[k] for k in drawn["stars"]]
    assert drawn["shares"][0] == pytest.approx([st.levels_with[k] / tasks for k in drawn["stars"]])
    assert drawn["mean_all"][0] == st.mean_all and drawn["mean_completed"][0] == st.mean_completed
    widths = [p.get_width() for p in ax.patches]
    assert widths == pytest.approx([100 * drawn["not_won"][0], *(100 * x for x in drawn["shares"][0])])
    assert sum(widths) == pytest.approx(100) and ax.get_xlim() == (0, 100)
    assert [t.get_text() for t in ax.get_yticklabels()] == [f"mock VLA\n(n={tasks}x{stars.runs})"]


def test_success_against_attempts_is_the_reports_att_k(dirs):
    from deepphy.plots import draw_success_by_attempt

    reports = [report_of(dirs["vla"]), report_of(dirs["wm"])]
    ax = _axes()
    drawn = draw_success_by_attempt(ax, reports)
    for series, r, line in zip(drawn["series"], reports, ax.get_lines()):
        assert series["success"] == r.overall.mean.success_at and series["attempts"] == list(range(1, 11))
        assert list(line.get_ydata()) == pytest.approx([100 * v for v in series["success"]])
        assert series["n"] == "6x2"
    assert [t.get_text() for t in ax.figure.legends[0].get_texts()] == ["mock VLA (n=6x2)", "mock WM (n=6x2)"]


def test_every_figure_fits_one_and_two_columns_with_readable_text(dirs):
    """Every figure at 3.3 in (one column) and 7 in (two): no text under MIN_FONT_PT, none
    outside the figure, and every setting's n written in it."""
    from matplotlib.text import Text

    from deepphy.plots import MIN_FONT_PT, WIDTHS, draw_figure

    from deepphy.metrics.leaderboard import leaderboard

    reports = [report_of(d) for d in dirs.values()]
    board = leaderboard(reports, list(map(str, dirs.values())))
    for stem, _, _, rs in [*figures_for(reports), ("leaderboard", None, None, reports)]:
        for width in WIDTHS.values():
            fig = draw_figure(stem, reports, width, board)
            assert fig.get_figwidth() == width
            texts = [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]
            small = [(t.get_text(), t.get_fontsize()) for t in texts if t.get_fontsize() < MIN_FONT_PT]
            assert not small, (stem, width, small)
            drawn = fig.get_tightbbox(fig.canvas.get_renderer())  # inches: everything drawn, text included
            assert drawn.x0 >= -0.02 and drawn.y0 >= -0.02 and drawn.x1 <= width + 0.02 \
                and drawn.y1 <= fig.get_figheight() + 0.02, (stem, width, drawn)
            words = "\n".join(t.get_text() for t in texts)
            from deepphy.plots import vla_wm_pairs

            shown = [r for pair in vla_wm_pairs(rs) for r in pair] if stem == "vla_vs_wm" else rs
            n = [f"{r.overall.tasks}x{r.runs}" for r in shown]
            assert all(x in words for x in n), (stem, width)


def test_which_figures_apply_is_read_from_the_reports(dirs):
    figures = figures_for([report_of(d) for d in dirs.values()])
    assert {stem for stem, *_ in figures} == {
        "cumulative_iphyre", "by_attempt_iphyre", "by_group_iphyre", "vla_vs_wm", "by_decision_kinetix", "by_size_kinetix",
        "annotate_kinetix", "by_shot_pooltool", "by_shot_angrybirds", "stars_angrybirds"}  # 8 levels: one scene
    titles = {stem: title for stem, title, *_ in figures}
    assert titles["cumulative_iphyre"].startswith("I-PHYRE: ") and titles["by_shot_angrybirds"].startswith("Angry Birds: ")
    # Kinetix alone, one setting: success by decision and per size
    assert {stem for stem, *_ in figures_for([report_of(dirs["kinetix"])])} == {"by_decision_kinetix", "by_size_kinetix"}


def test_plot_cli_writes_png_pdf_and_the_drawn_data(dirs, tmp_path, capsys):
    out = tmp_path / "figs"
    assert main(["plot", *map(str, dirs.values()), "--out", str(out)]) == 0
    printed = capsys.readouterr().out.split()
    for stem in ("cumulative_iphyre", "vla_vs_wm", "annotate_kinetix", "by_size_kinetix", "by_shot_pooltool",
                 "stars_angrybirds"):
        assert (out / f"{stem}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert (out / f"{stem}.pdf").read_bytes()[:5] == b"%PDF-"
        assert str(out / f"{stem}.png") in printed
    data = json.loads((out / "figures.json").read_text())
    assert data["vla_vs_wm"]["points"][0]["vla"] == report_of(dirs["vla"]).overall.pass_at[1]
    assert main(["plot", str(dirs["kinetix"]), "--out", str(tmp_path / "kinetix")]) == 0
    assert (tmp_path / "kinetix" / "by_size_kinetix.png").exists()


def test_plot_all_returns_the_files(dirs, tmp_path):
    written = plot_all([report_of(dirs["pooltool"])], tmp_path)
    assert {p.name for p in written} == {"by_shot_pooltool.png", "by_shot_pooltool.pdf", "by_shot_pooltool-1col.png",
                                         "by_shot_pooltool-1col.pdf", "figures.json"}


# -- LaTeX --------------------------------------------------------------------------------


def _plain(cell):
    return (cell.replace(r"$\pm$", "±").replace(r"\_", "_").replace(r"$\star$", "*").replace(r"$\to$", "->")
            .replace(r"\$", "$"))


def test_latex_is_the_report_table(dirs, capsys):
    reports = [report_of(dirs["vla"]), report_of(dirs["wm"])]
    header, rows = table(reports)
    latex = render_latex(reports)
    lines = latex.splitlines()
    assert lines[0].endswith(LATEX_PREAMBLE) and lines[-1] == r"\end{table}"
    assert r"\caption{I-PHYRE: mock VLA (the paper's set-up); mock WM (the paper's set-up); 2 run(s), seed 3." in latex
    assert r"\label{tab:deepphy-iphyre-mock-vla-mock-wm}" in latex
    # the blocks, side by side again, are the table
    blocks = [b.splitlines() for b in latex.split(r"\begin{tabular}{")[2:]]  # the first holds the others
    assert len(blocks) > 1  # 16 columns: split
    got_header, got_rows = [], [[] for _ in rows]
    for n, block in enumerate(blocks):
        body = [[_plain(c) for c in line[:-3].split(" & ")] for line in block if line.endswith(r" \\")]
        skip = 3 if n else 0  # setting, group, n: repeated in every block
        got_header += body[0][skip:]
        for i, line in enumerate(body[1:]):
            got_rows[i] += line[skip:]
    assert got_header == header and got_rows == rows
    cells = "\n".join(line for block in blocks for line in block if line.endswith(r" \\"))
    assert r"multi\_ball" in cells and "±" not in latex
    assert r"PredS$\to$F" in cells and not re.search(r"[<>]", cells.replace("$\\to$", ""))
    assert main(["report", "--latex", str(dirs["vla"]), str(dirs["wm"])]) == 0
    assert capsys.readouterr().out.strip() == latex


def _pdflatex(tex: str, where) -> str:
    """Compile a document holding `tex`; returns the log (fails on an error)."""
    doc = where / "table.tex"
    doc.write_text("\\documentclass{article}\n" + LATEX_PREAMBLE + "\n\\begin{document}\n" + tex
                   + "\n\\end{document}\n")
    done = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", doc.name], cwd=where,
                          capture_output=True, text=True, timeout=120)
    log = (where / "table.log").read_text(errors="replace")
    assert done.returncode == 0, log[-2000:]
    return log


@pytest.mark.skipif(shutil.which("pdflatex") is None,
                    reason="needs pdflatex with booktabs (Debian: texlive-latex-base texlive-latex-recommended)")
def test_every_latex_table_compiles_and_fits_the_page(dirs, tmp_path):
    wide = synthetic_run(tmp_path / "wide", env="angrybirds", limit=4, stars=True, fmt="wm")  # tokens, retries
    cases = {
        "one run": [report_of(dirs["vla"])],
        "vla and wm": [report_of(dirs["vla"]), report_of(dirs["wm"])],
        "kinetix sizes": [report_of(dirs["kinetix"]), report_of(dirs["kinetix-plain"])],
        "pooltool shots": [report_of(dirs["pooltool"])],
        "stars, wm, tokens": [report_of(wide), report_of(dirs["stars"])],
    }
    for name, reports in cases.items():
        header, _ = table(reports)
        where = tmp_path / re.sub(r"\W+", "-", name)
        where.mkdir()
        log = _pdflatex(render_latex(reports), where)
        assert "Overfull \\hbox" not in log and "Missing character" not in log, (name, len(header))
        assert (where / "table.pdf").read_bytes()[:5] == b"%PDF-"
    assert len(table(cases["stars, wm, tokens"])[0]) >= 20  # the widest of them: it is split and fits
