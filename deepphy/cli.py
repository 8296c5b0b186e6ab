"""The `deepphy` command: run, report, leaderboard, envs, show, watch, solve, dashboard, play, plot, export, repair.

This module imports only `os` and `sys` at its top: `--version`, `--help` and a bad flag
answer within Python's own start (a command imports what it needs when it runs), and `run`
says what it is doing before anything else is imported (`start_view`, deepphy/start_view.py).
"""

from __future__ import annotations

import os
import sys

TYPE_CHECKING = False  # typing's, without importing typing (which takes longer than Python's own start)
if TYPE_CHECKING:  # annotations only: both are imported where they are used
    import argparse
    from pathlib import Path

DEFAULT_OUT = "runs/demo"  # `deepphy run`'s run directory when --out is not given
SUITE_OUT = "runs/{suite}"  # `deepphy run --suite`'s root when --out is not given
PLAY_OUT = "runs/human-{player}-{env}"  # `deepphy play`'s run directory when --out is not given
SOLVER_COMMAND = "report"  # `deepphy solve --env E` with no solver arguments: its solvability report
PLAY_RUNS = 1  # a person plays each task once (a new run directory; a model's runs: RunConfig's)
# Fixed ports, so that a page's address stays the same from one start to the next; two of
# them, so that the dashboard and `deepphy play` can serve at once.
DASHBOARD_PORT = 8700
PLAY_PORT = 8710


class UserError(Exception):
    """Anything the user can fix. Printed as one line; exit status 2."""


class _NotAsked:
    """A command not named on the command line: listed by `--help`, its arguments not built."""

    def add_argument(self, *args, **kwargs) -> None:
        pass

    def add_mutually_exclusive_group(self, *args, **kwargs) -> "_NotAsked":
        return self

    def set_defaults(self, **kwargs) -> None:
        pass


