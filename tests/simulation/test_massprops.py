"""Mass properties against analytic formulas, independent numeric integration and shapely geometry."""

import math

import numpy as np
import pytest
from scipy.integrate import quad
from shapely.geometry import LineString, Point, Polygon
from shapely.ops import unary_union

from planar_lcp.spec.massprops import (body_area_properties, body_mass_properties, default_support_points, shape_area,
                                       shape_centroid, shape_polar_moment)
from planar_lcp.spec.scene import BodySpec, ShapeSpec, load_scene


# --- independent oracles ----------------------------------------------------------------------------------------


def ring_moments(coords):
    """Area, centroid, polar moment about the centroid of a simple polygon ring, by the shoelace-type sums
    A = 1/2 sum c_i, I_yy = 1/12 sum (x_i^2 + x_i x_j + x_j^2) c_i, ... with c_i = x_i y_j - x_j y_i."""
    p = np.asarray(coords, dtype=float)
    if np.allclose(p[0], p[-1]):
        p = p[:-1]
    p = p - p.mean(axis=0)
    x, y = p[:, 0], p[:, 1]
    xj, yj = np.roll(x, -1), np.roll(y, -1)
    c = x * yj - xj * y
    a = 0.5 * c.sum()
    cx = ((x + xj) * c).sum() / (6 * a)
    cy = ((y + yj) * c).sum() / (6 * a)
    ixx = ((y * y + y * yj + yj * yj) * c).sum() / 12
    iyy = ((x * x + x * xj + xj * xj) * c).sum() / 12
    return a, np.array([cx, cy]), ixx + iyy - a * (cx * cx + cy * cy)


def geometry_moments(geom):
    """The same for a shapely Polygon (no holes) or MultiPolygon: sum the pieces, shift by parallel axes."""
    parts = list(geom.geoms) if hasattr(geom, "geoms") else [geom]
    props = []
    for g in parts:
        assert len(g.interiors) == 0
        a, c, j = ring_moments(g.exterior.coords)
        if a < 0:  # shapely may hand back a clockwise ring
            a, j = -a, -j
        props.append((a, c + np.asarray(g.exterior.coords[:-1]).mean(axis=0), j))
    area = sum(p[0] for p in props)
    com = sum(p[0] * p[1] for p in props) / area
    polar = sum(p[2] + p[0] * np.sum((p[1] - com) ** 2) for p in props)
    return area, com, polar


def core_geometry(shape):
    core = shape.core_vertices_body()
    if len(core) == 1:
        return Point(core[0])
    if len(core) == 2:
        return LineString(core)
    return Polygon(core)


def buffered(shape, quad_segs=256):
    g = core_geometry(shape)
    return g.buffer(shape.radius, quad_segs=quad_segs) if shape.radius > 0 else g


def capsule_by_parts(length, r):
    """Rectangle 2r x L plus two half-disks, each moved by the parallel-axis theorem (about the capsule centre)."""
    a_rect = 2 * r * length
    j_rect = a_rect * (length ** 2 + (2 * r) ** 2) / 12
    a_half = math.pi * r * r / 2
    d = 4 * r / (3 * math.pi)          # half-disk centroid from its flat edge
    j_half_flat = math.pi * r ** 4 / 4  # about the centre of its flat edge
    j_half_own = j_half_flat - a_half * d * d
    j_half = j_half_own + a_half * (length / 2 + d) ** 2
    return a_rect + 2 * a_half, j_rect + 2 * j_half


def capsule_by_quadrature(length, r):
    """Integrate over x with the capsule's chord half-height h(x): dA = 2h dx, |p|^2 -> x^2 2h + 2h^3/3."""
    a = length / 2

    def h(x):
        return r if abs(x) <= a else math.sqrt(max(r * r - (abs(x) - a) ** 2, 0.0))

    pieces = [(-a - r, -a), (-a, a), (a, a + r)]
    area = sum(quad(lambda x: 2 * h(x), lo, hi, epsabs=0, epsrel=1e-13)[0] for lo, hi in pieces)
    polar = sum(quad(lambda x: x * x * 2 * h(x) + 2 * h(x) ** 3 / 3, lo, hi, epsabs=0, epsrel=1e-13)[0]
                for lo, hi in pieces)
    return area, polar


# --- single shapes --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("r", [0.05, 1.0, 3.7])
def test_disk_is_exact(r):
    s = ShapeSpec("disk", radius=r, offset=(0.3, -1.2), angle=0.7)
    assert shape_area(s) == pytest.approx(math.pi * r * r, rel=1e-14)
    assert shape_polar_moment(s) == pytest.approx(math.pi * r ** 4 / 2, rel=1e-14)
    np.testing.assert_allclose(shape_centroid(s), [0.3, -1.2], rtol=0, atol=1e-15)


