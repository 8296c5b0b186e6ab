"""18: ball to a ball sitting in a jar on a bar. A blue ball sits in a gray jar on a black
shelf; the green ball rests on a higher black shelf and must reach the blue ball."""

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar, jar
from deepphy.envs.phyre.templates import Skip, Template, mx, sign, u


def build(rng):
    side = sign(rng)  # +1: green on the left
    gy = u(rng, 150, 210)
    gl = u(rng, 40, 80)
    g_shelf = bar(mx(gl / 2 + 1, side), gy, gl)
    r = u(rng, 6, 11)
    green = ball(mx(u(rng, 0.5, 0.9) * gl, side), gy + BAR_T / 2 + r, r, "green")
    jy = u(rng, 40, gy - 60)
    jw = u(rng, 40, 60)
    jh = u(rng, 24, 40)
    jx = gl + jw / 2 + u(rng, 0, 50)
    sl = jw + u(rng, 10, 50)
    if jx + sl / 2 > W - 2 or jy < 40:
        raise Skip
    shelf = bar(mx(jx, side), jy, sl)
    pot = jar(mx(jx, side), jy + BAR_T / 2, jw, jh, "gray")
    br = u(rng, 6, min(12, jw * 0.25))
    blue = ball(mx(jx, side), jy + BAR_T / 2 + 4 + br, br, "blue")
    return Scene((g_shelf, green, shelf, pot, blue), subject=1, goal=(4,),
                 description="make the green ball touch the blue ball in the jar")


TEMPLATE = Template(18, "ball in a jar on a bar", "get the green ball to the blue ball in the gray jar", build)
