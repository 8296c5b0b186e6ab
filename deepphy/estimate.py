"""What a run will ask of its model before it asks (`deepphy run --dry-run`): requests,
images and input tokens per request measured on the actual rendered prompts, bounds for
the whole run, its cost at the models file's prices, and its time at the endpoint's
request rate limit. No model is called; nothing is written.

The prompts are measured, not guessed: for each of the first `sample` tasks the
environment is reset and stepped once (a MOCK action, in this process) and the real
prompt builder renders the first request, a request after one failed attempt and a
request after one earlier decision; the differences are what every further attempt or
decision adds. The bounds assume every episode uses all K attempts and all decisions of
each (a model that solves tasks asks less).

The expected number of requests is what the reference random baseline asks: MOCK (the
run's seed, run 0) plays the same sampled tasks in-process through the real attempt
protocol, and its mean requests per episode times the run's episodes is the figure. A
model that solves more tasks than random asks fewer (down to the lower bound), one that
never solves asks the upper bound; for most cells the two are close, as random solves
little.

The times are what the endpoint's limiter lets through (`limit_seconds`), under every limit
it enforces at once: requests/min (paced), tokens/min (each request reserving its input and
max_tokens until it is answered, then its actual use), max_concurrent (and the run's
episodes in flight). `time>=`: every request, answered at once with no output (the least
the limits allow); `time~`: the expected requests, each reply taking REPLY_S and using
max_tokens. A suite runs all its endpoints at once, so its figure is the slowest endpoint's
sum.

Image tokens follow each provider's published rule (its `ProviderSpec.image_tokens`, with
its source and the date it was read); text tokens are estimated as characters / 4
(CHARS_PER_TOKEN), the usual rule of thumb for English with these tokenizers: the figure is
an estimate, not a count.
"""

from __future__ import annotations

import asyncio
import math
import struct
from dataclasses import dataclass, replace

from deepphy.agent import declared
from deepphy.agents import MockModel, endpoint_config
from deepphy.chat import Image, ImagePart, Message, TextPart
from deepphy.config import RunConfig, RuntimeOptions
from deepphy.envs.base import Planning
from deepphy.models.config import ModelConfig, RateLimits
from deepphy.models.limiter import WINDOW_S
from deepphy.plan import RunPlan, plan
from deepphy.prompts import PastAttempt, PastStep, build_messages
from deepphy.protocol import LocalEnv, MemoryArtifacts, run_episode
from deepphy.seeding import seeded_rng

CHARS_PER_TOKEN = 4  # text tokens ~ characters / 4 (OpenAI's and Anthropic's rule of thumb)
DEFAULT_SAMPLE = 3  # tasks per run whose prompts are rendered and measured
REPLY_S = 10.0  # time~: how long a reply is assumed to take (a typical VLM answer; no model is called)


def png_size(image: Image) -> tuple[int, int]:
    """(width, height) from the PNG header."""
    data = image.load()[:24]
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"image {image.name!r} is not a PNG")
    return struct.unpack(">II", data[16:24])


@dataclass(frozen=True)
class PromptSize:
    chars: int
    images: list[tuple[int, int]]

    def __sub__(self, other: "PromptSize") -> "PromptSize":
        return PromptSize(self.chars - other.chars, self.images[len(other.images):])


def prompt_size(messages: list[Message]) -> PromptSize:
    chars = sum(len(p.text) for m in messages for p in m.content if isinstance(p, TextPart))
    return PromptSize(chars, [png_size(p.image) for m in messages for p in m.content if isinstance(p, ImagePart)])


