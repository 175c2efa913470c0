"""`world.damping` (Chipmunk's space.damping: the fraction of velocity kept after one second) and a body's
`center_of_mass` (docs/scene-format.md, docs/method.md "Damping"): the two modelling choices gym-pusht's Push-T makes.

Oracles: a free body's velocity decays as damping^t exactly and its position is the sum of the steps' velocities;
damping 0 starts every step at rest (a falling body falls at h g per step); damping 1 is the method without damping,
bit for bit; pymunk, given the same damping through the bridge, decays the same way; a body spun about a given
centre of mass keeps that point still, with the parallel-axis inertia.
"""

import math

import numpy as np
import pytest

from planar_lcp import simulate
from planar_lcp.model import compile_scene
from planar_lcp.spec.massprops import body_mass_properties
from planar_lcp.spec.scene import SceneError, parse_scene

H = 0.01


def free_doc(damping=None, plane="horizontal", velocity=(0.3, -0.1), omega=2.0, com=None, t_end=0.5):
    world = {"plane": plane}
    if damping is not None:
        world["damping"] = damping
    body = {"name": "box", "type": "dynamic", "mass": 0.5, "velocity": list(velocity), "angular_velocity": omega,
            "shapes": [{"type": "box", "width": 0.1, "height": 0.06}]}
    if plane == "horizontal":
        body["support_friction"] = 0.0
    if com is not None:
        body["center_of_mass"] = list(com)
    return {"name": "free", "world": world, "sim": {"h": H, "t_end": t_end}, "bodies": [body]}


@pytest.mark.parametrize("damping", [0.0, 0.2, 0.9])
def test_a_free_bodys_velocity_decays_as_damping_to_the_time(damping):
    tr = simulate(free_doc(damping))
    n = len(tr.t) - 1
    keep = damping ** (H * np.arange(1, n + 1))
    v0 = np.array([0.3, -0.1, 2.0])
    assert np.abs(tr.v_com[1:, 0] - keep[:, None] * v0).max() < 1e-13
    q = tr.q_com[0, 0] + H * np.cumsum(keep[:, None] * v0, axis=0)
    assert np.abs(tr.q_com[1:, 0] - q).max() < 1e-12
    if damping == 0.0:
        assert np.all(tr.q_com[:, 0] == tr.q_com[0, 0])              # it never moves


def test_with_no_memory_a_falling_body_falls_h_g_per_step():
    tr = simulate(free_doc(0.0, plane="vertical", velocity=(0.0, 0.0), omega=0.0, t_end=0.1))
    g = 9.81
    assert np.abs(tr.v_com[1:, 0, 1] + H * g).max() < 1e-13
    n = np.arange(len(tr.t))
    assert np.abs(tr.q_com[:, 0, 1] - (tr.q_com[0, 0, 1] - n * H * H * g)).max() < 1e-13


def test_damping_one_is_the_method_without_it_bit_for_bit():
    a = simulate("push_box")
    doc_scene = parse_scene(free_doc(1.0))
    assert doc_scene.world.damping == 1.0
    from planar_lcp.spec.scene import load_scene
    import dataclasses
    sc = load_scene("push_box")
    b = simulate(dataclasses.replace(sc, world=dataclasses.replace(sc.world, damping=1.0)))
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v)


def test_pymunk_decays_the_same_way_through_the_bridge():
    """The same velocities; Chipmunk moves a body by the velocity it has at the START of a step (then damps it),
    ours by the one at its end, so pymunk's pose after step n is ours after step n - 1 plus h v0."""
    pytest.importorskip("pymunk")
    from planar_lcp.bridges.pymunk import simulate_pymunk
    scene = parse_scene(free_doc(0.3, omega=0.0))
    ours, theirs = simulate(scene), simulate_pymunk(scene)
    assert np.abs(theirs.v_com - ours.v_com).max() < 1e-12
    v0 = np.array([0.3, -0.1, 0.0])
    assert np.abs(theirs.q_com[1:, 0] - (ours.q_com[:-1, 0] + H * v0)).max() < 1e-12


@pytest.mark.parametrize("value, message", [
    (1.5, "world.damping must be in [0, 1] (the fraction of velocity kept after 1 s), got 1.5"),
    (-0.1, "world.damping must be in [0, 1] (the fraction of velocity kept after 1 s), got -0.1"),
    ("no", "world.damping must be a number, got 'no'"),
])
def test_bad_damping_is_refused_in_one_line(value, message):
    with pytest.raises(SceneError) as e:
        parse_scene(free_doc(value))
    assert message in str(e.value)


def test_a_given_centre_of_mass_is_where_the_body_turns_about():
    com = (0.02, 0.01)
    # the origin's velocity that leaves the centre of mass at rest: -omega x com
    scene = parse_scene(free_doc(1.0, velocity=(3.0 * com[1], -3.0 * com[0]), omega=3.0, com=com))
    body = scene.body("box")
    c, inertia = body_mass_properties(body)
    plain, inertia0 = body_mass_properties(parse_scene(free_doc(1.0)).body("box"))
    assert tuple(c) == com and np.allclose(plain, 0.0)
    assert inertia == pytest.approx(inertia0 + 0.5 * (0.02 ** 2 + 0.01 ** 2), rel=1e-14)    # parallel axis
    model = compile_scene(scene)
    assert tuple(model.com_local[0]) == com and model.arrays.dyn_inertia[0] == inertia
    tr = simulate(scene)
    assert np.abs(tr.q_com[:, 0, :2] - tr.q_com[0, 0, :2]).max() < 1e-15      # the centre stays
    origin = tr.q[:, 0, :2]                                                   # the frame's origin turns about it
    r = np.hypot(*(origin - tr.q_com[:, 0, :2]).T)
    assert np.abs(r - math.hypot(*com)).max() < 1e-14 and np.ptp(origin[:, 0]) > 0.01


def test_center_of_mass_is_for_dynamic_bodies():
    doc = free_doc()
    doc["bodies"].append({"name": "wall", "type": "static", "position": [1.0, 0.0], "center_of_mass": [0.0, 0.0],
                          "shapes": [{"type": "box", "width": 0.1, "height": 0.1}]})
    with pytest.raises(SceneError, match=r"bodies\[1\]\.center_of_mass is not allowed on a static body"):
        parse_scene(doc)


def test_the_tables_pressure_stays_on_the_shapes_with_a_given_centre_of_mass():
    """The limit surface's support pressure is kept about the model's centre of mass: with center_of_mass given, its
    edges, nodes and size are the plain body's moved by the offset (the pressure stays where the shapes are)."""
    from planar_lcp.spec.limit_surface import gyration_radius, support_pressure
    plain = parse_scene(free_doc(1.0)).body("box")
    moved = parse_scene(free_doc(1.0, com=(0.02, 0.01))).body("box")
    a, b = support_pressure(plain, 8), support_pressure(moved, 8)
    off = np.array([0.02, 0.01])
    assert len(a.edges) == 4 and np.allclose(b.edges + np.tile(off, 2), a.edges, rtol=0, atol=1e-15)
    assert np.allclose(b.far[:, :2] + off, a.far[:, :2], rtol=0, atol=1e-15)
    assert np.array_equal(b.far[:, 2], a.far[:, 2])
    assert b.edge_scale == a.edge_scale and b.size > a.size
    assert gyration_radius(moved) ** 2 == pytest.approx(gyration_radius(plain) ** 2 + 0.02 ** 2 + 0.01 ** 2, rel=1e-12)
