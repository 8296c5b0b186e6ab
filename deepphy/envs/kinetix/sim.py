"""Everything that touches JAX / kinetix-env: level loading with a disk cache, one compiled
decision function per level size, batched (vmapped) stepping.

Imported lazily by the environment (importing kinetix takes seconds and pulls in its
whole training stack).

Batching is invisible: a record never depends on which episodes shared a batch.
- Every decision of a size, alone or in company, runs through ONE compiled program: the
  decision function vmapped over `BATCH` lanes. A short batch is padded with copies of its
  first episode (their results are dropped); a long one is cut into chunks of `BATCH`.
- Lanes never interact: kinetix's control flow is `scan` and `switch`, which vmap turns
  into per-lane selects, so a lane's result depends only on its own state and action.
- Programs of different batch shapes are not interchangeable: XLA rewrites and fuses a
  program according to its shapes, and XLA:CPU contracts `a*b + c` into fused
  multiply-adds, so two programs need not round alike. Measured over 16 random decisions
  per level: a vmap over 1 lane rounded differently from one over 8 lanes in 19 of 40 L
  levels and 2 of 24 M levels (S: none), from the first decision on, so a record depended
  on whether its episode happened to step alone. On L, vmaps over 2, 8 and 64 lanes and
  the unbatched function agreed with each other, but nothing guarantees that; one shape
  removes the question.

Cost control:
- Levels: kinetix's JSON loader is slow (0.1-2 s per level). The converted level
  (`jax.device_get(state)`, static and env params) is pickled once under
  `<cache root>/kinetix/levels/<kinetix version>/`; later loads take milliseconds.
- Compilation: one jitted, vmapped "decision" function (16 env steps in a `lax.scan`) per
  level size, compiled for the one shape `BATCH`; the three sizes have one StaticEnvParams
  each, and all levels share their EnvParams. The persistent JAX compilation cache lives
  under `<cache root>/kinetix/jax/` and is shared by workers.
- Cache root: the per-machine cache (deepphy.cache).
"""

from __future__ import annotations

import hashlib
import logging
import os
import pickle
import sys
import tempfile
import threading
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from deepphy.cache import cache_root as deepphy_cache_root
from deepphy.envs.kinetix.levels import STEPS_PER_DECISION, level_path

# The one batch shape compiled per size (see the module doc). 8 balances the cost of a lone
# episode (padded to 8 lanes) against throughput on many (benchmarks/kinetix_batching.py).
BATCH = 8
NUM_MOTOR_BINDINGS = 4
NUM_THRUSTER_BINDINGS = 2

_lock = threading.RLock()
_configured = False


# grain (imported by kinetix's level loading) warns through absl, at import, that this jaxlib
# is too old for its multiprocess worker profiling, which nothing here uses: `deepphy show`
# printed it. Only that message is dropped.
logging.getLogger("absl").addFilter(lambda record: not record.getMessage().startswith("Grain multiprocess"))


JAX_DEFAULT_LOG_LEVEL = "1"  # what `import jax` sets TF_CPP_MIN_LOG_LEVEL to when it is unset


def quiet_xla_log() -> None:
    """Keep XLA's C++ log (absl, on file descriptor 2) to fatal errors, unless the user chose
    its level (TF_CPP_MIN_LOG_LEVEL other than jax's own default). jaxlib 0.9 logs an ERROR
    for every program it loads from the persistent compilation cache (cpu_aot_loader.cc:
    "Target machine feature +prefer-no-scatter is not supported on the host machine ...
    could lead to ... SIGILL": it compares tuning flags that are no CPU features, on the
    machine that compiled them): `gymnasium.make("deepphy/kinetix-v0")` printed 128 such
    lines (237 KB), `--dry-run` 16. Our own errors are Python's (exceptions, logging), which
    this does not touch; a failure inside XLA still raises one. Done here, where JAX is
    first imported: jaxlib reads the variable as it loads; one loaded already is told."""
    if os.environ.get("TF_CPP_MIN_LOG_LEVEL", JAX_DEFAULT_LOG_LEVEL) != JAX_DEFAULT_LOG_LEVEL:
        return
    os.environ["TF_CPP_MIN_LOG_LEVEL"] = "3"
    if "jaxlib" in sys.modules:  # imported before deepphy's Kinetix (by the user's own code)
        try:
            from jax._src.lib import utils  # loaded already (the check above)

            utils.absl_set_min_log_level(3)
        except (ImportError, AttributeError):  # another jaxlib: its log stays as it is
            pass


