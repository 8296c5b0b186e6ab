"""10: ball onto the right bar, with a dynamic jar in the scene. The green ball falls into
a gray jar standing on a black shelf; the goal is a purple bar sloping down into the
right-hand corner of the floor."""

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar, bar_between, jar
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    tl = u(rng, 100, 150)  # target bar length
    target = bar_between(W - tl, u(rng, 8, 20), W - 1, BAR_T / 2, "purple")
    sx = u(rng, 40, W - tl - 20)
    sy = u(rng, 40, 120)
    sl = u(rng, 50, 90)
    jw = u(rng, 35, 55)
    jh = u(rng, 25, 45)
    jx = sx + u(rng, -0.2, 0.2) * (sl - jw)
    if sx - sl / 2 < 3 or sx + sl / 2 > W - tl - 10:
        raise Skip
    shelf = bar(sx, sy, sl)
    pot = jar(jx, sy + BAR_T / 2, jw, jh, "gray")
    r = u(rng, 6, jw * 0.3)
    gy = u(rng, sy + jh + 30, 235)
    green = ball(jx + u(rng, -0.35, 0.35) * jw, gy, r, "green")
    return Scene((target, shelf, pot, green), subject=3, goal=(0,),
                 description="get the green ball onto the purple bar on the right")


TEMPLATE = Template(10, "ball to the right bar", "get the green ball onto the purple bar on the right", build)
