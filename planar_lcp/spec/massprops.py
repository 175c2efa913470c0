"""Mass properties of shapes and bodies at uniform density, and default table-support points.

Every shape except the halfplane is a convex core (1, 2 or >= 3 vertices) inflated by a radius r: the Minkowski
sum of the core polygon and a disk of radius r. Its area, centroid and polar moment are exact: the core polygon,
plus an r-wide rectangle outward on each edge, plus a circular sector of radius r at each vertex whose angle is
the exterior angle there (the angles sum to 2*pi). A disk is the 1-vertex case (one sector of 2*pi), a capsule
or rounded segment the 2-vertex case (two rectangles back to back and two half-disks).

All quantities are in the BODY frame: lengths in m, areas in m^2, polar moments of area in m^4.
A body's shapes are taken as disjoint: where two shapes of one body overlap, the overlap is counted twice.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from planar_lcp.frames import rotation

if TYPE_CHECKING:  # pragma: no cover
    from planar_lcp.spec.scene import BodySpec, ShapeSpec


def _check_shape(shape) -> None:
    if shape.type == "halfplane":
        raise ValueError("mass properties are not defined for a halfplane (it is unbounded)")


def _core_props(core: np.ndarray, r: float):
    """Area, centroid and polar moment about the centroid of a convex CCW core (k, 2) inflated by r."""
    core = np.asarray(core, dtype=np.float64)
    k = len(core)
    o = core.mean(axis=0)
    v = core - o                          # about the core mean, so the shift back loses no digits
    area = 0.0
    first = np.zeros(2)                   # integral of x dA, x relative to o
    second = 0.0                          # integral of |x|^2 dA
    if k == 1:
        area = math.pi * r * r
        second = 0.5 * math.pi * r ** 4
        return area, o.copy(), second
    if k >= 3:
        # Fan from vertex 0: integral of |x|^2 over a triangle (a, b, c) is A/6 (|a|^2+|b|^2+|c|^2+a.b+b.c+c.a).
        a = v[0]
        for i in range(1, k - 1):
            b, c = v[i], v[i + 1]
            at = 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
            area += at
            first += at * (a + b + c) / 3.0
            second += at / 6.0 * (a @ a + b @ b + c @ c + a @ b + b @ c + c @ a)
    if r > 0.0:
        edges = np.roll(v, -1, axis=0) - v                    # edges[i] = v[i+1] - v[i]
        lengths = np.linalg.norm(edges, axis=1)
        normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) / lengths[:, None]   # outward for CCW
        for i in range(k):
            # Edge rectangle: L x r, outward of edge i.
            L = lengths[i]
            ar = L * r
            m = 0.5 * (v[i] + v[(i + 1) % k]) + 0.5 * r * normals[i]
            area += ar
            first += ar * m
            second += ar * (L * L + r * r) / 12.0 + ar * (m @ m)
            # Vertex sector at v[i], between the normals of edges i-1 and i.
            ep, en = edges[i - 1], edges[i]
            alpha = math.pi if k == 2 else math.atan2(ep[0] * en[1] - ep[1] * en[0], ep @ en)
            n0 = normals[i - 1]
            ca, sa = math.cos(0.5 * alpha), math.sin(0.5 * alpha)
            u = np.array([ca * n0[0] - sa * n0[1], sa * n0[0] + ca * n0[1]])   # the sector's bisector
            asec = 0.5 * alpha * r * r
            d = 4.0 * r * math.sin(0.5 * alpha) / (3.0 * alpha)              # centroid distance from v[i]
            area += asec
            first += asec * (v[i] + d * u)
            second += asec * (v[i] @ v[i]) + 2.0 * asec * d * (v[i] @ u) + 0.25 * alpha * r ** 4
    if area == 0.0:
        # A segment without radius: no area; its centroid is the midpoint.
        return 0.0, o.copy(), 0.0
    c = first / area
    return float(area), o + c, float(second - area * (c @ c))


def _shape_props(shape):
    """Area, centroid (body frame) and polar moment about the centroid of one shape."""
    _check_shape(shape)
    core = shape.core_vertices_body()
    area, c, polar = _core_props(core, shape.radius)
    # Symmetric shapes: the centroid is exactly the placement (no round-off), so a body made of one such shape
    # at offset 0 has its centre of mass exactly at the body-frame origin.
    if shape.type in ("disk", "capsule", "box"):
        c = np.array(shape.offset, dtype=np.float64)
    elif shape.type == "segment":
        c = 0.5 * (core[0] + core[1])
    return area, c, polar


def shape_area(shape: ShapeSpec) -> float:
    """Area of a shape, m^2 (0 for a segment with radius 0). ValueError for a halfplane."""
    return _shape_props(shape)[0]


def shape_centroid(shape: ShapeSpec) -> np.ndarray:
    """(2,) float64, m: the shape's centroid in the body frame (a radius-0 segment: its midpoint)."""
    return _shape_props(shape)[1]