@dataclass
class CellEstimate:
    """One run's bounds. Tokens and cost are None for a random baseline (no model)."""

    label: str
    episodes: int
    attempts_max: int
    requests_min: int  # one decision per episode
    requests_max: int  # every attempt, every decision
    images_first: float  # in the first request of an episode (mean over the sampled tasks)
    images_max: int  # in the largest request, after the endpoint's max_images
    max_images: int | None
    tokens_first: float | None  # input tokens of the first request
    tokens_max: float | None  # input tokens of the largest request
    input_tokens_max: float | None  # over the whole run
    output_tokens_max: int | None  # every request answering max_tokens
    cost_input_max: float | None  # USD; None where the price is unknown
    cost_output_max: float | None
    price_known: bool
    rate_limit_min: float | None  # time>=: minutes the endpoint's limits take for requests_max at the least
    sampled: int
    requests_expected: float = 0.0  # what the reference random baseline asks (see the module)
    endpoint: str | None = None  # the endpoint's limiter key (cells of one endpoint share its limit)
    model: str = ""  # the agent's name (a suite's per-model summary groups by it)
    note: str | None = None  # a user's agent whose model cost cannot be bounded: why (one line)
    expected_min: float | None = None  # time~: minutes the limits take for requests_expected (see the module)


def limit_seconds(limits: RateLimits, requests: float, input_tokens: float, max_tokens: int, reply_s: float,
                  output_tokens: float, in_flight: int) -> float:
    """Seconds an endpoint's limiter (deepphy.models.limiter) takes to grant `requests`
    requests of `input_tokens` input tokens in all, each holding its input + `max_tokens`
    while its reply (`reply_s` long, `output_tokens` used) is awaited, at most `in_flight` of
    them at once (the run's episodes in progress): the slowest of its limits. Each is its
    steady pace, less what the first window lets through at once; tests/test_estimate.py
    checks them against the limiter itself on a virtual clock."""
    if requests <= 0:
        return 0.0
    window = WINDOW_S + limits.window_margin_s
    reserved = input_tokens / requests + max_tokens  # what a grant needs room for
    used = input_tokens / requests + output_tokens  # what it counts once answered
    seconds = [0.0]
    if limits.requests_per_min:  # paced: `burst` at once, then one every window / rpm
        seconds.append(max(0.0, requests - limits.burst) * window / limits.requests_per_min)
    if limits.tokens_per_min:  # a grant needs what the window holds plus `reserved` to fit in T
        held = min(reply_s, window)
        per_request = (held * reserved + (window - held) * used) / window  # what a request holds of a window
        room = limits.tokens_per_min - reserved  # what the window may hold when a request is granted
        per_window = math.floor(room / per_request) + 1 if room >= 0 else 1  # over the limit: alone in a window
        seconds.append(max(0.0, requests - per_window) * window / per_window)
    if reply_s > 0:
        seconds.append(requests * reply_s / min(limits.max_concurrent or in_flight, in_flight))
    return max(seconds)


@dataclass(frozen=True)
class TaskPrompts:
    """One task's measured prompts: the first request, and what one failed attempt and
    one earlier decision add to it."""

    first: PromptSize
    per_attempt: PromptSize
    per_step: PromptSize


_measured: dict[str, list[TaskPrompts]] = {}  # the prompts do not depend on the model: a suite measures once
_baseline: dict[str, list[int]] = {}  # nor does the reference baseline's play


def _key(config: RunConfig, sample: int) -> str:
    return config.model_copy(update={"model": "", "runs": 1}).model_dump_json() + f"/{sample}"


def baseline_requests(plan: RunPlan, sample: int = DEFAULT_SAMPLE) -> list[int]:
    """Requests MOCK makes in an episode of each of the plan's first `sample` tasks (its
    run 0 at the config's seed), played in-process through `deepphy.protocol.run_episode`."""
    key = _key(plan.config, sample)
    if key in _baseline:
        return _baseline[key]
    env = LocalEnv(plan.make_env())
    mock, prompt, artifacts = MockModel(), plan.prompt(), MemoryArtifacts()
    config = plan.config.model_copy(update={"model": "mock"})

    async def episode(task) -> int:
        records = await run_episode(plan.spec, prompt, config, task, 0, plan.k_max, env, mock, artifacts)
        return sum(r.summary().decisions for r in records)

    _baseline[key] = [asyncio.run(episode(task)) for task in plan.tasks[:sample]]
    return _baseline[key]


