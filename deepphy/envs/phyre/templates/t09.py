"""09: knock a bar off an obstacle. A green bar lies balanced on a black pillar; it must
fall to the floor."""


from deepphy.envs.phyre.scene import BAR_T, W, Scene, bar, box
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    px = u(rng, 0.25, 0.75) * W
    ph = u(rng, 30, 140)
    pw = u(rng, 8, 26)
    length = u(rng, 60, 150)
    off = u(rng, -0.25, 0.25) * pw
    if px + off - length / 2 < 3 or px + off + length / 2 > W - 3:
        raise Skip
    pillar = box(px, ph / 2, pw, ph)
    green = bar(px + off, ph + BAR_T / 2, length, 0.0, "green")
    objs = [pillar, green]
    if rng.random() < 0.5:  # a black bar hanging above makes some placements impossible
        hy = u(rng, ph + 35, 230)
        objs.append(bar(u(rng, 0.2, 0.8) * W, hy, u(rng, 30, 80), u(rng, -0.3, 0.3)))
    return Scene(tuple(objs), subject=1, goal=("bottom",), description="make the green bar touch the floor")


TEMPLATE = Template(9, "bar off a pillar", "knock the green bar off the pillar onto the floor", build)
