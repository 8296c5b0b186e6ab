"""Shared by the model benchmarks: real I-PHYRE requests, the server's stats, windows."""

from __future__ import annotations

import bisect
import json
import os
import tempfile
import urllib.request

import yaml

from deepphy.envs import get_env_class
from deepphy.models import ModelRequest, RequestContext
from deepphy.prompts import PromptFormat, build_messages


def bench_endpoint(latency: float, **model_fields) -> tuple[object, str, str]:
    """Start the local model server with `latency` and write a models file whose entry
    `bench` points at it. Returns (server process, base URL, models file path)."""
    from deepphy.testing.model_server import spawn

    proc, url = spawn("--latency", str(latency))
    models = os.path.join(tempfile.mkdtemp(prefix="dpbench"), "models.yaml")
    entry = {"name": "bench", "provider": "openai", "model": "deepphy-mock", "base_url": url + "/v1",
             "send_context": True, **model_fields}
    with open(models, "w") as f:
        yaml.safe_dump({"models": [entry]}, f)
    return proc, url, models


def iphyre_requests(n: int, *, images: bool = True) -> list[ModelRequest]:
    """`n` distinct requests (real prompts of the first 8 games; run/attempt vary the context)."""
    cls = get_env_class("iphyre")
    env = cls()
    tasks = cls.tasks(env.options)[:8]
    prompt = cls.spec.load_prompt()
    base = []
    for task in tasks:
        obs = env.reset(task)
        if not images:
            obs = obs.model_copy(update={"images": []})
        base.append((task, obs, build_messages(prompt, PromptFormat.VLA, task, obs, [])))
    out = []
    for i in range(n):
        task, obs, messages = base[i % len(base)]
        ctx = RequestContext(env="iphyre", task_id=task.id, run=i // len(base), attempt=1, step=1, seed=0,
                             format=PromptFormat.VLA, action_space=obs.action_space.model_dump(mode="json"))
        out.append(ModelRequest(messages=messages, context=ctx))
    return out


def server_stats(url: str, arrivals: bool = True) -> dict:
    with urllib.request.urlopen(f"{url}/stats?arrivals={int(arrivals)}", timeout=60) as r:
        return json.load(r)


def max_in_window(times: list[float], window: float) -> int:
    """Most arrivals in any closed window [t, t + window]."""
    times = sorted(times)
    return max((bisect.bisect_right(times, t + window) - i for i, t in enumerate(times)), default=0)