def build_parser(argv: list[str] | None = None):
    """The command line's parser (argparse, imported here: not before a run's first line);
    given `argv`, with the arguments of its command only."""
    import argparse

    from deepphy.loopback import LOOPBACK_HOST
    from deepphy.start_view import LOG_S

    class Parser(argparse.ArgumentParser):
        def error(self, message: str) -> None:  # one line, not usage + error
            raise UserError(message)

    class Version(argparse.Action):
        """`--version`: the installed version, read only when asked for."""

        def __init__(self, option_strings, dest, **kwargs) -> None:
            super().__init__(option_strings, dest, nargs=0, help="show the installed version and exit")

        def __call__(self, parser, namespace, values, option_string=None) -> None:
            print_version()

    p = Parser(prog="deepphy", description="Evaluate vision-language models on interactive physics (DeepPHY).")
    p.add_argument("--version", action=Version)
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)
    # the command named (the first word that is no option: the top level has none with a value)
    named = next((a for a in argv if not a.startswith("-")), "") if argv is not None else None

    def command(name: str, **kwargs):
        parser = sub.add_parser(name, **kwargs)
        every = named is None or (named and named not in COMMANDS)  # all of them, or a misspelt one's error
        return parser if every or named == name else _NotAsked()

    run = command("run", help="run or resume an evaluation into a run directory")
    run.add_argument("--suite", metavar="NAME|FILE",
                     help="run every cell of a suite (`paper`, or a suite YAML file) into --out, one run directory "
                          "per cell, in one Ray runtime; the suite sets the environments, formats, runs and seed")
    run.add_argument("--env", help="environment (see `deepphy envs`); default iphyre")
    run.add_argument("--model", help="model name; default mock (random valid actions); with --suite, "
                     "comma-separated models or groups of the models file, e.g. paper, paper-open, "
                     "paper-closed (default: the suite's)")
    run.add_argument("--agent", metavar="PACKAGE.MODULE:FACTORY",
                     help="evaluate your own agent (docs/agents.md): the factory returns a deepphy.agent.Agent; the "
                          "run's model name is made of the entry point and --agent-arg's (with --suite: the suite's "
                          "agents)")
    run.add_argument("--agent-arg", action="append", metavar="KEY=VALUE",
                     help="keyword argument of the agent's factory, a JSON value or a string (repeatable)")
    run.add_argument("--models-file", help="YAML file of model endpoints (default: $DEEPPHY_MODELS_FILE, "
                     "else the shipped deepphy/models/models.yaml)")
    run.add_argument("--max-cost", type=float, metavar="USD",
                     help="stop once the run's model cost reaches this (resume with a higher budget); with "
                          "--suite, per cell")
    run.add_argument("--format", choices=["vla", "wm"], help="prompt format; default vla")
    run.add_argument("--runs", type=int, help="repetitions of every task; default 3")
    run.add_argument("--seed", type=int, help="seed of MOCK and of any sampling; default 0")
    run.add_argument("--out", help=f"run directory (with --suite: the suite root); default {DEFAULT_OUT} "
                     f"(with --suite: {SUITE_OUT.format(suite='<suite name>')})")
    run.add_argument("--tasks", help="task ids, separated by commas or spaces or lines, as `deepphy envs --tasks ENV` "
                                     "prints them (default: the evaluation set)")
    run.add_argument("--limit", type=int, help="only the first N tasks")
    run.add_argument("--max-attempts", type=int, help="attempts per task (default: the protocol's)")
    run.add_argument("--env-option", action="append", metavar="KEY=VALUE",
                     help="environment option, e.g. annotate=false (repeatable)")
    run.add_argument("--address", help="join an existing Ray cluster (default: start a local one)")
    run.add_argument("--in-process", action="store_true",
                     help="no Ray: the same scheduler, protocol and records with the environment and the model "
                          "client in this process (a quick check of a prompt or an endpoint)")
    run.add_argument("--num-cpus", type=int, help="CPUs of the local cluster; default 2")
    run.add_argument("--env-workers", type=int, help="environment worker actors (default: one per CPU; "
                     "--in-process: one thread)")
    run.add_argument("--env-resource", metavar="NAME",
                     help="place environment workers only on nodes with this custom Ray resource")
    run.add_argument("--max-in-flight", type=int, help="episodes in progress at once; default 256")
    run.add_argument("--no-progress", action="store_true", help="no live progress line")
    run.add_argument("--cell-lines", action="store_true",
                     help=f"with --suite: a progress line per running cell too (every {LOG_S:g} s), below the "
                          "suite's")
    run.add_argument("--dry-run", action="store_true",
                     help="print what the run would ask of its model (requests, images, input tokens measured on the "
                          "rendered prompts of its first tasks, cost, time at the rate limit) without calling it or "
                          "writing anything")

    rep = command("report", help="print the paper-style table of one or more run directories")
    rep.add_argument("run_dirs", nargs="+", metavar="RUN_DIR",
                     help="run directories of one environment (e.g. VLA, WM and MOCK) for one combined table")
    fmt = rep.add_mutually_exclusive_group()
    for flag in ("json", "csv", "markdown", "latex"):
        fmt.add_argument(f"--{flag}", action="store_true", help=f"print {flag} instead of a text table")

    board = command("leaderboard", help="the master table across run directories: a row per model x format, "
                           "a column group per environment")
    board.add_argument("paths", nargs="+", metavar="ROOT_OR_RUN_DIR",
                       help="run directories, or directories holding them (a suite root) up to three folders down")
    fmt = board.add_mutually_exclusive_group()
    for flag in ("json", "csv", "markdown", "latex"):
        fmt.add_argument(f"--{flag}", action="store_true", help=f"print {flag} instead of a text table")

    envs = command("envs", help="list environments and their task counts")
    envs.add_argument("--tasks", metavar="ENV", help="list the task ids of one environment, one a line (they paste "
                                                     "into `run --tasks`)")
    envs.add_argument("--groups", action="store_true", help="with --tasks: each id's group after a tab")

    watch = command("watch", help="stream the live progress of a run, or of every run on a Ray cluster")
    watch.add_argument("run_dir", nargs="?", metavar="RUN_DIR",
                       help="a run directory a `deepphy run` is writing now (a local run included): joins its Ray "
                            "cluster and follows that run until it ends")
    watch.add_argument("--address", help="a Ray cluster's address (as given to `run --address`): every run on it")
    watch.add_argument("--interval", type=float, default=2.0, help="seconds between snapshots; default %(default)g")
    watch.add_argument("--once", action="store_true", help="print one snapshot per live run and exit")
    watch.add_argument("--json", action="store_true", help="one JSON object per line (for dashboards)")

    dash = command("dashboard", help="live web dashboard of run directories (and of the runs on a Ray cluster)")
    dash.add_argument("run_dirs", nargs="*", metavar="RUN_DIR",
                      help="run directories, or directories of run directories (new ones join the page as they "
                           "appear; so does a run started later into a directory given here)")
    dash.add_argument("--address", help="also show every run live on this Ray cluster")
    dash.add_argument("--host", default=LOOPBACK_HOST, help="interface to listen on; default %(default)s (this machine only)")
    dash.add_argument("--port", type=int, default=DASHBOARD_PORT, help="port; default %(default)s, 0 picks a free one")

    play = command("play", help="play the tasks yourself in the browser, recorded as a run (model human:NAME)")
    play.add_argument("--env", help="environment (see `deepphy envs`); default: the one of the run directory given, "
                      "else iphyre")
    play.add_argument("--player", help="your name (letters, digits, . _ -): the run's model is human:NAME; "
                      "default: your login name")
    play.add_argument("--out", help="run directory (an existing one resumes; its options are kept); default "
                      f"{PLAY_OUT.format(player='<player>', env='<env>')}")
    play.add_argument("--tasks", help="task ids, separated by commas or spaces or lines (default: the evaluation set)")
    play.add_argument("--limit", type=int, help="only the first N tasks")
    play.add_argument("--runs", type=int, help=f"repetitions of every task; default {PLAY_RUNS}")
    play.add_argument("--max-attempts", type=int, help="attempts per task (default: the protocol's, as models get)")
    play.add_argument("--seed", type=int, help="seed (recorded with the run); default 0")
    play.add_argument("--env-option", action="append", default=[], metavar="KEY=VALUE",
                      help="environment option, e.g. annotate=false (repeatable)")
    play.add_argument("--host", default=LOOPBACK_HOST, help="interface to listen on; default %(default)s (this machine only)")
    play.add_argument("--port", type=int, default=PLAY_PORT, help="port; default %(default)s, 0 picks a free one")

    plot = command("plot", help="draw the paper's figures of one or more run directories (PNG and PDF)")
    plot.add_argument("run_dirs", nargs="+", metavar="RUN_DIR",
                      help="run directories, or directories holding them (a suite root) up to three folders down")
    plot.add_argument("--out", required=True, help="directory for the figures")

    repair = command("repair", help="set aside what a resume cannot go on from (docs/running.md, the run directory)")
    repair.add_argument("run_dir", metavar="RUN_DIR")

    export = command("export", help="write the decisions of run directories as a Parquet dataset")
    export.add_argument("run_dirs", nargs="+", metavar="RUN_DIR")
    export.add_argument("--out", required=True, help="dataset directory (Parquet, images, README.md)")
    export.add_argument("--layout", choices=["decisions", "chat"], default="decisions",
                        help="decisions: every field of each decision; chat: each decision as the conversation "
                             "the model saw plus its reply, images by path, for fine-tuning; default %(default)s")

    # --help is the solver's own once an environment is named: `solve --env phyre --help`
    solve = command("solve", add_help=False,
                           help="search an environment's tasks for solving actions (its solvability report)")
    solve.add_argument("-h", "--help", action="store_true",
                       help="this help; with --env, the help of that environment's solver (its commands and options)")
    solve.add_argument("--env", help="an environment with a solver (see `deepphy envs`)")
    solve.add_argument("solver_args", nargs=argparse.REMAINDER,
                       help=f"the solver's own arguments; default `{SOLVER_COMMAND}`, the solvability report")
    solve.set_defaults(usage=solve)

    show = command("show", help="write the images a model would see for one task")
    show.add_argument("--env", required=True)
    show.add_argument("--task", required=True)
    show.add_argument("--out", required=True, help="directory for the PNG files")
    show.add_argument("--env-option", action="append", default=[], metavar="KEY=VALUE")
    return p