@pytest.mark.parametrize("w,h", [(0.2, 0.1), (1.0, 1.0), (3.0, 0.01)])
def test_rectangle_is_exact(w, h):
    s = ShapeSpec("box", width=w, height=h, offset=(1.0, 2.0), angle=0.4)
    a = w * h
    assert shape_area(s) == pytest.approx(a, rel=1e-14)
    assert shape_polar_moment(s) == pytest.approx(a * (w * w + h * h) / 12, rel=1e-13)
    np.testing.assert_allclose(shape_centroid(s), [1.0, 2.0], rtol=0, atol=1e-14)


@pytest.mark.parametrize("length,r", [(0.5, 0.05), (1.0, 0.01), (0.1, 0.4)])
def test_capsule_formula_and_quadrature(length, r):
    s = ShapeSpec("capsule", length=length, radius=r, offset=(-0.2, 0.1), angle=1.1)
    a_parts, j_parts = capsule_by_parts(length, r)
    a_quad, j_quad = capsule_by_quadrature(length, r)
    # The two oracles agree with each other (so neither is a typo) and with the implementation.
    assert a_parts == pytest.approx(a_quad, rel=1e-10)
    assert j_parts == pytest.approx(j_quad, rel=1e-10)
    assert shape_area(s) == pytest.approx(a_parts, rel=1e-13)
    assert shape_polar_moment(s) == pytest.approx(j_parts, rel=1e-12)
    np.testing.assert_allclose(shape_centroid(s), [-0.2, 0.1], rtol=0, atol=1e-15)


def test_rounded_segment_is_a_capsule():
    a, b = np.array([0.3, -0.1]), np.array([1.1, 0.5])
    seg = ShapeSpec("segment", a=tuple(a), b=tuple(b), radius=0.07)
    length = float(np.linalg.norm(b - a))
    a_parts, j_parts = capsule_by_parts(length, 0.07)
    assert shape_area(seg) == pytest.approx(a_parts, rel=1e-13)
    assert shape_polar_moment(seg) == pytest.approx(j_parts, rel=1e-12)
    np.testing.assert_allclose(shape_centroid(seg), (a + b) / 2, rtol=0, atol=1e-15)


def test_segment_without_radius_has_no_area():
    seg = ShapeSpec("segment", a=(0.0, 0.0), b=(2.0, 0.0), offset=(1.0, 1.0), angle=math.pi / 2)
    assert shape_area(seg) == 0.0
    assert shape_polar_moment(seg) == 0.0
    np.testing.assert_allclose(shape_centroid(seg), [1.0, 2.0], atol=1e-15)


POLYGONS = {
    "triangle": ((0.0, 0.0), (1.0, 0.0), (0.2, 0.7)),
    "pentagon": ((0.0, 0.0), (2.0, -0.3), (2.5, 1.0), (1.0, 2.0), (-0.4, 1.1)),
    "far_quad": ((100.0, 50.0), (100.3, 50.0), (100.35, 50.2), (99.9, 50.1)),
    "thin": ((0.0, 0.0), (1.0, 0.0), (1.0, 0.001)),
}


@pytest.mark.parametrize("name", sorted(POLYGONS))
def test_polygon_exact(name):
    s = ShapeSpec("polygon", vertices=POLYGONS[name], offset=(0.5, -0.5), angle=0.3)
    a, c, j = ring_moments(s.core_vertices_body())
    c = c + s.core_vertices_body().mean(axis=0)
    assert shape_area(s) == pytest.approx(a, rel=1e-12)
    assert shape_polar_moment(s) == pytest.approx(j, rel=1e-9)
    np.testing.assert_allclose(shape_centroid(s), c, rtol=1e-12, atol=1e-12)


ROUNDED = [
    ShapeSpec("polygon", vertices=POLYGONS["triangle"], radius=0.1),
    ShapeSpec("polygon", vertices=POLYGONS["pentagon"], radius=0.5, offset=(1.0, 0.0), angle=0.2),
    ShapeSpec("polygon", vertices=POLYGONS["thin"], radius=0.3),
    ShapeSpec("box", width=0.2, height=0.1, radius=0.02, offset=(0.1, 0.2), angle=-0.5),
    ShapeSpec("box", width=0.01, height=0.5, radius=0.3),
    ShapeSpec("segment", a=(0.0, 0.0), b=(0.4, 0.3), radius=0.05),
    ShapeSpec("capsule", length=0.5, radius=0.05, angle=0.9),
    ShapeSpec("disk", radius=0.25, offset=(0.3, 0.3)),
]