quiet_xla_log()


def cache_root() -> Path:
    return deepphy_cache_root() / "kinetix"


def configure_jax() -> None:
    """Point JAX's persistent compilation cache at the shared cache root (once per process).

    A JAX_COMPILATION_CACHE_DIR set by the user wins.
    """
    global _configured
    with _lock:
        if _configured:
            return
        import jax  # after quiet_xla_log(): jaxlib reads its log level as it loads

        if not os.environ.get("JAX_COMPILATION_CACHE_DIR"):
            path = cache_root() / "jax"
            path.mkdir(parents=True, exist_ok=True)
            jax.config.update("jax_compilation_cache_dir", str(path))
        # Our compiles take seconds; cache everything that takes more than half a second.
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
        _configured = True


# -- levels ---------------------------------------------------------------------------


@dataclass
class Level:
    """A converted level: numpy state (the initial state) and its parameters."""

    name: str  # "s/h0_weak_thrust"
    state: Any  # kinetix EnvState of numpy arrays
    static_params: Any
    env_params: Any


_levels: dict[str, Level] = {}


def _kinetix_version() -> str:
    try:
        return metadata.version("kinetix-env")
    except metadata.PackageNotFoundError:  # pragma: no cover
        return "unknown"


def load_level(name: str) -> Level:
    """Level "s/h0_weak_thrust" from memory, the disk cache, or kinetix's JSON loader."""
    with _lock:
        if name in _levels:
            return _levels[name]
        src = level_path(name)
        digest = hashlib.sha256(src.read_bytes()).hexdigest()[:12]
        path = cache_root() / "levels" / _kinetix_version() / f"{name.replace('/', '_')}-{digest}.pkl"
        level = None
        if path.exists():
            try:
                with open(path, "rb") as f:
                    level = pickle.load(f)
            except Exception:  # a torn or stale file: rebuild it
                level = None
        if level is None:
            level = _convert(name)
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
            with os.fdopen(fd, "wb") as f:
                pickle.dump(level, f, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, path)  # atomic: concurrent workers never read a partial file
        _levels[name] = level
        return level


def _convert(name: str) -> Level:
    # JAX and kinetix after quiet_xla_log() (jaxlib reads its log level as it loads)
    import jax
    import jax.numpy as jnp
    from kinetix.util.saving import load_from_json_file

    state, static_params, env_params = load_from_json_file(name)
    # Loaded levels carry weakly typed scalars; fix their dtypes or the second step recompiles.
    state = state.replace(timestep=jnp.int32(0), last_distance=jnp.float32(-1.0))
    return Level(name=name, state=jax.device_get(state), static_params=static_params, env_params=env_params)


# -- compiled stepping ----------------------------------------------------------------


@dataclass
class DecisionOut:
    """Result of one decision (16 env steps, stopped early at the end of the episode)."""

    state: Any  # numpy EnvState after the decision
    done: bool
    goal: bool  # info["GoalR"] at the step that ended the episode
    reward: float  # kinetix reward of the last step taken (+-1 at the end, dense shaping otherwise)
    steps: int  # env steps actually taken (<= 16)
    timestep: int  # kinetix timestep after the decision


