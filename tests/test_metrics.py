"""The protocol's figures on hand-computed examples."""

import math

import pytest

from deepphy.config import RunConfig
from deepphy.envs import Task
from deepphy.metrics import figures as F
from deepphy.metrics.report import build_report, render_csv, render_markdown, render_text, table
from deepphy.runs.records import AttemptRecord, StepRecord


def rec(task, run, attempt, success=False, invalid=None, stars=None, steps=1, group=""):
    return AttemptRecord(
        env="iphyre", task=task, group=group, run=run, attempt=attempt, model="mock", format="vla", seed=0,
        steps=[StepRecord(step=i + 1, prompt="0123abcd", raw_output="x") for i in range(steps)],
        success=success, invalid_reason=invalid, stars=stars,
    )


def episode_records(task, run, solved_at=None, k=10, invalid_at=(), group=""):
    n = solved_at or k
    return [
        rec(task, run, a, success=(a == solved_at), invalid="bad" if a in invalid_at else None, group=group)
        for a in range(1, n + 1)
    ]


def test_pass_at_k_is_the_papers_solved_in_at_least_one_of_k_runs():
    """Hand-made: task a solved in 1 of 3 runs (at attempt 4), b in all 3, c in none. Pass@k as the
    paper's tables compute it, with the unbiased estimator 1 - C(n-c, k)/C(n, k)."""
    records = (episode_records("a", 0, None) + episode_records("a", 1, 4) + episode_records("a", 2, None)
               + [r for run in range(3) for r in episode_records("b", run, 1)]
               + [r for run in range(3) for r in episode_records("c", run, None)])
    eps = F.episodes(records, 10)
    assert F.pass_at(eps, 1, 3, 3) == pytest.approx((1 / 3 + 1 + 0) / 3)  # a: Pass@1 = 1/3
    assert F.pass_at(eps, 2, 3, 3) == pytest.approx((1 - 1 / 3 + 1) / 3)  # a: 1 - C(2,2)/C(3,2) = 2/3
    assert F.pass_at(eps, 3, 3, 3) == pytest.approx(2 / 3)  # a and b: solved in one of the 3 runs
    assert F.pass_at(eps, 4, 3, 3) is None  # fewer runs than k: no number invented
    # not Att.k: task a's success needed 4 attempts, so Att.1 misses it in every run
    assert F.success_at([e for e in eps if e.run == 1], 1, 3) == pytest.approx(1 / 3)
    tasks = [Task(env="iphyre", id=t) for t in "abc"]
    report = build_report(RunConfig(env="iphyre", runs=3), tasks, records, k_max=10)
    assert report.overall.pass_at == pytest.approx([4 / 9, 5 / 9, 2 / 3])
    header, rows = table([report])
    assert header[header.index("Att.10") + 2:][:3] == ["Pass@1", "Pass@2", "Pass@3"]  # beside Att.k, after AvgAtt
    assert rows[0][header.index("Pass@1"):header.index("Pass@3") + 1] == ["44.4", "55.6", "66.7"]
    text = render_text(report)
    assert "Pass@k: tasks solved within the attempt budget in at least one of k runs (%, the paper's Pass@k)" in text
    assert "the paper's set-up" in text.splitlines()[0]


def test_success_at_k_is_cumulative_and_hand_computed():
    # 4 tasks: solved at 1, at 3, at 10, never.
    records = (episode_records("a", 0, 1) + episode_records("b", 0, 3) + episode_records("c", 0, 10)
               + episode_records("d", 0, None))
    eps = F.episodes(records, 10)
    assert [F.success_at(eps, k) for k in (1, 2, 3, 9, 10)] == [0.25, 0.25, 0.5, 0.5, 0.75]
    assert F.average_attempts(eps) == pytest.approx((1 + 3 + 10) / 3)
    # Denominator is the task set, not the episodes seen so far.
    assert F.success_at(eps, 10, n_tasks=8) == 3 / 8