MAX_OPTION_DEPTH = 16  # nesting of an --env-option's JSON value (no environment needs more than 2)


def _env_options(pairs: list[str], flag: str = "--env-option") -> dict[str, object]:
    import json

    options: dict[str, object] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise UserError(f"{flag} expects KEY=VALUE, got {pair[:80]!r}")
        try:
            options[key] = json.loads(value)
            too_deep = _depth(options[key]) > MAX_OPTION_DEPTH
        except json.JSONDecodeError:
            options[key], too_deep = value, False
        except RecursionError:  # deeper than Python's parser goes
            too_deep = True
        if too_deep:
            raise UserError(f"{flag} {key[:40]}: the value is nested deeper than {MAX_OPTION_DEPTH} levels")
    return options


def _depth(value: object) -> int:
    """How deeply lists and dicts nest in `value` (iterative: any depth)."""
    deepest, todo = 0, [(value, 1)]
    while todo:
        v, d = todo.pop()
        if isinstance(v, (list, dict)):
            deepest = max(deepest, d)
            todo += [(x, d + 1) for x in (v.values() if isinstance(v, dict) else v)]
    return deepest


SUITE_SETS = ("env", "format", "runs", "seed", "tasks", "limit", "max_attempts", "env_option")  # run options a suite sets


def _validated(make):
    """`make()`, a Pydantic model built from flags: a validation error as one line."""
    from pydantic import ValidationError

    from deepphy.messages import validation_message

    try:
        return make()
    except ValidationError as e:
        raise UserError(validation_message(e)) from None


def print_version() -> None:
    from deepphy import installed_version

    print(f"deepphy {installed_version()}")
    raise SystemExit(0)


def start_view(argv: list[str]):
    """`run`'s first line, said before anything but the standard library's `os` and `sys` is
    imported: on a terminal; a log hears of the checks only should they take a while, so an
    error stays the one line of a run that did not start. None for any other command."""
    if not argv or argv[0] != "run" or any(a in argv for a in ("--no-progress", "-h", "--help")):
        return None
    from deepphy.start_view import StartView

    view = StartView(sys.stderr)
    view.say("checking the suite" if "--suite" in argv else "checking the run", at_once=view.tty)
    return view


