"""Helpers for the model client tests: real I-PHYRE prompts and a local server."""

from __future__ import annotations

import functools

from deepphy.envs import get_env_class
from deepphy.models import ModelConfig, ModelRequest, RequestContext
from deepphy.envs import get_spec
from deepphy.prompts import PastAttempt, PromptFormat, build_messages


@functools.lru_cache(maxsize=None)
def _observation(task_index: int):
    cls = get_env_class("iphyre")
    env = cls()
    task = cls.tasks(env.options)[task_index]
    obs = env.reset(task)
    return task, obs


def iphyre_request(
    task_index: int = 0,
    *,
    fmt: PromptFormat = PromptFormat.VLA,
    run: int = 0,
    attempt: int = 1,
    seed: int = 0,
    history_frames: int = 0,
    tried: list[str] | None = None,
) -> ModelRequest:
    """A real I-PHYRE prompt (2 observation images + `history_frames` key frames)."""
    task, obs = _observation(task_index)
    history = []
    for k in range(history_frames):
        frame = obs.images[k % len(obs.images)].model_copy(update={"name": f"past{k}", "caption": f"past frame {k}"})
        history.append(PastAttempt(attempt=k + 1, actions=["[]"], outcome="failed.", key_frames=[frame]))
    messages = build_messages(get_spec("iphyre").load_prompt(), fmt, task, obs, history)
    ctx = RequestContext(
        env="iphyre", task_id=task.id, run=run, attempt=attempt, step=1, seed=seed, format=fmt,
        action_space=obs.action_space.model_dump(mode="json"), tried=tried or [],
    )
    return ModelRequest(messages=messages, context=ctx)


BASES = {"openai": "/v1", "anthropic": "/v1", "gemini": "/v1beta"}


def local_config(server_url: str, provider: str = "openai", **kw) -> ModelConfig:
    fields = dict(
        name=f"local-{provider}", provider=provider, model="deepphy-mock", base_url=server_url + BASES[provider],
        send_context=True, timeouts={"request_s": 5.0, "connect_s": 2.0},
        retry={"max_retries": 3, "base_delay_s": 0.05, "max_delay_s": 0.2},
    )
    fields.update(kw)
    return ModelConfig.model_validate(fields)
