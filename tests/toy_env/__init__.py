"""A test-only environment: everything a new environment needs, in one package.

A cart on a rail must stop on the flag. `space.py` holds the action syntax, `env.py` the
environment (physics, rendering), `prompt.py` the words, and this file the `SPEC`. A
package under deepphy/envs/ is found by itself; this one lives in tests/ and the tests
register it with `deepphy.envs.register(SPEC)`.
"""

from deepphy.envs import EnvSpec, Planning, ReportSpec
from toy_env.space import MAX_PUSHES, PushAction, PushSpace  # noqa: F401 - registers the space kind

SPEC = EnvSpec(
    name="toy_cart",
    title="Toy cart",
    environment="toy_env.env:CartEnv",
    prompt="toy_env.prompt:CartPrompt",
    planning=Planning.ON_THE_FLY,
    max_attempts=2,
    max_steps=MAX_PUSHES,
    report=ReportSpec(step_checkpoints=(1, 2, 4), step_noun="push"),
    description="push a cart onto a flag (test-only)",
)
