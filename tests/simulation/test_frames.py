"""planar_lcp.frames (body frame <-> centre of mass) and planar_lcp.geometry (shapes as shapely geometries).

Oracles: the inverse conversion, the time derivative of a rigid motion (finite differences), the rotation matrix's
own properties, and massprops' exact areas.
"""

import math

import numpy as np
import pytest

from planar_lcp.frames import com_to_frame, com_velocity, frame_to_com, frame_velocity, rotation
from planar_lcp.spec.massprops import shape_area
from planar_lcp.spec.scene import load_scene

RNG = np.random.default_rng(11)
COM = RNG.uniform(-0.3, 0.3, (4, 2))


def test_rotation_is_a_proper_rotation_by_theta():
    for theta in RNG.uniform(-10, 10, 20):
        R = rotation(theta)
        assert np.allclose(R @ R.T, np.eye(2), atol=1e-15) and np.linalg.det(R) == pytest.approx(1.0, abs=1e-15)
        assert R @ np.array([1.0, 0.0]) == pytest.approx([math.cos(theta), math.sin(theta)], abs=1e-15)


def test_com_and_frame_poses_are_inverse_and_keep_the_angle():
    q = RNG.uniform(-2, 2, (7, 4, 3))
    assert np.allclose(frame_to_com(com_to_frame(q, COM), COM), q, atol=1e-14)
    assert np.array_equal(com_to_frame(q, COM)[..., 2], q[..., 2])
    # the COM lies at com_local from the origin, rotated with the body
    qf = com_to_frame(q, COM)
    for j in range(4):
        d = q[3, j, :2] - qf[3, j, :2]
        assert d == pytest.approx(rotation(q[3, j, 2]) @ COM[j], abs=1e-14)


def test_frame_velocity_is_the_time_derivative_of_the_frame_pose():
    """A rigid motion with constant COM velocity and spin: the origin's velocity from frame_velocity matches the
    central difference of com_to_frame over a short time."""
    q0, v = RNG.uniform(-1, 1, (4, 3)), RNG.uniform(-2, 2, (4, 3))
    dt = 1e-6
    fd = (com_to_frame(q0 + dt * v, COM) - com_to_frame(q0 - dt * v, COM)) / (2 * dt)
    assert np.allclose(frame_velocity(q0, v, COM), fd, atol=1e-8)


def test_com_velocity_inverts_frame_velocity():
    q, v = RNG.uniform(-1, 1, (4, 3)), RNG.uniform(-2, 2, (4, 3))
    vo = frame_velocity(q, v, COM)
    for j in range(4):
        assert com_velocity(q[j, 2], vo[j, :2], vo[j, 2], COM[j]) == pytest.approx(v[j, :2], abs=1e-14)


@pytest.mark.parametrize("name", ["falling_rod", "four_disks", "push_t", "box_tip"])
def test_shape_geometry_has_the_exact_area(name):
    pytest.importorskip("shapely")
    from planar_lcp.geometry import shape_geometry
    for body in load_scene(name).bodies:
        for s in body.shapes:
            if s.type == "halfplane":
                continue
            g = shape_geometry(s, quad_segs=64)
            assert g.area == pytest.approx(shape_area(s), rel=2e-4, abs=1e-12)
            assert shape_geometry(s, quad_segs=8).area <= g.area     # inscribed arcs: coarser is smaller


def test_frame_state_is_both_conversions_with_one_rotation():
    """A Trajectory's q and v (`frame_state`): the frame origin o = c - R(theta) com_local and its velocity
    v_c + omega x (o - c), against the rotation written out; a body whose COM is its origin gets copies."""
    from planar_lcp.frames import frame_state
    rng = np.random.default_rng(3)
    q, v = rng.normal(size=(7, 2, 3)), rng.normal(size=(7, 2, 3))
    com = np.array([[0.1, -0.2], [0.0, 0.0]])
    qf, vf = frame_state(q, v, com)
    for t in range(7):
        for b in range(2):
            r = rotation(q[t, b, 2]) @ com[b]
            assert np.allclose(qf[t, b], [q[t, b, 0] - r[0], q[t, b, 1] - r[1], q[t, b, 2]], rtol=0, atol=1e-15)
            w = v[t, b, 2]
            assert np.allclose(vf[t, b], [v[t, b, 0] + w * r[1], v[t, b, 1] - w * r[0], w], rtol=0, atol=1e-15)
    assert np.array_equal(qf, com_to_frame(q, com)) and np.array_equal(vf, frame_velocity(q, v, com))
    q0, v0 = frame_state(q, v, np.zeros((2, 2)))
    assert np.array_equal(q0, q) and np.array_equal(v0, v)
    assert not np.shares_memory(q0, q) and not np.shares_memory(v0, v)