def cmd_run(args) -> int:
    from pathlib import Path

    from deepphy.config import RunConfig, RuntimeOptions

    view = getattr(args, "start_view", None)  # main's (start_view)
    if view and args.no_progress:  # asked for by an abbreviation (--no-prog)
        view.stop()
        view = None
    # a flag not given takes the model's default (the one place a default is said; the help repeats it,
    # and a test holds the two equal)
    given = {"address": args.address, "num_cpus": args.num_cpus, "env_workers": args.env_workers,
             "env_resource": args.env_resource, "max_in_flight": args.max_in_flight}
    runtime = _validated(lambda: RuntimeOptions(
        **{k: v for k, v in given.items() if v is not None}, in_process=args.in_process,
        progress=not args.no_progress, max_cost_usd=args.max_cost,
        # absolute: model workers may run in another directory
        models_file=str(Path(args.models_file).resolve()) if args.models_file else None,
    ))
    if args.in_process and args.num_cpus is not None:
        raise UserError("--in-process runs without Ray: it takes no --num-cpus")
    if args.agent_arg and not args.agent:
        raise UserError("--agent-arg needs --agent")
    if args.suite:
        if args.in_process:
            raise UserError("--in-process runs one run directory; a suite runs on Ray")
        return run_suite_command(args, runtime, view)
    model, agent = None, None  # neither given: RunConfig's model
    if args.agent:
        from deepphy.agent import load_agent

        if args.model:
            raise UserError("--agent and --model name two agents; a run directory holds one (several: --suite)")
        agent = load_agent(args.agent, _env_options(args.agent_arg or [], "--agent-arg"))
        model = agent.name
    elif args.model:
        from deepphy.agents import expand_models

        models = expand_models([m for m in args.model.split(",") if m], runtime.models_file)
        if len(models) != 1:
            raise UserError(f"several models need --suite (one run directory holds one model); --model "
                            f"{args.model[:60]} names {len(models)}")
        model = models[0]
    flags = {"env": args.env, "model": model, "format": args.format, "runs": args.runs, "seed": args.seed}
    config = _validated(lambda: RunConfig(
        **{k: v for k, v in flags.items() if v is not None}, tasks=_task_ids(args.tasks),
        limit=args.limit, max_attempts=args.max_attempts, env_options=_env_options(args.env_option or []),
        agent=agent,
    ))
    warn_retired([config.model] if agent is None else [], runtime.models_file)
    if args.dry_run:
        from deepphy.estimate import estimate, render

        if view:
            view.say("measuring the prompts of the first tasks", at_once=view.tty)
        table = render([estimate(config, runtime.models_file, max_in_flight=runtime.max_in_flight)])
        if view:
            view.stop()
        print(table)
        return 0
    from deepphy.runner import evaluate

    outcome = evaluate(config, args.out or DEFAULT_OUT, runtime, view=view)
    lines, status = run_summary(outcome)
    print(lines[0])
    for line in lines[1:]:
        print(line, file=sys.stdout if status == 0 else sys.stderr)
    return status


def run_suite_command(args: argparse.Namespace, runtime, view=None) -> int:
    from pathlib import Path

    from deepphy import suite as S

    given = [f"--{name.replace('_', '-')}" for name in SUITE_SETS if getattr(args, name) is not None]
    if given:
        raise UserError(f"{given[0]} is set by the suite; write it in a suite file instead")
    try:
        suite = S.load_suite(args.suite)
        if args.agent:  # replaces the suite's agents, as --model replaces its models
            suite = suite.model_copy(update={"agents": [
                S.SuiteAgent(entry=args.agent, args=_env_options(args.agent_arg or [], "--agent-arg"))]})
        models = S.suite_models(suite, [m for m in args.model.split(",") if m] if args.model else None,
                                runtime.models_file)
        warn_retired(models, runtime.models_file)
        root = Path(args.out or SUITE_OUT.format(suite=suite.name))
        if args.dry_run:
            from deepphy.estimate import estimate, render, render_by_model

            if view:
                view.say("measuring the prompts of the first tasks of every cell", at_once=view.tty)
            estimates = [estimate(c.config, runtime.models_file, label=c.dir, max_in_flight=runtime.max_in_flight)
                         for c in S.cells(suite, models)]
            if view:
                view.stop()
            print(render(estimates))
            if len({e.model for e in estimates}) > 1:
                print()
                print(render_by_model(estimates, retirement_status(models, runtime.models_file)))
            return 0
        outcomes = S.run_suite(suite, root, runtime, models, cell_lines=args.cell_lines, view=view)
    except S.SuiteError as e:
        raise UserError(str(e)) from None
    complete = sum(o.done == o.total for o in outcomes)
    for o in outcomes:
        print(f"  {o.cell.dir}: {o.done}/{o.total} episodes complete ({o.new_records} new attempt records)")
    print(f"suite {suite.name} in {root}: {complete}/{len(outcomes)} cells complete")
    if complete < len(outcomes):
        print("the suite is incomplete; run the same command again to resume it", file=sys.stderr)
        return 1
    print(f"next: deepphy leaderboard {root}")
    return 0


def warn_retired(models: list[str], models_file: str | None) -> None:
    """A line on stderr for each model its provider has retired or will retire, before Ray
    starts. A warning, not a refusal: the entry's date is the provider's public one, and an
    endpoint can outlive it (OpenAI sells capacity past a shutdown date; a base_url may point
    at another platform's schedule); a model that no longer answers costs nothing, its
    episodes are left unfinished with the provider's own error."""
    import datetime

    from deepphy.agents import retiring

    for c in retiring(models, models_file):
        print(f"deepphy: warning: {c.retirement.notice(c.name, c.model, datetime.date.today())}", file=sys.stderr)


