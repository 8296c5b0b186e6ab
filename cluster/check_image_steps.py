#!/usr/bin/env python3
"""Check the Dockerfile without a Docker engine: execute its steps for real in a Debian
root filesystem and run the result.

    sudo python3 cluster/check_image_steps.py [--workdir DIR] [--fresh-cache] [--keep]

What it does, in order:
1. Base. `python:3.11-slim-bookworm` is debian:bookworm-slim plus a CPython built into
   /usr/local. The stand-in is a debootstrap `minbase` bookworm (what debian:bookworm-slim
   is made of) plus Debian's own python3.11 and pip, with pip allowed to install into
   /usr/local as in the Python image. Built once under WORKDIR/base, copied fresh per check.
2. Build. Every instruction of the Dockerfile, in order, as Docker runs it: RUN through
   `/bin/sh -c` in WORKDIR as USER with the accumulated ENV/ARG (in a chroot, in its own
   mount and PID namespaces, with Docker's default 64 MiB /dev/shm); COPY from the build
   context filtered by .dockerignore (with --chown); `RUN --mount=type=cache` binds a cache
   directory (by default the host's uv cache, so wheels are not downloaded again;
   --fresh-cache starts empty and downloads everything from PyPI as a real build would).
3. Run. As the image's USER, in its WORKDIR, with its ENV (what `docker run IMAGE CMD`
   does): no Ray token or other state baked into the image; every shared library the
   installed wheels link to resolves, except a listed few nothing of deepphy loads (ldd);
   every simulator imports; a real `deepphy run` (MOCK, local Ray) of every environment
   plus `deepphy report`, its run directory owned by the image user; a login shell (what
   `ray up` runs commands in) finds `deepphy` and `ray` in the venv.

Not covered: Docker itself (layer caching, the image config, `docker push`), the exact
CPython build of the python image (Debian's python3.11 differs in patch level and build
flags), and anything a cluster adds (`ray up`, KubeRay). Needs root, `unshare`, `chroot`
and network access to deb.debian.org and PyPI. Exit status 0 only if every step passed.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASE_IMAGE = "python:3.11-slim-bookworm"
DEBIAN_SUITE = "bookworm"
DEBIAN_MIRROR = "http://deb.debian.org/debian"
# The Python image's own configuration (docker-library/python, 3.11/slim-bookworm).
BASE_ENV = {"PATH": "/usr/local/bin:/usr/local/sbin:/usr/sbin:/usr/bin:/sbin:/bin", "LANG": "C.UTF-8"}
STEP_TIMEOUT_S = 3600
SUPPORTED = {"FROM", "ARG", "ENV", "RUN", "COPY", "WORKDIR", "USER", "CMD", "LABEL", "EXPOSE"}


# ---------------------------------------------------------------- Dockerfile parsing


@dataclass
class Instruction:
    name: str  # upper case, e.g. RUN
    args: str  # the rest of the line, continuations joined, flags removed
    flags: dict[str, str] = field(default_factory=dict)  # --chown=..., --mount=...
    line: int = 0


def parse_dockerfile(text: str) -> list[Instruction]:
    """Instructions of a Dockerfile: comments dropped, `\\` continuations joined, leading
    `--flag=value` options split off. Raises ValueError on an instruction this checker
    cannot execute (so the check never silently skips a step)."""
    out: list[Instruction] = []
    pending, start = "", 0
    for number, raw in enumerate(text.splitlines(), 1):
        stripped = raw.strip()
        if not pending and (not stripped or stripped.startswith("#")):
            continue
        if pending and stripped.startswith("#"):  # a comment inside a continued instruction
            continue
        if not pending:
            start = number
        if stripped.endswith("\\"):
            pending += stripped[:-1].rstrip() + " "
            continue
        logical = pending + stripped
        pending = ""
        name, _, rest = logical.partition(" ")
        name = name.upper()
        if name not in SUPPORTED:
            raise ValueError(f"Dockerfile line {start}: {name} is not supported by this check")
        flags: dict[str, str] = {}
        rest = rest.strip()
        while rest.startswith("--"):
            flag, _, rest = rest.partition(" ")
            key, _, value = flag[2:].partition("=")
            flags[key] = value
            rest = rest.strip()
        out.append(Instruction(name, rest, flags, start))
    if pending:
        raise ValueError("Dockerfile ends inside a continued line")
    return out


def substitute(text: str, env: dict[str, str]) -> str:
    """Docker's variable substitution for non-RUN instructions: $VAR, ${VAR}, ${VAR:-default}."""

    def repl(m: re.Match) -> str:
        name = m.group(1) or m.group(3)
        default = m.group(2)
        value = env.get(name, "")
        return value if value or default is None else default

    return re.sub(r"\$\{(\w+)(?::-([^}]*))?\}|\$(\w+)", repl, text)


