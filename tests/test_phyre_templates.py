"""PHYRE templates on real pymunk: stability without a ball, and a solving placement each."""

import pytest

from deepphy.envs.phyre import scene as S
from deepphy.envs.phyre.templates import NUM_TEMPLATES, accepted_seeds, templates, variant_scene

# One placement per template that solves the named variant: (variant, x, y, r) in scene
# px with y up. Picked from the solver's search and checked by eye in the key frames.
SOLUTIONS: dict[int, tuple[int, float, float, float]] = {
}

TEMPLATES = sorted(templates())


def test_all_templates_present():
    assert TEMPLATES == list(range(NUM_TEMPLATES))


@pytest.mark.parametrize("template", TEMPLATES)
def test_stable_without_a_ball(template):
    """Nothing solves itself, nothing explodes, nothing leaves the scene."""
    verified = accepted_seeds().get(template)
    variants = [v for v in range(100) if verified is None or verified[v] is not None]
    for v in variants[:: 1 if verified else 10]:
        scene = variant_scene(template, v)
        for o in scene.objects:
            assert S.inside_scene(o, margin=-0.5), (template, v, o)
        out = S.simulate(scene)
        assert not out.success, (template, v)
        assert out.reason != "exploded" and out.max_speed < 600, (template, v, out.max_speed)
        assert not out.left_scene, (template, v)


@pytest.mark.parametrize("template", TEMPLATES)
def test_hand_picked_solution(template):
    assert template in SOLUTIONS, "add a solving placement for this template"
    variant, x, y, r = SOLUTIONS[template]
    scene = variant_scene(template, variant)
    assert S.placement_problem(scene, x, y, r) is None
    assert S.simulate(scene, (x, y, r)).success
    assert not S.simulate(scene).success


@pytest.mark.parametrize("template", TEMPLATES)
def test_recorded_solutions_solve(template):
    """The placement recorded for each verified variant by `solve generate` still solves it."""
    entries = accepted_seeds().get(template)
    if entries is None:
        pytest.skip("template not yet verified")
    for v in range(0, 100, 10):
        if entries[v] is not None:
            assert S.simulate(variant_scene(template, v), tuple(entries[v][1])).success, (template, v)