def test_average_attempts_none_when_nothing_solved():
    assert F.average_attempts(F.episodes(episode_records("a", 0, None), 10)) is None


def test_auccess_excludes_invalid_attempts():
    # Solved at attempt 3 after two invalid attempts: 1 valid attempt to solve -> s_k = 1 for all k.
    eps = F.episodes(episode_records("a", 0, 3, invalid_at=(1, 2)), 10)
    assert eps[0].invalid == 2
    assert F.auccess(eps) == pytest.approx(1.0)
    # Solved at the 2nd valid attempt: s_1 = 0, s_k = 1 for k >= 2.
    eps = F.episodes(episode_records("a", 0, 2), 10)
    w = [math.log(k + 1) - math.log(k) for k in range(1, 101)]
    assert F.auccess(eps) == pytest.approx(sum(w[1:]) / sum(w))


def test_stars_figures():
    records = [rec("a", 0, 1, success=True, stars=3), rec("b", 0, 1, success=True, stars=1),
               rec("c", 0, 1, success=False, stars=0), rec("d", 0, 1, success=True, stars=0)]
    s = F.stars(F.episodes(records, 10))
    assert (s.total, s.mean_all, s.mean_completed) == (4, 1.0, 4 / 3)
    assert s.levels_with == {0: 1, 1: 1, 2: 0, 3: 1}  # a level won without a star counts too


def test_success_within_steps():
    records = [rec("a", 0, 1, success=True, steps=2), rec("b", 0, 1, success=True, steps=7), rec("c", 0, 1, steps=15)]
    eps = F.episodes(records, 10)
    assert [F.success_within_steps(eps, k) for k in (1, 3, 6, 9, 15)] == [0, 1 / 3, 1 / 3, 2 / 3, 2 / 3]
    assert F.average_steps(eps) == 4.5


def test_mean_std_over_runs():
    ms = F.MeanStd.of([0.5, 0.7, None])
    assert ms.mean == pytest.approx(0.6) and ms.std == pytest.approx(math.sqrt(0.02))
    assert F.MeanStd.of([0.4]).std == 0.0
    assert F.MeanStd.of([None]).mean is None


def test_report_counts_add_up_per_run_and_group():
    tasks = [Task(env="iphyre", id=t, group=g) for t, g in [("a", "x"), ("b", "x"), ("c", "y")]]
    config = RunConfig(runs=2)
    records = (episode_records("a", 0, 2, group="x") + episode_records("b", 0, None, group="x")
               + episode_records("a", 1, 1, group="x") + episode_records("b", 1, 5, group="x")
               + episode_records("c", 1, None, group="y")[:4])  # c run 0 missing, run 1 unfinished
    report = build_report(config, tasks, records, k_max=10)
    runs = report.overall.per_run
    assert [(r.solved, r.unsolved, r.unfinished) for r in runs] == [(1, 1, 1), (2, 0, 1)]
    for r in runs:
        assert r.solved + r.unsolved + r.unfinished == r.tasks == 3
        assert all(a <= b for a, b in zip(r.success_at, r.success_at[1:]))
    assert report.overall.mean.success_at[0] == pytest.approx((0 + 1 / 3) / 2)
    assert report.groups["x"].per_run[1].success_at[4] == 1.0
    assert report.groups["y"].tasks == 1
    for render in (render_text, render_markdown, render_csv):
        out = render(report)
        assert "Att.10" in out and "16.7" in out  # mean Att.1 = 1/6