def parse_env(args: str, env: dict[str, str]) -> dict[str, str]:
    """`ENV A=1 B="x y"` (or the legacy `ENV A value`) -> {name: value}, values substituted."""
    words = shlex.split(args)
    if words and "=" not in words[0]:
        return {words[0]: substitute(" ".join(words[1:]), env)}
    pairs = {}
    for word in words:
        key, sep, value = word.partition("=")
        if not sep:
            raise ValueError(f"ENV expects KEY=VALUE, got {word!r}")
        pairs[key] = substitute(value, env)  # Docker: the values from before this instruction
    return pairs


def mount_flags(spec: str) -> dict[str, str]:
    return dict(part.partition("=")[::2] for part in spec.split(","))


# ---------------------------------------------------------------- build context


def dockerignore_patterns(context: Path) -> list[tuple[bool, re.Pattern]]:
    """(is_exception, regex) per line of .dockerignore; Docker's rules: paths relative to the
    context root, `**` any number of directories, `!` re-includes."""
    path = context / ".dockerignore"
    patterns = []
    for line in path.read_text().splitlines() if path.exists() else []:
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        exception = line.startswith("!")
        line = os.path.normpath(line.lstrip("!").strip().lstrip("/"))
        regex = ""
        for part in re.split(r"(\*\*/?)", line):
            if part.startswith("**"):
                regex += "(?:.*/)?" if part.endswith("/") else ".*"
            elif part:
                regex += _glob_to_regex(part)
        patterns.append((exception, re.compile(regex + r"\Z")))
    return patterns


def _glob_to_regex(glob: str) -> str:
    """A path-segment glob as a regex: `*` and `?` never cross a `/`."""
    out = ""
    i = 0
    while i < len(glob):
        c = glob[i]
        if c == "*":
            out += "[^/]*"
        elif c == "?":
            out += "[^/]"
        elif c == "[":
            end = glob.find("]", i)
            if end == -1:
                out += re.escape(c)
            else:
                out += glob[i : end + 1]
                i = end
        else:
            out += re.escape(c)
        i += 1
    return out


def is_ignored(rel: str, patterns: list[tuple[bool, re.Pattern]]) -> bool:
    """Whether a context path is excluded: the last matching pattern decides; a pattern that
    matches a parent directory excludes everything below it."""
    parts = rel.split("/")
    candidates = ["/".join(parts[: i + 1]) for i in range(len(parts))]
    ignored = False
    for exception, regex in patterns:
        if any(regex.match(c) for c in candidates):
            ignored = not exception
    return ignored


def context_files(context: Path) -> list[str]:
    """Every file the Docker client would send as the build context (relative paths)."""
    patterns = dockerignore_patterns(context)
    files = []
    for dirpath, dirnames, filenames in os.walk(context):
        rel_dir = os.path.relpath(dirpath, context)
        rel_dir = "" if rel_dir == "." else rel_dir + "/"
        # An excluded directory is skipped whole unless some `!` pattern could re-include
        # a path below it (then it is walked, as Docker does).
        if not any(exception for exception, _ in patterns):
            dirnames[:] = [d for d in dirnames if not is_ignored(rel_dir + d, patterns)]
        files += [rel_dir + f for f in filenames if not is_ignored(rel_dir + f, patterns)]
    return sorted(files)


# ---------------------------------------------------------------- the chroot


def sh(cmd: list[str] | str, **kw) -> subprocess.CompletedProcess:
    shell = isinstance(cmd, str)
    print(f"+ {cmd if shell else shlex.join(cmd)}", flush=True)
    return subprocess.run(cmd, shell=shell, check=True, **kw)


