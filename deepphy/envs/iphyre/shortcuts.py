"""I-PHYRE's shortcut baseline (deepphy/envs/shortcuts.py)."""

from __future__ import annotations

import json

from deepphy.envs.iphyre.space import MAX_CLICKS, IPhyreSpace
from deepphy.envs.shortcuts import ShortcutContext, ShortcutPolicy


def all_at_once(ctx: ShortcutContext) -> str:
    """Every gray block removed at t = 0: whatever rests on a block falls at once."""
    space = ctx.action_space
    assert isinstance(space, IPhyreSpace)
    return json.dumps([{"time": 0.0, "index": i} for i in range(min(space.num_blocks, MAX_CLICKS))])


SHORTCUTS = {
    "all-at-once": ShortcutPolicy(all_at_once, "removes every gray block at t = 0 (no timing, no choice)"),
}
