"""24: ball through a hole while a second ball tries to stop it. A gray ball, bigger than
the hole of a black platform, drops into the hole and plugs it just before the green
ball falling from higher up gets there; the green ball must reach the floor."""

from deepphy.envs.phyre.scene import W, Scene, ball, bar
from deepphy.envs.phyre.templates import Template, sign, u


def build(rng):
    side = sign(rng)
    py = u(rng, 50, 110)
    hx = u(rng, 70, 186)
    hole = u(rng, 18, 28)
    left = bar((hx - hole / 2) / 2, py, hx - hole / 2)
    rl = W - hx - hole / 2
    right = bar(hx + hole / 2 + rl / 2, py, rl)
    gray_r = hole / 2 + u(rng, 3, 7)
    gray = ball(hx + side * u(rng, 0, 0.5) * gray_r, py + u(rng, 25, 70), gray_r, "gray")
    r = u(rng, 4, hole / 2 - 2)
    green = ball(hx + u(rng, -3, 3), u(rng, gray.y + gray_r + 40, 240), r, "green")
    return Scene((left, right, gray, green), subject=3, goal=("bottom",),
                 description="get the green ball through the hole to the floor")


TEMPLATE = Template(24, "race to the hole", "get the green ball through the hole before the gray ball plugs it", build)
