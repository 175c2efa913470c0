"""The table's friction on a body in the horizontal plane as a limit surface (docs/method.md, "Table friction").

With the normal load m g known and spread over the body by a support pressure p (uniform over the body's shapes, or
equal shares at given support points), Coulomb's law at every point gives the friction wrench of a body moving with
twist t = (v_x, v_y, omega) about its centre of mass:

    w(t) = -mu m g  integral p(r) (u(r), r x u(r)) dA / integral p dA,   u(r) = v(r) / |v(r)|,
    v(r) = (v_x - omega r_y, v_y + omega r_x).

The set of all such wrenches (with |u(r)| <= 1 anywhere) is the limit surface's interior W, convex and symmetric; the
friction a sliding body feels is the point of W that dissipates most, -mu m g L(t) with L(t) the "unit-load wrench"
of t, evaluated by engine/limit_surface.py `unit_load_wrench`. Here, once per body at compile time: the pressure's
pieces (polygon edges for the closed form, full disks for the unit disk's table, Gauss nodes for the other curved
pieces and for far twists), the unit disk's table, and the fixed twist directions whose wrenches span the polyhedral
part of the model. The Gauss resolution n is the scene's `[sim] limit_surface_resolution`.

All in the body's COM frame: lengths m, weights dimensionless (summing to 1), twists (m/s, m/s, rad/s).
"""

from __future__ import annotations

import functools
import math
from collections import namedtuple

import numpy as np

from planar_lcp.spec.massprops import body_area_properties, body_mass_properties, support_share

def _gauss01(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def _sector_nodes(c, r, a0, a1, n):
    """Circular sector of radius r about c from angle a0 to a1 (a1 > a0): Gauss in the radius with the polar weight;
    in the angle, Gauss on a partial sector, the midpoint rule (exact for the periodic integrand) on a full circle.
    Returns nodes (P, 2) and weights (P,), m^2."""
    s, ws = _gauss01(n)
    span = a1 - a0
    if span >= 2.0 * math.pi - 1e-12:
        m = 4 * n
        ang = a0 + (np.arange(m) + 0.5) * span / m
        wa = np.full(m, span / m)
    else:
        m = max(n, int(math.ceil(n * span / (0.5 * math.pi))))
        x, wx = _gauss01(m)
        ang = a0 + span * x
        wa = span * wx
    R, A = np.meshgrid(r * s, ang, indexing="ij")
    pts = c + np.stack([R * np.cos(A), R * np.sin(A)], -1)
    w = np.outer(r * r * ws * s, wa)
    return pts.reshape(-1, 2), w.ravel()


#: Gauss points per direction on each fan triangle of a polygon piece for twists whose centre of rotation is far from
#: the body (engine/limit_surface.py FAR_RATIO): there the integrand is analytic over the body and the closed form
#: would lose digits to cancellation. tests/simulation/test_limit_surface.py measures the agreement where the two meet.
FAR_RESOLUTION = 3


def _fan_nodes(poly, n):
    """Gauss nodes and weights (m^2) over a convex CCW polygon: n x n per fan triangle from the vertex mean."""
    poly = np.asarray(poly, dtype=np.float64)
    o = poly.mean(axis=0)
    s, ws = _gauss01(n)
    S, T = np.meshgrid(s, s, indexing="ij")
    pts, wts = [], []
    for i in range(len(poly)):
        ea, eb = poly[i] - o, poly[(i + 1) % len(poly)] - o
        area2 = abs(ea[0] * eb[1] - ea[1] * eb[0])
        pts.append((o + S[..., None] * ((1.0 - T)[..., None] * ea + T[..., None] * eb)).reshape(-1, 2))
        wts.append((area2 * np.outer(ws * s, ws)).ravel())
    return np.concatenate(pts), np.concatenate(wts)


def _ccw_edges(poly):
    """Directed edges (k, 4) = (a_x, a_y, b_x, b_y) of a convex polygon, counter-clockwise."""
    poly = np.asarray(poly, dtype=np.float64)
    x, y = poly[:, 0], poly[:, 1]
    if np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)) < 0.0:
        poly = poly[::-1]
    return np.hstack([poly, np.roll(poly, -1, axis=0)])