def measure(plan: RunPlan, sample: int = DEFAULT_SAMPLE) -> list[TaskPrompts]:
    """Render and measure the prompts of the plan's first `sample` tasks (see the module)."""
    config = plan.config
    key = _key(config, sample)
    if key in _measured:
        return _measured[key]
    spec, env, prompt = plan.spec, plan.make_env(), plan.prompt()
    out = []
    for task in plan.tasks[:sample]:
        observation = env.reset(task)
        first = prompt_size(build_messages(prompt, config.format, task, observation, []))
        space = observation.action_space
        text = space.reference_reply(seeded_rng("estimate", config.seed, config.env, task.id), [])
        try:
            result = env.step(space.parse(text))
            frames, feedback = list(result.key_frames), result.feedback
        except ValueError:  # the baseline's refusal (PHYRE's one in ten): no frames to show
            frames, feedback = [], "invalid"
        if spec.planning is Planning.ON_THE_FLY:
            frames = frames[-1:]  # as deepphy.protocol.past_attempt shows an earlier attempt
        past = PastAttempt(attempt=1, actions=[text], outcome=f"failed. {feedback}", key_frames=frames)
        after_attempt = prompt_size(build_messages(prompt, config.format, task, observation, [past]))
        after_step = prompt_size(build_messages(prompt, config.format, task, observation, [], [
            PastStep(step=1, action=text, feedback=feedback, frame=observation.images[0])]))
        out.append(TaskPrompts(first, after_attempt - first, after_step - first))
    _measured[key] = out
    return out


