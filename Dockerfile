# The deepphy image: the harness, its simulators and Ray, installed from uv.lock. One image
# for `deepphy run` on one machine, the nodes of a `ray up` cluster and KubeRay pods.
#
#   docker build -t deepphy:latest .
#   docker run --rm --shm-size=1g -v deepphy-runs:/data/runs deepphy:latest \
#       deepphy run --env iphyre --model mock --runs 1 --limit 5 --out runs/try
#
# Run directories go under /data/runs (relative --out paths start in /data). A new named
# volume there starts owned by the image's user (uid 1000); a bind-mounted host
# directory must be writable by uid 1000.
# Without a Docker engine, `sudo python3 cluster/check_image_steps.py` executes these
# steps in a Debian bookworm chroot and runs the result (see that file for what it covers).
FROM python:3.11-slim-bookworm

# No graphics or audio libraries: the wheels (opencv-python-headless, pygame, pymunk,
# Box2D, panda3d, jax) bundle what deepphy loads. What they link to but the slim base
# lacks (GL/EGL/X11 for panda3d's display modules, glib for pygame's mixer, numba's
# OpenMP/TBB layers) is never loaded; cluster/check_image_steps.py holds that list and
# fails on anything else `ldd` cannot resolve.
# rsync and openssh-client: `ray up` syncs files into the container with rsync, and the
# head's autoscaler reaches the worker machines over SSH.
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
      rsync openssh-client \
 && rm -rf /var/lib/apt/lists/*

ARG UV_VERSION=0.13.9
RUN pip install --no-cache-dir "uv==${UV_VERSION}"

# Never download a Python (use the image's 3.11); copy out of the cache mount (another
# filesystem); compile bytecode now, as the venv is read-only to the runtime user.
ENV UV_PYTHON_DOWNLOADS=never \
    UV_LINK_MODE=copy \
    UV_COMPILE_BYTECODE=1 \
    UV_PROJECT_ENVIRONMENT=/opt/deepphy/.venv
WORKDIR /opt/deepphy
# Dependencies first: this layer changes only with uv.lock.
COPY pyproject.toml uv.lock ./
RUN --mount=type=cache,target=/root/.cache/uv \
    uv sync --frozen --no-dev --no-install-project
COPY README.md ./
COPY deepphy ./deepphy
RUN --mount=type=cache,target=/root/.cache/uv \
    uv sync --frozen --no-dev

# Optional extra packages, e.g. the cloud SDK the Ray autoscaler needs on a `ray up` head
# node: docker build --build-arg EXTRA_PACKAGES="boto3" (see cluster/ray-cluster.yaml).
ARG EXTRA_PACKAGES=""
RUN if [ -n "${EXTRA_PACKAGES}" ]; then \
      uv pip install --no-cache --python /opt/deepphy/.venv/bin/python ${EXTRA_PACKAGES}; fi

# A non-root user owns /data (run directories) and its home (caches, Ray's token); the
# installed code stays root-owned. Login shells (what `ray up` runs commands in) reset
# PATH in /etc/profile, so profile.d puts the venv back in front.
RUN useradd --create-home --uid 1000 --shell /bin/bash deepphy \
 && mkdir -p /data/runs \
 && chown -R deepphy:deepphy /data \
 && echo 'export PATH="/opt/deepphy/.venv/bin:$PATH"' > /etc/profile.d/deepphy.sh

# HOME explicitly: `ray up` reads it from the image config to place file mounts.
# RAY_AUTH_MODE=token: every process (node, driver, CLI) uses Ray's token authentication.
ENV PATH=/opt/deepphy/.venv/bin:$PATH \
    HOME=/home/deepphy \
    PYTHONUNBUFFERED=1 \
    RAY_USAGE_STATS_ENABLED=0 \
    RAY_AUTH_MODE=token \
    RAY_ENABLE_UV_RUN_RUNTIME_ENV=0 \
    PYGAME_HIDE_SUPPORT_PROMPT=1 \
    DEEPPHY_CACHE_DIR=/home/deepphy/.cache/deepphy
USER deepphy
WORKDIR /data
# The build fails here if the installed harness cannot list its environments.
RUN deepphy envs
# The compile caches (Pooltool's numba kernels, Kinetix's JAX functions: minutes) filled in
# the image, as the runtime user: a container's or a cluster node's first run loads them.
RUN python -m deepphy.warm_up
CMD ["deepphy", "--help"]