@pytest.mark.parametrize("shape", ROUNDED, ids=lambda s: f"{s.type}-r{s.radius}")
def test_rounded_shapes_match_shapely_buffer(shape):
    a, c, j = geometry_moments(buffered(shape))
    assert shape_area(shape) == pytest.approx(a, rel=1e-4)
    assert shape_polar_moment(shape) == pytest.approx(j, rel=1e-4)
    np.testing.assert_allclose(shape_centroid(shape), c, rtol=0, atol=1e-4 * math.sqrt(a))


def test_rounded_polygon_area_is_steiner():
    # Steiner's formula for a convex body inflated by r: A + perimeter r + pi r^2, exactly.
    s = ShapeSpec("polygon", vertices=POLYGONS["pentagon"], radius=0.37)
    core = Polygon(s.core_vertices_body())
    assert shape_area(s) == pytest.approx(core.area + core.length * 0.37 + math.pi * 0.37 ** 2, rel=1e-13)


def test_halfplane_has_no_mass_properties():
    hp = ShapeSpec("halfplane")
    for f in (shape_area, shape_centroid, shape_polar_moment):
        with pytest.raises(ValueError, match="halfplane"):
            f(hp)


# --- bodies ---------------------------------------------------------------------------------------------------


def t_body(**kw):
    return BodySpec(name="T", type="dynamic", mass=0.1, shapes=(
        ShapeSpec("box", width=0.120, height=0.030),
        ShapeSpec("box", width=0.030, height=0.090, offset=(0.0, -0.060)),
    ), **kw)


def test_compound_t_vs_parallel_axis_and_shapely_union():
    body = t_body()
    com, inertia = body_mass_properties(body)
    # Parallel-axis theorem by hand.
    a1, a2 = 0.120 * 0.030, 0.030 * 0.090
    y = (a1 * 0.0 + a2 * -0.060) / (a1 + a2)
    j = (a1 * (0.120 ** 2 + 0.030 ** 2) / 12 + a1 * y * y
         + a2 * (0.030 ** 2 + 0.090 ** 2) / 12 + a2 * (-0.060 - y) ** 2)
    np.testing.assert_allclose(com, [0.0, y], rtol=0, atol=1e-15)
    assert inertia == pytest.approx(0.1 / (a1 + a2) * j, rel=1e-12)
    # The union of the two boxes is one T-shaped polygon.
    union = unary_union([buffered(s) for s in body.shapes])
    assert union.geom_type == "Polygon"
    a, c, ju = geometry_moments(union)
    assert a == pytest.approx(a1 + a2, rel=1e-12)
    np.testing.assert_allclose(com, c, rtol=0, atol=1e-12)
    assert inertia == pytest.approx(0.1 / a * ju, rel=1e-9)


def test_compound_rounded_body_vs_shapely_union():
    shapes = (
        ShapeSpec("box", width=0.3, height=0.1, radius=0.02, angle=0.3),
        ShapeSpec("disk", radius=0.08, offset=(0.5, 0.4)),
        ShapeSpec("polygon", vertices=((-0.6, -0.4), (-0.3, -0.45), (-0.35, -0.2)), radius=0.03, angle=-0.2),
        ShapeSpec("capsule", length=0.3, radius=0.04, offset=(0.0, 0.6), angle=0.1),
        ShapeSpec("segment", a=(0.6, -0.6), b=(0.8, -0.5)),      # no area: carries no mass
    )
    body = BodySpec(name="b", type="dynamic", mass=2.5, shapes=shapes, position=(3.0, 4.0), angle=1.0)
    pieces = [buffered(s) for s in shapes if s.radius > 0 or s.type != "segment"]
    union = unary_union(pieces)
    assert union.geom_type == "MultiPolygon" and len(union.geoms) == 4   # disjoint, so the union is exact
    a, c, j = geometry_moments(union)
    area, com, polar = body_area_properties(body)
    assert area == pytest.approx(a, rel=1e-4)
    np.testing.assert_allclose(com, c, rtol=0, atol=1e-5)
    assert polar == pytest.approx(j, rel=1e-4)
    com2, inertia = body_mass_properties(body)
    np.testing.assert_array_equal(com2, com)
    assert inertia == pytest.approx(2.5 / area * polar, rel=1e-15)


def test_given_inertia_wins_and_com_still_from_shapes():
    com, inertia = body_mass_properties(t_body(inertia=0.123))
    assert inertia == 0.123
    assert com[1] < 0.0


def test_body_without_mass_raises():
    pusher = BodySpec(name="pusher", type="kinematic", shapes=(ShapeSpec("disk", radius=0.1),))
    with pytest.raises(ValueError, match="'pusher' is kinematic: it has no mass properties"):
        body_mass_properties(pusher)


