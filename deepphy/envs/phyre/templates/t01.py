"""01: ball touches the left or right wall. The green ball rests on a small platform on
the top of a roof-shaped floor whose two slopes run down to the walls."""

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar, bar_between
from deepphy.envs.phyre.templates import Skip, Template, u


def build(rng):
    apex_x = u(rng, 0.3, 0.7) * W
    apex_y = u(rng, 40, 110)
    plat = u(rng, 20, 44)
    r = u(rng, 0.05, 0.1) * W / 2 * 2
    if r > plat / 2 + 4:
        raise Skip
    left = bar_between(0, 6, apex_x - plat / 2, apex_y)
    right = bar_between(apex_x + plat / 2, apex_y, W, 6)
    top = bar(apex_x, apex_y, plat + BAR_T)
    green = ball(apex_x + u(rng, -2, 2), apex_y + BAR_T / 2 + r, r, "green")
    # a black shelf above, so placements are not all free
    if rng.random() < 0.5:
        sh_y = u(rng, apex_y + 2 * r + 30, 200)
        shelf = bar(u(rng, 0.25, 0.75) * W, sh_y, u(rng, 40, 90))
        objs = (left, right, top, shelf, green)
    else:
        objs = (left, right, top, green)
    return Scene(objs, subject=len(objs) - 1, goal=("left", "right"),
                 description="make the green ball touch the left or the right wall")


TEMPLATE = Template(1, "ball touches a wall", "make the green ball touch the left or right wall", build)