def shape_polar_moment(shape: ShapeSpec) -> float:
    """Polar second moment of AREA about the shape's own centroid, integral of |r - c|^2 dA, m^4."""
    return _shape_props(shape)[2]


def body_area_properties(body: BodySpec):
    """Area, area centroid and polar moment of area about that centroid of a body's shapes.

    Returns
    -------
    area : float, m^2
    com : (2,) float64, m, body frame
    polar : float, m^4
        sum over shapes of J_s + A_s |c_s - com|^2.
    """
    props = [_shape_props(s) for s in body.shapes]
    area = sum(p[0] for p in props)
    if area <= 0.0:
        raise ValueError(f"body {body.name!r} has no shape with area")
    com = sum(p[0] * p[1] for p in props) / area
    polar = sum(p[2] + p[0] * float((p[1] - com) @ (p[1] - com)) for p in props)
    return float(area), com, float(polar)


def body_mass_properties(body: BodySpec):
    """Centre of mass and moment of inertia of a body at uniform density.

    Returns
    -------
    com : (2,) float64, m
        Body frame: `body.center_of_mass` if given, else the area-weighted centroid of the shapes.
    inertia : float, kg m^2
        About the centre of mass: `body.inertia` if given, else mass / area * polar moment of area.

    Raises
    ------
    ValueError
        For a body without mass (static or kinematic) or without a shape with area.
    """
    if body.mass is None:
        raise ValueError(f"body {body.name!r} is {body.type}: it has no mass properties")
    area, com, polar = body_area_properties(body)
    inertia = float(body.inertia) if body.inertia is not None else float(body.mass / area * polar)
    if body.center_of_mass is not None:
        # the shapes' polar moment is about their centroid; about another centre it grows by area * distance^2
        centre = np.asarray(body.center_of_mass, dtype=np.float64)
        if body.inertia is None:
            inertia += float(body.mass * np.sum((centre - com) ** 2))
        com = centre
    return com, inertia


def _match_moments(points: np.ndarray, weights: np.ndarray, centroid: np.ndarray, mean_sq: float) -> np.ndarray:
    """Move and scale points about `centroid` so that sum w p = centroid and sum w |p - centroid|^2 = mean_sq."""
    q = points - weights @ points
    s = math.sqrt(mean_sq / float(weights @ np.sum(q * q, axis=1)))
    return centroid + s * q


def _grid_2x2(w: float, h: float) -> np.ndarray:
    """Gauss points of a w x h rectangle centred at 0: exact for quadratics."""
    gx, gy = w / (2.0 * math.sqrt(3.0)), h / (2.0 * math.sqrt(3.0))
    return np.array([[-gx, -gy], [gx, -gy], [gx, gy], [-gx, gy]])


def _to_body(shape, local: np.ndarray) -> np.ndarray:
    return local @ rotation(shape.angle).T + np.asarray(shape.offset, dtype=np.float64)


