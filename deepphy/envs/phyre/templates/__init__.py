"""The 25 PHYRE-B templates, one module per template: `tNN.py` for NN = 00..24.

Template API (all a new template file needs)
-------------------------------------------
A module `deepphy/envs/phyre/templates/tNN.py` defines

    TEMPLATE = Template(
        id=NN,
        name="short name",
        description="one line, what the solver must achieve",
        build=build,
    )

    def build(rng: np.random.Generator) -> Scene: ...

`build` draws the variant's parameters from `rng` (and nothing else: no global random
state, no time, no hashing of Python objects, so a variant is the same in every process)
and returns a `Scene` made with the helpers in `deepphy.envs.phyre.scene`:
`ball`, `bar`, `bar_between`, `box`, `jar`, `poly`; coordinates in px in a 256 x 256
scene with y UP; colours: "black" static, "gray" dynamic, "green" the dynamic subject,
"blue" dynamic goal object, "purple" static goal object. The goal is
`Scene(objects, subject=<index of the green object>, goal=(<indices and/or wall names
"bottom"/"left"/"right"/"top">,), relation="touching" | "not_touching")`.
Raise `Skip` for parameter draws that make a bad scene (overlaps, out of the scene); the
generator then tries the next sub-seed.

Rules a template must satisfy (checked by tests/test_phyre_templates.py and by
`python -m deepphy.envs.phyre.solve generate`):
- with no ball placed the task is NOT solved, nothing explodes and nothing leaves the
  scene;
- some red ball placement solves it (the generator keeps only verified variants; the
  accepted sub-seed of every variant is committed in `variants.json`).

Variant v of template t is built from `seeded_rng("phyre", t, v, k)` where k is the
accepted sub-seed from `variants.json` (the first k whose build does not raise `Skip`
when the file has no entry yet).
"""

from __future__ import annotations

import functools
import importlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from deepphy.seeding import seeded_rng
from deepphy.envs.phyre.scene import Scene

NUM_TEMPLATES = 25
VARIANTS = 100
VARIANTS_FILE = Path(__file__).with_name("variants.json")


class Skip(Exception):
    """A parameter draw that does not make a valid scene; the next sub-seed is tried."""


@dataclass(frozen=True)
class Template:
    id: int
    name: str
    description: str
    build: Callable[[np.random.Generator], Scene]


@functools.lru_cache(maxsize=None)
def templates() -> dict[int, Template]:
    """Every template module present, by id."""
    out = {}
    for t in range(NUM_TEMPLATES):
        try:
            module = importlib.import_module(f"deepphy.envs.phyre.templates.t{t:02d}")
        except ModuleNotFoundError as e:
            if e.name and e.name.endswith(f"t{t:02d}"):
                continue
            raise
        out[t] = module.TEMPLATE
    return out


@functools.lru_cache(maxsize=None)
def accepted_seeds() -> dict[int, list]:
    """template -> per variant [sub-seed, [x, y, r] of a verified solving placement]."""
    if not VARIANTS_FILE.exists():
        return {}
    data = json.loads(VARIANTS_FILE.read_text())
    return {int(k): v for k, v in data.get("templates", {}).items()}


def build_with_seed(template: int, variant: int, sub_seed: int) -> Scene:
    return templates()[template].build(seeded_rng("phyre", template, variant, sub_seed))


def first_valid_seed(template: int, variant: int, start: int = 0, limit: int = 10_000) -> tuple[int, Scene]:
    for k in range(start, start + limit):
        try:
            return k, build_with_seed(template, variant, k)
        except Skip:
            continue
    raise RuntimeError(f"template {template} variant {variant}: no valid parameters in {limit} draws")


@functools.lru_cache(maxsize=4096)
def variant_scene(template: int, variant: int) -> Scene:
    """The scene of variant `variant` of `template` (deterministic)."""
    entry = accepted_seeds().get(template)
    if entry is not None and variant < len(entry) and entry[variant] is not None:
        return build_with_seed(template, variant, int(entry[variant][0]))
    return first_valid_seed(template, variant)[1]


def verified_solution(template: int, variant: int) -> tuple[float, float, float] | None:
    entry = accepted_seeds().get(template)
    if entry is None or variant >= len(entry) or entry[variant] is None:
        return None
    return tuple(entry[variant][1])  # type: ignore[return-value]


def u(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A uniform float in [lo, hi]."""
    return float(rng.uniform(lo, hi))


def sign(rng: np.random.Generator) -> int:
    """+1 or -1: many templates are mirrored left/right at random."""
    return 1 if rng.random() < 0.5 else -1


def mx(x: float, side: int) -> float:
    """Mirror an x coordinate about the scene centre when side == -1."""
    from deepphy.envs.phyre.scene import W

    return x if side > 0 else W - x