def retirement_status(models: list[str], models_file: str | None) -> dict[str, str]:
    """model -> `retired DATE` / `retires DATE`, for the models that have a retirement."""
    import datetime

    from deepphy.agents import retiring

    return {c.name: c.retirement.status(datetime.date.today()) for c in retiring(models, models_file)}


def _task_ids(text: str | None) -> list[str] | None:
    """`--tasks`: ids separated by commas, spaces or lines (`deepphy envs --tasks ENV`'s output
    pastes in); None when none are given."""
    import re

    ids = [t for t in re.split(r"[,\s]+", text or "") if t]
    return ids or None


def run_summary(outcome) -> tuple[list[str], int]:
    """The lines `deepphy run` ends with, and its exit status (1 if anything is left to do).
    A run that recorded nothing leaves no directory it made (deepphy.runs.store): its lines
    never name one."""
    written = outcome.out.is_dir()
    counts = (f"{outcome.episodes_done}/{outcome.episodes_total} episodes complete, {outcome.new_records} new "
              "attempt records")
    lines = [f"run directory: {outcome.out} ({counts})" if written
             else f"nothing was recorded ({counts}); no run directory was written"]
    if outcome.errored:
        where = outcome.out / "errors.jsonl" if written else "the run directory, which was not kept"
        lines.append(f"{len(outcome.errored)} attempt(s) failed with an error (details and tracebacks in "
                     f"{where}); first: {outcome.errored[0][:200]}")
    lines += [f"unfinished: {line}" for line in outcome.unfinished[:10]]
    if not outcome.complete:
        lines.append(f"the run is incomplete; run the same command again to {'resume' if written else 'start'} it")
        return lines, 1
    lines.append(f"next: deepphy report {outcome.out}")
    return lines, 0


def cmd_report(args: argparse.Namespace) -> int:
    from deepphy.metrics.report import (
        mixed_task_sets, render_csv, render_json, render_latex, render_markdown, render_text, report_of,
    )

    reports = [report_of(run_dir) for run_dir in args.run_dirs]
    envs = sorted({r.env for r in reports})
    if len(envs) > 1:
        raise UserError(f"a report combines runs of one environment; got {', '.join(envs)}")
    render = (render_json if args.json else render_csv if args.csv else render_markdown if args.markdown
              else render_latex if args.latex else render_text)
    note = mixed_task_sets(reports)
    if note and render is not render_text:  # the text table says so itself
        print(f"deepphy: warning: {note}", file=sys.stderr)
    print(render(reports))
    return 0


def _board_reports(paths: list[Path], plain_runs: bool = False) -> dict[Path, dict]:
    """Each run directory's report, by resolved path: the runs given, those below the
    directories given (a suite root), and the cells of a suite manifest not started yet
    (as reports with no record). `plain_runs`: a path that holds no run is passed on as
    one (its reader says what is wrong), else refused here."""
    from deepphy.metrics.leaderboard import not_started
    from deepphy.metrics.report import report_of
    from deepphy.runs.discovery import runs_in

    found: dict[Path, Path] = {}
    waiting: dict[Path, dict] = {}
    for path in paths:
        if not plain_runs and not path.is_dir():
            raise UserError(f"{path} is not a directory")
        runs = runs_in(path)
        for run_dir in runs or ([path] if plain_runs else []):
            found.setdefault(run_dir.resolve(), run_dir)
        listed = not_started(path, set(found) | set(waiting))  # a bad manifest: RunDirError
        waiting.update(listed)
        if not runs and not plain_runs and not listed:
            raise UserError(f"{path} holds no run directory (none up to three folders down)")
    return {**{d: report_of(p) for d, p in found.items()}, **waiting}


def cmd_leaderboard(args: argparse.Namespace) -> int:
    from pathlib import Path

    from deepphy.metrics import leaderboard as L

    reports = _board_reports(list(map(Path, args.paths)))
    try:
        board = L.leaderboard(list(reports.values()), [_shown_path(str(d)) for d in reports])
    except L.LeaderboardError as e:
        raise UserError(str(e)) from None
    render = (L.render_json if args.json else L.render_csv if args.csv else L.render_markdown if args.markdown
              else L.render_latex if args.latex else L.render_text)
    for note in board.notes if render is not L.render_text else ():  # the text table says so itself
        print(f"deepphy: warning: {note}", file=sys.stderr)
    print(render(board))
    return 0


