"""Every agent a run can evaluate, by name: deepphy's random baselines and the model
endpoints of a models file. All are `ModelClient`s, so a baseline's answer goes through
the same prompt, parser and records as a real model's.

The random baselines answer from a generator seeded by (seed, task, run, attempt, step),
so a run's actions do not depend on scheduling, and their text goes through the same parser
as a real model's:
- `mock`: the reference implementation's random baseline of each environment (its
  `ActionSpace.reference_reply`), so MOCK rows compare with published ones;
- `mock-uniform`: a uniformly random valid action that never repeats one of the task's
  failed attempts where the space allows (a stronger random baseline);
- `shortcut-<name>`: one of the environment's shortcut baselines (deepphy/envs/shortcuts.py),
  a policy that understands nothing but exploits something (aim straight at the nearest
  pig, cut the first rope); it may read privileged state.

A user's own agent (`--agent package.module:factory`, deepphy/agent.py) is named by its
`AgentSpec`, which the run's config carries: `make_agent(..., agent=spec)` hosts it.
"""

from __future__ import annotations

import asyncio
from pathlib import Path

from deepphy.agent import AgentClient, endpoint_configs
from deepphy.config import AgentSpec, RunConfig
from deepphy.envs import ActionSpace, get_spec
from deepphy.envs import shortcuts
from deepphy.models import ModelClient, ModelConfig, UnknownModel, client_from_config, load_models
from deepphy.models.config import load_groups
from deepphy.models.base import ModelRequest, ModelResponse, RequestContext
from deepphy.models.limiter import Limiter
from deepphy.chat import PromptFormat
from deepphy.prompts import OUTCOMES, mock_reply
from deepphy.seeding import seeded_rng


def mock_text(ctx: RequestContext, baseline: str = "mock") -> str:
    """A random baseline's whole reply in the request's format (WM: with a coin-flip outcome)."""
    outcome = None
    if ctx.format is PromptFormat.WM:
        rng = seeded_rng("mock-outcome", ctx.seed, ctx.env, ctx.task_id, ctx.run, ctx.attempt, ctx.step)
        outcome = OUTCOMES[int(rng.integers(len(OUTCOMES)))]
    return mock_reply(ctx.format, mock_action_text(ctx, baseline), outcome)


def mock_action_text(ctx: RequestContext, baseline: str = "mock") -> str:
    """A random baseline's action text for a request: depends only on the seed and the
    request's position."""
    get_spec(ctx.env).load_package()  # registers the environment's action spaces
    space = ActionSpace.from_json(ctx.action_space)
    rng = seeded_rng("mock", ctx.seed, ctx.env, ctx.task_id, ctx.run, ctx.attempt, ctx.step)
    if baseline == "mock":
        return space.reference_reply(rng, ctx.earlier)
    tried = []
    for text in ctx.tried:
        try:
            tried.append(space.parse(text))
        except ValueError:
            pass
    return space.format(space.sample(rng, exclude=tried))


class MockModel(ModelClient):
    """The reference implementation's random baseline."""

    name = "mock"
    answers_at_once = True

    async def complete(self, request: ModelRequest) -> ModelResponse:
        return ModelResponse(text=mock_text(request.context, self.name))


class UniformMockModel(MockModel):
    """Uniform over the valid actions, never repeating a failed attempt's action."""

    name = "mock-uniform"


def shortcut_text(name: str, ctx: RequestContext) -> str:
    """Shortcut baseline `name`'s whole reply to a request (WM: the action, nothing predicted)."""
    spec = get_spec(ctx.env)
    spec.load_package()
    policy = shortcuts.shortcut_for(spec, name)
    rng = seeded_rng("shortcut", name, ctx.seed, ctx.env, ctx.task_id, ctx.run, ctx.attempt, ctx.step)
    view = shortcuts.context(spec, ctx.env_options, ctx.task_id, ActionSpace.from_json(ctx.action_space),
                             ctx.earlier, ctx.tried, rng)
    return mock_reply(ctx.format, policy.policy(view))


class ShortcutModel(ModelClient):
    """A shortcut baseline (`shortcut-<name>`): deterministic, in this process. It may replay
    the attempt in a simulator, so it answers in a thread, never on the event loop."""

    def __init__(self, name: str) -> None:
        self.name = name

    async def complete(self, request: ModelRequest) -> ModelResponse:
        return ModelResponse(text=await asyncio.to_thread(shortcut_text, self.name, request.context))


BASELINES: dict[str, type[ModelClient]] = {"mock": MockModel, "mock-uniform": UniformMockModel}


def is_baseline(name: str) -> bool:
    """A random or shortcut baseline: built in, answered in this process, no models-file entry."""
    return name in BASELINES or shortcuts.is_shortcut(name)


def endpoint_config(name: str, models_file: str | Path | None = None) -> ModelConfig | None:
    """The models-file entry of an endpoint; None for a baseline. UnknownModel otherwise."""
    if is_baseline(name):
        return None
    models = load_models(models_file)
    if name not in models:
        groups = load_groups(models_file)
        raise UnknownModel(name, [*BASELINES, "shortcut-<name>", *sorted(models), *(f"{g} (group)" for g in sorted(groups))])
    return models[name]


def expand_models(names: list[str], models_file: str | Path | None = None) -> list[str]:
    """`names` with each group of the models file replaced by its entries, in order, each
    name once. Baselines are never looked up (a run of `mock` needs no models file)."""
    if all(is_baseline(name) for name in names):
        return list(dict.fromkeys(names))
    groups = load_groups(models_file)
    return list(dict.fromkeys(member for name in names for member in groups.get(name, [name])))


def retiring(names: list[str], models_file: str | Path | None = None) -> list[ModelConfig]:
    """The entries among `names` whose provider has retired them or announced it (baselines
    never). UnknownModel for a name that is not an agent."""
    configs = [endpoint_config(name, models_file) for name in dict.fromkeys(names)]
    return [c for c in configs if c is not None and c.retirement is not None]


def run_endpoints(config: RunConfig, models_file: str | Path | None = None) -> list[ModelConfig]:
    """The models-file entries a run calls: its endpoint, or those its agent declares; none
    for a baseline."""
    if config.agent is not None:
        return endpoint_configs(config.agent, models_file)
    endpoint = endpoint_config(config.model, models_file)
    return [endpoint] if endpoint is not None else []


def make_agent(name: str, models_file: str | Path | None = None, limiter: Limiter | None = None,
               env: str | None = None, agent: AgentSpec | None = None) -> ModelClient:
    """The client for `name`: a baseline, or the endpoint's HTTP client (its key read from
    the environment; `limiter` the endpoint's shared limiter, None for an in-process one),
    or, given its `agent` spec, a user's agent (built, its endpoints' keys read; its setup
    waits for its first request). `env`: the environment it will play, where known (a
    shortcut must be one of its own: `shortcuts.UnknownShortcut` otherwise)."""
    if agent is not None:
        return AgentClient(agent, models_file)
    config = endpoint_config(name, models_file)
    if config is None:
        if shortcuts.is_shortcut(name):
            if env is not None:
                shortcuts.shortcut_for(get_spec(env), name)
            return ShortcutModel(name)
        return BASELINES[name]()
    return client_from_config(config, limiter=limiter)
