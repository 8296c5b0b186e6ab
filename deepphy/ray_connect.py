"""Connecting a command to Ray: join the cluster at an address, or start a local instance
(deepphy.local_ray) watched by deepphy.reaper. A run, a suite, `deepphy watch` and the
dashboard's live view all connect here."""

from __future__ import annotations

import logging
import os
import socket
import sys
import tempfile
import threading
import time
from typing import Callable

from deepphy import local_ray, reaper
from deepphy.config import RuntimeOptions
from deepphy.loopback import LOOPBACK_HOST
from deepphy.ray_env import quiet_environment

CONNECT_TIMEOUT_S = 10.0  # joining a cluster: a clear error instead of Ray's minutes of retries


class ClusterUnavailable(RuntimeError):
    """No usable Ray cluster at the address given. The message is for the user."""


def ensure_ray(runtime: RuntimeOptions, say: Callable[[str], None] = lambda _: None) -> bool:
    """Connect to Ray; returns True if this call connected (to disconnect or shut down later).
    An address (HOST:PORT or "auto") joins that cluster; so does RAY_ADDRESS when none is
    given (`ray job submit` and KubeRay set it for the driver). Otherwise a new local cluster
    starts (deepphy.local_ray), even if `ray start` left an address file on this machine.
    `say` hears what is being done (and a retried start)."""
    import ray  # seconds to import: only a command that uses a cluster pays for it

    if ray.is_initialized():
        return False
    quiet_environment()
    address = runtime.address or os.environ.get("RAY_ADDRESS")
    if address:
        say(f"joining the Ray cluster at {address}")
        join_cluster(address)
        return True
    say(f"starting Ray (local, {runtime.num_cpus} CPUs)")
    # Started first: if this process dies at any point from here (kill -9 during Ray's own
    # start included), the watchdog stops every process of the local Ray instance it started.
    reaper.start(local_ray.temp_root())
    # Worker output stays in the run directory's logs/ and Ray's session logs, not the terminal.
    local_ray.start(runtime.num_cpus, local_ray.LOOPBACK_NODE_IP, say=say, include_dashboard=False,
                    object_store_memory=256 * 1024**2, logging_level=logging.WARNING, log_to_driver=False)
    return True


def disconnect(connected: bool) -> None:
    """Undo `ensure_ray` where it connected (a local instance it started stops)."""
    if connected:
        import ray  # loaded already: this process connected

        ray.shutdown()


def join_cluster(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """`ray.init(address=...)`, failing within seconds with one line that names the address
    (and the token setting, when that is the cause) instead of retrying for minutes.

    Ray's client retries print to the process's stderr from C++; while connecting, that
    output goes to a temporary file, read only to tell an authentication failure."""
    import ray  # seconds to import: only a command that uses a cluster pays for it

    host, sep, port = address.rpartition(":")
    if sep and port.isdigit() and "://" not in address:  # HOST:PORT: is anything listening?
        _probe(host, int(port), address, timeout_s)
    failure: list[BaseException] = []

    def connect() -> None:
        try:
            ray.init(address=address, logging_level=logging.WARNING)
        except BaseException as e:  # noqa: BLE001 - reported below
            failure.append(e)

    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as noise:
        os.dup2(noise.fileno(), 2)
        try:
            worker = threading.Thread(target=connect, daemon=True)
            worker.start()
            deadline = time.monotonic() + timeout_s
            said = ""
            while worker.is_alive() and time.monotonic() < deadline and not _refused(said):
                worker.join(0.25)
                noise.seek(0)
                said = noise.read().decode(errors="replace")
            said += "".join(f"{type(e).__name__}: {e}" for e in failure)
        finally:
            if worker.is_alive() or failure:
                # Ray keeps retrying in the background until this process exits: keep its
                # output away from the terminal and give Python a stderr of its own.
                sys.stderr = os.fdopen(saved, "w", buffering=1)
            else:
                os.dup2(saved, 2)
                os.close(saved)
    if not worker.is_alive() and not failure:
        return
    if _refused(said):
        mode = os.environ.get("RAY_AUTH_MODE", "unset")
        raise ClusterUnavailable(
            f"the Ray cluster at {address} refused this client's credentials (RAY_AUTH_MODE is {mode}; a "
            "cluster with token authentication needs RAY_AUTH_MODE=token and its token, e.g. ~/.ray/auth_token)"
        )
    if worker.is_alive():
        raise ClusterUnavailable(f"the Ray cluster at {address} did not accept the connection within {timeout_s:g} s")
    first = str(failure[0]).strip().splitlines()[0][:200] if str(failure[0]).strip() else type(failure[0]).__name__
    raise ClusterUnavailable(f"cannot join the Ray cluster at {address}: {first}")


def _refused(said: str) -> bool:
    """Ray's words for a client whose token does not match the cluster's."""
    said = said.lower()
    return "unauthenticated" in said or "invalidauthtoken" in said or "auth_token" in said


def _probe(host: str, port: int, address: str, timeout_s: float) -> None:
    try:
        with socket.create_connection((host or LOOPBACK_HOST, port), timeout=min(timeout_s, 5.0)):
            pass
    except OSError as e:
        reason = e.strerror or type(e).__name__
        raise ClusterUnavailable(f"no Ray cluster answers at {address} ({reason.lower()})") from None
