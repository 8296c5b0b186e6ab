"""07: funnel a ball onto a target pad. The green ball falls into a black funnel whose
exit drops it beside a small purple cup on the floor."""

from deepphy.envs.phyre.scene import W, Scene, ball, bar_between, jar
from deepphy.envs.phyre.templates import Skip, Template, sign, u


def build(rng):
    side = sign(rng)
    fx = u(rng, 70, W - 70)  # funnel exit centre
    fy = u(rng, 80, 130)  # exit height
    gap = u(rng, 26, 36)
    spread = u(rng, 35, 60)
    rise = u(rng, 25, 45)
    left = bar_between(fx - gap / 2 - spread, fy + rise, fx - gap / 2, fy)
    right = bar_between(fx + gap / 2, fy, fx + gap / 2 + spread, fy + rise)
    r = u(rng, 6, gap / 2 - 4)
    gx = fx + u(rng, -0.6, 0.6) * (spread + gap / 2)
    gy = u(rng, fy + rise + 20, 235)
    cw = u(rng, 34, 50)
    cx = fx + side * (cw / 2 + u(rng, 18, 55))
    if cx - cw / 2 < 2 or cx + cw / 2 > W - 2 or fx - gap / 2 - spread < 2 or fx + gap / 2 + spread > W - 2:
        raise Skip
    cup = jar(cx, 0, cw, u(rng, 12, 20), "purple")
    objs = (left, right, cup, ball(gx, gy, r, "green"))
    return Scene(objs, subject=3, goal=(2,), description="get the green ball into the purple cup")


TEMPLATE = Template(7, "funnel to a pad", "get the green ball from the funnel onto the purple target", build)
