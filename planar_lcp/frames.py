"""Body frame <-> centre of mass (COM): the one place that converts poses and velocities between the two.

A scene describes a body by the pose and velocity of its body-frame ORIGIN; the dynamics use its centre of mass,
which lies at `com_local` (the COM in the body frame, `massprops.body_mass_properties`). Poses are (x, y, theta) in
m and rad, velocities (vx, vy, omega) in m/s and rad/s; the angle and omega are the same in both frames.

Arrays of poses are (..., nbody, 3) with com_local (nbody, 2): any leading axes (steps) broadcast.
"""

import math

import numpy as np


def rotation(theta):
    """(2, 2) rotation matrix of the angle theta (rad), a scalar."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def _origin_offset(theta, com_local):
    """The body-frame origin less the COM, in the world frame: -R(theta) com_local, as (x, y), each (..., nbody)."""
    c, s = np.cos(theta), np.sin(theta)
    cx, cy = com_local[:, 0], com_local[:, 1]
    return -(c * cx - s * cy), -(s * cx + c * cy)


def com_to_frame(q_com, com_local):
    """COM poses (..., nbody, 3) -> body-frame origin poses."""
    q_com = np.asarray(q_com, dtype=float)
    return frame_state(q_com, None, com_local)[0]


def frame_to_com(q_frame, com_local):
    """Body-frame origin poses (..., nbody, 3) -> COM poses."""
    q_frame = np.asarray(q_frame, dtype=float)
    out = q_frame.copy()
    rx, ry = _origin_offset(q_frame[..., 2], com_local)
    out[..., 0] -= rx                          # o - (o - c): the same bits as o + R com_local (negation is exact)
    out[..., 1] -= ry
    return out


def frame_velocity(q_com, v_com, com_local):
    """Velocity of the body-frame origin from the COM pose and velocity: v_o = v_c + omega x (o - c)."""
    return frame_state(q_com, v_com, com_local)[1]


def frame_state(q_com, v_com, com_local):
    """Body-frame origin poses and velocities (v_o = v_c + omega x (o - c)) from COM poses and velocities
    (..., nbody, 3), with one rotation of com_local for both (a Trajectory's q and v); v_com None: poses only
    (None in its place). Bodies whose COM is their frame's origin (com_local all zero: every symmetric shape) are
    copies."""
    q = q_com.copy()
    v = None if v_com is None else v_com.copy()
    if not com_local.any():
        return q, v
    rx, ry = _origin_offset(q_com[..., 2], com_local)
    q[..., 0] += rx
    q[..., 1] += ry
    if v is not None:
        v[..., 0] = v_com[..., 0] - v_com[..., 2] * ry
        v[..., 1] = v_com[..., 1] + v_com[..., 2] * rx
    return q, v


def com_velocity(angle, velocity, angular_velocity, com):
    """Velocity (vx, vy) of the COM of one body from its frame angle, origin velocity and omega, com (2,) in the body
    frame: v_c = v_o + omega x r_c with r_c = R(angle) com."""
    rc = rotation(angle) @ com
    return velocity[0] - angular_velocity * rc[1], velocity[1] + angular_velocity * rc[0]