def _shape_support(shape):
    """(area, points (P, 2) in the body frame, weights (P,) summing to 1) with the shape's zeroth, first and
    polar second moments, or None for a shape without area."""
    area, c, polar = _shape_props(shape)
    if area == 0.0:
        return None
    r = shape.radius
    t = shape.type
    if t == "disk":
        a = r / math.sqrt(2.0)
        pts = _to_body(shape, np.array([[a, 0.0], [0.0, a], [-a, 0.0], [0.0, -a]]))
        return area, pts, np.full(4, 0.25)
    if t == "box":
        pts = _to_body(shape, _grid_2x2(shape.width + 2 * r, shape.height + 2 * r))
    elif t in ("capsule", "segment"):
        core = shape.core_vertices_local()
        axis = core[1] - core[0]
        L = float(np.linalg.norm(axis))
        grid = _grid_2x2(L + 2 * r, 2 * r)
        ux = axis / L
        rot = np.array([ux, [-ux[1], ux[0]]])           # rows: the local axes of the segment
        pts = _to_body(shape, grid @ rot + 0.5 * (core[0] + core[1]))
    else:  # polygon: per fan triangle its edge midpoints, each A_t / 3 (exact for quadratics), shared ones merged
        v = shape.core_vertices_body()
        k = len(v)
        acc = {}
        for i in range(1, k - 1):
            at = 0.5 * ((v[i][0] - v[0][0]) * (v[i + 1][1] - v[0][1]) - (v[i][1] - v[0][1]) * (v[i + 1][0] - v[0][0]))
            for key in ((0, i), (i, i + 1), (0, i + 1)):
                acc[key] = acc.get(key, 0.0) + at / 3.0
        keys = list(acc)
        pts = np.array([0.5 * (v[a] + v[b]) for a, b in keys])
        w = np.array([acc[key] for key in keys])
        w = w / w.sum()
        if r > 0.0:
            pts = _match_moments(pts, w, c, polar / area)
        return area, pts, w
    w = np.full(4, 0.25)
    if r > 0.0:
        pts = _match_moments(pts, w, c, polar / area)
    return area, pts, w


def default_support_points(body: BodySpec):
    """Points where the table carries a body in the horizontal plane, with their share of the load.

    `body.support_points` if given (equal weights; `support_share` of the load, the rest as without them). Otherwise
    per shape a few points whose weights are proportional to area and whose zeroth, first and second moments match
    the body's area distribution:
    sum w = 1, sum w p = com, sum w |p - com|^2 = polar / area (see `body_area_properties`). A box (radius 0)
    gives its 2x2 Gauss points, a disk 4 points on the ring of radius R/sqrt(2), a polygon the edge midpoints of
    its fan triangles; rounded shapes a grid on their outer box, moved and scaled about their centroid so the
    moments match exactly.

    Returns
    -------
    points : (P, 2) float64, m, body frame
    weights : (P,) float64, summing to 1
    """
    share = support_share(body)
    if share == 1.0:
        pts = np.array(body.support_points, dtype=np.float64).reshape(-1, 2)
        return pts, np.full(len(pts), 1.0 / len(pts))
    parts = [sup for sup in map(_shape_support, body.shapes) if sup is not None]
    total = sum(a for a, _, _ in parts)
    if total <= 0.0:
        raise ValueError(f"body {body.name!r} has no shape with area")
    pts = np.concatenate([p for _, p, _ in parts])
    w = np.concatenate([a / total * ws for a, _, ws in parts])
    if share == 0.0:
        return pts, w
    given = np.array(body.support_points, dtype=np.float64).reshape(-1, 2)
    return np.concatenate([pts, given]), np.concatenate([(1.0 - share) * w, np.full(len(given), share / len(given))])


def support_share(body: BodySpec) -> float:
    """The share of the table load at `body.support_points` (`support_share`, default 1 with support points), 0
    without them: the rest is spread over the shapes."""
    if body.support_points is None:
        return 0.0
    return 1.0 if body.support_share is None else float(body.support_share)


def support_points(body: BodySpec, world):
    """How the table carries a dynamic body in the horizontal plane: `default_support_points` and the body-table
    Coulomb coefficient (`body.support_friction`, else `world.friction`).

    Returns
    -------
    points : (P, 2) float64, m, body frame
    weights : (P,) float64, summing to 1 (each point's share of the load m g)
    mu : float
    """
    pts, w = default_support_points(body)
    return pts, w, support_friction(body, world)


def support_friction(body: BodySpec, world) -> float:
    """The body-table Coulomb coefficient: `body.support_friction`, else `world.friction`."""
    return float(body.support_friction if body.support_friction is not None else world.friction)
