"""13: ball through a field of static balls to the floor (second layout). Two staggered
rows of black balls; the green ball lands in a gap of the top row and stays there."""

from deepphy.envs.phyre.scene import W, Scene, ball
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    n = int(rng.integers(2, 5))
    br = u(rng, 6, 11)
    gap = u(rng, 8, 14)
    pitch = 2 * br + gap
    y1 = u(rng, 90, 160)
    y2 = y1 - u(rng, 30, 55)
    x0 = u(rng, 3 + br + pitch / 2, W - 3 - br - n * pitch)
    if x0 < 3 + br + pitch / 2:
        raise Skip
    top = [ball(x0 + i * pitch, y1, br, "black") for i in range(n)]
    low = [ball(x0 + (i - 0.5) * pitch, y2, br, "black") for i in range(n + 1)]
    r = u(rng, gap / 2 + 3, gap / 2 + 9)
    i = 0 if rng.random() < 0.5 else n - 2  # an end gap
    gx = x0 + (i + 0.5) * pitch + u(rng, -2, 2)
    gy = u(rng, y1 + 40, 235)
    objs = (*top, *low, ball(gx, gy, r, "green"))
    return Scene(objs, subject=len(objs) - 1, goal=("bottom",), description="get the green ball to the floor")


TEMPLATE = Template(13, "through two ball rows", "get the green ball through the black balls to the floor", build)
