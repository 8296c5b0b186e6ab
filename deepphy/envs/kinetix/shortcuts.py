"""Kinetix's shortcut baseline (deepphy/envs/shortcuts.py)."""

from __future__ import annotations

from deepphy.envs.kinetix.space import KinetixAction, KinetixSpace
from deepphy.envs.shortcuts import ShortcutContext, ShortcutPolicy


def full_throttle(ctx: ShortcutContext) -> str:
    """Every motor forward and every thruster on, at every decision: whatever the machine
    is, drive it as hard as it goes."""
    space = ctx.action_space
    assert isinstance(space, KinetixSpace)
    return space.format(KinetixAction(motors=(1,) * space.num_motors, thrusters=(1,) * space.num_thrusters))


SHORTCUTS = {
    "full-throttle": ShortcutPolicy(full_throttle, "every motor forward and every thruster on, every decision"),
}
