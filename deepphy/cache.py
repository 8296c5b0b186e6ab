"""The per-machine cache shared by every deepphy process (compiled kernels, converted
levels, downloaded task data): `$DEEPPHY_CACHE_DIR`, else `~/.cache/deepphy` (the one
place that says so; the environments' documents name this module)."""

from __future__ import annotations

import os
from pathlib import Path


CACHE_DIR_ENV = "DEEPPHY_CACHE_DIR"  # the cache elsewhere (a test's warmed copy, a shared disk)


def cache_root() -> Path:
    root = os.environ.get(CACHE_DIR_ENV)
    return Path(root).expanduser() if root else Path.home() / ".cache" / "deepphy"
