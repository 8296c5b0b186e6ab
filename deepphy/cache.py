"""The per-machine cache shared by every deepphy process (compiled kernels, converted
levels, downloaded task data): `$DEEPPHY_CACHE_DIR`, else `~/.cache/deepphy`."""

from __future__ import annotations

import os
from pathlib import Path


def cache_root() -> Path:
    root = os.environ.get("DEEPPHY_CACHE_DIR")
    return Path(root).expanduser() if root else Path.home() / ".cache" / "deepphy"
