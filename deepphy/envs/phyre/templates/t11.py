"""11: the ball must not roll off a cliff. The green ball rolls down a black ramp onto a
purple plateau that ends in a cliff; left alone it rolls over the edge."""

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar, bar_between, box
from deepphy.envs.phyre.templates import Skip, Template, mx, sign, u


def build(rng):
    side = sign(rng)  # +1: ramp on the left, cliff on the right
    py = u(rng, 50, 130)  # plateau height
    ramp_len = u(rng, 50, 90)
    rise = u(rng, 15, 45)
    plat = u(rng, 50, 100)
    x0 = u(rng, 3, 20)
    x1 = x0 + ramp_len
    x2 = x1 + plat
    if x2 > W - 40:
        raise Skip
    ramp = bar_between(mx(x0, side), py + rise, mx(x1, side), py)
    plateau = bar(mx((x1 + x2) / 2, side), py, plat, 0.0, "purple")
    support = box(mx((x1 + x2) / 2, side), (py - BAR_T / 2) / 2, plat * 0.6, py - BAR_T / 2)
    r = u(rng, 6, 12)
    green = ball(mx(x0 + 10 + r, side), py + rise + r + 6, r, "green")
    return Scene((ramp, plateau, support, green), subject=3, goal=(1,),
                 description="keep the green ball on the purple plateau")


TEMPLATE = Template(11, "stop at the cliff", "keep the green ball on the purple plateau", build)
