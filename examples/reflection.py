"""A reflection agent: any endpoint of the models file, which after a failure first says
what went wrong, then acts.

    deepphy run --env phyre --agent examples.reflection:ReflectionAgent --agent-arg endpoint=gpt-4o

Its first attempt at a task is the endpoint's own answer. Before each later attempt it
asks the model, shown the same prompt (the failed attempts, their outcomes and key
frames), what went wrong and what it will change; then it asks for the action with that
analysis in the conversation. Both requests go through the endpoint's own client and its
rate limiter, and both are counted to the decision's tokens and cost.

The analysis is kept in the episode's state for the attempt's later decisions (on-the-fly
environments). State is a cache (deepphy/agent.py): after a resume the analysis is asked
for again, from the same prompt, so a deterministic endpoint makes the same decisions.
"""

from __future__ import annotations

from typing import Any

from deepphy.agent import Agent, Endpoints
from deepphy.chat import Message, TextPart
from deepphy.models import ModelRequest

REFLECT = ("Before you act: in a few sentences, say what went wrong in your failed attempts and what you will do "
           "differently now. Do not give an action yet.")
ACT = "Now give your action, in exactly the form the instructions ask for."


class ReflectionAgent(Agent):
    """`endpoint`: a models-file entry; `reflection_tokens`: the analysis' length limit."""

    def __init__(self, endpoint: str, reflection_tokens: int = 512) -> None:
        self.endpoint = endpoint
        self.reflection_tokens = reflection_tokens
        self.endpoints = {endpoint: 2}  # per decision at most: the analysis and the action

    async def setup(self, endpoints: Endpoints) -> None:
        self.model = endpoints[self.endpoint]

    async def act(self, request: ModelRequest, state: dict[str, Any]) -> str:
        ctx = request.context
        if ctx.attempt == 1:  # nothing has failed yet
            return (await self.model.complete(request)).text
        if state.get("attempt") != ctx.attempt:  # this attempt's analysis, asked once
            state.update(attempt=ctx.attempt, reflection=await self.reflect(request))
        conversation = [*request.messages, Message(role="assistant", content=[TextPart(text=state["reflection"])]),
                        Message(role="user", content=[TextPart(text=ACT)])]
        return (await self.model.complete(request.model_copy(update={"messages": conversation}))).text

    async def reflect(self, request: ModelRequest) -> str:
        """The model's analysis of its failed attempts: the prompt, with the question at its end."""
        last = request.messages[-1]
        asked = last.model_copy(update={"content": [*last.content, TextPart(text=REFLECT)]})
        question = request.model_copy(update={"messages": [*request.messages[:-1], asked],
                                              "max_tokens": self.reflection_tokens})
        return (await self.model.complete(question)).text