def test_combined_report_labels_rows_by_setting():
    tasks = [Task(env="kinetix", id=t, group=g) for t, g in [("a", "S"), ("b", "M")]]
    records = episode_records("a", 0, 1, group="S") + episode_records("b", 0, None, group="M")
    vla = build_report(RunConfig(env="iphyre", runs=1), tasks, records, k_max=10)
    wm = build_report(RunConfig(env="iphyre", runs=1, format="wm", env_options={"annotate": False}), tasks, [], k_max=10)
    header, rows = table([vla, wm])
    assert header[:3] == ["setting", "group", "n"]
    # groups in the environment's task order, not alphabetical
    assert [r[:2] for r in rows] == [["mock VLA", "all"], ["mock VLA", "S"], ["mock VLA", "M"],
                                     ["mock WM annotate=False", "all"], ["mock WM annotate=False", "S"],
                                     ["mock WM annotate=False", "M"]]
    assert rows[0][3] == "50.0" and rows[3][3] == "0.0"


# -- live metrics (what the metrics actor serves to progress views) ---------------------


def test_summaries_cross_to_the_metrics_actor_as_json_unchanged():
    from deepphy.actors.metrics_actor import MetricsImpl
    from deepphy.chat import Usage
    from deepphy.runs.records import ModelStats, summaries_from_json, summaries_json

    paid = rec("a", 0, 2, success=True, stars=3, steps=2).model_copy(
        update={"model_stats": ModelStats(usage=Usage(input_tokens=1200, output_tokens=30, cost_usd=0.0123), retries=2)})
    summaries = [rec("a", 0, 1, invalid="bad", group="S").summary(), paid.summary()]
    assert summaries_from_json(summaries_json(summaries)) == summaries
    actor = MetricsImpl(episodes_total=1, max_attempts=3)
    actor.add(summaries_json(summaries))
    snap = actor.snapshot()
    assert (snap["episodes_done"], snap["solved"], snap["attempts"]) == (1, 1, 2)
    with pytest.raises(ValueError):  # a batch is validated as it arrives
        actor.add(b'[{"task": "a"}]')


def test_live_metrics_snapshot_counts_finished_episodes_and_rates():
    from deepphy.metrics.live import LiveMetrics

    now = [100.0]
    live = LiveMetrics(episodes_total=4, max_attempts=3, clock=lambda: now[0])
    # Resumed from disk: task a solved at attempt 2 (finished), task b one failed attempt.
    live.add([rec("a", 0, 1).summary(), rec("a", 0, 2, success=True).summary(), rec("b", 0, 1).summary()],
             resumed=True)
    snap = live.snapshot()
    assert (snap["episodes_done"], snap["episodes_total"], snap["solved"], snap["attempts"]) == (1, 4, 1, 3)
    assert snap["new_attempts"] == 0 and snap["eta_s"] is None  # nothing finished in this session yet
    live.update(phase="compiling")
    now[0] = 400.0  # five minutes of compiling kernels: not part of any rate
    live.update(phase="running")
    now[0] = 410.0
    # This session: b fails twice more (out of attempts: finished, unsolved), c is solved at once.
    live.add([rec("b", 0, 2, invalid="bad").summary(), rec("b", 0, 3).summary()])
    live.add([rec("c", 0, 1, success=True, steps=4).summary()])
    live.update(in_flight=1, decisions=6, phase="running")
    snap = live.snapshot()
    assert (snap["episodes_done"], snap["solved"], snap["attempts"], snap["new_attempts"]) == (3, 2, 6, 3)
    assert snap["invalid_attempts"] == 1
    assert snap["attempts_per_s"] == pytest.approx(3 / 10)  # over the 10 s running, not the 310 s since start
    assert snap["eta_s"] == pytest.approx(1 * 10 / 2)  # 1 episode left at 2 finished per 10 s of running
    assert snap["elapsed_s"] == pytest.approx(310) and snap["running_s"] == pytest.approx(10)
    # An episode is counted once, however many of its attempts arrive.
    assert sum(1 for e in live.episodes.values() if e.finished) == 3


