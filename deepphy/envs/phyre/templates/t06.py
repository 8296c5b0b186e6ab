"""06: a falling jar must touch a ball. The green jar drops onto the floor beside a
purple ball; it must end up touching it."""

from deepphy.envs.phyre.scene import W, Scene, ball, jar
from deepphy.envs.phyre.templates import Skip, Template, sign, u


def build(rng):
    side = sign(rng)
    jw = u(rng, 36, 60)
    jh = u(rng, 30, 55)
    jx = u(rng, 50, W - 50)
    jy = u(rng, 60, W - jh - 10)
    br = u(rng, 8, 20)
    gap = u(rng, 12, 45)
    bx = jx + side * (jw / 2 + gap + br)
    if bx - br < 2 or bx + br > W - 2:
        raise Skip
    objs = (jar(jx, jy, jw, jh, "green"), ball(bx, br, br, "purple"))
    return Scene(objs, subject=0, goal=(1,), description="make the green jar touch the purple ball")


TEMPLATE = Template(6, "jar touches ball", "make the falling green jar touch the purple ball", build)
