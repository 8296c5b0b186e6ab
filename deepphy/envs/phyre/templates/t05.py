"""05: the ball must not fall into a jar. The green ball falls straight into a black jar
standing on the floor; it must reach the floor instead."""

from deepphy.envs.phyre.scene import W, Scene, ball, jar
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    jw = u(rng, 50, 100)
    jh = u(rng, 30, 70)
    jx = u(rng, jw / 2 + 25, W - jw / 2 - 25)
    r = u(rng, 6, min(16, jw * 0.3))
    gx = jx + u(rng, -0.15, 0.15) * jw
    gy = u(rng, jh + 40, 235)
    if gy + r > W - 2:
        raise Skip
    objs = (jar(jx, 0, jw, jh, "black"), ball(gx, gy, r, "green"))
    return Scene(objs, subject=1, goal=("bottom",), description="make the green ball touch the floor, not the jar")


TEMPLATE = Template(5, "miss the jar", "keep the green ball out of the jar so it lands on the floor", build)
