"""Seeded randomness that depends only on what it is for, never on process or order."""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np


def seeded_rng(*keys: Any) -> np.random.Generator:
    """A generator that depends only on `keys`: stable across processes and machines."""
    digest = hashlib.sha256(repr(keys).encode()).digest()
    return np.random.default_rng(int.from_bytes(digest[:16], "little"))
