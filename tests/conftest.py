"""Shared fixtures: one real local Ray runtime per test session, on loopback."""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import pytest

from deepphy.cache import cache_root

# Before Ray or pygame are imported anywhere. Auth off: a purely local loopback cluster
# that the CLI subprocesses of the tests join with --address.
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
os.environ.setdefault("RAY_AUTH_MODE", "disabled")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")  # see deepphy.ray_env.quiet_environment
# One compile cache: the one `make setup` warmed (python -m deepphy.warm_up), so a test run after
# it compiles no kernel. Pinned here because some tests move HOME (pooltool writes its config
# there), which would move a HOME-relative cache. Tests that need a cold cache make their own.
os.environ["DEEPPHY_CACHE_DIR"] = str(cache_root())
# Ray workers must import test-only packages (tests/toy_env) as the tests do.
TESTS = os.path.dirname(os.path.abspath(__file__))
os.environ["PYTHONPATH"] = os.pathsep.join(p for p in [TESTS, os.environ.get("PYTHONPATH", "")] if p)

RAY_TIMEOUT_S = 120
pytest_plugins = ["browser_support"]  # the browser tests' one harness (chromium, pages, screenshots)
# The tests' own data (ground truth from the real simulators), kept in the repository:
# tests/data/README.md says where each file came from.
TEST_DATA = Path(__file__).resolve().parent / "data"


def data_file(name: str) -> Path:
    return TEST_DATA / name


# Nothing under tests/ reads beside the repository (a clone with nothing beside it must pass):
# every file this process opens or lists inside the repository's parent folder but outside the
# repository is noted, and the session fails naming them. (Subprocesses are not watched here;
# .ci/run runs the suite in a clone with nothing beside it, which catches those.)
REPO = str(Path(__file__).resolve().parents[1])
BESIDE = os.path.dirname(REPO) + os.sep
READ_BESIDE: list[str] = []


def _audit(event: str, args: tuple) -> None:
    if event not in ("open", "os.listdir", "os.scandir") or not args or not isinstance(args[0], (str, bytes, os.PathLike)):
        return
    path = os.fsdecode(args[0])
    if not os.path.isabs(path) or ".." in path:
        path = os.path.abspath(path)
    if path.startswith(BESIDE) and not (path == REPO or path.startswith(REPO + os.sep)):
        READ_BESIDE.append(path)


sys.addaudithook(_audit)


@pytest.fixture(scope="session")
def ray_cluster():
    """A 2-CPU Ray runtime for the whole session; yields its GCS address."""
    import logging

    import ray

    from deepphy import local_ray

    temp_dir = tempfile.mkdtemp(prefix="dpray", dir="/tmp")  # short: socket paths have a length limit
    # As `deepphy run` starts it: the machine the tests run on is often busy.
    local_ray.start(2, local_ray.LOOPBACK_NODE_IP, temp_dir=temp_dir, include_dashboard=False,
                    object_store_memory=200 * 1024**2, logging_level=logging.WARNING)
    address = ray.get_runtime_context().gcs_address
    assert address.startswith("127."), f"the test cluster must stay on loopback, got {address}"
    yield address
    ray.shutdown()


@pytest.fixture
def deepphy_cmd():
    """The CLI, run with this interpreter."""
    return [sys.executable, "-m", "deepphy.cli"]


def pytest_sessionfinish(session, exitstatus):
    """deepphy play's background work (a Kinetix warm-up still compiling after its test) must
    end before Python's exit, which aborts inside it ("terminate called ...")."""
    background = sys.modules.get("deepphy.play.background")
    if background is not None:
        background.wait(600)
    if READ_BESIDE:
        paths = sorted(set(READ_BESIDE))
        print(f"\nthe tests read {len(paths)} path(s) beside the repository (a clone with nothing beside it "
              f"would fail): {', '.join(paths[:10])}", file=sys.stderr)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
