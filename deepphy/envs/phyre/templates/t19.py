"""19: two balls must NOT touch. The green ball falls into a black jar on the floor where
the blue ball already lies; keep them apart (NOT_TOUCHING, PHYRE's rule)."""

from deepphy.envs.phyre.scene import W, Scene, ball, jar
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    jw = u(rng, 50, 80)
    jh = u(rng, 30, 55)
    jx = u(rng, jw / 2 + 15, W - jw / 2 - 15)
    t = 4.0
    br = u(rng, 7, 13)
    blue = ball(jx, t + br + 0.5, br, "blue")
    r = u(rng, 6, 12)
    if 2 * (br + r) < jw * 0.8 - 2 * t:  # the green must not fit beside the blue ball
        raise Skip
    green = ball(jx + u(rng, -0.15, 0.15) * jw, u(rng, jh + 40, 235), r, "green")
    pot = jar(jx, 0, jw, jh, "black", thickness=t)
    return Scene((pot, blue, green), subject=2, goal=(1,), relation="not_touching",
                 description="keep the green ball from touching the blue ball")


TEMPLATE = Template(19, "balls must not touch", "keep the green ball and the blue ball apart", build)
