"""00: two balls touch. A green and a blue ball hang at the same height and fall apart."""

from deepphy.envs.phyre.scene import W, Scene, ball
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    r1, r2 = u(rng, 0.06, 0.12) * W / 2, u(rng, 0.06, 0.12) * W / 2
    x1, x2 = u(rng, 0.05, 0.95) * W, u(rng, 0.05, 0.95) * W
    h = u(rng, 0.2, 0.8) * W
    if x2 < x1:
        x1, x2 = x2, x1
    if x1 - r1 < 2 or x2 + r2 > W - 2 or (x2 - r2) - (x1 + r1) < max(r1, r2) * 2:
        raise Skip
    green_first = rng.random() < 0.5
    a = ball(x1, h + r1, r1, "green" if green_first else "blue")
    b = ball(x2, h + r2, r2, "blue" if green_first else "green")
    return Scene((a, b), subject=0 if green_first else 1, goal=(1 if green_first else 0,),
                 description="make the two balls touch")


TEMPLATE = Template(0, "two balls touch", "make the green ball touch the blue ball", build)