def estimate(config: RunConfig, models_file: str | None = None, sample: int = DEFAULT_SAMPLE,
             label: str | None = None, max_in_flight: int | None = None) -> CellEstimate:
    """Measure the prompts of `config`'s first `sample` tasks and bound the whole run
    (`max_in_flight`: the run's episodes in progress at once; default the runtime's)."""
    if config.agent is not None:
        return estimate_agent(config, models_file, sample, label)
    the_plan = plan(config)
    spec, tasks, k_max = the_plan.spec, the_plan.tasks, the_plan.k_max
    endpoint: ModelConfig | None = endpoint_config(config.model, models_file)
    measured = measure(the_plan, sample)
    recent_cap = the_plan.prompt().recent_steps_shown
    steps = spec.max_steps
    firsts = [m.first for m in measured]
    per_attempt = [m.per_attempt for m in measured]
    per_step = [m.per_step for m in measured]

    cap = endpoint.resolved_max_images if endpoint is not None else None
    rule = endpoint.spec.image_tokens if endpoint is not None else None

    def tokens(size: PromptSize, n_images: int) -> float:
        """Input tokens of a request of this size, `n_images` of its images sent."""
        image_tokens = [rule(w, h) for w, h in size.images] or [0]
        return size.chars / CHARS_PER_TOKEN + n_images * sum(image_tokens) / len(image_tokens)

    # Every request of an episode that uses all K attempts and all decisions, per sampled task.
    totals, largest, largest_images = [], [], 0
    for first, attempt, step in zip(firsts, per_attempt, per_step):
        total = 0.0
        for a in range(k_max):
            for s in range(steps):
                shown = min(s, recent_cap)
                size = PromptSize(first.chars + a * attempt.chars + shown * step.chars,
                                  first.images + a * attempt.images + shown * step.images)
                n = len(size.images) if cap is None else min(cap, len(size.images))
                largest_images = max(largest_images, n)
                if rule is not None:
                    t = tokens(size, n)
                    total += t
                    largest.append(t)
        totals.append(total)
    n_sampled = len(firsts)
    episodes = len(tasks) * config.runs
    requests_max = episodes * k_max * steps
    max_tokens = endpoint.max_tokens or config.max_tokens if endpoint is not None else None
    # a price written in the entry is known, $0 included (a self-hosted server's); an absent one is not
    known = endpoint is not None and ("price" in endpoint.model_fields_set or endpoint.price.input_per_mtok > 0
                                      or endpoint.price.output_per_mtok > 0)
    input_max = episodes * sum(totals) / n_sampled if rule is not None else None
    played = baseline_requests(the_plan, sample)
    expected = episodes * sum(played) / len(played)
    limits = endpoint.rate_limits if endpoint is not None and endpoint.rate_limits.enabled else None
    in_flight = min(max_in_flight or RuntimeOptions().max_in_flight, episodes)

    def minutes(requests: float, reply_s: float, output_tokens: int) -> float | None:
        if limits is None or input_max is None:
            return None
        tokens = input_max * requests / requests_max  # at the run's mean input per request
        return limit_seconds(limits, requests, tokens, max_tokens, reply_s, output_tokens, in_flight) / 60

    return CellEstimate(
        label=label or f"{config.env} {config.model} {config.format.value}",
        episodes=episodes,
        attempts_max=episodes * k_max,
        requests_min=episodes,
        requests_max=requests_max,
        images_first=sum(len(f.images) for f in firsts) / n_sampled,
        images_max=largest_images,
        max_images=cap,
        tokens_first=sum(tokens(f, len(f.images) if cap is None else min(cap, len(f.images))) for f in firsts)
        / n_sampled if rule is not None else None,
        tokens_max=max(largest) if largest else None,
        input_tokens_max=input_max,
        output_tokens_max=requests_max * max_tokens if max_tokens is not None else None,
        cost_input_max=input_max * endpoint.price.input_per_mtok / 1e6 if known else None,
        cost_output_max=requests_max * max_tokens * endpoint.price.output_per_mtok / 1e6 if known else None,
        price_known=known,
        rate_limit_min=minutes(requests_max, 0.0, 0),
        sampled=n_sampled,
        requests_expected=expected,
        endpoint=endpoint.limiter_key if endpoint is not None else None,
        model=config.model,
        expected_min=minutes(expected, REPLY_S, max_tokens or 0),
    )


# -- rendering --------------------------------------------------------------------------


def _n(x: float | None, digits: int = 0) -> str:
    if x is None:
        return "-"
    return f"{x:,.{digits}f}"


def _usd(x: float | None, known: bool, baseline: bool) -> str:
    if baseline:
        return "$0 (no model)"
    return f"${x:,.2f}" if known and x is not None else "unknown price"


