"""`support_share`: a share of a body's table load at its `support_points`, the rest spread over its shapes
(docs/scene-format.md, `[[bodies]]`; docs/method.md, "Table friction").

Oracle: the limit surface's unit-load wrench is linear in the pressure, so the mixture's is (1 - s) times the
uniform pressure's plus s times the points' for every twist, in each regime of its evaluation (closed form, far
nodes, the disk table, curved nodes); share 1 is the support points alone and no share the shapes alone, bit for
bit; the points model and the gyration radius mix the same way.
"""

import numpy as np
import pytest

from planar_lcp.engine.layout import model_struct
from planar_lcp.engine.limit_surface import unit_load_wrench
from planar_lcp.model import compile_scene
from planar_lcp.sim import simulate
from planar_lcp.spec.limit_surface import gyration_radius, support_pressure
from planar_lcp.spec.massprops import body_area_properties, default_support_points
from planar_lcp.spec.scene import SceneError, parse_scene

RING = [[0.03 * np.cos(a), 0.03 * np.sin(a)] for a in np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False)]
SHAPES = {
    "box": [{"type": "box", "width": 0.2, "height": 0.1}],
    "disk": [{"type": "disk", "radius": 0.05}],
    "capsule": [{"type": "capsule", "length": 0.1, "radius": 0.03}],
    "two_boxes": [{"type": "box", "width": 0.2, "height": 0.05, "offset": [0.0, 0.075]},
                  {"type": "box", "width": 0.05, "height": 0.15}],
}


def body_scene(shapes, share=None, points=RING, model="limit_surface"):
    body = {"name": "b", "type": "dynamic", "mass": 1.0, "shapes": shapes}
    if points is not None:
        body["support_points"] = points
    if share is not None:
        body["support_share"] = share
    return parse_scene({"name": "share", "world": {"plane": "horizontal", "support_model": model},
                        "sim": {"h": 0.01, "t_end": 0.5}, "bodies": [body]})


def wrenches(scene, twists):
    m = model_struct(compile_scene(scene).arrays)
    out, res = np.zeros(3), []
    for t in twists:
        unit_load_wrench(m, 0, float(t[0]), float(t[1]), float(t[2]), out)
        res.append(out.copy())
    return np.array(res)


def twists(rho, seed=1):
    rng = np.random.default_rng(seed)
    t = rng.normal(size=(60, 3))
    t[:, 2] /= rho
    far = t[:20].copy()
    far[:, 2] *= 1e-3                                   # centres of rotation far away: the far nodes' regime
    return np.concatenate([t, far, [[0.3, -0.2, 0.0]]])   # and a translation


@pytest.mark.parametrize("kind", sorted(SHAPES))
@pytest.mark.parametrize("share", [0.25, 0.6])
def test_the_mixture_wrench_is_the_weighted_sum(kind, share):
    shapes = SHAPES[kind]
    t = twists(0.05)
    uniform = wrenches(body_scene(shapes, points=None), t)
    points = wrenches(body_scene(shapes), t)
    mixed = wrenches(body_scene(shapes, share), t)
    assert np.abs(mixed - ((1.0 - share) * uniform + share * points)).max() < 1e-13
    assert np.abs(points - uniform).max() > 0.01                # the two pressures differ


@pytest.mark.parametrize("kind", sorted(SHAPES))
def test_share_one_is_the_points_and_no_points_the_shapes_bit_for_bit(kind):
    shapes = SHAPES[kind]
    a, b = body_scene(shapes), body_scene(shapes, 1.0)
    pa, pb = support_pressure(a.bodies[0], 8), support_pressure(b.bodies[0], 8)
    for x, y in zip(pa, pb):
        if isinstance(x, list):
            assert all(np.array_equal(u, v) for u, v in zip(x, y))
        else:
            assert np.array_equal(np.asarray(x), np.asarray(y))
    assert gyration_radius(a.bodies[0]) == gyration_radius(b.bodies[0])
    pts_a, w_a = default_support_points(a.bodies[0])
    pts_b, w_b = default_support_points(b.bodies[0])
    assert np.array_equal(pts_a, pts_b) and np.array_equal(w_a, w_b)


def test_the_points_model_and_the_gyration_radius_mix_the_same_way():
    share = 0.4
    mixed = body_scene(SHAPES["box"], share).bodies[0]
    area, com, polar = body_area_properties(mixed)
    pts, w = default_support_points(mixed)
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    ring = np.asarray(RING)
    assert w[-len(ring):] == pytest.approx(share / len(ring), abs=0)
    second = np.sum(w * np.sum((pts - com) ** 2, axis=1))
    expect = (1.0 - share) * polar / area + share * np.mean(np.sum((ring - com) ** 2, axis=1))
    assert second == pytest.approx(expect, rel=1e-12)
    assert gyration_radius(mixed) == pytest.approx(np.sqrt(expect), rel=1e-12)


@pytest.mark.parametrize("model", ["limit_surface", "points"])
def test_a_spinning_box_stops_sooner_the_more_load_at_its_rim(model):
    """A spinning box's friction torque grows with the load's distance from its centre: the support points at the
    corners stop it sooner the larger their share."""
    corners = [[0.09, 0.04], [-0.09, 0.04], [-0.09, -0.04], [0.09, -0.04]]
    stops = []
    for share in (None, 0.5, 1.0):
        body = {**{"name": "b", "type": "dynamic", "mass": 1.0, "shapes": SHAPES["box"], "angular_velocity": 5.0},
                **({"support_points": corners, "support_share": share} if share else {})}
        scene = parse_scene({"name": "spin", "world": {"plane": "horizontal", "support_model": model},
                             "sim": {"h": 0.002, "t_end": 0.5}, "bodies": [body]})
        traj = simulate(scene)
        moving = np.flatnonzero(np.abs(traj.v[:, 0, 2]) > 1e-9)
        stops.append(traj.t[moving[-1] + 1])
    assert stops[0] > stops[1] > stops[2]


@pytest.mark.parametrize("extra, message", [
    ({"support_share": 0.5}, "bodies[0].support_share needs support_points on the same body"),
    ({"support_points": RING, "support_share": 0.0}, "bodies[0].support_share must be in (0, 1]"),
    ({"support_points": RING, "support_share": 1.5}, "bodies[0].support_share must be in (0, 1]"),
    ({"support_points": RING, "support_share": "half"}, "bodies[0].support_share must be a number, got 'half'"),
])
def test_bad_shares_are_refused(extra, message):
    body = {"name": "b", "type": "dynamic", "mass": 1.0, "shapes": SHAPES["box"], **extra}
    with pytest.raises(SceneError) as e:
        parse_scene({"name": "x", "world": {"plane": "horizontal"}, "bodies": [body]})
    assert message in str(e.value) and "\n" not in str(e.value)


def test_share_is_only_for_dynamic_bodies_in_the_horizontal_plane():
    with pytest.raises(SceneError, match=r"bodies\[0\]\.support_share is only allowed in the horizontal plane"):
        parse_scene({"name": "x", "world": {"plane": "vertical"}, "bodies": [
            {"name": "b", "type": "dynamic", "mass": 1.0, "shapes": SHAPES["box"], "support_share": 0.5}]})
    with pytest.raises(SceneError, match=r"bodies\[0\]\.support_share is not allowed on a kinematic body"):
        parse_scene({"name": "x", "world": {"plane": "horizontal"}, "bodies": [
            {"name": "b", "type": "kinematic", "shapes": SHAPES["box"], "support_share": 0.5}]})
