"""Cut the Rope: our own headless game on pymunk, 88 levels in five boxes, scored by the game.

- `constants.py`: every number of the game (light);
- `level.py`: the level format (pydantic) and the level files under `levels/` (light);
- `space.py`: the action syntax, availability, MOCK's reference baseline (light);
- `sim.py`: the world (state, element rules) and pymunk for the dynamics;
- `render.py`: the OpenCV screenshot; `env.py`: the environment; `prompt.py`: the words;
- `design.py`: the 88 levels as designed by hand, each with its idea (the level files are
  made from them);
- `oracle.py`: the search for winning plans, replay, the plans' timing;
- `calibrate.py`: what a level measures (reference baseline, timing grid, robustness, what
  its three stars need);
- `shortcuts.py`: the shortcut baselines (first-id, all-at-once, random-pauses);
- `solve.py`: the command line (solvability report, calibration, search, make).
Importing this package does not import pymunk.
"""

from deepphy.envs.base import Planning
from deepphy.envs.cuttherope.constants import MAX_ACTIONS
from deepphy.envs.cuttherope.space import CutAction, CutSpace
from deepphy.envs.spec import EnvSpec, ReportSpec

SPEC = EnvSpec(
    name="cuttherope",
    title="Cut the Rope",
    environment="deepphy.envs.cuttherope.env:CutTheRopeEnv",
    prompt="deepphy.envs.cuttherope.prompt:CutTheRopePrompt",
    planning=Planning.ON_THE_FLY,
    max_attempts=1,
    max_steps=MAX_ACTIONS,
    report=ReportSpec(stars=True, step_noun="action", step_checkpoints=(1, 3, 5, 10)),
    solver="deepphy.envs.cuttherope.solve:main",
    shortcuts="deepphy.envs.cuttherope.shortcuts:SHORTCUTS",
    description="88 levels in 5 boxes (season 1's Cardboard, Fabric, Foil, Magic, Valentine): cut ropes, pop "
                "bubbles, puff air so the candy reaches Om Nom; 0-3 stars",
)

__all__ = ["SPEC", "CutAction", "CutSpace"]
