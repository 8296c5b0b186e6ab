"""The 74 handcrafted levels shipped in kinetix-env, found without importing kinetix."""

from __future__ import annotations

import functools
import importlib.util
import re
from pathlib import Path

SIZES = ("S", "M", "L")

# Decisions: each holds the action for STEPS_PER_DECISION kinetix env steps of two 1/60 s
# physics substeps; kinetix ends an episode after MAX_TIMESTEPS env steps.
STEPS_PER_DECISION = 16
MAX_TIMESTEPS = 256
MAX_DECISIONS = MAX_TIMESTEPS // STEPS_PER_DECISION  # 16
SECONDS_PER_DECISION = STEPS_PER_DECISION * 2 / 60  # ~0.53 s


@functools.lru_cache(maxsize=1)
def levels_dir() -> Path:
    spec = importlib.util.find_spec("kinetix")  # locates the package without running it
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError("kinetix-env is not installed")
    return Path(next(iter(spec.submodule_search_locations))) / "levels"


def _natural(name: str) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]


def level_names(size: str) -> list[str]:
    """Level names of one size ("S", "M" or "L"), e.g. "s/h0_weak_thrust", in natural order."""
    d = levels_dir() / size.lower()
    return [f"{size.lower()}/{p.stem}" for p in sorted(d.glob("*.json"), key=lambda p: _natural(p.stem))]


def level_path(name: str) -> Path:
    return levels_dir() / f"{name}.json"


def task_id(level: str) -> str:
    """"s/h0_weak_thrust" -> "s_h0_weak_thrust" (filesystem-safe)."""
    return level.replace("/", "_")
