"""The scheduler's calls to an environment worker: many decisions per Ray call, each with
its own outcome."""

from __future__ import annotations

import asyncio

from conftest import RAY_TIMEOUT_S


def test_decisions_of_one_loop_turn_are_one_call_and_each_keeps_its_own_outcome(ray_cluster, tmp_path):
    """Steps asked in the same event-loop turn reach the worker as one call; each episode
    gets its own outcome: a result, its environment's error (the others' results are whole),
    or WorkerLost for an episode the worker does not hold (as after a restart)."""
    import ray
    from toy_env.broken import Explodes
    from toy_env.space import PushAction

    from deepphy.actors.env_worker import make_env_worker
    from deepphy.scheduler import StepBatcher, WorkerLost

    trigger = tmp_path / "explode"
    trigger.touch()  # flag-05 raises at its second push
    worker = make_env_worker(Explodes.spec, {"explode_if_exists": str(trigger)}, num_cpus=0)
    tasks = {t.id: t for t in Explodes.tasks(Explodes.Options())}
    push = PushAction(force=1)

    async def steps(requests):
        batcher = StepBatcher(worker, RAY_TIMEOUT_S)
        return await asyncio.gather(*(batcher.step(*r) for r in requests), return_exceptions=True)

    try:
        first = asyncio.run(steps([("a", push, tasks["flag-02"]), ("b", push, tasks["flag-05"])]))
        assert [type(o).__name__ for o in first] == ["StepResult", "StepResult"], first
        assert not any(o.done for o in first)
        second = asyncio.run(steps([("a", push, None), ("b", push, None), ("ghost", push, None)]))
        assert type(second[0]).__name__ == "StepResult" and second[0].observation is not None
        assert isinstance(second[1], RuntimeError) and "left the rail" in str(second[1])
        assert "in the environment worker" in "".join(second[1].__notes__)  # its traceback where it was raised
        assert isinstance(second[2], WorkerLost)
        stats = ray.get(worker.stats.remote(), timeout=RAY_TIMEOUT_S)
        assert stats["calls"] == 2 and stats["steps"] == 4, stats  # 5 decisions in 2 calls; the ghost never stepped
    finally:
        ray.kill(worker)