def cmd_envs(args: argparse.Namespace) -> int:
    from collections import Counter

    from deepphy.envs import get_spec, specs

    if args.tasks:
        cls = get_spec(args.tasks).load()
        for t in cls.tasks(cls.Options()):
            print(f"{t.id}\t{t.group}" if args.groups else t.id)
        return 0
    print(f"{'env':10} {'title':12} {'tasks':>6}  {'planning':11} {'K':>3} {'steps':>5}  groups")
    for name, spec in specs().items():
        cls = spec.load()
        tasks = cls.tasks(cls.Options())
        groups = Counter(t.group for t in tasks if t.group)
        print(f"{name:10} {spec.title:12} {len(tasks):6d}  {spec.planning.value:11} {spec.max_attempts:3d} "
              f"{spec.max_steps:5d}  {', '.join(f'{g} {n}' for g, n in groups.items())}")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from pathlib import Path

    from deepphy.envs import get_spec
    from deepphy.plan import env_options

    spec = get_spec(args.env)
    cls, options = spec.load(), env_options(spec, _env_options(args.env_option))
    tasks = {t.id: t for t in cls.tasks(options)}
    if args.task not in tasks:
        raise UserError(f"unknown {args.env} task {args.task!r}; see `deepphy envs --tasks {args.env}`")
    observation = cls(options).reset(tasks[args.task])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for image in observation.images:
        path = out / f"{args.env}_{args.task}_{image.name}.png"
        path.write_bytes(image.png)
        print(f"{path}  ({image.caption})")
    if observation.text:
        (out / f"{args.env}_{args.task}_state.txt").write_text(observation.text + "\n")
        print(f"{out / f'{args.env}_{args.task}_state.txt'}  (text state)")
    return 0


def cmd_solve(args: argparse.Namespace) -> int:
    from deepphy.envs import get_spec, specs

    with_solver = ", ".join(n for n, s in specs().items() if s.solver) or "none"
    if args.env is None:
        if args.help:
            args.usage.print_help()
            print(f"\nenvironments with a solver: {with_solver}")
            return 0
        raise UserError(f"solve needs --env (environments with a solver: {with_solver})")
    solver = get_spec(args.env).load_solver()
    if solver is None:
        raise UserError(f"{args.env} has no solver (environments with one: {with_solver})")
    try:
        return solver(["--help"] if args.help else args.solver_args or [SOLVER_COMMAND])
    except SystemExit as e:  # argparse in the solver: --help (0), or a usage error it has printed (2)
        return e.code if isinstance(e.code, int) else 2


def cmd_watch(args: argparse.Namespace) -> int:
    import json
    import os
    import time

    from deepphy.runs.status import read_status

    only = None  # the run id followed, when a run directory is given
    address = args.address
    if args.run_dir:
        from deepphy.runs.store import read_config

        read_config(args.run_dir)  # not a run directory: a clear error
        status = read_status(args.run_dir)
        if status is None or not status.ray_address:
            raise UserError(f"no deepphy run is writing {args.run_dir} now (`deepphy report {args.run_dir}` shows "
                            "what it holds)")
        only, address = status.run_id, address or status.ray_address
        if status.ray_auth and "RAY_AUTH_MODE" not in os.environ:  # a local run's Ray wants its token
            os.environ["RAY_AUTH_MODE"] = status.ray_auth
    elif not address:
        raise UserError("give a run directory being written, or --address of a Ray cluster")

    from deepphy.config import RuntimeOptions
    from deepphy.metrics.live import format_progress
    from deepphy.ray_connect import ensure_ray
    from deepphy.runs.discovery import live_snapshots

    ensure_ray(RuntimeOptions(address=address))
    seen = False
    while True:
        live = live_snapshots(only)
        for run_id, snap in live.items():
            seen = True
            print(json.dumps({"run_id": run_id, **snap}) if args.json
                  else f"[{_shown_path(snap.get('run_dir'))} {run_id}] {format_progress(snap)}", flush=True)
        if args.once or (only and not live and read_status(args.run_dir) is None):
            if not seen:
                print(f"no deepphy run is live {'in ' + args.run_dir if only else 'on this cluster'}", file=sys.stderr)
            elif only and not live:
                print(f"the run writing {args.run_dir} has ended (`deepphy report {args.run_dir}`)", file=sys.stderr)
            return 0 if seen else 1
        time.sleep(args.interval)


def _shown_path(path: str | None) -> str:
    """A run directory as a person would type it: relative to here when it is below here."""
    if not path:
        return "?"
    import os

    rel = os.path.relpath(path)
    return path if rel.startswith("..") else rel


def _check_port(port: int) -> None:
    """`--port` of the dashboard and of `deepphy play`."""
    if not 0 <= port <= 65535:
        raise UserError(f"--port must be 0..65535, got {port}")


def _token_note(host: str, whoever_has_it: str) -> None:
    """The line a page served beyond loopback adds to its URL (which carries its token)."""
    print(f"note: listening on {host}: the page asks for the token in this URL; whoever has the URL "
          f"{whoever_has_it}", file=sys.stderr)


