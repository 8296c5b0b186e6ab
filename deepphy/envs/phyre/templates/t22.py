"""22: ball to a ball in a jar, with an obstacle. The green ball rests on a black shelf;
the blue ball lies in a black jar on the floor under a black obstacle bar."""

from deepphy.envs.phyre.scene import BAR_T, W, Scene, ball, bar, jar
from deepphy.envs.phyre.templates import Skip, Template, mx, sign, u


def build(rng):
    side = sign(rng)  # +1: green on the left
    gy = u(rng, 130, 200)
    gl = u(rng, 40, 80)
    shelf = bar(mx(gl / 2 + 1, side), gy, gl)
    r = u(rng, 6, 11)
    green = ball(mx(u(rng, 0.5, 0.9) * gl, side), gy + BAR_T / 2 + r, r, "green")
    jw = u(rng, 40, 60)
    jh = u(rng, 22, 36)
    jx = gl + jw / 2 + u(rng, 0, 50)
    pot = jar(mx(jx, side), 0, jw, jh, "black")
    br = u(rng, 6, min(12, jw * 0.25))
    blue = ball(mx(jx, side), 5 + br, br, "blue")
    oy = u(rng, jh + 30, gy - 30)
    ol = u(rng, 25, 45)
    ox = jx + u(rng, -0.5, 0.5) * jw
    if oy < jh + 30 or ox + ol / 2 > W - 2:
        raise Skip
    obstacle = bar(mx(ox, side), oy, ol, u(rng, -0.4, 0.4))
    return Scene((shelf, green, pot, blue, obstacle), subject=1, goal=(3,),
                 description="make the green ball touch the blue ball in the jar")


TEMPLATE = Template(22, "jar with an obstacle", "get the green ball past the obstacle to the blue ball in the jar", build)
