"""The environment contract (deepphy/envs/checker.py), over every registered environment,
and a test-only environment that gets the checks and the whole pipeline for free."""

from __future__ import annotations

import pytest

from deepphy.envs import get_spec, register, specs, unregister
from deepphy.envs.checker import check_env

BUILT_IN = sorted(specs())
COMPILED = {"kinetix"}  # traces its JAX programs in a fresh process (~45 s): with the slow tests, which CI runs


@pytest.mark.parametrize("name", [pytest.param(n, marks=[pytest.mark.slow] if n in COMPILED else [])
                                  for n in BUILT_IN])
def test_every_registered_environment_keeps_the_contract(name):
    assert check_env(get_spec(name)) == []


@pytest.fixture
def toy():
    import toy_env

    register(toy_env.SPEC)
    yield toy_env.SPEC
    unregister(toy_env.SPEC.name)


def test_a_new_environment_is_one_package_and_gets_the_checks(toy):
    assert toy.name in specs() and toy.name not in BUILT_IN
    assert check_env(toy, tasks_checked=10) == []


@pytest.mark.parametrize("broken, expected", [
    ("random_start", "reset is not deterministic"),
    ("unsafe_ids", "not filesystem-safe"),
    ("never_ends", "did not end within max_steps = 4"),
    ("bad_example", "example action does not parse"),
])
def test_a_broken_rule_is_reported(broken, expected):
    from toy_env import broken as B

    cls = {"random_start": B.RandomStart, "unsafe_ids": B.UnsafeIds, "never_ends": B.NeverEnds,
           "bad_example": B.BadExample}[broken]
    problems = check_env(cls.spec, fresh_process=False)
    assert any(expected in p for p in problems), problems


def test_the_toy_environment_runs_through_the_whole_pipeline(ray_cluster, toy, tmp_path):
    """Nothing outside its package names the toy: run, records, history and report work."""
    from deepphy.config import RunConfig, RuntimeOptions
    from deepphy.metrics.report import render_text, report_of
    from deepphy.runner import evaluate
    from deepphy.runs.store import read_records, stored_prompt_json

    config = RunConfig(env=toy.name, runs=2, seed=3)
    outcome = evaluate(config, tmp_path, RuntimeOptions(progress=False, env_workers=2))
    assert outcome.complete and outcome.episodes_total == 20
    records = read_records(tmp_path)
    assert {r.env for r in records} == {"toy_cart"} and max(r.attempt for r in records) <= 2
    assert any(len(r.steps) > 1 for r in records) and all(len(r.steps) <= 4 for r in records)
    assert all(r.truncated == (not r.success) for r in records)
    second = [r for r in records if r.attempt == 2]
    assert second, "some episode needed a second attempt"
    stored = stored_prompt_json(tmp_path, second[0].task, second[0].run, second[0].steps[0].prompt)
    prompt = "\n".join(p for m in stored for p in m["content"] if isinstance(p, str))  # its texts
    assert "Your previous 1 attempt(s) at this task failed" in prompt
    report = report_of(tmp_path)
    assert set(report.overall.mean.success_within_steps) == {"1", "2", "4"}
    assert "Push1" in render_text(report) and set(report.groups) == {"near", "far"}


def test_an_attempt_that_raises_is_isolated_logged_and_retried_on_resume(ray_cluster, tmp_path):
    """An environment bug in one episode: the others finish, the error (with its traceback)
    goes to errors.jsonl, not the terminal; the episode has no record, and a resume runs it."""
    import json

    from toy_env.broken import Explodes

    from deepphy.cli import run_summary
    from deepphy.config import RunConfig, RuntimeOptions
    from deepphy.plan import plan
    from deepphy.runner import evaluate
    from deepphy.runs.store import read_records

    register(Explodes.spec)
    try:
        trigger = tmp_path / "explode"
        trigger.touch()
        config = RunConfig(env="explodes", runs=1, seed=1, env_options={"explode_if_exists": str(trigger)})
        run_dir = tmp_path / "run"
        outcome = evaluate(config, run_dir, RuntimeOptions(progress=False, env_workers=1))
        assert not outcome.complete and outcome.episodes_done == 9 and len(outcome.errored) == 1
        assert "flag-05" in outcome.errored[0] and "RuntimeError" in outcome.errored[0]
        assert {r.task for r in read_records(run_dir)} == {f"flag-{f:02d}" for f in range(2, 12)} - {"flag-05"}
        # counted as the records were written, and what the directory says
        assert outcome.new_records == len(read_records(run_dir))
        the_plan = plan(config)
        assert (outcome.episodes_done, outcome.episodes_total) == (the_plan.episodes_done(read_records(run_dir)),
                                                                   the_plan.episodes_total)
        errors = [json.loads(line) for line in (run_dir / "errors.jsonl").read_text().splitlines()]
        assert [(e["task"], e["attempt"]) for e in errors] == [("flag-05", 1)]
        assert "the cart left the rail" in errors[0]["message"] and "Traceback" in errors[0]["traceback"]
        lines, status = run_summary(outcome)
        assert status == 1 and any("1 attempt(s) failed with an error" in line and "errors.jsonl" in line for line in lines)

        trigger.unlink()  # the bug is fixed: the resume runs the errored episode and only it
        again = evaluate(config, run_dir, RuntimeOptions(progress=False, env_workers=1))
        assert again.complete and not again.errored and again.new_records >= 1
        assert again.new_records == len(read_records(run_dir)) - outcome.new_records
        assert {r.task for r in read_records(run_dir) if r.task == "flag-05"} == {"flag-05"}
    finally:
        unregister("explodes")


def test_the_install_time_warm_up_covers_the_environments_that_compile():
    """`make setup` and the Docker image run `python -m deepphy.warm_up`, which fills the
    compile caches of the environments that have a warm-up of their own (and only those)."""
    from deepphy.warm_up import compiling_envs

    assert compiling_envs() == ["kinetix", "pooltool"]
