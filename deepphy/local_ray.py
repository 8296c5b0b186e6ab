"""Starting a local Ray instance on a busy machine, beside other local instances.

`ray.init(address="local")` fails there in two ways (Ray 2.60):
- its dashboard agent listens on a fixed port (52365): a second local instance on the same
  host cannot bind it;
- the raylet waits at most 30 s (not configurable) for its agents to write their port
  files; on a starved machine the dashboard agent takes longer than that to import its
  modules, and the raylet aborts ("The current node timed out during startup").

So every port Ray's agents open is chosen here, free and outside the range the kernel hands
out, before the start (`ray.init` takes no such options; `_ray_params` hands them to the
RayParams it builds), and the dashboard agent's HTTP port, which the raylet only reads to
report it, is written to the session's port file as soon as the session exists (the agent
writes the same number once it is up).
A start that still fails is retried with fresh ports; its processes are stopped first.

The autoscaler's monitor is not started: a local instance has a fixed size, and on a
2-core machine its start (one more process importing Ray) delays the first attempt.
"""

from __future__ import annotations

import contextlib
import glob
import logging
import os
import random
import re
import socket
import sys
import threading
import time
from pathlib import Path
from typing import Callable

import psutil

from deepphy.loopback import LOOPBACK_HOST
from deepphy.reaper import GRACE_S

START_TRIES = 3
# Ray takes 127.0.0.1 as "no address given" and advertises the machine's primary interface;
# any other loopback address keeps the local cluster's traffic on loopback. macOS only
# configures 127.0.0.1, so there we fall back to it.
LOOPBACK_NODE_IP = "127.0.0.2" if sys.platform.startswith("linux") else LOOPBACK_HOST
SESSION_WAIT_S = 120.0  # the GCS's port file (Ray's default wait is 30 s)
WORKER_REGISTER_TIMEOUT_S = 300  # a worker process's start, imports included (Ray's default: 60 s)
# Results up to this size travel inside the reply to their caller instead of through the object
# store (Ray's default: 100 KiB). An environment worker's answer to a batch of decisions is
# 30-800 KiB (up to 8 steps of 10-100 KiB, their images as PNG): through the object store each
# answer costs a put, a get and a release in the raylet and both processes (measured with
# benchmarks/cpu_per_attempt.py: Ray's own processes 0.4 -> 0.2 ms per I-PHYRE attempt).
INLINE_RESULT_MAX = 4 * 1024 * 1024
# Where the agents' ports are chosen (before the start, so they are free then): below the
# kernel's ephemeral range (Linux: from 32768), which binding port 0 and every outgoing
# connection draw from. Ray's own processes (each worker's gRPC server, their connections)
# take ports from it while its agents still import, and one did take the dashboard agent's
# port chosen there (the agent failed to bind, and the raylet, which shares its fate, died
# two seconds into the run). From 20000: above the worker ports of a `ray start` node
# (10002-19999) that may share the machine.
AGENT_PORTS = (20000, 32768)
EPHEMERAL_RANGE = "/proc/sys/net/ipv4/ip_local_port_range"
# What a failed start's logs say, most telling first.
CAUSES = [
    (re.compile(r"address already in use", re.I), "a port it needs is in use"),
    (re.compile(r"Timed out waiting for file \S*/(\w+?)_port_"), "the raylet timed out waiting for {0}"),
    (re.compile(r"Check failed: (.{0,120})"), "{0}"),
]


class RayStartFailed(RuntimeError):
    """The local Ray instance did not start. The message is for the user."""


def free_ports(host: str, n: int) -> list[int]:
    """`n` distinct ports free on every address (Ray's agents listen on all), chosen at random
    in `AGENT_PORTS` below the kernel's ephemeral range; from that range (a port the kernel
    hands out) only where the machine leaves no room below it."""
    low, high = AGENT_PORTS[0], min(AGENT_PORTS[1], _ephemeral_start())
    if high - low < 1000:
        return _kernel_ports(host, n)
    pick = random.Random()  # a port, not an outcome: nothing to seed
    ports: list[int] = []
    for _ in range(100 * n):
        port = pick.randrange(low, high)
        if port not in ports and _bindable(port, host):
            ports.append(port)
            if len(ports) == n:
                return ports
    return _kernel_ports(host, n)