def shape_pressure(shape, n):
    """One shape's area in the pieces of `massprops` (its convex core, a strip of width r outward of each core edge,
    a sector of radius r at each core vertex; a capsule: the rectangle around its segment and two half-disks; a
    disk: itself). Body frame, m; weights m^2. Returns a dict:

    edges (E, 4): the directed edges of its polygon pieces (integrated in closed form);
    far (F, 2), far_w (F,): Gauss quadrature of those polygon pieces, for a far centre of rotation;
    disks (D, 3): (centre x, y, radius) of a full disk (by the unit disk's table, `disk_table`), with
    disk_nodes [(Q, 2), (Q,)]: its polar Gauss nodes, for a very far centre of rotation and translations;
    nodes (P, 2), weights (P,): Gauss quadrature of its other curved pieces, n points per direction."""
    core = shape.core_vertices_body()
    r = float(shape.radius)
    k = len(core)
    edges, nodes, disks, disk_nodes = [], [], [], []
    if k >= 3:
        edges.append(_ccw_edges(core))
    if r > 0.0:
        if k == 2:
            e = core[1] - core[0]
            nrm = np.array([e[1], -e[0]]) / np.hypot(e[0], e[1])
            edges.append(_ccw_edges([core[0] + r * nrm, core[1] + r * nrm, core[1] - r * nrm, core[0] - r * nrm]))
        elif k >= 3:
            ccw = _ccw_edges(core)
            for a, b in zip(ccw[:, :2], ccw[:, 2:]):
                e = b - a
                nrm = np.array([e[1], -e[0]]) / np.hypot(e[0], e[1])    # outward of a CCW core
                edges.append(_ccw_edges([a, b, b + r * nrm, a + r * nrm]))
        if k == 1:
            disks.append([core[0][0], core[0][1], r])
            disk_nodes.append(_sector_nodes(core[0], r, 0.0, 2.0 * math.pi, n))
        else:
            ring = core if k == 2 else _ccw_edges(core)[:, :2]
            for i in range(len(ring)):
                # the corner sector between the outward normals of the two edges that meet at vertex i
                if k == 2:
                    e_in = ring[i] - ring[1 - i]
                    e_out = e_in
                else:
                    e_in, e_out = ring[i] - ring[i - 1], ring[(i + 1) % len(ring)] - ring[i]
                a0 = math.atan2(-e_in[0], e_in[1])
                a1 = a0 + math.pi if k == 2 else math.atan2(-e_out[0], e_out[1])
                while a1 <= a0:
                    a1 += 2.0 * math.pi
                nodes.append(_sector_nodes(ring[i], r, a0, a1, n))
    far, far_w = _cat([_fan_nodes(e[:, :2], FAR_RESOLUTION) for e in edges])
    curved, curved_w = _cat(nodes)
    return dict(edges=np.concatenate(edges) if edges else np.zeros((0, 4)), far=far, far_w=far_w,
                disks=np.array(disks, dtype=np.float64).reshape(-1, 3), disk_nodes=disk_nodes,
                nodes=curved, weights=curved_w)


def _cat(parts):
    if not parts:
        return np.zeros((0, 2)), np.zeros(0)
    return np.concatenate([p for p, _ in parts]), np.concatenate([w for _, w in parts])


#: A body's support pressure about its centre of mass, as one limit-surface element (`support_pressure`): m, COM
#: frame; node weights (x, y, w) normalized by the area; edge_scale = 1 / area (1/m^2) for the closed forms.
SupportPressure = namedtuple("SupportPressure", ["edges", "edge_scale", "nodes", "far", "disks", "disk_nodes", "size"])


def support_pressure(body, n):
    """A dynamic body's support pressure as a `SupportPressure`: uniform over the body's shapes (overlaps counted
    twice, as in `massprops`), or equal shares at `body.support_points` when the scene gives them (then nodes only),
    or `support_share` of the load at them and the rest uniform.
    nodes: its curved pieces' (or the support points); far: its polygon pieces'; disk_nodes: one (Q, 3) array per
    disk; size: the largest distance of the support from the COM, m. Positions are about the body's centre of mass
    (`body_mass_properties`: the shapes' area centroid, or `center_of_mass` when given), the frame the model uses."""
    area, _, _ = body_area_properties(body)
    com = np.asarray(body_mass_properties(body)[0], dtype=np.float64)
    share = support_share(body)
    if share == 1.0:
        pts = np.array(body.support_points, dtype=np.float64).reshape(-1, 2) - com
        nodes = np.column_stack([pts, np.full(len(pts), 1.0 / len(pts))])
        return SupportPressure(np.zeros((0, 4)), 0.0, nodes, np.zeros((0, 3)), np.zeros((0, 3)), [],
                               float(np.max(np.hypot(pts[:, 0], pts[:, 1]))))
    parts = [shape_pressure(s, n) for s in body.shapes]
    # the uniform part carries 1 - share of the load: L(t) is linear in the pressure, so its nodes' weights and the
    # closed forms' scale shrink by that factor and the support points join the nodes with the rest
    # (w / area * 1.0: the pressure without support points, bit for bit)
    rest = 1.0 - share

    def weighted(pts, w):
        keep = w > 0.0                       # a radius-0 segment has no area
        return np.ascontiguousarray(np.column_stack([pts[keep] - com, w[keep] / area * rest]))
    edges = np.concatenate([p["edges"] for p in parts]) - np.tile(com, 2)
    nodes = weighted(np.concatenate([p["nodes"] for p in parts]), np.concatenate([p["weights"] for p in parts]))
    if share > 0.0:
        pts = np.array(body.support_points, dtype=np.float64).reshape(-1, 2) - com
        nodes = np.ascontiguousarray(np.concatenate([nodes, np.column_stack([pts, np.full(len(pts),
                                                                                           share / len(pts))])]))
    far = weighted(np.concatenate([p["far"] for p in parts]), np.concatenate([p["far_w"] for p in parts]))
    disks = np.concatenate([p["disks"] for p in parts])
    disks[:, :2] -= com
    disk_nodes = [weighted(*dn) for p in parts for dn in p["disk_nodes"]]
    reach = np.concatenate([np.hypot(edges[:, 0], edges[:, 1]), np.hypot(nodes[:, 0], nodes[:, 1]),
                            np.hypot(disks[:, 0], disks[:, 1]) + disks[:, 2]])
    size = float(reach.max()) if len(reach) else 0.0
    return SupportPressure(np.ascontiguousarray(edges), 1.0 / area * rest, nodes, far, np.ascontiguousarray(disks),
                           disk_nodes, size)


