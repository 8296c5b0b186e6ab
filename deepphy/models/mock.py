"""MOCK: the random baseline. Answers with a uniformly random valid action, in the syntax."""

from __future__ import annotations

from deepphy.envs import ActionSpace, get_env_class, seeded_rng
from deepphy.models.base import ModelClient, ModelRequest, ModelResponse, RequestContext
from deepphy.prompts import mock_reply


def mock_action_text(ctx: RequestContext) -> str:
    """MOCK's action for a request: depends only on the seed and the request's position."""
    get_env_class(ctx.env)  # imports the environment module, which registers its action space
    space = ActionSpace.from_json(ctx.action_space)
    rng = seeded_rng("mock", ctx.seed, ctx.env, ctx.task_id, ctx.run, ctx.attempt, ctx.step)
    tried = []
    for text in ctx.tried:
        try:
            tried.append(space.parse(text))
        except ValueError:
            pass
    return space.format(space.sample(rng, exclude=tried))


class MockModel(ModelClient):
    name = "mock"

    async def complete(self, request: ModelRequest) -> ModelResponse:
        ctx = request.context
        return ModelResponse(text=mock_reply(ctx.format, mock_action_text(ctx)))
