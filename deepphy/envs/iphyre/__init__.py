"""I-PHYRE on the real `iphyre` package: remove gray blocks at chosen times so every red
ball falls out of the bottom of the scene.

- `space.py`: the plan syntax (light: no iphyre import);
- `env.py`: the environment (iphyre's simulator, our OpenCV renderer);
- `prompt.py`: the words.
"""

from deepphy.envs.base import Planning
from deepphy.envs.iphyre.space import Click, IPhyrePlan, IPhyreSpace
from deepphy.envs.spec import EnvSpec, ReportSpec

SPEC = EnvSpec(
    name="iphyre",
    title="I-PHYRE",
    environment="deepphy.envs.iphyre.env:IPhyreEnv",
    prompt="deepphy.envs.iphyre.prompt:IPhyrePrompt",
    planning=Planning.IN_ADVANCE,
    max_attempts=10,
    max_steps=1,
    report=ReportSpec(pass_k=3),  # the paper's Pass@3 figure
    shortcuts="deepphy.envs.iphyre.shortcuts:SHORTCUTS",
    description="40 games: remove gray blocks at chosen times so every red ball falls out",
)

__all__ = ["SPEC", "Click", "IPhyrePlan", "IPhyreSpace"]