#: The unit disk's table (`disk_table`): centre-of-rotation distances 0, DISK_TABLE_STEP, ..., DISK_TABLE_MAX radii.
DISK_TABLE_STEP = 1.0 / 256.0
DISK_TABLE_MAX = 8.0


@functools.lru_cache(maxsize=1)
def disk_table():
    """(T, 2): for the unit disk about the origin and a centre of rotation c at distance d = 0, DISK_TABLE_STEP, ...,
    DISK_TABLE_MAX on the +x axis, Phi(d) = integral |r - c| dA and G_x(d) of G = integral (r - c) / |r - c| dA
    (G_y = 0; dPhi / dd = -G_x). In polar coordinates about c, where the integrand is smooth: for d < 1 the ray in
    direction theta leaves the disk at rho = -d cos(theta) + sqrt(1 - d^2 sin^2(theta)) and
    Phi = integral rho^3 / 3 dtheta, G_x = integral cos(theta) rho^2 / 2 dtheta (the trapezoid rule: periodic and
    analytic, 2048 points); for d >= 1, with sin(psi) = sin(phi) / d and X = sqrt(d^2 - sin^2 phi) over
    phi in [-pi/2, pi/2] (Gauss-Legendre, 96 points): Phi = integral 2/3 cos^2(phi) (3 X^2 + cos^2 phi) / X dphi,
    G_x = -2/d integral X cos^2(phi) dphi. tests/simulation/test_limit_surface.py checks it against the naive oracle."""
    d = np.arange(0.0, DISK_TABLE_MAX + 0.5 * DISK_TABLE_STEP, DISK_TABLE_STEP)
    out = np.empty((len(d), 2))
    inside = d < 1.0
    m = 2048
    th = (np.arange(m) + 0.5) * 2.0 * np.pi / m
    di = d[inside][:, None]
    rho = -di * np.cos(th) + np.sqrt(1.0 - di * di * np.sin(th) ** 2)
    out[inside, 0] = (rho ** 3).sum(axis=1) * (2.0 * np.pi / m) / 3.0
    out[inside, 1] = 0.5 * (np.cos(th) * rho ** 2).sum(axis=1) * (2.0 * np.pi / m)
    x, w = np.polynomial.legendre.leggauss(96)
    phi, w = 0.5 * np.pi * x, 0.5 * np.pi * w
    do = d[~inside][:, None]
    X = np.sqrt(do * do - np.sin(phi) ** 2)
    c2 = np.cos(phi) ** 2
    out[~inside, 0] = (2.0 / 3.0 * c2 * (3.0 * X * X + c2) / X * w).sum(axis=1)
    out[~inside, 1] = -2.0 / do[:, 0] * (X * c2 * w).sum(axis=1)
    out.flags.writeable = False
    return out


def gyration_radius(body):
    """sqrt(integral p |r - com|^2 dA / integral p dA), m: the radius that makes a twist's spin commensurate with its
    slide (the support pressure's, like `support_pressure`), about the body's centre of mass."""
    area, centroid, polar = body_area_properties(body)
    com = np.asarray(body_mass_properties(body)[0], dtype=np.float64)
    share = support_share(body)
    # the uniform part's second moment about the centroid, moved to the centre of mass (parallel axes)
    second = (1.0 - share) * (polar / area + float(np.sum((com - centroid) ** 2))) if share < 1.0 else 0.0
    if share > 0.0:
        pts = np.array(body.support_points, dtype=np.float64).reshape(-1, 2) - com
        second += share * float(np.mean(np.sum(pts * pts, axis=1)))
    return float(np.sqrt(second))


def twist_directions(count, rho):
    """`count` (even, >= 6) fixed twist directions (count, 3) in antipodal pairs: first +-x, +-y, +-spin, then pairs
    spread evenly over the sphere of (v_x, v_y, rho omega) (a Fibonacci lattice on the upper half). Unit in that
    scaled norm; omega is returned in rad/s per (m/s)."""
    if count < 6 or count % 2:
        raise ValueError(f"the number of limit-surface twists must be an even number >= 6, got {count}")
    half = [np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])]
    extra = count // 2 - 3
    golden = math.pi * (3.0 - math.sqrt(5.0))
    for i in range(extra):
        z = 1.0 - (i + 0.5) / extra          # upper hemisphere, z in (0, 1)
        rr = math.sqrt(max(0.0, 1.0 - z * z))
        half.append(np.array([rr * math.cos(golden * i), rr * math.sin(golden * i), z]))
    d = np.array(half + [-x for x in half])
    d[:, 2] /= rho
    return d