def render(cells: list[CellEstimate]) -> str:
    """A table: a row per run, then the total."""
    header = ["run", "episodes", "attempts<=", "requests", "requests~", "images/request", "in tokens/request",
              "in tokens<=", "in cost<=", "out cost<=", "time~", "time>="]
    rows = []
    for c in cells:
        baseline = c.tokens_first is None and c.note is None
        images = f"{c.images_first:g}..{c.images_max}" + (f" (cap {c.max_images})" if c.max_images is not None else "")
        rows.append([
            c.label, _n(c.episodes), _n(c.attempts_max), f"{_n(c.requests_min)}..{_n(c.requests_max)}",
            _n(c.requests_expected), images,
            "-" if baseline else f"{_n(c.tokens_first)}..{_n(c.tokens_max)}", _n(c.input_tokens_max),
            *((_usd(c.cost_input_max, c.price_known, baseline), _usd(c.cost_output_max, c.price_known, baseline))
              if c.note is None else ("unknown", "unknown")),
            "-" if c.expected_min is None else _minutes(c.expected_min),
            "-" if c.rate_limit_min is None else _minutes(c.rate_limit_min),
        ])
    if len(cells) > 1:
        priced = [c for c in cells if c.tokens_first is not None]
        unknown = any(not c.price_known for c in priced) or any(c.note for c in cells)
        total_in = sum(c.cost_input_max or 0 for c in priced)
        total_out = sum(c.cost_output_max or 0 for c in priced)
        rows.append(["total", _n(sum(c.episodes for c in cells)), _n(sum(c.attempts_max for c in cells)),
                     f"{_n(sum(c.requests_min for c in cells))}..{_n(sum(c.requests_max for c in cells))}",
                     _n(sum(c.requests_expected for c in cells)), "", "",
                     _n(sum(c.input_tokens_max or 0 for c in cells)),
                     f"${total_in:,.2f}" + (" + unknown" if unknown else ""),
                     f"${total_out:,.2f}" + (" + unknown" if unknown else ""), *suite_time(cells)])
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    fmt = lambda cells: "  ".join(c.ljust(w) if i == 0 else c.rjust(w)  # noqa: E731
                                  for i, (c, w) in enumerate(zip(cells, widths))).rstrip()
    sampled = sorted({c.sampled for c in cells})
    return "\n".join([
        fmt(header), fmt(["-" * w for w in widths]), *map(fmt, rows), "",
        f"dry run: no model was called. Prompts measured on the first {'/'.join(map(str, sampled))} task(s) of each "
        "run; bounds assume every attempt and every decision is used; text tokens ~ characters/"
        f"{CHARS_PER_TOKEN}, image tokens by the provider's rule; out cost<= if every reply used max_tokens; "
        "requests~: what the reference random baseline (MOCK, the run's seed) asks on those tasks, per episode, "
        "times the episodes (a model that solves more asks fewer); time~ and time>=: requests~ and requests<= at "
        "every limit of the endpoint's limiter (requests/min, tokens/min with each request holding its input and "
        f"max_tokens until answered, max_concurrent), time~ with replies of {REPLY_S:g} s using max_tokens, time>= "
        "with replies at once (a suite's total: its slowest endpoint, as endpoints run at once).",
        *(f"note: {c.note}" for c in cells if c.note),
    ])


def suite_time(cells: list[CellEstimate]) -> list[str]:
    """The total row's time~ and time>=: the endpoints run at once, each at its own limit,
    so a suite takes as long as its slowest endpoint's cells together ("-": no limits)."""
    expected: dict[str, float] = {}
    bound: dict[str, float] = {}
    for c in cells:
        if c.endpoint is not None and c.rate_limit_min is not None:
            expected[c.endpoint] = expected.get(c.endpoint, 0.0) + c.expected_min
            bound[c.endpoint] = bound.get(c.endpoint, 0.0) + c.rate_limit_min
    if not expected:
        return ["-", "-"]
    return [_minutes(max(expected.values())), _minutes(max(bound.values()))]


def _minutes(m: float) -> str:
    if m < 10:
        return f"{m:.1f} min"
    return f"{m:,.0f} min" if m < 120 else f"{m / 60:,.1f} h"


def render_by_model(cells: list[CellEstimate], status: dict[str, str] | None = None) -> str:
    """A suite's cells summed per model (rows in the cells' order), then the total: what each
    model's share of the grid asks and costs, and how long its cells take at its endpoint's
    limit (the total's time: the slowest endpoint, as `suite_time`). `status`: model -> a note
    (e.g. its retirement)."""
    status = status or {}
    header = ["model", "cells", "requests~", "requests<=", "in tokens<=", "cost<=", "time~", "time>=", "status"]
    models = list(dict.fromkeys(c.model for c in cells))

    def row(label: str, group: list[CellEstimate], note: str) -> list[str]:
        priced = [c for c in group if c.tokens_first is not None]
        cost = sum((c.cost_input_max or 0) + (c.cost_output_max or 0) for c in priced)
        noted = any(c.note for c in group)  # a user's agent whose cost cannot be bounded
        unknown = any(not c.price_known for c in priced) or noted
        shown = ("$0 (no model)" if not priced and not noted else "unknown price" if unknown and not cost
                 else f"${cost:,.2f}" + (" + unknown" if unknown else ""))
        return [label, _n(len(group)), _n(sum(c.requests_expected for c in group)),
                _n(sum(c.requests_max for c in group)), _n(sum(c.input_tokens_max or 0 for c in group)), shown,
                *suite_time(group), note]

    rows = [row(m, [c for c in cells if c.model == m], status.get(m, "")) for m in models]
    rows.append(row(f"total ({len(models)} models)", cells, ""))
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    fmt = lambda r: "  ".join(c.ljust(w) if i in (0, len(header) - 1) else c.rjust(w)  # noqa: E731
                              for i, (c, w) in enumerate(zip(r, widths))).rstrip()
    return "\n".join([fmt(header), fmt(["-" * w for w in widths]), *map(fmt, rows), "",
                      "per model: its cells summed; cost<= = in cost<= + out cost<=; time~ and time>=: its cells one "
                      "after another at its endpoint's requests/min (the total: the slowest endpoint)."])


