"""17: ball to a target with a dynamic bar and a ramp. The green ball falls onto a black
ramp that runs down to a purple cup in the corner, but a gray bar lies across the cup's
mouth."""

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar, bar_between, jar
from deepphy.envs.phyre.templates import Skip, Template, mx, sign, u


def build(rng):
    side = sign(rng)  # +1: the cup is in the left corner
    cw = u(rng, 36, 52)
    ch = u(rng, 16, 26)
    cx = cw / 2 + u(rng, 3, 25)
    cup = jar(mx(cx, side), 0, cw, ch, "purple")
    lid_len = cw + u(rng, 8, 24)
    lid_x = max(cx + u(rng, -4, 4), lid_len / 2 + 1)  # inside the scene
    lid = bar(mx(lid_x, side), ch + BAR_T / 2 + 0.5, lid_len, 0.0, "gray")
    rx0 = cx + lid_len / 2 + u(rng, 4, 15)
    ry0 = ch + u(rng, 12, 30)
    rx1 = u(rng, rx0 + 60, min(W - 10, rx0 + 150))
    ry1 = ry0 + (rx1 - rx0) * u(rng, 0.2, 0.6)
    if ry1 > 180 or rx1 - rx0 < 60:
        raise Skip
    ramp = bar_between(mx(rx0, side), ry0, mx(rx1, side), ry1)
    r = u(rng, 6, 11)
    gx = rx0 + u(rng, 0.5, 0.9) * (rx1 - rx0)
    green = ball(mx(gx, side), u(rng, ry1 + 25, 235), r, "green")
    return Scene((cup, lid, ramp, green), subject=3, goal=(0,),
                 description="get the green ball into the purple cup")


TEMPLATE = Template(17, "ramp and bar", "get the green ball down the ramp into the purple cup under the gray bar", build)
