"""15: ball to a target among three static bars. The green ball falls past three tilted
black bars and misses a small purple cup on the floor."""

from deepphy.envs.phyre.scene import W, Scene, ball, bar, jar
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    bars = []
    for _ in range(3):
        bars.append(bar(u(rng, 30, W - 30), u(rng, 50, 190), u(rng, 30, 70), u(rng, -0.6, 0.6)))
    cw = u(rng, 36, 56)
    cx = u(rng, cw / 2 + 3, W - cw / 2 - 3)
    cup = jar(cx, 0, cw, u(rng, 14, 22), "purple")
    r = u(rng, 6, 12)
    green = ball(u(rng, 20, W - 20), u(rng, 210, 240), r, "green")
    objs = (*bars, cup, green)
    for b in bars:  # keep the bars apart from each other and from the ball's start
        if abs(b.y - green.y) < 35:
            raise Skip
    for i in range(3):
        for j in range(i):
            if abs(bars[i].x - bars[j].x) < 45 and abs(bars[i].y - bars[j].y) < 35:
                raise Skip
    return Scene(objs, subject=4, goal=(3,), description="get the green ball into the purple cup")


TEMPLATE = Template(15, "among three bars", "get the green ball past the bars into the purple cup", build)
