"""Kinetix on the real kinetix-env (JAX): the 74 handcrafted levels, sizes S/M/L.

- `levels.py`: the level list and the decision constants (no kinetix import);
- `space.py`: the action syntax (pure Python);
- `render.py`: our OpenCV renderer and label placement (numpy only);
- `sim.py`: everything that touches JAX / kinetix (loaded on the first reset);
- `env.py`: the environment; `prompt.py`: the words.
Importing this package does not import JAX.
"""

from deepphy.envs.base import Planning
from deepphy.envs.kinetix.levels import MAX_DECISIONS
from deepphy.envs.kinetix.space import KinetixAction, KinetixSpace
from deepphy.envs.spec import EnvSpec, ReportSpec

SPEC = EnvSpec(
    name="kinetix",
    title="Kinetix",
    environment="deepphy.envs.kinetix.env:KinetixEnv",
    prompt="deepphy.envs.kinetix.prompt:KinetixPrompt",
    planning=Planning.ON_THE_FLY,
    # The protocol budgets Kinetix in decisions per episode, not attempts.
    max_attempts=1,
    max_steps=MAX_DECISIONS,
    report=ReportSpec(step_noun="decision", group_noun="size", leaderboard_groups=True),
    shortcuts="deepphy.envs.kinetix.shortcuts:SHORTCUTS",
    description="74 handcrafted levels (S, M, L): drive motors and thrusters so green touches blue",
)

__all__ = ["SPEC", "KinetixAction", "KinetixSpace"]
