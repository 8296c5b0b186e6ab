"""Where a run's I/O actors go: on the driver's node. Metrics, model workers and the rate
limiter need no CPU; beside the driver they live and die with it, and a worker node that
fails takes only environment workers (which Ray restarts elsewhere) with it."""

from __future__ import annotations

import ray
from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy


def beside_driver() -> NodeAffinitySchedulingStrategy:
    # soft: a driver outside the cluster (Ray client) has no node of its own
    return NodeAffinitySchedulingStrategy(node_id=ray.get_runtime_context().get_node_id(), soft=True)
