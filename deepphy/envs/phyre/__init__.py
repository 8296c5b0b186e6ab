"""PHYRE-B on pymunk: our own implementation of the 25 PHYRE-B templates.

- `scene.py`: objects, simulation with PHYRE's success rule, rendering;
- `templates/`: the 25 task templates (template API in `templates/__init__.py`);
- `space.py`: the `Cell: N, Radius: R` action space (light, no physics imports);
- `env.py`: the Environment (folds, observations, attempts); `prompt.py`: the words;
- `solve.py`: solvability search and variant verification (`deepphy solve --env phyre`).
"""

from deepphy.envs.base import Planning
from deepphy.envs.phyre.space import PhyreAction, PhyreSpace
from deepphy.envs.spec import EnvSpec, ReportSpec

SPEC = EnvSpec(
    name="phyre",
    title="PHYRE-B",
    environment="deepphy.envs.phyre.env:PhyreEnv",
    prompt="deepphy.envs.phyre.prompt:PhyrePrompt",
    planning=Planning.IN_ADVANCE,
    max_attempts=10,
    max_steps=1,
    report=ReportSpec(auccess=True),
    solver="deepphy.envs.phyre.solve:main",
    description="place one red ball so the green object reaches its goal (within- and cross-template test sets)",
)

__all__ = ["SPEC", "PhyreAction", "PhyreSpace"]
