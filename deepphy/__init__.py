"""deepphy: the DeepPHY benchmark harness."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("deepphy")
except PackageNotFoundError:  # run from a source tree that is not installed
    __version__ = "unknown"
