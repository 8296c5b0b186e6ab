"""deepphy: the DeepPHY benchmark harness."""

from __future__ import annotations

import os
import sys

DISTRIBUTION = "deepphy"


def installed_version() -> str:
    """The installed distribution's version, from its metadata (`<name>-<version>.dist-info/
    METADATA` on sys.path, the first found, as importlib.metadata finds it). Read directly:
    importing importlib.metadata took twice Python's own start, which `deepphy --version`
    waited for."""
    prefix = DISTRIBUTION + "-"
    for entry in sys.path:
        try:
            names = [n for n in os.listdir(entry or ".") if n.startswith(prefix) and n.endswith(".dist-info")]
        except OSError:  # not a directory (a zip, a missing entry)
            continue
        for name in names:
            try:
                with open(os.path.join(entry or ".", name, "METADATA"), encoding="utf-8") as metadata:
                    for line in metadata:
                        if line.startswith("Version:"):
                            return line.partition(":")[2].strip()
                        if not line.strip():  # the headers end here
                            break
            except OSError:
                continue
    from importlib.metadata import PackageNotFoundError, version  # another kind of install

    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:  # run from a source tree that is not installed
        return "unknown"


def __getattr__(name: str) -> str:
    if name == "__version__":  # read when asked for: importing deepphy reads nothing
        return installed_version()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