# -- a user's agent (deepphy/agent.py) -------------------------------------------------------


def estimate_agent(config: RunConfig, models_file: str | None = None, sample: int = DEFAULT_SAMPLE,
                   label: str | None = None) -> CellEstimate:
    """A user's agent's run, bounded from the endpoints it declares (`Agent.endpoints`: each
    with the requests it makes per decision at most, each about the size of the decision's
    prompt): every endpoint's figures for this run times those requests, summed. Its time is
    its slowest endpoint's, as they run at once. An agent that declares no endpoint, or no
    number for one, gets its decisions bounded and a note that its cost cannot be."""
    label = label or f"{config.env} {config.model} {config.format.value}"
    calls = declared(config.agent).endpoints
    unknown = [name for name, per_decision in calls.items() if per_decision is None]
    if not calls or unknown:
        decisions = estimate(config.model_copy(update={"model": "mock", "agent": None}), models_file, sample, label)
        why = ("it declares no endpoint (Agent.endpoints)" if not calls else
               f"it does not declare how often it calls {', '.join(unknown)} per decision (Agent.endpoints)")
        return replace(decisions, model=config.model, price_known=False,
                       note=f"{label}: cannot estimate this agent's model cost: {why}")
    parts = [(estimate(config.model_copy(update={"model": name, "agent": None}), models_file, sample, label), k)
             for name, k in calls.items()]
    first = parts[0][0]

    def total(field: str) -> float | None:
        values = [getattr(e, field) for e, _ in parts]
        return None if any(v is None for v in values) else sum(v * k for v, (_, k) in zip(values, parts))

    def largest(field: str) -> float | None:
        values = [getattr(e, field) for e, _ in parts if getattr(e, field) is not None]
        return max(values) if values else None

    expected = total("requests_expected")
    # the endpoint that takes longest at its limit sets the run's time
    slowest, k = max(parts, key=lambda p: (p[0].rate_limit_min or 0.0) * p[1])
    return CellEstimate(
        label=label, episodes=first.episodes, attempts_max=first.attempts_max,
        requests_min=round(total("requests_min")), requests_max=round(total("requests_max")),
        images_first=max(e.images_first for e, _ in parts), images_max=max(e.images_max for e, _ in parts),
        max_images=largest("max_images"), tokens_first=largest("tokens_first"), tokens_max=largest("tokens_max"),
        input_tokens_max=total("input_tokens_max"), output_tokens_max=total("output_tokens_max"),
        cost_input_max=total("cost_input_max"), cost_output_max=total("cost_output_max"),
        price_known=all(e.price_known for e, _ in parts),
        rate_limit_min=slowest.rate_limit_min * k if slowest.rate_limit_min is not None else None,
        sampled=first.sampled, requests_expected=expected,
        endpoint=slowest.endpoint,
        expected_min=slowest.expected_min * k if slowest.expected_min is not None else None,
        model=config.model,
    )
