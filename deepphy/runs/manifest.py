"""A suite root's manifest (`suite.json`): the suite's name and every cell, each a run
directory below the root with its config. Written by `deepphy run --suite`; read by the
suite on resume and by the views (leaderboard, dashboard) for the cells not started yet."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

from deepphy.config import RunConfig
from deepphy.messages import one_line
from deepphy.runs.store import RunDirError, atomic_write

MANIFEST = "suite.json"
CELL_DIR = re.compile(r"[A-Za-z0-9._=+-]+(/[A-Za-z0-9._=+-]+)*")  # a cell's directory, relative to the root


@dataclass(frozen=True)
class Cell:
    dir: str  # relative to the suite root
    config: RunConfig


def has_manifest(root: Path) -> bool:
    return (root / MANIFEST).is_file()


def read_manifest(root: Path) -> list[Cell]:
    """The cells a suite root's manifest names (validated: each a directory inside the root),
    or RunDirError."""
    path = root / MANIFEST
    try:
        data = json.loads(path.read_text())
        listed = [Cell(str(c["dir"]), RunConfig.model_validate(c["config"])) for c in data["cells"]]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise RunDirError(f"{path} is not a suite manifest ({one_line(str(e))[:200]})") from None
    for cell in listed:
        if not CELL_DIR.fullmatch(cell.dir) or ".." in cell.dir.split("/"):
            raise RunDirError(f"{path} names a cell outside the suite root: {cell.dir[:100]!r}")
    return listed


def write_manifest(root: Path, suite: str, description: str, cells: list[Cell]) -> None:
    """Write (atomically) the manifest of suite `suite` with these cells; OSError if it cannot be."""
    data = {"suite": suite, "description": description,
            "cells": [{"dir": c.dir, "config": c.config.model_dump(mode="json")} for c in cells]}
    root.mkdir(parents=True, exist_ok=True)
    atomic_write(root / MANIFEST, json.dumps(data, indent=2).encode())
