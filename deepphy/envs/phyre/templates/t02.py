"""02: the ball must avoid a bar and hit the ground. The green ball falls onto a static
bar that would hold it; it must reach the floor instead."""

from deepphy.envs.phyre.scene import W, Scene, ball, bar
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    r = u(rng, 0.04, 0.08) * W
    bx = u(rng, 0.2, 0.8) * W
    by = u(rng, 50, 150)
    bl = u(rng, 0.25, 0.55) * W
    if bx - bl / 2 < 5 or bx + bl / 2 > W - 5:
        raise Skip
    gx = bx + u(rng, -0.3, 0.3) * bl
    gy = u(rng, by + 40, 230)
    if gy + r > W - 2:
        raise Skip
    objs = (bar(bx, by, bl), ball(gx, gy, r, "green"))
    return Scene(objs, subject=1, goal=("bottom",), description="make the green ball touch the floor")


TEMPLATE = Template(2, "ball avoids a bar", "make the green ball hit the ground instead of the bar", build)
