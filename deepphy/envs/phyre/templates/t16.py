"""16: ball down a launch ramp to a small floor target. The green ball waits on a black
ledge at the top of a ramp that ends in the air; a small purple cup stands further on."""

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar, bar_between, jar
from deepphy.envs.phyre.templates import Skip, Template, mx, sign, u


def build(rng):
    side = sign(rng)  # +1: ramp on the left, launching to the right
    ly = u(rng, 140, 200)  # ledge height
    ll = u(rng, 30, 60)
    x0 = u(rng, 3, 15)
    ledge = bar(mx(x0 + ll / 2, side), ly, ll)
    rl = u(rng, 40, 80)
    drop = u(rng, 30, 80)
    ramp = bar_between(mx(x0 + ll, side), ly, mx(x0 + ll + rl, side), ly - drop)
    cw = u(rng, 30, 44)
    cx = x0 + ll + rl + u(rng, 30, 120)
    if cx + cw / 2 > W - 3:
        raise Skip
    cup = jar(mx(cx, side), 0, cw, u(rng, 14, 22), "purple")
    r = u(rng, 6, 12)
    green = ball(mx(x0 + u(rng, 0.3, 0.6) * ll, side), ly + BAR_T / 2 + r, r, "green")
    return Scene((ledge, ramp, cup, green), subject=3, goal=(2,),
                 description="launch the green ball off the ramp into the purple cup")


TEMPLATE = Template(16, "launch ramp", "send the green ball down the ramp into the small purple cup", build)