def _ephemeral_start() -> int:
    try:
        return int(Path(EPHEMERAL_RANGE).read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return AGENT_PORTS[1]


def _bindable(port: int, host: str) -> bool:
    for address in ("", host, LOOPBACK_HOST):  # every address ("": all of them), then the two Ray names
        try:
            with socket.socket() as s:
                s.bind((address, port))
        except OSError:
            return False
    return True


def _kernel_ports(host: str, n: int) -> list[int]:
    """`n` distinct ports the kernel hands out as free on `host` and on 127.0.0.1."""
    ports: list[int] = []
    held = []
    try:
        while len(ports) < n:
            s = socket.socket()
            s.bind((host, 0))
            held.append(s)
            port = s.getsockname()[1]
            try:
                if host != LOOPBACK_HOST:
                    with socket.socket() as t:
                        t.bind((LOOPBACK_HOST, port))
            except OSError:
                continue
            ports.append(port)
    finally:
        for s in held:
            s.close()
    return ports


@contextlib.contextmanager
def _ray_params(fields: dict):
    """`ray.init(address="local")` with these RayParams fields set (it has no options for them)."""
    # Ray (seconds to import): only when a local instance is started
    import ray._private.parameter as parameter

    original = parameter.RayParams

    class WithFields(original):  # type: ignore[misc, valid-type]
        def __init__(self, **kwargs):
            super().__init__(**{**kwargs, **fields})

    parameter.RayParams = WithFields
    try:
        yield
    finally:
        parameter.RayParams = original


def temp_root() -> str:
    # Ray (seconds to import): only when a local instance is started
    import ray._common.utils

    return os.environ.get("RAY_TMPDIR") or ray._common.utils.get_default_ray_temp_dir()


def sessions_of(pid: int, root: str | None = None) -> list[str]:
    """Session directories of the local instances started by process `pid` (Ray names them
    session_<date>_<pid>), newest last."""
    found = glob.glob(os.path.join(root or temp_root(), f"session_*_{pid}"))
    return sorted(found, key=os.path.getmtime)


def _announce_listen_port(session_root: str, since: float, port: int, stop: threading.Event) -> None:
    """Write the dashboard agent's HTTP port file of the session this process starts, as soon
    as the session has a node (its GCS port file), unless the agent was faster."""
    # Ray (seconds to import): only when a local instance is started
    from ray._raylet import DASHBOARD_AGENT_LISTEN_PORT_NAME, GCS_SERVER_PORT_NAME, persist_port

    while not stop.wait(0.05):
        for session in sessions_of(os.getpid(), session_root):
            if os.path.getmtime(session) < since - 1:
                continue
            for name in os.listdir(session):
                if name.startswith(GCS_SERVER_PORT_NAME + "_"):
                    node_id = name[len(GCS_SERVER_PORT_NAME) + 1:]
                    target = os.path.join(session, f"{DASHBOARD_AGENT_LISTEN_PORT_NAME}_{node_id}")
                    if not os.path.exists(target):
                        persist_port(session, node_id, DASHBOARD_AGENT_LISTEN_PORT_NAME, port)
                    return


def start(num_cpus: int, node_ip: str, say: Callable[[str], None] = lambda _: None, temp_dir: str | None = None,
          **init_kwargs) -> None:
    """`ray.init` of a new local instance (its sessions under `temp_dir`, default Ray's),
    retried; RayStartFailed with the cause and the logs' directory when it does not come up."""
    # Ray (seconds to import): only when a local instance is started
    import ray

    root = temp_dir or temp_root()
    if temp_dir:
        init_kwargs["_temp_dir"] = temp_dir
    logging.getLogger("ray._private.authentication.authentication_token_setup").setLevel(logging.ERROR)
    for attempt in range(1, START_TRIES + 1):
        since = time.time()
        agent, metrics, runtime_env, export = free_ports(node_ip, 4)
        stop = threading.Event()
        writer = threading.Thread(target=_announce_listen_port, args=(root, since, agent, stop), daemon=True)
        writer.start()
        os.environ.setdefault("RAY_gcs_server_port_wait_time_s", str(int(SESSION_WAIT_S)))
        try:
            with _ray_params({"dashboard_agent_listen_port": agent, "metrics_agent_port": metrics,
                              "runtime_env_agent_port": runtime_env, "metrics_export_port": export,
                              "no_monitor": True}):
                ray.init(address="local", num_cpus=num_cpus, _node_ip_address=node_ip,
                         _system_config={"worker_register_timeout_seconds": WORKER_REGISTER_TIMEOUT_S,
                                         "max_direct_call_object_size": INLINE_RESULT_MAX,
                                         "enable_metrics_collection": False},
                         **init_kwargs)
            return
        except Exception as e:  # noqa: BLE001 - Ray raises plain Exceptions here
            failure = e
        finally:
            stop.set()
            writer.join()
        sessions = [s for s in sessions_of(os.getpid(), root) if os.path.getmtime(s) >= since - 1]
        logs = os.path.join(sessions[-1], "logs") if sessions else root
        cause = failure_cause(logs) or first_line(failure)
        stop_leftovers(since)
        if attempt == START_TRIES:
            raise RayStartFailed(f"the local Ray instance did not start ({START_TRIES} tries; last: {cause}); "
                                 f"its logs: {logs}") from None
        say(f"Ray did not start ({cause}); trying again ({attempt + 1}/{START_TRIES})")


def first_line(error: BaseException) -> str:
    text = str(error).strip()
    return text.splitlines()[0][:200] if text else type(error).__name__


def failure_cause(logs: str) -> str | None:
    """The most telling line of a failed start's logs, in words."""
    lines = []
    for path in sorted(Path(logs).glob("*")):
        if path.is_file() and path.suffix in (".out", ".err", ".log"):
            try:
                lines += path.read_text(errors="replace").splitlines()
            except OSError:
                continue
    for pattern, words in CAUSES:
        for line in lines:
            found = pattern.search(line)
            if found:
                return words.format(*found.groups()).strip()
    return None


def stop_leftovers(since: float) -> None:
    """Stop what a failed start left running: this process's children started since then
    (Ray's processes) and their descendants; never the watchdog (deepphy.reaper)."""
    me = psutil.Process()
    family = []
    for child in me.children():
        try:
            if child.create_time() >= since - 1 and "deepphy.reaper" not in " ".join(child.cmdline()):
                family += [child, *child.children(recursive=True)]
        except psutil.Error:
            continue
    for p in family:
        with contextlib.suppress(psutil.Error):
            p.terminate()
    _, alive = psutil.wait_procs(family, timeout=GRACE_S)
    for p in alive:  # the agents ignore SIGTERM
        with contextlib.suppress(psutil.Error):
            p.kill()
    psutil.wait_procs(alive, timeout=5)