def cmd_dashboard(args: argparse.Namespace) -> int:
    import asyncio
    from pathlib import Path

    from deepphy import webguard
    from deepphy.dashboard.server import TOKEN_ENV, Dashboard, serve
    from deepphy.dashboard.source import RunSource
    from deepphy.runs.discovery import is_run_dir, runs_in

    if not args.run_dirs and not args.address:
        raise UserError("give run directories and/or --address of a Ray cluster")
    _check_port(args.port)
    paths, roots = [], []
    for arg in map(Path, args.run_dirs):
        if arg.exists() and not arg.is_dir():
            raise UserError(f"{arg} is not a directory")
        if not is_run_dir(arg):  # a directory of runs, or one a run is about to be written to
            roots.append(arg)
            if not runs_in(arg):
                print(f"deepphy: {arg} holds no run yet; the page shows it once one appears", file=sys.stderr)
        paths += [p.resolve() for p in runs_in(arg)]
    sources = [RunSource(p) for p in dict.fromkeys(paths)]  # a bad run directory: a clear error now
    if args.address:
        from deepphy.config import RuntimeOptions
        from deepphy.ray_connect import ensure_ray

        ensure_ray(RuntimeOptions(address=args.address))  # no cluster there: a clear error now, not a page that waits

    # Beyond loopback, every request must carry a token (printed with the URL).
    token = webguard.token_for(args.host, TOKEN_ENV)

    def announce(url: str) -> None:
        print(f"dashboard: {url}  (Ctrl-C to stop)", flush=True)
        if token:
            _token_note(args.host, "can read these runs' prompts, replies and frames")

    try:
        asyncio.run(serve(Dashboard(sources, roots, address=args.address), args.host, args.port, announce, token))
    except OSError as e:
        raise UserError(f"cannot listen on {args.host}:{args.port}: {e.strerror or e}") from None
    except KeyboardInterrupt:
        pass
    return 0


def cmd_play(args: argparse.Namespace) -> int:
    import asyncio
    import getpass
    from pathlib import Path

    from pydantic import ValidationError

    from deepphy.config import RunConfig
    from deepphy.messages import validation_message
    from deepphy.play import background
    from deepphy.play.human import HUMAN_PREFIX, player_model
    from deepphy import webguard
    from deepphy.play.server import TOKEN_ENV, serve
    from deepphy.play.session import PlaySession
    from deepphy.runs.store import CONFIG, read_config

    _check_port(args.port)
    asked = {"env": args.env, "runs": args.runs, "seed": args.seed, "limit": args.limit,
             "max_attempts": args.max_attempts, "tasks": _task_ids(args.tasks),
             "env_options": _env_options(args.env_option) or None}
    asked = {k: v for k, v in asked.items() if v is not None}
    stored = read_config(args.out) if args.out and (Path(args.out) / CONFIG).exists() else None
    try:
        if stored is not None:  # resume: what is not asked for is kept
            if not stored.model.startswith(HUMAN_PREFIX):
                raise UserError(f"{args.out} holds a run of the model {stored.model}, not a person's")
            player = args.player or stored.model.removeprefix(HUMAN_PREFIX)
            config = RunConfig(**{**stored.model_dump(), **asked, "model": player_model(player)})
        else:
            player = args.player or getpass.getuser()
            config = RunConfig(**{"runs": PLAY_RUNS, **asked, "model": player_model(player)})
    except ValidationError as e:
        raise UserError(validation_message(e)) from None
    except ValueError as e:
        raise UserError(str(e)) from None
    out = Path(args.out or PLAY_OUT.format(player=player, env=config.env))
    session = PlaySession(config, out)
    token = webguard.token_for(args.host, TOKEN_ENV)  # beyond loopback, every request must carry it

    def announce(url: str) -> None:
        print(f"play: {url}  (open it in a browser; Ctrl-C stops, the same command resumes)", flush=True)
        if token:
            _token_note(args.host, "can play in your name")

    def done(progress: dict) -> None:
        print(f"play: {progress['episodes_done']}/{progress['episodes_total']} episodes played, {progress['solved']} "
              f"solved -> {out} (`deepphy report {out}`); the page stays up for replays (Ctrl-C to stop)", flush=True)

    try:
        asyncio.run(serve(session, args.host, args.port, announce, done, token))
    except OSError as e:
        raise UserError(f"cannot listen on {args.host}:{args.port}: {e.strerror or e} (--port 0 picks a free one)") \
            from None
    except KeyboardInterrupt:
        session.close()
        if background.still_working():
            # A thread inside a simulator's C++ (Kinetix compiling, say) aborts Python's exit
            # ("terminate called ..."): the play is saved, so leave without finalizing.
            print(INTERRUPTED, file=sys.stderr, flush=True)
            sys.stdout.flush()
            os._exit(130)
        raise
    finally:
        session.close()
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    from pathlib import Path

    from deepphy.metrics.leaderboard import LeaderboardError, leaderboard
    from deepphy.metrics.report import mixed_task_sets
    from deepphy.plots import plot_all
    from deepphy.runs.discovery import is_run_dir

    # a suite root (or any directory of runs) stands for its run directories
    by_dir = _board_reports(list(map(Path, args.run_dirs)), plain_runs=True)
    reports = [r for d, r in by_dir.items() if is_run_dir(d)]  # a cell not started is on the board only
    for env in dict.fromkeys(r.env for r in reports):
        note = mixed_task_sets([r for r in reports if r.env == env])
        if note:
            print(f"deepphy: warning: {note}", file=sys.stderr)
    try:
        board = leaderboard(list(by_dir.values()), [_shown_path(str(d)) for d in by_dir])
    except LeaderboardError as e:  # e.g. two runs of one setting: the other figures still apply
        print(f"deepphy: warning: no leaderboard figure: {e}", file=sys.stderr)
        board = None
    written = plot_all(reports, args.out, board)
    if not written:
        raise UserError("none of the figures applies to these run directories")
    import json

    drawn = json.loads((Path(args.out) / "figures.json").read_text())
    for note in (n for figure in drawn.values() if isinstance(figure, dict) for n in figure.get("notes", [])):
        print(f"deepphy: note: {note}", file=sys.stderr)
    for path in written:
        print(path)
    return 0


