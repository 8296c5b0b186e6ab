"""23: ball to a ball in a jar, with steps and a blocker. The green ball rests on the top
step of black stairs; at their foot a gray box blocks the way to a gray jar holding the
blue ball."""

from deepphy.envs.phyre.scene import W, Scene, ball, box, jar
from deepphy.envs.phyre.templates import Skip, Template, mx, sign, u


def build(rng):
    side = sign(rng)
    n = int(rng.integers(2, 4))
    sw = u(rng, 22, 32)
    sh = u(rng, 18, 28)
    steps = []
    for i in range(n):
        h = (n - i) * sh
        steps.append(box(mx((i + 0.5) * sw + 2, side), h / 2, sw, h))
    end = n * sw + 2
    bw = u(rng, 10, 20)
    bh = u(rng, 8, 18)
    blocker = box(mx(end + u(rng, 4, 15) + bw / 2, side), bh / 2, bw, bh, 0.0, "gray")
    jw = u(rng, 40, 60)
    jx = end + 22 + jw / 2 + u(rng, 0, 20)
    if jx + jw / 2 > W - 3:
        raise Skip
    pot = jar(mx(jx, side), 0, jw, u(rng, 14, min(26, n * sh - 12)), "gray")
    br = u(rng, 6, 11)
    blue = ball(mx(jx, side), 5 + br, br, "blue")
    r = u(rng, 5, min(11, sw / 2 - 1))
    green = ball(mx(sw * u(rng, 0.6, 0.9) + 2, side), n * sh + r, r, "green")
    objs = (*steps, blocker, pot, blue, green)
    return Scene(objs, subject=len(objs) - 1, goal=(len(objs) - 2,),
                 description="make the green ball touch the blue ball in the jar")


TEMPLATE = Template(23, "steps and a blocker", "get the green ball down the steps, past the blocker, to the blue ball", build)
