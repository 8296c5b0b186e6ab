"""The attempt protocol's history: each failed attempt is shown to the later attempts of its
episode as made from its record, though the protocol makes it once and shows it again."""

from __future__ import annotations

import asyncio

from deepphy.agents import make_agent
from deepphy.chat import image_digest
from deepphy.config import RunConfig
from deepphy.protocol import LocalEnv, MemoryArtifacts, past_attempt, run_attempt, run_episode
from deepphy.prompts import build_messages, prompt_as_json, prompt_digest
from deepphy.plan import plan


def _episode(config: RunConfig, task_id: str):
    the_plan = plan(config)
    spec = the_plan.spec
    task = next(t for t in the_plan.tasks if t.id == task_id)
    env = LocalEnv(the_plan.make_env())
    artifacts = MemoryArtifacts()
    records = asyncio.run(run_episode(spec, the_plan.prompt(), config, task, 0, the_plan.k_max, env,
                                      make_agent(config.model), artifacts))
    return spec, task, env, artifacts, records


def test_every_prompt_of_an_episode_equals_one_built_from_fresh_records():
    config = RunConfig(env="iphyre", model="mock", runs=1, tasks=["hinder"])
    spec, task, env, artifacts, records = _episode(config, "hinder")
    assert len(records) >= 3 and not records[0].success  # a history of several failed attempts
    prompt = spec.load_prompt()
    observation = env.env.reset(task)
    for k, record in enumerate(records):
        fresh = [past_attempt(r.model_copy(deep=True), spec, artifacts) for r in records[:k]]
        messages = build_messages(prompt, config.format, task, observation, fresh)
        assert record.steps[0].prompt == prompt_digest(messages)
        assert artifacts.prompts[prompt_digest(messages)] == prompt_as_json(messages)


def test_a_record_shown_again_shows_the_frames_of_the_artifacts_now_in_use():
    """The same record objects, read through another store (another run directory holding
    other bytes under the same names), show that store's frames, not the first one's."""
    config = RunConfig(env="iphyre", model="mock", runs=1, tasks=["hinder"])
    spec, task, env, first, records = _episode(config, "hinder")
    failed = [r for r in records if not r.success][:2]
    other = MemoryArtifacts()
    other.frames = {rel: png[::-1] for rel, png in first.frames.items()}  # different bytes, same names
    asyncio.run(run_attempt(spec, spec.load_prompt(), config, task, 0, len(failed) + 1, failed, env,
                            make_agent(config.model), other))
    shown = set(other.images)  # the digests of every image the prompt showed
    expected = {f.path for r in failed for f in r.key_frames}
    assert expected
    assert {image_digest(other.frames[rel]) for rel in expected} <= shown
    assert not {image_digest(first.frames[rel]) for rel in expected} & shown
