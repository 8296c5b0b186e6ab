"""14: ball to a target bar past a hole and a separator. The green ball rests on a black
platform with a hole; below, a black separator splits the floor and the purple target
bar covers the far part of the floor."""

import math

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar
from deepphy.envs.phyre.templates import Skip, Template, mx, sign, u


def build(rng):
    side = sign(rng)  # +1: the target is on the right
    py = u(rng, 90, 160)
    hole_x = u(rng, 80, 160)
    hole = u(rng, 30, 45)
    sep_x = hole_x + u(rng, -5, 25)
    sep_h = u(rng, 35, py - 40)
    if sep_h < 35:
        raise Skip
    left = bar(mx((hole_x - hole / 2) / 2, side), py, hole_x - hole / 2)
    right_len = W - (hole_x + hole / 2)
    right = bar(mx(hole_x + hole / 2 + right_len / 2, side), py, right_len)
    sep = bar(mx(sep_x, side), sep_h / 2 + BAR_T / 2, sep_h, math.pi / 2)
    tgt_len = W - sep_x - BAR_T / 2 - 2
    target = bar(mx(W - 1 - tgt_len / 2, side), BAR_T / 2, tgt_len, 0.0, "purple")
    r = u(rng, 6, min(14, hole / 2 - 3))
    gx = u(rng, 15 + r, hole_x - hole / 2 - r - 10)
    green = ball(mx(gx, side), py + BAR_T / 2 + r, r, "green")
    return Scene((left, right, sep, target, green), subject=4, goal=(3,),
                 description="get the green ball onto the purple floor beyond the separator")


TEMPLATE = Template(14, "hole and separator", "get the green ball through the hole and past the separator", build)
