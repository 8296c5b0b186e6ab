"""04: the ball must not fall off a beam balancer. A blue beam lies on a black ball
(the fulcrum) on a full-width black shelf, between two black guard posts; the green ball
drops onto the beam from high up and, left alone, ends up off the beam."""

import math

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    shelf_y = u(rng, 0.1, 0.6) * W
    cx = u(rng, 0.25, 0.65) * W
    length = u(rng, 0.3, 0.45) * W
    fr = 0.05 * W  # fulcrum radius (PHYRE: a static ball of scale 0.1)
    r = 0.05 * W
    gx = u(rng, 0.2, 0.8) * W
    gy = 0.9 * W + r
    if gx + r < cx - length / 2 or gx - r > cx + length / 2:
        raise Skip
    shelf = bar(W / 2, shelf_y + BAR_T / 2, W)
    fulcrum = ball(cx, shelf_y + BAR_T + fr, fr, "black")
    beam_y = shelf_y + BAR_T + 2 * fr + BAR_T / 2
    if gy - r < beam_y + 10:
        raise Skip
    beam = bar(cx, beam_y, length, 0.0, "blue")
    g_len = 0.2 * W
    g_top = max(gy - r - 0.15 * W, shelf_y + BAR_T + g_len)
    gl_x = cx - length / 2 - 0.15 * W
    gr_x = cx + length / 2 + 0.15 * W
    objs = [shelf, fulcrum, beam]
    for x in (gl_x, gr_x):
        if 3 < x < W - 3:
            objs.append(bar(x, g_top - g_len / 2, g_len, math.pi / 2))
    objs.append(ball(gx, gy, r, "green"))
    return Scene(tuple(objs), subject=len(objs) - 1, goal=(2,), description="keep the green ball on the blue beam")


TEMPLATE = Template(4, "beam balancer", "keep the green ball on the blue beam", build)
