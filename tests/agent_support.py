"""Agents for the tests of deepphy/agent.py (importable by Ray workers: tests/ is on their path)."""

from __future__ import annotations

import json
import weakref
from typing import Any

from deepphy.agent import Agent, Endpoints
from deepphy.agents import mock_text
from deepphy.models import ModelRequest


class _Token:
    """Held by an episode's state: alive exactly as long as the state is."""


LIVE: "weakref.WeakSet[_Token]" = weakref.WeakSet()


class ProbeAgent(Agent):
    """Answers as MOCK does, after a first line that says what it sees: the resources Ray
    assigned its actor, the decisions its episode's state has seen (this one included) and
    the episode states alive in its process."""

    def __init__(self, num_cpus: float = 0) -> None:
        self.resources = {"num_cpus": num_cpus} if num_cpus else {}

    async def act(self, request: ModelRequest, state: dict[str, Any]) -> str:
        import ray

        if "token" not in state:
            state["token"] = _Token()
            LIVE.add(state["token"])
        state["seen"] = state.get("seen", 0) + 1
        try:  # an actor's resources; None in the driver (an agent in this process)
            assigned = ray.get_runtime_context().get_assigned_resources() if ray.is_initialized() else None
        except AssertionError:  # Ray says "only available when the process is a worker"
            assigned = None
        seen = {"assigned": assigned, "seen": state["seen"],
                "live": len(LIVE)}
        return json.dumps(seen) + "\n" + mock_text(request.context)


def probe_of(raw_output: str) -> dict[str, Any]:
    return json.loads(raw_output.split("\n", 1)[0])


class BrokenSetupAgent(Agent):
    """An agent whose setup fails where it runs (a checkpoint that is not there)."""

    async def setup(self, endpoints: Endpoints) -> None:
        raise FileNotFoundError("no checkpoint at /nonexistent/model.pt")

    async def act(self, request: ModelRequest, state: dict[str, Any]) -> str:
        raise AssertionError("never asked: its setup failed")


def not_an_agent(**kwargs: Any) -> dict:
    return dict(kwargs)


class DriverOnlyAgent(Agent):
    """Builds in the driver, not in a Ray worker: as where a node lacks the agent's package."""

    def __init__(self) -> None:
        import ray

        if ray.is_initialized() and ray.get_runtime_context().worker.mode == ray.WORKER_MODE:
            raise ModuleNotFoundError("No module named 'mypolicy' (on this node)")

    async def act(self, request: ModelRequest, state: dict[str, Any]) -> str:
        return mock_text(request.context)
