"""20: ball behind a separator with a hole to the floor. The green ball rests on the floor
behind a black wall that hangs from above and leaves a low opening; the purple target
covers the floor on the other side."""

import math

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar
from deepphy.envs.phyre.templates import Template, mx, sign, u


def build(rng):
    side = sign(rng)  # +1: green on the left
    sep_x = u(rng, 90, 170)
    r = u(rng, 6, 12)
    opening = u(rng, 2 * r + 6 + BAR_T, 2 * r + 25)
    top = u(rng, 160, 250)
    sep = bar(mx(sep_x, side), (opening + top) / 2, top - opening, math.pi / 2)
    tgt_len = W - sep_x - BAR_T
    target = bar(mx(W - 1 - tgt_len / 2, side), BAR_T / 2, tgt_len, 0.0, "purple")
    shelf_y = u(rng, 60, 130)
    shelf_len = u(rng, 40, sep_x - 20)
    shelf = bar(mx(shelf_len / 2 + 1, side), shelf_y, shelf_len)
    green = ball(mx(u(rng, 10 + r, sep_x - 15 - r), side), r, r, "green")
    return Scene((sep, target, shelf, green), subject=3, goal=(1,),
                 description="get the green ball under the wall onto the purple floor")


TEMPLATE = Template(20, "under the separator", "get the green ball through the low opening to the purple floor", build)