def test_progress_line_says_what_is_happening():
    from deepphy.metrics.live import LiveMetrics, format_progress

    now = [0.0]
    live = LiveMetrics(episodes_total=120, max_attempts=10, clock=lambda: now[0])
    assert format_progress(live.snapshot()).startswith("starting · episodes 0/120")
    live.update(phase="compiling", in_flight=0)
    now[0] = 3.0
    line = format_progress(live.snapshot())
    assert line.startswith("compiling · episodes 0/120 · solved 0 · attempts 0 · ")  # no rate before running
    assert "/s" not in line and "ETA" not in line and line.endswith("3s")
    live.update(phase="running", in_flight=64, decisions=200)
    live.add([rec(t, 0, 1, success=True).summary() for t in "abc"])
    now[0] = 75.0
    line = format_progress(live.snapshot())
    assert line.startswith("episodes 3/120 · in flight 64 · solved 3 · attempts 3 (0.042/s) · decisions 200 (2.8/s)")
    # 3 episodes finished and the 64 in flight at 197 of their at most 10 decisions each: 22.7
    # episodes' work in 72 s of running; 117 - 19.7 episodes' work left
    assert "ETA 5m09s" in line and line.endswith("1m15s")
    assert "% of finished" not in line
    assert "waiting" not in line
    # What a run that seems stuck is doing, named by its model (the metrics actor's run info):
    live.update(rate_limited=3, retrying=12, retry_wait_s=29.7, retry_reason="429", answering_slow=1, answer_wait_s=95)
    snap = {**live.snapshot(), "config": {"model": "gpt-4o"}}
    assert ("· gpt-4o: 12 requests waiting 30 s to retry (429), 3 for the rate limit, 1 for an answer for 95 s ·"
            in format_progress(snap))
    live.update(rate_limited=0, retrying=0, answering_slow=1, answer_wait_s=200)
    assert "· gpt-4o: 1 request waiting for an answer for 3m20s ·" in format_progress({**live.snapshot(),
                                                                                      "config": {"model": "gpt-4o"}})


def test_eta_counts_the_work_of_episodes_in_flight():
    """Pooltool as issue 26 saw it: every episode in flight at once, long episodes. Two
    finished after 50 s of running (16 decisions), the other ten are 79 decisions in."""
    from deepphy.metrics.live import LiveMetrics

    now = [0.0]
    live = LiveMetrics(episodes_total=12, max_attempts=1, max_steps=15, clock=lambda: now[0])
    live.update(phase="compiling")
    now[0] = 300.0  # five minutes compiling
    live.update(phase="running")
    now[0] = 350.0
    live.add([rec("a", 0, 1, success=True, steps=7).summary(), rec("b", 0, 1, success=True, steps=9).summary()])
    live.update(in_flight=10, decisions=95)
    snap = live.snapshot()
    done_work = 2 + 79 / 15  # episodes' worth of work in 50 s
    assert snap["eta_s"] == pytest.approx((10 - 79 / 15) * 50 / done_work)  # about 33 s, not 10 x 25 s
    assert snap["decisions_per_s"] == pytest.approx(95 / 50) and snap["attempts_per_s"] == pytest.approx(2 / 50)


def test_wm_predicted_outcomes_are_scored_against_the_attempt():
    def wm_rec(task, attempt, success, said):
        r = rec(task, 0, attempt, success=success, steps=len(said))
        for step, outcome in zip(r.steps, said):
            step.predicted_outcome = outcome
        return r

    records = [
        wm_rec("a", 1, False, ["success"]),  # predicted success, failed
        wm_rec("a", 2, True, ["success"]),  # right
        wm_rec("b", 1, False, ["failure", None, "success"]),  # right, unstated, wrong
    ]
    p = F.prediction_scores(records)
    assert (p.decisions, p.stated) == (5, 4)
    assert p.confusion == {"success": {"success": 1, "failure": 2}, "failure": {"success": 0, "failure": 1}}
    assert p.accuracy == pytest.approx(2 / 4) and p.predicted_success_failed == pytest.approx(2 / 3)
    tasks = [Task(env="iphyre", id="a"), Task(env="iphyre", id="b")]
    wm = build_report(RunConfig(runs=1, format="wm"), tasks, records, k_max=10)
    assert wm.overall.mean.wm.accuracy == pytest.approx(0.5)
    text = render_text(wm)
    assert "PredAcc" in text and "50.0" in text and "predicted success: 1 solved, 2 failed" in text
    assert "4 of 5 decisions stated one" in text  # counts are integers, not 4.0 of 5.0
    assert "wm" not in build_report(RunConfig(runs=1), tasks, records, k_max=10).to_json()["overall"]["mean"]


