"""Example agents for `deepphy run --agent` (docs/agents.md).

Run from the repository's root (Ray's workers import from the driver's working directory),
or install your own agent's package, and name an agent by its entry point:

    deepphy run --env phyre --agent examples.reflection:ReflectionAgent --agent-arg endpoint=gpt-4o
    deepphy run --env iphyre --agent examples.gym_policy:GymPolicyAgent \\
        --agent-arg policy=examples.gym_policy:iphyre_brightness_policy

The version below is what a run records for these agents (an installed package's own
version is read from its distribution instead).
"""

__version__ = "0.1.0"
