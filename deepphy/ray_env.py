"""The environment variables a command sets for itself and the Ray processes it starts
(standard library only: `deepphy` sets them before any command runs)."""

from __future__ import annotations

import os
import sys


def quiet_environment() -> None:
    """Environment variables for this process and the Ray processes it starts. Best before
    `ray` is imported (Ray reads them at import time); the one that keeps a run from
    packaging the working directory is also applied to an already imported Ray."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    os.environ.setdefault("RAY_DEDUP_LOGS", "0")
    # Under `uv run`, Ray would otherwise package the working directory and build a second
    # virtual environment for its workers; ours is already installed and identical.
    os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
    if "ray._private.ray_constants" in sys.modules:  # imported already: it read the variable then
        from ray._private import ray_constants  # loaded already: never the import that costs

        ray_constants.RAY_ENABLE_UV_RUN_RUNTIME_ENV = ray_constants.env_bool("RAY_ENABLE_UV_RUN_RUNTIME_ENV", True)