# -- the report's table -----------------------------------------------------------------


def shots(task, run, solved_at_shot=None, stars=None, group=""):
    """One Pooltool-like game: solved at that shot, or 15 shots without."""
    r = rec(task, run, 1, success=solved_at_shot is not None, steps=solved_at_shot or 15, stars=stars, group=group)
    return [r.model_copy(update={"env": "pooltool"})]


def test_single_attempt_environment_has_no_attempt_columns_and_integer_counts():
    tasks = [Task(env="pooltool", id=t) for t in "abc"]
    records = (shots("a", 0, 3) + shots("b", 0) + shots("c", 0)
               + shots("a", 1, 1) + shots("b", 1, 6) + shots("c", 1))
    report = build_report(RunConfig(env="pooltool", runs=2), tasks, records, k_max=1)
    header, rows = table([report])
    assert header == ["group", "n", "Success", "Shot1", "Shot3", "Shot6", "Shot9", "Shot12", "Shot15", "AvgShots",
                      "Solved", "Invalid"]  # no Att.1 / AvgAtt with one attempt
    assert rows[0][header.index("Success")] == "50.0±23.6"
    assert rows[0][header.index("Solved")] == "1.5±0.7" and rows[0][header.index("Invalid")] == "0"  # 1 and 2 solved
    one = build_report(RunConfig(env="pooltool", runs=1), tasks, records[:3], k_max=1)
    header, rows = table([one])
    assert rows[0][header.index("Solved")] == "1"  # a count, not 1.0
    text = render_text(one)
    assert text.splitlines()[0].startswith("Pooltool · mock VLA · 1 run(s)")  # the environment's title
    assert "Shotk: tasks solved within k shots (%)" in text and "Invalid: attempts that ended on an invalid action" in text
    assert "success rate (%)" not in text  # no header that puts counts under a percentage


def test_zero_star_wins_are_counted():
    tasks = [Task(env="cuttherope", id=t) for t in "ab"]
    records = [r.model_copy(update={"env": "cuttherope"}) for r in
               [rec("a", 0, 1, success=True, stars=0, steps=2), rec("b", 0, 1, success=True, stars=2, steps=4)]]
    report = build_report(RunConfig(env="cuttherope", runs=1), tasks, records, k_max=1)
    assert report.overall.mean.stars.levels_with == {"0": 1, "1": 0, "2": 1, "3": 0}
    header, rows = table([report])
    assert header[header.index("Stars"):] == ["Stars", "Stars/lvl", "Stars/won", "0*", "1*", "2*", "3*"]
    assert rows[0][header.index("0*")] == "1"


def test_runs_of_different_task_sets_are_flagged():
    from deepphy.metrics.report import mixed_task_sets

    two = [Task(env="iphyre", id=t) for t in "ab"]
    three = two + [Task(env="iphyre", id="c")]
    records = episode_records("a", 0, 1) + episode_records("b", 0, 2)
    a = build_report(RunConfig(runs=1), three, records + episode_records("c", 0, None), k_max=10)
    b = build_report(RunConfig(runs=1, format="wm"), two, records, k_max=10)
    same = build_report(RunConfig(runs=1, format="wm"), list(reversed(three)), records, k_max=10)
    assert mixed_task_sets([a, same]) is None  # the same tasks in another order
    note = mixed_task_sets([a, b])
    assert note and "n=3" in note and "n=2" in note
    assert f"note: {note}" in render_text([a, b])
    other = build_report(RunConfig(runs=1, format="wm"), [Task(env="iphyre", id=t) for t in "abd"], records, k_max=10)
    assert "n=3 each, other tasks" in mixed_task_sets([a, other])  # as many tasks, not the same ones


