"""12: ball through a field of static balls to the floor. The green ball falls onto a row
of black balls and gets stuck between two of them; it must reach the floor."""

from deepphy.envs.phyre.scene import W, Scene, ball
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    n = int(rng.integers(4, 8))
    br = u(rng, 6, 12)
    gap = u(rng, 8, 16)  # between neighbouring balls
    y = u(rng, 40, 140)
    pitch = 2 * br + gap
    x0 = u(rng, 3 + br, W - 3 - br - (n - 1) * pitch)
    if x0 < 3 + br:
        raise Skip
    field = [ball(x0 + i * pitch, y, br, "black") for i in range(n)]
    r = u(rng, gap / 2 + 3, gap / 2 + 10)
    i = 0 if rng.random() < 0.5 else n - 2  # an end gap
    gx = x0 + (i + 0.5) * pitch + u(rng, -2, 2)
    gy = u(rng, y + 40, 235)
    objs = (*field, ball(gx, gy, r, "green"))
    return Scene(objs, subject=n, goal=("bottom",), description="get the green ball to the floor")


TEMPLATE = Template(12, "through the ball field", "get the green ball through the black balls to the floor", build)