def ensure_debootstrap(workdir: Path) -> list[str]:
    """The debootstrap command: the installed one, else Debian's package unpacked (no install)."""
    if shutil.which("debootstrap"):
        return ["debootstrap"]
    unpacked = workdir / "debootstrap"
    if not (unpacked / "usr/sbin/debootstrap").exists():
        sh(f"cd {shlex.quote(str(workdir))} && apt-get download debootstrap")
        deb = next(workdir.glob("debootstrap_*.deb"))
        sh(["dpkg", "-x", str(deb), str(unpacked)])
    os.environ["DEBOOTSTRAP_DIR"] = str(unpacked / "usr/share/debootstrap")
    return [str(unpacked / "usr/sbin/debootstrap")]


def build_base(workdir: Path) -> Path:
    base = workdir / "base"
    done = base / ".deepphy-base-ok"
    if done.exists():
        return base
    shutil.rmtree(base, ignore_errors=True)
    sh([*ensure_debootstrap(workdir), "--variant=minbase", "--include=ca-certificates,netbase,tzdata",
        DEBIAN_SUITE, str(base), DEBIAN_MIRROR])
    shutil.copy("/etc/resolv.conf", base / "etc/resolv.conf")
    in_root(base, "apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "
                  "python3.11 python3-pip && rm -rf /var/lib/apt/lists/*", env=BASE_ENV)
    # The Python image's pip installs into /usr/local, as root, without PEP 668's marker.
    for marker in (base / "usr/lib").glob("python3*/EXTERNALLY-MANAGED"):
        marker.unlink()
    (base / "usr/local/bin").mkdir(parents=True, exist_ok=True)
    for name in ("python3", "python", "python3.11"):
        link = base / "usr/local/bin" / name
        if not link.exists():
            link.symlink_to("/usr/bin/python3.11")
    done.write_text(time.strftime("%Y-%m-%d %H:%M:%S\n"))
    return base


def user_ids(root: Path, user: str) -> tuple[int, int, str]:
    """(uid, gid, home) of USER ("name", "uid" or "name:group") in the root filesystem."""
    name, _, group = user.partition(":")
    for line in (root / "etc/passwd").read_text().splitlines():
        fields = line.split(":")
        if name in (fields[0], fields[2]):
            uid, gid, home = int(fields[2]), int(fields[3]), fields[5]
            break
    else:
        if not name.isdigit():
            raise ValueError(f"USER {name}: no such user in the image")
        uid, gid, home = int(name), int(name), "/"
    if group:
        for line in (root / "etc/group").read_text().splitlines():
            fields = line.split(":")
            if group in (fields[0], fields[2]):
                gid = int(fields[2])
    return uid, gid, home


NAMESPACE_SCRIPT = r"""
set -e
R=$1; SHM=$2; shift 2
mount -t proc proc "$R/proc"
mount -t sysfs -o ro sysfs "$R/sys"
mount -t tmpfs -o mode=755 tmpfs "$R/dev"
for d in null zero full random urandom tty; do touch "$R/dev/$d"; mount --bind "/dev/$d" "$R/dev/$d"; done
mkdir -p "$R/dev/shm" "$R/dev/pts"
mount -t tmpfs -o "size=$SHM,mode=1777" shm "$R/dev/shm"
ln -s /proc/self/fd "$R/dev/fd"
while [ "$1" = "--bind" ]; do
  if [ -d "$2" ]; then mkdir -p "$R$3"; else mkdir -p "$(dirname "$R$3")"; [ -e "$R$3" ] || touch "$R$3"; fi
  mount --bind "$2" "$R$3"; shift 3
done
exec chroot "$@"
"""