def cmd_repair(args: argparse.Namespace) -> int:
    from deepphy.plan import plan
    from deepphy.runs.store import read_config, repair

    done = repair(args.run_dir, plan(read_config(args.run_dir)).k_max)
    if not done.dropped_lines:
        print(f"{args.run_dir}: nothing to repair")
        return 0
    print(f"{args.run_dir}: set aside {done.dropped_lines} line(s) of attempts.jsonl"
          + (f" ({done.unreadable} not valid records)" if done.unreadable else "")
          + f"; the old log is kept as {done.backup.name}")
    for p in done.episodes[:10]:
        print(f"  task {p.task} run {p.run}: from attempt {p.attempt} ({p.what})")
    if len(done.episodes) > 10:
        print(f"  ... and {len(done.episodes) - 10} more episode(s)")
    print("the next `deepphy run` with the run's options runs them again")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from deepphy.export import export

    summary = export(args.run_dirs, args.out, args.layout)
    print(f"{summary.rows} decisions from {summary.runs} run director{'y' if summary.runs == 1 else 'ies'}, "
          f"{summary.images} images -> {summary.out}")
    return 0


INTERRUPTED = "deepphy: interrupted; run the same command again to resume"

COMMANDS = {"run": cmd_run, "report": cmd_report, "leaderboard": cmd_leaderboard, "envs": cmd_envs, "show": cmd_show,
            "watch": cmd_watch, "solve": cmd_solve, "dashboard": cmd_dashboard, "play": cmd_play, "plot": cmd_plot,
            "export": cmd_export, "repair": cmd_repair}


# The errors a user can fix, besides UserError, by the module that defines them: one line,
# exit status 2. Looked up among the modules loaded by then: an error of a module never
# imported cannot have been raised, and `--version`, `--help` and a bad flag import none.
USER_ERRORS = {
    "deepphy.plan": ("ConfigError",),
    "deepphy.ray_connect": ("ClusterUnavailable",),
    "deepphy.runs.store": ("RunDirError",),
    "deepphy.envs": ("UnknownEnvironment",),
    "deepphy.envs.shortcuts": ("UnknownShortcut",),
    "deepphy.agent": ("AgentError",),
    "deepphy.models": ("UnknownModel",),
    "deepphy.models.base": ("AccessDenied", "RequestRejected"),
    "deepphy.models.config": ("MissingKey", "ModelsFileError"),
    "deepphy.local_ray": ("RayStartFailed",),
}


def user_errors() -> tuple[type[BaseException], ...]:
    loaded = [(sys.modules[m], names) for m, names in USER_ERRORS.items() if m in sys.modules]
    return (UserError, *(getattr(module, name) for module, names in loaded for name in names))


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv == ["--version"]:  # answered before argparse is imported (its import is half the work)
        print_version()
    view = start_view(argv)
    try:
        try:
            args = build_parser(argv).parse_args(argv)
            if view:
                view.repeat()
            args.start_view = view
            from deepphy.ray_env import quiet_environment

            quiet_environment()
            return COMMANDS[args.command](args)
        finally:  # before any error line: on a terminal the view's line is cleared
            if view:
                view.stop()
    except BrokenPipeError:  # output piped into `head` and friends
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        print(INTERRUPTED, file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - a user's error in one line; a bug: one line, the traceback in a file
        if isinstance(e, user_errors()):
            from deepphy.messages import one_line

            print(f"deepphy: error: {one_line(str(e))}", file=sys.stderr)
            return 2
        return _crashed(e)


def _crashed(error: Exception) -> int:
    import tempfile
    import traceback

    text = "".join(traceback.format_exception(error))
    try:
        fd, path = tempfile.mkstemp(prefix="deepphy-error-", suffix=".txt")
        with os.fdopen(fd, "w") as f:
            f.write(f"deepphy {' '.join(sys.argv[1:])}\n{text}")
        where = f"the traceback is in {path}"
    except OSError:
        where = "no file could be written for the traceback"
    from deepphy.messages import one_line

    message = one_line(str(error))[:300] or "(no message)"
    print(f"deepphy: error: unexpected {type(error).__name__}: {message} ({where}; please report it)", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
