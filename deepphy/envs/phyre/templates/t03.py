"""03: knock a standing bar against a wall. A green bar stands upright on the floor near a
purple side wall, beside an upside-down static jar (a cap); toppled toward the wall
it comes to lean on it."""

import math

from deepphy.envs.phyre.scene import W, Scene, bar, jar
from deepphy.envs.phyre.templates import Skip, Template, sign, u


def build(rng):
    side = sign(rng)  # +1: the goal is the right wall
    length = u(rng, 50, 110)
    dist = u(rng, 0.3, 0.75) * length  # from the wall to the bar
    x = W - dist if side > 0 else dist
    green = bar(x, length / 2, length, math.pi / 2, "green")
    jw = u(rng, 40, 70)
    jh = u(rng, 25, 45)
    # The cap hangs beside the bar's top, on the side away from the wall.
    jx = x - side * (jw / 2 + u(rng, 8, 30))
    top = length + u(rng, -10, 40) + jh
    if top > W - 4 or jx - jw / 2 < 2 or jx + jw / 2 > W - 2:
        raise Skip
    cap = jar(jx, top, jw, jh, "black", angle=math.pi)  # upside down: its base is at `top`
    return Scene((cap, green), subject=1, goal=("right" if side > 0 else "left",),
                 description="make the green bar touch the purple wall")


TEMPLATE = Template(3, "bar against the wall", "topple the green bar so it touches the purple wall", build)