def in_root(root: Path, command: str, *, env: dict[str, str], user: str = "root", workdir: str = "/",
            binds: list[tuple[str, str]] = (), timeout: float = STEP_TIMEOUT_S,
            capture: bool = False) -> subprocess.CompletedProcess:
    """Run `/bin/sh -c command` in the root filesystem as Docker's RUN / `docker run` would:
    own mount and PID namespaces (every process it leaves behind dies with it, and all die
    if this check is killed), /proc, a read-only /sys, a minimal /dev with a 64 MiB
    /dev/shm, the host's network."""
    uid, gid, home = user_ids(root, user)
    full_env = {"HOME": home, **env}
    bind_args = [arg for src, dst in binds for arg in ("--bind", src, dst)]
    inner = f"cd {shlex.quote(workdir)} && {command}"
    cmd = ["unshare", "--mount", "--pid", "--fork", "--kill-child", "--propagation", "private",
           "sh", "-c", NAMESPACE_SCRIPT, "sh",
           str(root), "64m", *bind_args, f"--userspec={uid}:{gid}", str(root),
           "/usr/bin/env", "-i", *[f"{k}={v}" for k, v in full_env.items()], "/bin/sh", "-c", inner]
    print(f"+ [{user} in {workdir}] {command}", flush=True)
    return subprocess.run(cmd, check=True, timeout=timeout, text=True,
                          stdout=subprocess.PIPE if capture else None, stderr=subprocess.STDOUT if capture else None)


# ---------------------------------------------------------------- build and run


@dataclass
class Image:
    root: Path | None
    env: dict[str, str]
    user: str
    workdir: str
    cmd: str
    args: dict[str, str]  # build arguments in force (their defaults: this check passes no --build-arg)


def image_config(instructions: list[Instruction]) -> Image:
    """The configuration after `instructions` (ENV, ARG, USER, WORKDIR, CMD), without building:
    what `docker run` starts from, or what a step runs with."""
    env, args = dict(BASE_ENV), {}
    user, workdir, cmd = "root", "/", ""
    for ins in instructions:
        scope = {**args, **env}
        if ins.name == "ARG":
            args.update(parse_env(ins.args, scope) if "=" in ins.args else {ins.args: ""})
        elif ins.name == "ENV":
            env.update(parse_env(ins.args, scope))
        elif ins.name == "WORKDIR":
            workdir = os.path.join(workdir, substitute(ins.args, scope))
        elif ins.name == "USER":
            user = substitute(ins.args, scope)
        elif ins.name == "CMD":
            cmd = ins.args
    return Image(None, env, user, workdir, cmd, args)


def host_network() -> tuple[list[tuple[str, str]], dict[str, str]]:
    """Binds and environment that let RUN steps reach the network the way this host does.
    A host whose egress goes through a TLS-intercepting proxy trusts the proxy's CA through
    SSL_CERT_FILE; the chroot gets that bundle (over its own) for the duration of a RUN
    step, as a `docker build` on such a host would need too. Nothing of it lands in the image."""
    bundle = os.environ.get("SSL_CERT_FILE")
    if not bundle or not Path(bundle).is_file():
        return [], {}
    target = "/etc/ssl/certs/ca-certificates.crt"
    return [(bundle, target)], {"SSL_CERT_FILE": target}


def build(root: Path, context: Path, dockerfile: Path, cache: Path) -> Image:
    files = context_files(context)
    net_binds, net_env = host_network()
    instructions = parse_dockerfile(dockerfile.read_text())
    for i, ins in enumerate(instructions):
        config = image_config(instructions[:i])  # what is in force at this step
        scope = {**config.args, **config.env}
        print(f"\n=== Dockerfile:{ins.line} {ins.name} {ins.args[:100]}", flush=True)
        if ins.name == "FROM" and (i > 0 or ins.args.split()[0] != BASE_IMAGE):
            raise SystemExit(f"the stand-in base emulates one stage FROM {BASE_IMAGE} only, not {ins.args}")
        elif ins.name == "WORKDIR":
            (root / image_config(instructions[: i + 1]).workdir.lstrip("/")).mkdir(parents=True, exist_ok=True)
        elif ins.name == "USER":
            user_ids(root, substitute(ins.args, scope))  # must exist
        elif ins.name == "COPY":
            copy(root, context, files, substitute(ins.args, scope), config.workdir, ins.flags.get("chown"))
        elif ins.name == "RUN":
            binds = list(net_binds)
            if "mount" in ins.flags:
                spec = mount_flags(ins.flags["mount"])
                if spec.get("type") != "cache":
                    raise SystemExit(f"RUN --mount type {spec.get('type')} is not supported by this check")
                binds.append((str(cache), spec["target"]))
            in_root(root, ins.args, env={**net_env, **scope}, user=config.user, workdir=config.workdir, binds=binds)
    final = image_config(instructions)
    final.root = root
    return final


