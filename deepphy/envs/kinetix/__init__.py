"""Kinetix on the real kinetix-env. Importing this package does not import JAX: the action
space (space.py), level list (levels.py) and renderer (render.py) are numpy-only; JAX and
kinetix load on the first reset (sim.py)."""

from deepphy.envs.kinetix.env import KinetixEnv, KinetixOptions
from deepphy.envs.kinetix.space import KinetixAction, KinetixSpace

__all__ = ["KinetixAction", "KinetixEnv", "KinetixOptions", "KinetixSpace"]