def test_text_table_stays_within_its_width_with_every_column(tmp_path):
    from dashboard_support import synthetic_run
    from deepphy.metrics.report import TEXT_WIDTH, report_of

    wide = [report_of(synthetic_run(tmp_path / f, env="angrybirds", limit=6, stars=True, fmt=f))
            for f in ("vla", "wm")]  # shots, stars, WM scores, retries, tokens and cost
    header, _ = table(wide)
    assert {"Shot8", "3*", "PredS->F", "Retries", "TokensIn", "Cost$"} <= set(header) and len(header) >= 24
    text = render_text(wide)
    assert max(len(line) for line in text.splitlines()) <= TEXT_WIDTH
    for h in header:  # every column is in one of the blocks
        assert h in text


def test_a_persons_time_is_reported_as_human_time_median_and_total():
    """A person's decision times (`timing.decision_s`) per decision and per finished task,
    median and in total, in the report and its table, labelled as a person's; a model's run
    has none (its latency is not a person's time)."""
    from deepphy.runs.records import Timing

    tasks = [Task(env="iphyre", id=t) for t in "abc"]
    records = [
        *(r.model_copy(update={"model": "human:ana", "timing": Timing(decision_s=[s])})
          for r, s in zip(episode_records("a", 0, 2), [10.0, 20.0])),  # task a: 30 s over two attempts
        rec("b", 0, 1, success=True).model_copy(update={"model": "human:ana", "timing": Timing(decision_s=[4.0])}),
        rec("c", 0, 1).model_copy(update={"model": "human:ana", "timing": Timing(decision_s=[100.0])}),  # unfinished
    ]
    person = build_report(RunConfig(model="human:ana", runs=1), tasks, records, k_max=10)
    assert person.to_json()["human_time"] == {"decisions": 4, "tasks": 2, "median_decision_s": 15.0, "median_task_s": 17.0,
                                              "total_s": 134.0}
    model = build_report(RunConfig(runs=1), tasks, [r.model_copy(update={"model": "mock"}) for r in records], k_max=10)
    assert model.human_time is None and "human_time" not in model.to_json()
    header, rows = table([person, model])
    at = header.index("Human s/dec")
    assert header[at:at + 3] == ["Human s/dec", "Human s/task", "Human min"]
    assert rows[0][at:at + 3] == ["15.0", "17.0", "2.2"] and rows[1][at:at + 3] == ["-", "-", "-"]
    assert "a person's time to decide" in render_text([person, model])


def test_a_partial_report_counts_finished_episodes_only_and_says_so():
    """A run in progress: the report counts an unfinished episode as unsolved and says the run
    is partial; the finished-only report (live views) leaves it out, and n says how many are done."""
    tasks = [Task(env="iphyre", id=t) for t in "abcd"]
    records = episode_records("a", 0, 1) + episode_records("b", 0, None) + [rec("c", 0, 1), rec("c", 0, 2)]
    full = build_report(RunConfig(runs=1), tasks, records, k_max=10)
    partial = build_report(RunConfig(runs=1), tasks, records, k_max=10, finished_only=True)
    assert full.overall.mean.success_at[9] == 0.25  # 1 of 4 tasks, c and d counted as unsolved
    assert partial.overall.mean.success_at[9] == 0.5  # 1 of the 2 finished (a solved, b failed)
    assert partial.partial and full.overall.finished == partial.overall.finished == 2
    assert table([full])[1][0][1] == "4x1 (2 done)"
    assert "partial, 2 of 4 episodes finished" in render_text(full)
    assert "over the finished episodes only" in render_text(partial)