def copy(root: Path, context: Path, files: list[str], spec: str, workdir: str, chown: str | None) -> None:
    *sources, dest = shlex.split(spec)
    dest_path = dest if dest.startswith("/") else os.path.join(workdir, dest)
    uid = gid = 0
    if chown:
        uid, gid, _ = user_ids(root, chown)
    to_dir = dest.endswith("/") or len(sources) > 1
    for source in sources:
        source = os.path.normpath(source)
        matched = [f for f in files if f == source or f.startswith(source + "/")]
        if not matched:
            raise SystemExit(f"COPY {source}: not in the build context (missing or excluded by .dockerignore)")
        for rel in matched:
            if rel == source:  # a file
                target = os.path.join(dest_path, os.path.basename(rel)) if to_dir else dest_path
            else:  # a directory: its contents go to dest
                target = os.path.join(dest_path, os.path.relpath(rel, source))
            out = root / target.lstrip("/")
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(context / rel, out)
            os.chown(out, uid, gid)
            for parent in out.relative_to(root / dest_path.lstrip("/")).parents:
                os.chown(root / dest_path.lstrip("/") / parent, uid, gid)
    print(f"copied {sources} -> {dest_path}", flush=True)


SMOKE_IMPORTS = "import cv2, pygame, pymunk, Box2D, pooltool, kinetix, jax, ray, deepphy; print('imports ok')"

# One short real run per environment: every simulator steps (numba and JAX compile) in the image.
SMOKE_RUNS = {"iphyre": 4, "phyre": 2, "pooltool": 1, "kinetix": 1}

# Libraries some installed .so files link to that the slim base lacks, on purpose: nothing
# deepphy does loads them (the check fails on any library not listed here).
UNUSED_LIBRARIES = {
    "libGL.so.1": "panda3d's OpenGL display modules: deepphy renders with OpenCV, never opens a window",
    "libEGL.so.1": "panda3d's headless OpenGL module (same)",
    "libX11.so.6": "panda3d's X11 display modules and pygame.scrap (clipboard)",
    "libglib-2.0.so.0": "pygame's audio mixer",
    "libgthread-2.0.so.0": "pygame's audio mixer",
    "libgomp.so.1.0.0": "numba's optional OpenMP threading layer (numba falls back to its own)",
    "libtbb.so.12": "numba's optional TBB threading layer (same)",
}

# `ldd` on every shared object of the venv; "NAME => not found" lines, except libraries the
# wheel ships itself (found through the loading module's rpath, which ldd on the library
# alone does not see) and panda3d's deploy_libs (stdlib stubs for its app freezer, never
# imported).
LDD_SCAN = r"""
import json, os, subprocess, sys
venv = sys.prefix
files, shipped = [], set()
for d, _, fs in os.walk(venv):
    shipped.update(fs)
    files += [os.path.join(d, f) for f in fs if ".so" in f and "/deploy_libs" not in d]
missing = {}
for p in files:
    out = subprocess.run(["ldd", p], capture_output=True, text=True).stdout
    for line in out.splitlines():
        name, arrow, where = line.strip().partition(" => ")
        if arrow and where.strip() == "not found" and name not in shipped:
            missing.setdefault(name, []).append(os.path.relpath(p, venv))
print(json.dumps(missing))
"""


