"""The paper's figures (`deepphy plot`) draw exactly the report's numbers; `report --latex`
is the report's table."""

import json

import pytest
from matplotlib.figure import Figure

from dashboard_support import mock_run, synthetic_run
from deepphy.cli import main
from deepphy.metrics.report import render_latex, report_of, table
from deepphy.plots import (
    draw_ablation_dumbbell, draw_cumulative_bars, draw_star_bars, draw_success_by_shot, draw_vla_wm_scatter,
    figures_for, plot_all,
)


@pytest.fixture(scope="module")
def dirs(ray_cluster, tmp_path_factory):
    base = tmp_path_factory.mktemp("plot-runs")
    kinetix = ["s_h0_weak_thrust", "s_h1_thrust_over_ball", "m_arm_hard", "m_arm_left", "l_car_launch", "l_car_swing_around"]
    return {
        "vla": mock_run(tmp_path_factory),
        "wm": mock_run(tmp_path_factory, fmt="wm"),
        "kinetix": synthetic_run(base / "kin-annotated", tasks=kinetix, runs=3),
        "kinetix-plain": synthetic_run(base / "kin-plain", tasks=kinetix, runs=3, env_options={"annotate": False}),
        "pooltool": synthetic_run(base / "pool", env="pooltool", limit=8, max_steps=15, p_success=0.5),
        "stars": synthetic_run(base / "stars", env="angrybirds", limit=8, stars=True),
    }


def _axes():
    return Figure().add_subplot()


def test_cumulative_bars_are_the_reports_success_at_1_4_7_10(dirs):
    reports = [report_of(dirs["vla"]), report_of(dirs["wm"])]
    ax = _axes()
    drawn = draw_cumulative_bars(ax, reports)
    bars = [p.get_height() for p in ax.patches]
    for i, r in enumerate(reports):
        m = r["overall"]["mean"]
        assert drawn["checkpoints"][i] == [1, 4, 7, 10]
        assert drawn["success"][i] == [m["success_at"][k - 1] for k in (1, 4, 7, 10)]
        assert drawn["avg_attempts"][i] == m["avg_attempts"]
        assert sum(drawn["segments"][i]) == pytest.approx(m["success_at"][9])
        # what is on the axes: the stacked segments, in percent
        assert bars[4 * i : 4 * i + 4] == pytest.approx([100 * s for s in drawn["segments"][i]])
    assert drawn["labels"] == ["mock VLA", "mock WM"]


def test_vla_wm_scatter_pairs_formats_at_pass_at_k(dirs):
    reports = [report_of(dirs[k]) for k in ("vla", "wm", "kinetix")]
    ax = _axes()
    drawn = draw_vla_wm_scatter(ax, reports)
    assert len(drawn["points"]) == 1  # kinetix has one format only
    p = drawn["points"][0]
    assert (p["env"], p["k"]) == ("iphyre", 10)
    assert p["vla"] == reports[0]["overall"]["mean"]["success_at"][9]
    assert p["wm"] == reports[1]["overall"]["mean"]["success_at"][9]
    assert list(ax.collections[0].get_offsets()[0]) == pytest.approx([100 * p["vla"], 100 * p["wm"]])
    assert draw_vla_wm_scatter(_axes(), reports, k=3)["points"][0]["vla"] == reports[0]["overall"]["mean"]["success_at"][2]


def test_annotation_dumbbell_by_size(dirs):
    with_, without = report_of(dirs["kinetix"]), report_of(dirs["kinetix-plain"])
    drawn = draw_ablation_dumbbell(_axes(), [without, with_])
    assert [row["group"] for row in drawn["rows"]] == ["S", "M", "L"]  # the environment's order, not alphabetical
    for row in drawn["rows"]:
        assert row["with"] == with_["groups"][row["group"]]["mean"]["success_at"][0]
        assert row["without"] == without["groups"][row["group"]]["mean"]["success_at"][0]
    assert any(row["with"] != row["without"] for row in drawn["rows"])


def test_success_by_shot_and_stars(dirs):
    pool = report_of(dirs["pooltool"])
    drawn = draw_success_by_shot(_axes(), [pool])
    m = pool["overall"]["mean"]
    assert drawn["series"][0]["shots"] == [int(k) for k in m["success_within_steps"]]
    assert drawn["series"][0]["success"] == list(m["success_within_steps"].values())
    assert drawn["series"][0]["avg_steps"] == m["avg_steps"]

    stars = report_of(dirs["stars"])
    ax = _axes()
    drawn = draw_star_bars(ax, [stars])
    st = stars["overall"]["mean"]["stars"]
    assert drawn["levels_with"][0] == [st["levels_with"][k] for k in ("1", "2", "3")]
    assert drawn["mean_all"][0] == st["mean_all"] and drawn["mean_completed"][0] == st["mean_completed"]
    assert [p.get_height() for p in ax.patches] == drawn["levels_with"][0]


def test_which_figures_apply_is_read_from_the_reports(dirs):
    stems = {stem for stem, *_ in figures_for([report_of(d) for d in dirs.values()])}
    assert stems == {"cumulative_iphyre", "vla_vs_wm", "annotate_kinetix", "by_shot_pooltool", "by_shot_angrybirds",
                     "stars_angrybirds"}
    assert figures_for([report_of(dirs["kinetix"])]) == []  # K = 1, one setting: nothing to draw


def test_plot_cli_writes_png_pdf_and_the_drawn_data(dirs, tmp_path, capsys):
    out = tmp_path / "figs"
    assert main(["plot", *map(str, dirs.values()), "--out", str(out)]) == 0
    printed = capsys.readouterr().out.split()
    for stem in ("cumulative_iphyre", "vla_vs_wm", "annotate_kinetix", "by_shot_pooltool", "stars_angrybirds"):
        assert (out / f"{stem}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert (out / f"{stem}.pdf").read_bytes()[:5] == b"%PDF-"
        assert str(out / f"{stem}.png") in printed
    data = json.loads((out / "figures.json").read_text())
    assert data["vla_vs_wm"]["points"][0]["vla"] == report_of(dirs["vla"])["overall"]["mean"]["success_at"][9]
    assert main(["plot", str(dirs["kinetix"]), "--out", str(tmp_path / "none")]) == 2
    assert "none of the figures applies" in capsys.readouterr().err
    assert not (tmp_path / "none").exists()


def test_plot_all_returns_the_files(dirs, tmp_path):
    written = plot_all([report_of(dirs["pooltool"])], tmp_path)
    assert {p.name for p in written} == {"by_shot_pooltool.png", "by_shot_pooltool.pdf", "figures.json"}


def test_latex_is_the_report_table(dirs, capsys):
    reports = [report_of(dirs["vla"]), report_of(dirs["wm"])]
    header, rows = table(reports)
    latex = render_latex(reports)
    lines = latex.splitlines()
    assert lines[1].startswith(r"\begin{tabular}{ll") and lines[-1] == r"\end{tabular}"
    body = [line for line in lines if line.endswith(r" \\")]
    assert len(body) == 1 + len(rows)

    def plain(cell):
        return cell.replace(r"$\pm$", "±").replace(r"\_", "_").replace(r"$\star$", "*")

    assert [plain(c) for c in body[0][:-3].split(" & ")] == header
    assert [[plain(c) for c in line[:-3].split(" & ")] for line in body[1:]] == rows
    assert r"multi\_ball" in latex and "±" not in latex
    assert main(["report", "--latex", str(dirs["vla"]), str(dirs["wm"])]) == 0
    assert capsys.readouterr().out.strip() == latex
