"""PHYRE's shortcut baseline (deepphy/envs/shortcuts.py)."""

from __future__ import annotations

from deepphy.envs.phyre import data, sim
from deepphy.envs.phyre.env import phyre_id
from deepphy.envs.phyre.space import InvalidPlacement, PhyreAction, PhyreSpace
from deepphy.envs.shortcuts import ShortcutContext, ShortcutPolicy


def drop_on_green(ctx: ShortcutContext) -> str:
    """The biggest ball that fits, dropped from as high as it fits straight above the green
    object (the grid column nearest its centre, then the next nearest): push the thing that
    must move. A failed attempt's action is not repeated; nothing else is learnt."""
    space = ctx.action_space
    assert isinstance(space, PhyreSpace)
    task = data.load_task(phyre_id(ctx.task))
    green = task.bodies[task.body1]
    tried = set(ctx.tried)
    columns = sorted(range(space.grid), key=lambda c: abs(space.cell_centre(c + 1)[0] - green.x))
    candidates = [PhyreAction(cell=row * space.grid + col + 1, radius=radius)
                  for col in columns for row in range(space.grid)
                  if space.cell_centre(row * space.grid + col + 1)[1] > green.y
                  for radius in range(space.radius_levels, 0, -1)]
    for action in candidates:
        text = space.format(action)
        if text in tried:
            continue
        try:
            sim.place(task, *space.to_phyre(action))
        except InvalidPlacement:
            continue
        return text
    return space.format(PhyreAction(cell=columns[0] + 1, radius=space.radius_levels))  # nothing fits above it


SHORTCUTS = {
    "drop-on-green": ShortcutPolicy(drop_on_green, "the biggest ball that fits, dropped straight onto the green object"),
}
