"""21: ball to a teeter bar. A blue bar rests tilted on a black wedge near a wall; the
green ball falls beside it onto the floor."""

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar, poly
from deepphy.envs.phyre.templates import Skip, Template, mx, sign, u


def build(rng):
    side = sign(rng)  # +1: the teeter is in the left part
    px = u(rng, 40, 110)
    ph = u(rng, 14, 30)
    pw = u(rng, 12, 20)
    length = u(rng, 60, 110)
    wedge = poly([(mx(px - pw / 2, side), 0), (mx(px + pw / 2, side), 0), (mx(px, side), ph)][:: side])
    beam = bar(mx(px, side), ph + BAR_T / 2, length, 0.0, "blue")
    if px - length / 2 < 3:
        raise Skip
    r = u(rng, 6, 12)
    gx = u(rng, px + length / 2 + r + 15, W - r - 10)
    green = ball(mx(gx, side), u(rng, 120, 235), r, "green")
    return Scene((wedge, beam, green), subject=2, goal=(1,), description="make the green ball touch the blue bar")


TEMPLATE = Template(21, "teeter bar", "get the green ball onto the blue teeter bar", build)