def test_shipped_scene_inertias():
    # box_push: a 0.2 x 0.1 box of 1 kg, (w^2 + h^2) / 12.
    com, inertia = body_mass_properties(load_scene("box_push").body("box"))
    np.testing.assert_allclose(com, [0.0, 0.0], atol=1e-15)
    assert inertia == pytest.approx((0.04 + 0.01) / 12, rel=1e-13)
    # falling_rod keeps Stewart & Trinkle's inertia, not the uniform-density one; a single centred capsule has its
    # centre of mass exactly at the body-frame origin (no round-off).
    com, inertia = body_mass_properties(load_scene("falling_rod").body("rod"))
    assert inertia == 0.002
    np.testing.assert_array_equal(com, [0.0, 0.0])


# --- default support points -----------------------------------------------------------------------------------


def moments_of(points, weights):
    m0 = weights.sum()
    m1 = weights @ points
    m2 = weights @ np.sum((points - m1 / m0) ** 2, axis=1)
    return m0, m1, m2


def assert_matches(body, tol):
    pts, w = default_support_points(body)
    area, com, polar = body_area_properties(body)
    assert pts.shape == (len(w), 2)
    assert np.all(w > 0)
    m0, m1, m2 = moments_of(pts, w)
    assert m0 == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(m1, com, rtol=0, atol=tol)
    assert m2 == pytest.approx(polar / area, rel=tol)
    return pts, w


def one(shape):
    return BodySpec(name="b", type="dynamic", mass=1.0, shapes=(shape,))


def test_support_points_box_are_gauss_points():
    pts, w = assert_matches(one(ShapeSpec("box", width=0.2, height=0.1)), 1e-12)
    g = 1 / (2 * math.sqrt(3))
    np.testing.assert_allclose(sorted(map(tuple, pts)),
                               sorted([(sx * 0.2 * g, sy * 0.1 * g) for sx in (-1, 1) for sy in (-1, 1)]), atol=1e-15)
    np.testing.assert_array_equal(w, [0.25] * 4)


def test_support_points_disk_ring():
    pts, w = assert_matches(one(ShapeSpec("disk", radius=0.3, offset=(1.0, -2.0))), 1e-12)
    assert len(pts) == 4
    np.testing.assert_allclose(np.linalg.norm(pts - [1.0, -2.0], axis=1), 0.3 / math.sqrt(2), rtol=1e-14)


@pytest.mark.parametrize("name", sorted(POLYGONS))
def test_support_points_polygon_midpoints(name):
    verts = POLYGONS[name]
    pts, w = assert_matches(one(ShapeSpec("polygon", vertices=verts, offset=(0.1, 0.2), angle=0.5)), 1e-12)
    assert len(pts) == 2 * len(verts) - 3      # shared fan midpoints are merged
    # Midpoint rule is exact for quadratics, so the full second-moment tensor matches too, not just its trace.
    s = ShapeSpec("polygon", vertices=verts, offset=(0.1, 0.2), angle=0.5)
    c = shape_centroid(s)
    d = pts - c
    cov = (w[:, None] * d).T @ d
    assert np.trace(cov) == pytest.approx(shape_polar_moment(s) / shape_area(s), rel=1e-12)


def test_support_points_t_body():
    pts, w = assert_matches(t_body(), 1e-12)
    assert len(pts) == 8
    np.testing.assert_allclose(w[:4], 0.120 * 0.030 / 0.0063 / 4, rtol=1e-14)


@pytest.mark.parametrize("shape", ROUNDED, ids=lambda s: f"{s.type}-r{s.radius}")
def test_support_points_rounded_shapes(shape):
    pts, w = assert_matches(one(shape), 1e-12)
    assert len(pts) <= 7


def test_support_points_compound_rounded_body_and_zero_area_segment():
    body = BodySpec(name="b", type="dynamic", mass=1.0, shapes=(
        ShapeSpec("capsule", length=0.4, radius=0.05, angle=0.3),
        ShapeSpec("disk", radius=0.1, offset=(0.5, 0.0)),
        ShapeSpec("segment", a=(0.0, 0.0), b=(0.0, 1.0)),
    ))
    pts, w = assert_matches(body, 1e-12)
    assert len(pts) == 8


def test_given_support_points_have_equal_weights():
    body = t_body(support_points=((0.0, 0.0), (0.01, -0.05), (-0.02, 0.0)))
    pts, w = default_support_points(body)
    np.testing.assert_array_equal(pts, [[0.0, 0.0], [0.01, -0.05], [-0.02, 0.0]])
    np.testing.assert_array_equal(w, [1 / 3] * 3)
