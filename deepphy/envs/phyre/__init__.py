"""PHYRE-B: the real PHYRE tasks (phyre 0.2.2's data) simulated on Box2D with PHYRE's rules.

- `thrift.py`: a small reader for Thrift's binary protocol (PHYRE's data format);
- `data.py`: fetching, verifying, decoding and caching the task data (first use);
- `splits.py`: PHYRE's evaluation setups and folds (md5-based shuffles);
- `space.py`: PHYRE's ball action mapper and the action spaces (grid, continuous);
- `sim.py`: the Box2D simulation with PHYRE's constants, goal test and placement rules;
- `render.py`: drawing scenes in PHYRE's colours;
- `env.py`: the Environment (task lists, observations, attempts);
- `solve.py`: solvability of the evaluation set (`deepphy solve --env phyre report`).
"""

from deepphy.envs.base import Planning
from deepphy.envs.phyre.space import PhyreAction, PhyreContinuousAction, PhyreContinuousSpace, PhyreSpace
from deepphy.envs.spec import EnvSpec, ReportSpec

SPEC = EnvSpec(
    name="phyre",
    title="PHYRE-B",
    environment="deepphy.envs.phyre.env:PhyreEnv",
    prompt="deepphy.envs.phyre.prompt:PhyrePrompt",
    planning=Planning.IN_ADVANCE,
    max_attempts=10,
    max_steps=1,
    report=ReportSpec(auccess=True, group_noun="setup", pass_k=5),  # the paper's Pass@5 figure
    solver="deepphy.envs.phyre.solve:main",
    shortcuts="deepphy.envs.phyre.shortcuts:SHORTCUTS",
    description="the real PHYRE-B tasks on Box2D: place one red ball so the green object reaches its goal",
)

__all__ = ["SPEC", "PhyreAction", "PhyreContinuousAction", "PhyreContinuousSpace", "PhyreSpace"]