class Sim:
    """The compiled decision function for one level size (one StaticEnvParams)."""

    def __init__(self, static_params: Any, env_params: Any) -> None:
        # JAX and kinetix after quiet_xla_log() (jaxlib reads its log level as it loads)
        import jax
        import jax.numpy as jnp
        from kinetix.environment.env import make_kinetix_env
        from kinetix.environment.spaces import ActionType, ObservationType

        configure_jax()
        self.static_params = static_params
        self.env_params = env_params
        self.env = make_kinetix_env(
            ActionType.MULTI_DISCRETE, ObservationType.SYMBOLIC_FLAT, None, env_params, static_params, auto_reset=False
        )
        env = self.env
        key = jax.random.PRNGKey(0)  # unused by kinetix when auto_reset is off

        def env_step(action, env_params, carry):
            """One env step of an episode, frozen once the episode has ended."""
            state, done, goal, reward, steps = carry
            _, nxt, r, d, info = env.step(key, state, action, env_params)
            live = ~done
            state = jax.tree.map(lambda a, b: jnp.where(live, a, b), nxt, state)
            goal = jnp.where(live, info["GoalR"], goal)
            reward = jnp.where(live, r, reward)
            steps = steps + live.astype(jnp.int32)
            done = done | d
            return state, done, goal, reward, steps

        def start(state):
            return state, jnp.bool_(False), jnp.bool_(False), jnp.float32(0.0), jnp.int32(0)

        def decision(state, action, env_params):
            """One episode's decision: 16 env steps, the state frozen once the episode ends."""
            carry, _ = jax.lax.scan(lambda c, _: (env_step(action, env_params, c), None), start(state), None,
                                    length=STEPS_PER_DECISION)
            return carry

        def path(state, action, env_params):
            """The states after each of a decision's env steps (for pictures only: another
            program than `decision`, which need not round alike)."""
            def body(c, _):
                c = env_step(action, env_params, c)
                return c, c[0]

            return jax.lax.scan(body, start(state), None, length=STEPS_PER_DECISION)[1]

        self.decision = decision  # unbatched and not jitted: for benchmarks and references
        self._fn = jax.jit(jax.vmap(decision, in_axes=(0, 0, None)))  # only ever called with BATCH lanes
        self._path = jax.jit(jax.vmap(path, in_axes=(0, 0, None)))  # compiled on first use (replays)

    def decide(self, states: list[Any], actions: np.ndarray) -> list[DecisionOut]:
        """Run one decision for each (state, 6-vector action), `BATCH` episodes per call."""
        import jax  # loaded by __init__, after quiet_xla_log()

        assert len(states) == len(actions)
        outs: list[DecisionOut] = []
        for start in range(0, len(states), BATCH):
            chunk = list(states[start : start + BATCH])
            acts = np.asarray(actions[start : start + BATCH], np.int32)
            real = len(chunk)
            if real < BATCH:  # pad with copies of the first episode; their results are dropped
                chunk += [chunk[0]] * (BATCH - real)
                acts = np.concatenate([acts, np.repeat(acts[:1], BATCH - real, axis=0)])
            batch = jax.tree.map(lambda *xs: np.stack(xs), *chunk)
            state, done, goal, reward, steps = jax.device_get(self._fn(batch, acts, self.env_params))
            for k in range(real):
                s = jax.tree.map(lambda x: x[k], state)
                outs.append(
                    DecisionOut(
                        state=s,
                        done=bool(done[k]),
                        goal=bool(goal[k]),
                        reward=float(reward[k]),
                        steps=int(steps[k]),
                        timestep=int(s.timestep),
                    )
                )
        return outs

    def path(self, state: Any, action: np.ndarray) -> list[Any]:
        """The states after each env step of one decision, for watching it (`BATCH` lanes, as
        `decide`). Not the record's program: its states may differ from `decide`'s in the
        last bits."""
        import jax  # loaded by __init__, after quiet_xla_log()

        batch = jax.tree.map(lambda x: np.stack([x] * BATCH), state)
        states = jax.device_get(self._path(batch, np.repeat(np.asarray(action, np.int32)[None], BATCH, axis=0),
                                           self.env_params))
        return [jax.tree.map(lambda x: x[0, k], states) for k in range(STEPS_PER_DECISION)]


_sims: dict[Any, Sim] = {}


def get_sim(level: Level) -> Sim:
    """The compiled stepping for the level's size: built once per size per process.

    (All shipped levels of a size share StaticEnvParams, and all share EnvParams.)
    """
    with _lock:
        key = (level.static_params, level.env_params)
        if key not in _sims:
            _sims[key] = Sim(level.static_params, level.env_params)
        return _sims[key]