def smoke(image: Image, workdir_out: Path) -> dict[str, object]:
    """Run the image's commands as `docker run` would; returns the facts checked."""

    def run(command: str, capture: bool = True) -> str:
        result = in_root(image.root, command, env=image.env, user=image.user, workdir=image.workdir,
                         capture=capture, timeout=1800)
        print(result.stdout if capture else "", flush=True)
        return result.stdout or ""

    facts: dict[str, object] = {}
    uid, _, home = user_ids(image.root, image.user)
    # The image must not carry a Ray token (every container would share it) or any state.
    baked = sorted(str(p.relative_to(image.root)) for p in (image.root / home.lstrip("/")).rglob("*")
                   if p.is_file() and not p.name.startswith((".bash", ".profile")))
    facts["home_after_build"] = baked
    if any(".ray" in p for p in baked):
        raise SystemExit(f"the image carries Ray state in {home}: {baked}")
    # First, so that a missing library shows up even when an import below fails on it.
    missing = json.loads(run(f"python -c {shlex.quote(LDD_SCAN)}").strip().splitlines()[-1])
    facts["unresolved_unused_libraries"] = sorted(missing)
    unexpected = {k: v for k, v in missing.items() if k not in UNUSED_LIBRARIES}
    if unexpected:
        raise SystemExit(f"libraries the image lacks (add their Debian packages to the Dockerfile): {unexpected}")
    run(f"python -c {shlex.quote(SMOKE_IMPORTS)}")
    envs = run("deepphy envs")
    facts["envs"] = [line.split()[0] for line in envs.splitlines()[1:] if line.strip()]
    if sorted(facts["envs"]) != sorted(SMOKE_RUNS):
        raise SystemExit(f"environments {facts['envs']} != the ones this check runs {sorted(SMOKE_RUNS)}")
    records = {}
    for env, limit in SMOKE_RUNS.items():
        out = f"runs/image-check-{env}"
        t0 = time.monotonic()
        run(f"deepphy run --env {env} --model mock --limit {limit} --runs 1 --out {out} --no-progress")
        facts[f"run_{env}_s"] = round(time.monotonic() - t0, 1)
        run(f"deepphy report {out}")
        run_dir = image.root / image.workdir.lstrip("/") / out
        owners = {p.stat().st_uid for p in run_dir.rglob("*")}
        if owners != {uid}:
            raise SystemExit(f"{out}: files owned by {owners}, expected the image user {uid}")
        records[env] = sum(1 for _ in (run_dir / "attempts.jsonl").open())
        shutil.copytree(run_dir, workdir_out / out, dirs_exist_ok=True)
    facts["records"] = records
    venv_bin = image.env["UV_PROJECT_ENVIRONMENT"] + "/bin/"
    login_path = run("bash --login -c 'command -v deepphy ray'").split()
    if len(login_path) != 2 or not all(p.startswith(venv_bin) for p in login_path):
        raise SystemExit(f"a login shell (as `ray up` uses) does not find deepphy and ray in the venv: {login_path}")
    facts["login_shell_path"] = login_path
    return facts


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--workdir", default="/tmp/deepphy-image-check", help="base, root filesystem and logs")
    p.add_argument("--context", default=str(ROOT), help="the build context (default: this repository)")
    p.add_argument("--fresh-cache", action="store_true",
                   help="an empty cache for RUN --mount=type=cache (downloads every wheel from PyPI)")
    p.add_argument("--keep", action="store_true", help="keep the built root filesystem for inspection")
    a = p.parse_args(argv)
    if os.geteuid() != 0:
        print("check_image_steps: needs root (debootstrap, chroot, mount namespaces)", file=sys.stderr)
        return 2
    workdir = Path(a.workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    context = Path(a.context).resolve()
    t0 = time.monotonic()
    base = build_base(workdir)
    root = workdir / "rootfs"
    shutil.rmtree(root, ignore_errors=True)
    sh(["cp", "-a", str(base), str(root)])
    if a.fresh_cache:
        cache = Path(tempfile.mkdtemp(prefix="cache-", dir=workdir))
    else:
        cache = Path(subprocess.run(["python3", "-m", "uv", "cache", "dir"], capture_output=True, text=True,
                                    check=True).stdout.strip())
    try:
        image = build(root, context, context / "Dockerfile", cache)
        built_s = time.monotonic() - t0
        facts = smoke(image, workdir)
        facts["build_s"] = round(built_s, 1)
        facts["venv_mb"] = int(subprocess.run(["du", "-sm", str(root / image.env["UV_PROJECT_ENVIRONMENT"].lstrip("/"))], capture_output=True,
                                              text=True).stdout.split()[0])
        facts["total_s"] = round(time.monotonic() - t0, 1)
        (workdir / "facts.json").write_text(json.dumps(facts, indent=2))
        print("\n=== image check passed\n" + json.dumps(facts, indent=2))
        return 0
    finally:
        if a.fresh_cache:
            shutil.rmtree(cache, ignore_errors=True)
        if not a.keep:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
