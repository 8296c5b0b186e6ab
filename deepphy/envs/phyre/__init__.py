"""PHYRE-B on pymunk: our own implementation of the 25 PHYRE-B templates.

- `scene.py`: objects, simulation with PHYRE's success rule, rendering;
- `templates/`: the 25 task templates (template API in `templates/__init__.py`);
- `space.py`: the `Cell: N, Radius: R` action space (light, no physics imports);
- `env.py`: the Environment (folds, observations, attempts);
- `solve.py`: solvability search and variant verification (`python -m deepphy.envs.phyre.solve`).
"""

from deepphy.envs.phyre.space import PhyreAction, PhyreSpace
from deepphy.envs.phyre.env import PhyreEnv, PhyreOptions

__all__ = ["PhyreAction", "PhyreEnv", "PhyreOptions", "PhyreSpace"]
