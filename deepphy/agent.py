"""Bring your own agent: how deepphy evaluates an agent of yours under its protocol.

An agent is anything that, shown what a model is shown, decides: a model with a reflection
or memory step, a perception module in front of a model, a local checkpoint, a policy
trained on `deepphy.gym`. deepphy runs it exactly where it runs a model endpoint, so the
prompts, parser, records, reports, leaderboard, suites, resume and the cost budget treat it
like any model (docs/agents.md is the guide):

    deepphy run --env phyre --agent mypackage.myagent:make_agent --agent-arg endpoint=gpt-4o

The entry point `package.module:factory` names a callable (a class, a function) that takes
the `--agent-arg`s as keyword arguments (JSON values, else strings) and returns an `Agent`.
The run's model name is derived from the entry point and the arguments (`AgentSpec.name`),
and the run's config stores them with the version of the agent's package: a resume with
other arguments or another version is refused, as any change of config is.

What an agent implements (the rest has defaults):

    class MyAgent(Agent):
        endpoints = {"gpt-4o": 2}       # models-file entries it calls, and how often per decision at most
        resources = {"num_gpus": 1}     # Ray resource requests of the actor it runs in (none: an I/O actor)

        async def setup(self, endpoints):   # once per process, before the first request
            self.model = endpoints["gpt-4o"]    # the endpoint's client, with the cluster's shared rate limiter

        async def act(self, request, state):
            ...                          # -> reply text, an `Action`, or an `AgentReply`

- `act(request, state)` gets the `ModelRequest` a model would get (`request.messages`: the
  same chat messages, images included; `request.context`: environment, its options, task,
  run, attempt, step, seed, prompt format, the decision's action space as JSON, the actions
  of the task's failed attempts, this attempt's earlier actions) and returns the reply text
  a model would give (parsed as a model's; text that does not parse is a recorded invalid
  action), or a structured action of the decision's action space (`ActionSpace.from_json(
  request.context.action_space)`), written in its syntax for the record.
- It is async: deepphy keeps many episodes in flight, and their requests reach one agent at
  once. Await your endpoints; run blocking work (a policy's forward pass, a simulator) with
  `await asyncio.to_thread(...)`, or gather concurrent requests into batches yourself.
- `state` is a dict of the episode's own (task, run of the run): empty at its first request,
  kept across its attempts, released when the episode ends. It is a CACHE, never memory: a
  resume starts every unfinished episode at the start of its next attempt with an empty
  state, as does a retried attempt's worker after a crash. So a resumed run makes the same
  decisions only if every decision is a function of its request (which carries the
  episode's history: the earlier attempts' actions, outcomes and frames, this attempt's
  earlier decisions) and of what `state` holds is recomputed from the requests when absent.
  Randomness: seed it from the request (e.g. `deepphy.seeding.seeded_rng(ctx.seed,
  ctx.task_id, ctx.run, ctx.attempt, ctx.step)`).
- Endpoint calls made through `setup`'s endpoints during `act` are accounted to the decision:
  tokens, cost (so `--max-cost` holds), retries. An endpoint that fails for good raises
  `ModelError`: the attempt is re-run, as a model's would be.
- Building the agent (the factory) happens in the driver too, to read its declarations and
  check its endpoints and their keys before anything starts: keep it cheap, and load
  weights or open connections in `setup`, which runs only where the agent runs.

Where it runs: in a model worker actor, like an endpoint's client (one per run, or per agent
for all of a suite's cells), with `max_concurrency` for every episode in flight; an agent
that declares `resources` gets them as the actor's Ray resource requests (a GPU node, say).
"""

from __future__ import annotations

import asyncio
import contextvars
import functools
import importlib
import json
import os
import re
import sys
from abc import ABC, abstractmethod
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, packages_distributions, version
from pathlib import Path
from typing import Any, Callable, Literal, Mapping, NamedTuple

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from deepphy.chat import PromptFormat, Usage
from deepphy.config import AGENT_ENTRY, AgentSpec
from deepphy.envs import Action, ActionSpace, get_spec
from deepphy.messages import one_line, validation_message
from deepphy.models import ModelClient, ModelRequest, ModelResponse, RequestContext, client_from_config, model_config
from deepphy.models.config import ModelConfig
from deepphy.models.limiter import Limiter

# -- what an agent implements ------------------------------------------------------------------


