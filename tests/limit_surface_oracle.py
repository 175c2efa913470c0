"""Naive oracle for table friction as a limit surface: the table's friction wrench on a body under uniform
support pressure, by direct quadrature of Coulomb's law at every point of the support region.

For a body moving with twist (vx, vy, omega) about its centre of mass, the friction force per area at body point r
(COM frame) is -mu p v(r) / |v(r)|, with v(r) = (vx - omega r_y, vy + omega r_x) and p = m g / area. The wrench
(fx, fy, torque about the COM) is its integral over the region. Gauss-Legendre nodes in both directions of each
region (a disk in polar coordinates, a rectangle in x and y); the integrand is bounded and smooth except at the
centre of rotation, so refining the nodes shows the accuracy reached (tests/simulation/test_limit_surface_oracle.py).
Deliberately independent of planar_lcp: it is what the simulator's limit-surface model will be checked against.
"""

import numpy as np


def disk_nodes(radius, n_radial=64, n_angular=256):
    """Quadrature nodes (N, 2) and weights (N,) (m^2) over a disk of `radius` centred at the origin."""
    x, w = np.polynomial.legendre.leggauss(n_radial)
    r = 0.5 * radius * (x + 1.0)
    w_r = 0.5 * radius * w * r                       # dA = r dr dtheta
    theta = (np.arange(n_angular) + 0.5) * 2.0 * np.pi / n_angular
    rr, tt = np.meshgrid(r, theta, indexing="ij")
    weights = np.outer(w_r, np.full(n_angular, 2.0 * np.pi / n_angular))
    return np.stack([rr * np.cos(tt), rr * np.sin(tt)], -1).reshape(-1, 2), weights.ravel()


def rect_nodes(cx, cy, half_x, half_y, n=128):
    """Quadrature nodes and weights over the rectangle centred at (cx, cy) with half-sizes half_x, half_y (m)."""
    x, w = np.polynomial.legendre.leggauss(n)
    X, Y = np.meshgrid(cx + half_x * x, cy + half_y * x, indexing="ij")
    return np.stack([X, Y], -1).reshape(-1, 2), np.outer(half_x * w, half_y * w).ravel()


def friction_wrench(nodes, weights, twist, mu, mass, g):
    """(fx, fy, torque) in N, N, N m: the table's friction on a body of `mass` (kg) under uniform pressure over the
    region of (nodes, weights), moving with twist (vx, vy, omega) (m/s, m/s, rad/s) about the origin of the nodes."""
    vx, vy, omega = twist
    r = np.asarray(nodes, dtype=float)
    v = np.stack([vx - omega * r[:, 1], vy + omega * r[:, 0]], -1)
    speed = np.hypot(v[:, 0], v[:, 1])
    speed = np.where(speed > 0.0, speed, np.inf)      # a point at the centre of rotation carries no force
    f = -mu * (mass * g / weights.sum()) * weights[:, None] * v / speed[:, None]
    return np.array([f[:, 0].sum(), f[:, 1].sum(), (r[:, 0] * f[:, 1] - r[:, 1] * f[:, 0]).sum()])


def slip_ratio_fixed_point(wrench, R, lo=0.3, hi=1.2):
    """The ratio eps = v / (R omega) at which a solid disk (J = m R^2 / 2, m = 1) sliding along x and spinning keeps
    its ratio, d(v / (R omega))/dt = 0, i.e. a_v / v = alpha / omega, by bisection on [lo, hi]. wrench(twist) returns
    the opposing unit-load wrench (fx, fy, torque) for the twist (eps R, 0, 1)."""
    def drift(eps):
        fx, _, tau = wrench((eps * R, 0.0, 1.0))
        return fx / (eps * R) - tau / (0.5 * R * R)

    assert drift(lo) * drift(hi) < 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if drift(lo) * drift(mid) <= 0.0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def disk_slip_ratio_limit(n_radial=64, n_angular=256):
    """The ratio v / (R omega) that a disk sliding and spinning on a table tends to as both motions stop (Farkas,
    Bartels, Unger & Wolf, PRL 90, 248302, 2003: about 0.653): `slip_ratio_fixed_point` of this quadrature.
    Scale-free (R, m, g, mu drop out)."""
    nodes, weights = disk_nodes(1.0, n_radial, n_angular)
    return slip_ratio_fixed_point(lambda t: -friction_wrench(nodes, weights, t, 1.0, 1.0, 1.0), 1.0)
