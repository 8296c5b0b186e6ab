"""08: ball into a jar past a staircase. The green ball rests on the top step of a black
staircase; a purple jar waits on the floor beyond the lowest step."""

from deepphy.envs.phyre.scene import W, Scene, ball, box, jar
from deepphy.envs.phyre.templates import Skip, Template, mx, sign, u


def build(rng):
    side = sign(rng)  # +1: stairs on the left, descending to the right
    n = int(rng.integers(3, 6))
    sw = u(rng, 22, 34)
    sh = u(rng, 14, 26)
    x0 = u(rng, 5, 25)
    steps = []
    for i in range(n):
        h = (n - i) * sh
        steps.append(box(mx(x0 + (i + 0.5) * sw, side), h / 2, sw, h))
    end = x0 + n * sw
    jw = u(rng, 40, 60)
    jx = end + jw / 2 + u(rng, 8, 60)
    if jx + jw / 2 > W - 3:
        raise Skip
    pot = jar(mx(jx, side), 0, jw, u(rng, 20, 35), "purple")
    r = u(rng, 5, min(12, sw / 2 - 1))
    green = ball(mx(x0 + sw * u(rng, 0.3, 0.7), side), n * sh + r, r, "green")
    objs = (*steps, pot, green)
    return Scene(objs, subject=len(objs) - 1, goal=(len(objs) - 2,),
                 description="get the green ball down the stairs and into the purple jar")


TEMPLATE = Template(8, "staircase to a jar", "get the green ball down the stairs into the purple jar", build)