class AgentReply(BaseModel):
    """An agent's answer to one request: reply `text` as a model would write it, or a
    structured `action` (with, in the WM format, the `prediction` and `outcome` it states)."""

    model_config = ConfigDict(arbitrary_types_allowed=True, frozen=True)

    text: str | None = None
    action: Action | None = None
    prediction: str | None = None
    outcome: Literal["success", "failure"] | None = None

    @model_validator(mode="after")
    def _one_answer(self) -> "AgentReply":
        if (self.text is None) == (self.action is None):
            raise ValueError("an AgentReply carries exactly one of text and action")
        return self


class Resources(BaseModel):
    """Ray resource requests of the actor an agent runs in (`Agent.resources`); none: an I/O
    actor beside the driver that reserves nothing, as an endpoint's client."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    num_cpus: float = Field(0, ge=0)
    num_gpus: float = Field(0, ge=0)
    memory: int | None = Field(None, ge=0, description="bytes")
    resources: dict[str, float] = Field(default_factory=dict, description="custom Ray resources, e.g. a node label")
    accelerator_type: str | None = None

    @property
    def requested(self) -> bool:
        return self != Resources()

    def actor_options(self) -> dict[str, Any]:
        """These requests as `ray.remote(...).options(...)` keywords."""
        return self.model_dump(exclude_defaults=True) | {"num_cpus": self.num_cpus}


class Endpoints:
    """The models-file endpoints an agent declared (`Agent.endpoints`), by name, as clients:
    `await endpoints["gpt-4o"].complete(request)`. Each is the endpoint's own HTTP client (its
    retries, deadlines, key) behind the endpoint's limiter, the one every worker of the
    cluster shares."""

    def __init__(self, clients: Mapping[str, ModelClient]) -> None:
        self._clients = dict(clients)

    def __getitem__(self, name: str) -> ModelClient:
        try:
            return self._clients[name]
        except KeyError:
            raise KeyError(f"endpoint {name!r} is not among the agent's declared endpoints "
                           f"({', '.join(self._clients) or 'none'}): add it to Agent.endpoints") from None

    def __iter__(self):
        return iter(self._clients)

    def __len__(self) -> int:
        return len(self._clients)


class Agent(ABC):
    """A user's agent (see the module). Subclass it; set `endpoints` and `resources` as class
    or instance attributes (they may depend on the factory's arguments)."""

    # Models-file entries the agent calls -> how many requests it makes of each per decision
    # at most, each about the size of the decision's prompt (the dry run's cost bound); None:
    # not known (the dry run then says it cannot bound the cost).
    endpoints: Mapping[str, float | None] = {}
    # Ray resource requests of its actor (`Resources` fields), e.g. {"num_gpus": 1}.
    resources: Mapping[str, Any] = {}

    async def setup(self, endpoints: Endpoints) -> None:
        """Once per process, before the first request: load weights, keep the endpoints."""

    @abstractmethod
    async def act(self, request: ModelRequest, state: dict[str, Any]) -> str | Action | AgentReply:
        """The decision for `request`; `state`: the episode's cache (see the module)."""

    async def close(self) -> None:
        """At the end of the run: release what `setup` took."""


# -- loading an agent by its entry point -------------------------------------------------------


class AgentError(RuntimeError):
    """An agent that cannot be loaded or run as asked. The message is for the user."""


class AgentFailed(AgentError):
    """The agent's setup failed where it runs: no attempt can go on, so the run stops (the
    attempts in flight are recorded first); the same command resumes once it is fixed."""


def load_agent(entry: str, args: Mapping[str, Any] | None = None) -> AgentSpec:
    """The spec of the agent at `entry` (package.module:factory) with `args`: its factory is
    imported (and nothing called), its package's version read. AgentError if it cannot be."""
    if not re.match(AGENT_ENTRY, entry):
        raise AgentError(f"--agent {entry[:80]!r}: expected an entry point package.module:factory")
    # The working directory is importable, as for `python -m` (the `deepphy` script's own path is
    # its bin/): Ray's workers import from the driver's working directory too.
    if os.getcwd() not in sys.path and "" not in sys.path:
        sys.path.append(os.getcwd())
    _factory(entry)
    package, version = _package_version(entry.partition(":")[0])
    try:
        return AgentSpec(entry=entry, args=dict(args or {}), package=package, version=version)
    except ValidationError as e:
        raise AgentError(f"agent {entry}: {validation_message(e)}") from None


def _factory(entry: str) -> Callable[..., Any]:
    module_name, _, attr = entry.partition(":")
    try:
        target: Any = importlib.import_module(module_name)
    except ImportError as e:
        raise AgentError(f"agent {entry}: cannot import {module_name} ({one_line(str(e))[:200]}); install its package "
                         "or run from the directory that holds it") from None
    for part in attr.split("."):
        try:
            target = getattr(target, part)
        except AttributeError:
            raise AgentError(f"agent {entry}: {module_name} has no {attr}") from None
    if not callable(target):
        raise AgentError(f"agent {entry}: {attr} is not callable (the factory returns an Agent)")
    return target


def _package_version(module_name: str) -> tuple[str, str | None]:
    """(package, version) of the code at `module_name`: its installed distribution's, else
    the top-level package's `__version__` (None where it has none)."""
    top = module_name.split(".")[0]
    for dist in packages_distributions().get(top, []):
        try:
            return dist, version(dist)
        except PackageNotFoundError:
            continue
    found = getattr(importlib.import_module(top), "__version__", None)
    return top, str(found) if found is not None else None


def build_agent(spec: AgentSpec) -> Agent:
    """Call the agent's factory with its arguments; AgentError if that fails or the result is
    not an Agent with valid declarations."""
    factory = _factory(spec.entry)
    try:
        agent = factory(**spec.args)
    except TypeError as e:  # missing or unexpected arguments, most often
        raise AgentError(f"agent {spec.entry}: {one_line(str(e))[:300]}") from None
    except Exception as e:  # noqa: BLE001 - the factory's own check of its arguments
        raise AgentError(f"agent {spec.entry}: {type(e).__name__}: {one_line(str(e))[:300]}") from None
    if not isinstance(agent, Agent):
        raise AgentError(f"agent {spec.entry}: the factory returned a {type(agent).__name__}, not a "
                         "deepphy.agent.Agent")
    declared_of(agent, spec.entry)
    return agent


@dataclass(frozen=True)
class Declared:
    """What an agent declares: the endpoints it calls (with requests per decision, None when
    unknown) and the Ray resources its actor needs."""

    endpoints: dict[str, float | None]
    resources: Resources


def declared_of(agent: Agent, entry: str) -> Declared:
    endpoints = dict(agent.endpoints)
    for name, calls in endpoints.items():
        if not isinstance(name, str) or not (calls is None or (isinstance(calls, (int, float)) and calls >= 0)):
            raise AgentError(f"agent {entry}: endpoints maps models-file names to requests per decision (a number "
                             f">= 0, or None), got {name!r}: {calls!r}")
    try:
        resources = Resources.model_validate(dict(agent.resources))
    except ValidationError as e:
        raise AgentError(f"agent {entry}: resources: {validation_message(e)}") from None
    return Declared(endpoints, resources)


@functools.lru_cache(maxsize=64)
def _declared(spec_json: str) -> Declared:
    spec = AgentSpec.model_validate_json(spec_json)
    return declared_of(build_agent(spec), spec.entry)


def declared(spec: AgentSpec) -> Declared:
    """The declarations of the agent `spec` names (its factory is called once per process)."""
    return _declared(spec.model_dump_json())


def endpoint_configs(spec: AgentSpec, models_file: str | Path | None = None) -> list[ModelConfig]:
    """The models-file entries the agent declared (UnknownModel for one the file lacks)."""
    return [model_config(name, models_file) for name in declared(spec).endpoints]


# -- running an agent: the host that makes it a ModelClient -----------------------------------


class Episode(NamedTuple):
    """Whose state an agent's `state` is: one episode of one run (a suite's cells share an
    agent's worker, so the run's environment setting and format are part of it)."""

    env: str
    options: str  # the environment options, as JSON with sorted keys
    format: str
    task: str
    run: int

    @classmethod
    def of(cls, ctx: RequestContext) -> "Episode":
        return cls(ctx.env, json.dumps(ctx.env_options, sort_keys=True), ctx.format.value, ctx.task_id, ctx.run)


@dataclass
class _Meter:
    """What the endpoints cost while answering one request."""

    usage: Usage
    retries: int = 0
    images_dropped: int = 0


_METER: contextvars.ContextVar[_Meter | None] = contextvars.ContextVar("deepphy_agent_meter", default=None)


class _Metered(ModelClient):
    """An endpoint's client as an agent sees it: each answer is also counted to the request
    the agent is answering (its task's context carries the meter, also into tasks it starts)."""

    def __init__(self, client: ModelClient) -> None:
        self.client, self.name = client, client.name

    async def complete(self, request: ModelRequest) -> ModelResponse:
        response = await self.client.complete(request)
        meter = _METER.get()
        if meter is not None:
            meter.usage = meter.usage + response.usage
            meter.retries += response.retries
            meter.images_dropped += response.images_dropped
        return response

    async def activity(self) -> dict[str, int]:
        return await self.client.activity()

    async def close(self) -> None:
        await self.client.close()


class AgentClient(ModelClient):
    """An `Agent` as deepphy's `ModelClient`: builds it and its endpoints' clients, runs its
    setup once, keeps each episode's state, accounts its endpoints' usage to each reply and
    writes a structured action in the action space's syntax. `limiter_for(config)`: the
    limiter of an endpoint (a model worker passes the cluster's shared one); None: each
    client limits itself in-process."""

    def __init__(self, spec: AgentSpec, models_file: str | Path | None = None,
                 limiter_for: Callable[[ModelConfig], Limiter | None] = lambda config: None) -> None:
        self.spec, self.name = spec, spec.name
        _, version = _package_version(spec.entry.partition(":")[0])
        if version != spec.version:
            raise AgentError(f"agent {spec.entry}: this process has {spec.package} {version or 'unversioned'}, the run "
                             f"was made with {spec.label}; install that version, or start a new run")
        self.agent = build_agent(spec)
        self.declared = declared_of(self.agent, spec.entry)
        self.endpoints = {
            name: _Metered(client_from_config(config, limiter=limiter_for(config)))
            for name, config in ((n, model_config(n, models_file)) for n in self.declared.endpoints)
        }
        self.states: dict[Episode, dict[str, Any]] = {}
        self._setup: asyncio.Future | None = None

    async def complete(self, request: ModelRequest) -> ModelResponse:
        if self._setup is None:
            self._setup = asyncio.ensure_future(self.agent.setup(Endpoints(self.endpoints)))
        try:
            await asyncio.shield(self._setup)
        except Exception as e:  # noqa: BLE001 - every request would fail alike: the run stops
            raise AgentFailed(f"agent {self.name}: setup failed: {type(e).__name__}: "
                              f"{one_line(str(e))[:300]}") from None
        state = self.states.setdefault(Episode.of(request.context), {})
        meter = _Meter(Usage())
        token = _METER.set(meter)
        try:
            reply = await self.agent.act(request, state)
        finally:
            _METER.reset(token)
        return ModelResponse(text=self.reply_text(reply, request.context), usage=meter.usage, retries=meter.retries,
                             images_dropped=meter.images_dropped)

    def reply_text(self, reply: str | Action | AgentReply, ctx: RequestContext) -> str:
        """The reply as the record keeps it and the parser reads it."""
        if isinstance(reply, str):
            return reply
        if isinstance(reply, Action):
            reply = AgentReply(action=reply)
        if not isinstance(reply, AgentReply):
            raise TypeError(f"agent {self.name}: act returned a {type(reply).__name__}, not reply text, an Action "
                            "or an AgentReply")
        if reply.text is not None:
            return reply.text
        get_spec(ctx.env).load_package()  # registers the environment's action spaces
        space = ActionSpace.from_json(ctx.action_space)
        try:
            text = space.format(reply.action)
        except Exception:  # noqa: BLE001 - a space formats its own actions only (some assert it)
            raise TypeError(f"agent {self.name}: its action {type(reply.action).__name__} is not an action of the "
                            f"decision's space ({space.kind})") from None
        if ctx.format is PromptFormat.VLA:
            return text
        lines = [f"Prediction: {reply.prediction or '(none stated)'}"]
        lines += [f"Outcome: {reply.outcome}"] if reply.outcome else []
        return "\n".join([*lines, f"Action: {text}"])

    def end_episode(self, episode: Episode) -> None:
        """The episode ended (solved, out of attempts, or left for a resume): drop its state."""
        self.states.pop(episode, None)

    async def activity(self) -> dict[str, int]:
        waiting = {"rate_limited": 0, "retrying": 0}
        for client in self.endpoints.values():
            for key, n in (await client.activity()).items():
                waiting[key] = waiting.get(key, 0) + n
        return waiting

    async def close(self) -> None:
        try:
            if self._setup is not None and self._setup.done() and not self._setup.exception():
                await self.agent.close()
        finally:
            for client in self.endpoints.values():
                await client.close()
