"""Contact generation (planar_lcp.engine.collision) against oracles.

Oracles:
- separated pairs: shapely's exact distance between the cores minus the radii (exact for inflated convex cores);
  the deepest contact's witness points ``point +- (phi / 2) normal`` must lie on the two inflated surfaces, which
  together with phi == exact distance pins down normal and point;
- overlapping cores: the penetration depth of two convex polygons by brute force in numpy,
  min over directions u of  max_B u.b - min_A u.a  (over all face normals, where the minimum is attained, and
  checked against 720 sampled directions); a point inside a polygon: shapely's distance to the boundary;
- analytic configurations (box on a table, Stewart & Trinkle's tilted rod, box stacks, a disk in a corner);
- invariances: swapping A and B, listing the vertices from another start, a rigid motion of the whole scene.
"""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from shapely.geometry import LineString, Point, Polygon

from planar_lcp.engine.collision import contact_core_core, contact_core_halfplane

TOL = 1e-9
BIG_MARGIN = 10.0


# ---------------------------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------------------------


def cc(va, ra, vb, rb, margin=BIG_MARGIN):
    """contact_core_core on world vertex arrays; returns (phi (m,), normal (m, 2), point (m, 2))."""
    phi = np.full(2, np.nan)
    nrm = np.full((2, 2), np.nan)
    pt = np.full((2, 2), np.nan)
    va = np.ascontiguousarray(va, dtype=float)
    vb = np.ascontiguousarray(vb, dtype=float)
    m = contact_core_core(va, len(va), float(ra), vb, len(vb), float(rb), float(margin), phi, nrm, pt)
    assert 0 <= m <= 2
    return phi[:m].copy(), nrm[:m].copy(), pt[:m].copy()


def hp(va, ra, p0, n0, margin=BIG_MARGIN):
    phi = np.full(2, np.nan)
    nrm = np.full((2, 2), np.nan)
    pt = np.full((2, 2), np.nan)
    va = np.ascontiguousarray(va, dtype=float)
    m = contact_core_halfplane(va, len(va), float(ra), np.asarray(p0, float), np.asarray(n0, float),
                               float(margin), phi, nrm, pt)
    assert 0 <= m <= 2
    return phi[:m].copy(), nrm[:m].copy(), pt[:m].copy()


def geom(v):
    """The shapely core: Point, LineString or Polygon."""
    if len(v) == 1:
        return Point(v[0])
    if len(v) == 2:
        return LineString(v)
    return Polygon(v)


def boundary(v):
    g = geom(v)
    return g.exterior if len(v) >= 3 else g


def box(w, h):
    return np.array([[-w, -h], [w, -h], [w, h], [-w, h]], float)


def at(local, x=0.0, y=0.0, theta=0.0):
    """World vertices R(theta) local + (x, y) of body-frame vertices local (k, 2): the engine places shapes the same
    way, written here in numpy so that the kernels under test get their input from outside the engine."""
    local = np.asarray(local, dtype=float)
    c, s = math.cos(theta), math.sin(theta)
    return np.column_stack([c * local[:, 0] - s * local[:, 1] + x, s * local[:, 0] + c * local[:, 1] + y])


def rand_polygon(rng):
    k = int(rng.integers(3, 8))
    while True:
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        gaps = np.diff(np.r_[ang, ang[0] + 2 * np.pi])
        if gaps.min() > 0.3 and gaps.max() < np.pi - 0.1:
            break
    a, b = rng.uniform(0.2, 0.7, 2)
    return np.c_[a * np.cos(ang), b * np.sin(ang)]


def rand_shape(kind, rng):
    """(local vertices, radius) of a random shape of the given kind."""
    if kind == "disk":
        return np.zeros((1, 2)), rng.uniform(0.05, 0.5)
    if kind == "capsule":
        h = rng.uniform(0.1, 0.6)
        return np.array([[-h, 0.0], [h, 0.0]]), rng.uniform(0.02, 0.2)
    if kind == "segment":
        h = rng.uniform(0.2, 1.0)
        return np.array([[-h, 0.0], [h, 0.0]]), rng.choice([0.0, rng.uniform(0.0, 0.1)])
    if kind == "box":
        return box(*rng.uniform(0.1, 0.6, 2)), 0.0
    if kind == "rbox":
        return box(*rng.uniform(0.1, 0.6, 2)), rng.uniform(0.02, 0.2)
    if kind == "polygon":
        return rand_polygon(rng), 0.0
    raise ValueError(kind)


SEPARATED_PAIRS = [
    ("disk", "disk"), ("disk", "capsule"), ("disk", "box"), ("disk", "polygon"), ("capsule", "capsule"),
    ("capsule", "box"), ("box", "box"), ("polygon", "polygon"), ("rbox", "rbox"), ("segment", "box"),
    ("capsule", "polygon"), ("segment", "capsule"),
]
FLAT_KINDS = ("capsule", "segment", "box", "rbox")  # faces that can be made parallel by aligning the angles


def rand_pair(ka, kb, rng, flat=False):
    la, ra = rand_shape(ka, rng)
    lb, rb = rand_shape(kb, rng)
    tha = rng.uniform(-np.pi, np.pi)
    thb = tha + rng.integers(0, 4) * np.pi / 2 if flat else rng.uniform(-np.pi, np.pi)
    va = at(la, *rng.uniform(-1, 1, 2), tha)
    ang = rng.uniform(0, 2 * np.pi)
    dist = rng.uniform(0.0, 2.5)
    c = va.mean(axis=0) + dist * np.array([np.cos(ang), np.sin(ang)])
    vb = at(lb, c[0], c[1], thb)
    return va, ra, vb, rb


def witness_on_surfaces(va, ra, vb, rb, phi, n, p, tol=TOL):
    """The witness points of one contact lie on A's and on B's inflated surfaces."""
    wa = p + 0.5 * phi * n
    wb = p - 0.5 * phi * n
    for v, r, w in ((va, ra, wa), (vb, rb, wb)):
        d_region = geom(v).distance(Point(w))
        d_bound = boundary(v).distance(Point(w))
        assert abs(d_region - r) <= tol, (d_region, r)
        assert abs(d_bound - r) <= tol, (d_bound, r)


def support_overlap(va, vb, u):
    """How far A must move along u (unit, from B to A) to separate the cores: max_B u.b - min_A u.a."""
    return np.max(vb @ u) - np.min(va @ u)


def face_normals(v):
    if len(v) == 1:
        return np.zeros((0, 2))
    e = np.roll(v, -1, axis=0) - v
    if len(v) == 2:
        e = e[:1]
    n = np.c_[e[:, 1], -e[:, 0]] / np.linalg.norm(e, axis=1)[:, None]
    return np.r_[n, -n] if len(v) == 2 else n


def penetration_oracle(va, vb):
    """(depth, unit direction) of the minimum translation separating two overlapping convex cores."""
    cands = np.r_[-face_normals(va), face_normals(vb)]  # A moves against its own outward normals
    o = np.array([support_overlap(va, vb, u) for u in cands])
    i = int(np.argmin(o))
    ang = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    sampled = min(support_overlap(va, vb, np.array([np.cos(a), np.sin(a)])) for a in ang)
    assert sampled >= o[i] - 1e-12  # the minimum over all directions is at a face normal
    return o[i], cands[i]


def same_contacts(r1, r2, tol):
    """Two results hold the same contacts (as sets: exact ties may order the two rows either way)."""
    (p1, n1, q1), (p2, n2, q2) = r1, r2
    assert len(p1) == len(p2), (p1, p2)
    if len(p1) == 2 and not (abs(p1[0] - p2[0]) <= tol and np.allclose(q1[0], q2[0], atol=tol)):
        p2, n2, q2 = p2[::-1], n2[::-1], q2[::-1]
    np.testing.assert_allclose(p1, p2, atol=tol, rtol=0)
    np.testing.assert_allclose(n1, n2, atol=tol, rtol=0)
    np.testing.assert_allclose(q1, q2, atol=tol, rtol=0)


def check_basic(res):
    phi, n, p = res
    assert np.all(np.isfinite(phi)) and np.all(np.isfinite(n)) and np.all(np.isfinite(p))
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    if len(phi) == 2:
        assert phi[0] <= phi[1]


# ---------------------------------------------------------------------------------------------------------------
# separated pairs: exact distance
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("ka,kb", SEPARATED_PAIRS)
def test_separated_pairs_match_exact_distance(ka, kb):
    rng = np.random.default_rng(sum(map(ord, ka + kb)))
    flat_family = ka in FLAT_KINDS and kb in FLAT_KINDS
    done = 0
    n_two = 0
    while done < 60:
        flat = flat_family and done % 3 == 0
        va, ra, vb, rb = rand_pair(ka, kb, rng, flat)
        ga, gb = geom(va), geom(vb)
        d = ga.distance(gb)
        if d <= 1e-6:
            continue
        if done % 2 == 1:
            # bring B close: small gaps and small inflated overlaps are where the contact logic is decided
            dirn = va.mean(0) - vb.mean(0)
            shift = (d - rng.uniform(1e-4, 0.05)) * dirn / np.linalg.norm(dirn)
            vb2 = vb + shift
            d2 = ga.distance(geom(vb2))
            if d2 > 1e-6:
                vb, d = vb2, d2
        exact = d - ra - rb
        res = cc(va, ra, vb, rb)
        check_basic(res)
        phi, n, p = res
        assert len(phi) >= 1
        assert abs(phi.min() - exact) <= TOL, (ka, kb, phi, exact)
        assert np.all(phi >= exact - TOL)
        witness_on_surfaces(va, ra, vb, rb, phi[0], n[0], p[0])
        if len(phi) == 2:
            n_two += 1
            np.testing.assert_allclose(n[0], n[1], atol=1e-15)
        # with a margin just above the gap, the deepest contact still comes back, and nothing deeper
        phi2, _, _ = cc(va, ra, vb, rb, margin=exact + 1e-6)
        assert len(phi2) >= 1 and abs(phi2[0] - exact) <= TOL
        assert len(cc(va, ra, vb, rb, margin=exact - 1e-6)[0]) == 0
        done += 1
    if flat_family:
        assert n_two > 0  # the aligned family must produce face-face manifolds


def test_disk_inside_polygon_least_penetration_face():
    rng = np.random.default_rng(7)
    for _ in range(100):
        poly = at(rand_polygon(rng), *rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi))
        w = rng.dirichlet(np.ones(len(poly)))
        c = w @ poly  # a point inside
        ra, rb = rng.uniform(0, 0.2, 2)
        phi, n, p = cc(c[None, :], ra, poly, rb)
        assert len(phi) == 1
        depth = Polygon(poly).exterior.distance(Point(c))
        assert abs(phi[0] - (-depth - ra - rb)) <= TOL
        # the normal is the face through the closest boundary point, pointing out of B
        q = c + depth * n[0]
        assert Polygon(poly).exterior.distance(Point(q)) <= TOL
        assert abs(support_overlap(c[None, :], poly, n[0]) - depth) <= TOL
        # A's witness is at distance ra from the centre; B's is on the face line at distance rb outside
        np.testing.assert_allclose(np.linalg.norm(p[0] + 0.5 * phi[0] * n[0] - c), ra, atol=TOL)
        assert abs(Polygon(poly).exterior.distance(Point(p[0] - 0.5 * phi[0] * n[0])) - rb) <= TOL


def test_halfplane_random_matches_shapely():
    rng = np.random.default_rng(11)
    kinds = ("disk", "capsule", "box", "rbox", "polygon")
    for i in range(100):
        local, r = rand_shape(kinds[i % len(kinds)], rng)
        v = at(local, *rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi))
        ang = rng.uniform(0, 2 * np.pi)
        n0 = np.array([np.cos(ang), np.sin(ang)])
        p0 = v.mean(0) - rng.uniform(0.3, 1.5) * n0
        t0 = np.array([-n0[1], n0[0]])
        line = LineString([p0 - 100 * t0, p0 + 100 * t0])
        d = line.distance(geom(v))
        if d <= 1e-6:
            continue
        phi, n, p = hp(v, r, p0, n0)
        assert len(phi) >= 1
        assert abs(phi[0] - (d - r)) <= TOL
        np.testing.assert_allclose(n, np.tile(n0, (len(phi), 1)))
        wa = p[0] + 0.5 * phi[0] * n0
        assert abs(geom(v).distance(Point(wa)) - r) <= TOL
        assert abs(np.dot(p[0] - 0.5 * phi[0] * n0 - p0, n0)) <= TOL  # B's witness is on the plane


# ---------------------------------------------------------------------------------------------------------------
# overlapping cores: minimum penetration
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("ka,kb", [("box", "box"), ("polygon", "polygon"), ("capsule", "box"),
                                   ("capsule", "capsule"), ("rbox", "polygon"), ("segment", "rbox")])
def test_overlapping_cores_min_penetration(ka, kb):
    rng = np.random.default_rng(sum(map(ord, ka + kb)) + 1)
    done = 0
    while done < 40:
        va, ra, vb, rb = rand_pair(ka, kb, rng)
        # mostly small overlaps: pull B towards A until the cores just intersect
        c = va.mean(0) - vb.mean(0)
        vb = vb + rng.uniform(0.3, 1.0) * c
        if not geom(va).intersects(geom(vb)):
            continue
        depth, u = penetration_oracle(va, vb)
        res = cc(va, ra, vb, rb)
        check_basic(res)
        phi, n, p = res
        assert len(phi) >= 1
        assert abs(phi[0] - (-depth - ra - rb)) <= TOL, (phi, depth)
        assert abs(support_overlap(va, vb, n[0]) - depth) <= TOL
        # the deepest contact's witnesses, moved back onto the cores, are A's lowest and B's highest support
        # points along the normal
        wa = p[0] + 0.5 * phi[0] * n[0] + ra * n[0]
        wb = p[0] - 0.5 * phi[0] * n[0] - rb * n[0]
        assert abs(wa @ n[0] - np.min(va @ n[0])) <= TOL
        assert abs(wb @ n[0] - np.max(vb @ n[0])) <= TOL
        done += 1


def test_box_pushed_one_mm_into_box():
    lower = at(box(0.5, 0.25), 0.0, 0.0)
    upper = at(box(0.3, 0.2), 0.1, 0.25 + 0.2 - 0.001)
    phi, n, p = cc(upper, 0.0, lower, 0.0, margin=0.01)
    assert len(phi) == 2
    np.testing.assert_allclose(phi, -0.001, atol=1e-12)
    np.testing.assert_allclose(n, [[0, 1], [0, 1]], atol=1e-12)
    np.testing.assert_allclose(sorted(p[:, 0]), [-0.2, 0.4], atol=1e-12)
    np.testing.assert_allclose(p[:, 1], 0.25 - 0.0005, atol=1e-12)
    # the same from the side, rotated by 90 degrees: face normal (1, 0)
    phi, n, p = cc(at(box(0.2, 0.3), 0.5 + 0.2 - 0.001, 0.0), 0.0, at(box(0.5, 0.5)), 0.0, margin=0.01)
    np.testing.assert_allclose(phi, -0.001, atol=1e-12)
    np.testing.assert_allclose(n, [[1, 0], [1, 0]], atol=1e-12)


# ---------------------------------------------------------------------------------------------------------------
# analytic configurations
# ---------------------------------------------------------------------------------------------------------------

TABLE_P, TABLE_N = np.zeros(2), np.array([0.0, 1.0])


def test_box_lying_on_halfplane():
    g = 0.003
    phi, n, p = hp(at(box(0.4, 0.1), 0.7, 0.1 + g), 0.0, TABLE_P, TABLE_N, margin=0.01)
    assert len(phi) == 2
    np.testing.assert_allclose(phi, g, atol=1e-15)
    np.testing.assert_allclose(n, [[0, 1], [0, 1]])
    np.testing.assert_allclose(sorted(p[:, 0]), [0.3, 1.1], atol=1e-15)
    np.testing.assert_allclose(p[:, 1], g / 2, atol=1e-15)


def test_tilted_box_on_halfplane_one_contact():
    th = 0.3
    v = at(box(0.4, 0.1), 0.0, 0.4 * np.sin(th) + 0.1 * np.cos(th) + 0.01, th)  # lowest corner 1 cm up
    low = v[np.argmin(v[:, 1])]
    phi, n, p = hp(v, 0.0, TABLE_P, TABLE_N, margin=0.05)
    assert len(phi) == 1
    assert phi[0] == pytest.approx(low[1], abs=1e-15)
    np.testing.assert_allclose(p[0], [low[0], low[1] / 2], atol=1e-15)


@pytest.mark.parametrize("y", [0.2, 0.175, 0.1])
def test_seed_rod_over_table(y):
    """Capsule of length 0.5 and radius 0.05 at 30 degrees, centre at height y."""
    th = np.deg2rad(30)
    v = at(np.array([[-0.25, 0.0], [0.25, 0.0]]), 0.3, y, th)
    phi, n, p = hp(v, 0.05, TABLE_P, TABLE_N, margin=0.01)
    expect = y - 0.25 * np.sin(th) - 0.05
    if expect >= 0.01:
        assert len(phi) == 0
        return
    assert len(phi) == 1
    assert phi[0] == pytest.approx(expect, abs=1e-15)
    np.testing.assert_allclose(n[0], [0, 1])
    np.testing.assert_allclose(p[0], [0.3 - 0.25 * np.cos(th), expect / 2], atol=1e-15)
    # the same rod against a wide static box as the table gives the same contact
    table = at(box(5.0, 0.5), 0.0, -0.5)
    phi2, n2, p2 = cc(v, 0.05, table, 0.0, margin=0.01)
    assert len(phi2) == 1
    np.testing.assert_allclose(phi2, phi, atol=1e-14)
    np.testing.assert_allclose(n2, n, atol=1e-14)
    np.testing.assert_allclose(p2, p, atol=1e-14)


def test_capsule_lying_flat_on_halfplane_and_box():
    v = at(np.array([[-0.25, 0.0], [0.25, 0.0]]), 0.4, 0.05 + 0.002)
    phi, n, p = hp(v, 0.05, TABLE_P, TABLE_N, margin=0.01)
    assert len(phi) == 2
    np.testing.assert_allclose(phi, 0.002, atol=1e-15)
    np.testing.assert_allclose(sorted(p[:, 0]), [0.15, 0.65], atol=1e-15)
    np.testing.assert_allclose(p[:, 1], 0.001, atol=1e-15)
    # on a box top (wider than the capsule): the two cap centres' feet
    top = at(box(1.0, 0.5), 0.0, -0.5)
    phi, n, p = cc(v, 0.05, top, 0.0, margin=0.01)
    assert len(phi) == 2
    np.testing.assert_allclose(phi, 0.002, atol=1e-15)
    np.testing.assert_allclose(n, [[0, 1], [0, 1]], atol=1e-15)
    np.testing.assert_allclose(sorted(p[:, 0]), [0.15, 0.65], atol=1e-15)
    np.testing.assert_allclose(p[:, 1], 0.001, atol=1e-15)
    # hanging over the box edge at x = 1: clipped to the box face
    phi, n, p = cc(v + [0.7, 0.0], 0.05, top, 0.0, margin=0.01)
    assert len(phi) == 2
    np.testing.assert_allclose(sorted(p[:, 0]), [0.85, 1.0], atol=1e-15)


@pytest.mark.parametrize("wb,expect_x", [(0.5, [-0.5, 0.5]), (2.0, [-0.5, 0.5]), (0.25, [-0.25, 0.25])])
def test_box_on_box(wb, expect_x):
    """Top box half-width 0.5; lower box half-width wb: equal, wider, narrower."""
    g = 0.004
    lower = at(box(wb, 0.3), 0.0, -0.3)
    upper = at(box(0.5, 0.2), 0.0, 0.2 + g)
    for a, b, sign in ((upper, lower, 1.0), (lower, upper, -1.0)):
        phi, n, p = cc(a, 0.0, b, 0.0, margin=0.01)
        assert len(phi) == 2  # exactly two, never four
        np.testing.assert_allclose(phi, g, atol=1e-15)
        np.testing.assert_allclose(n, [[0, sign], [0, sign]], atol=1e-15)
        np.testing.assert_allclose(sorted(p[:, 0]), expect_x, atol=1e-15)
        np.testing.assert_allclose(p[:, 1], g / 2, atol=1e-15)


def test_disk_in_corner_between_two_boxes():
    floor = at(box(1.0, 0.5), 0.0, -0.5)  # top face y = 0
    wall = at(box(0.5, 1.0), -1.5, 1.0)  # right face x = -1
    r = 0.1
    c = np.array([[-1.0 + r + 0.002, r + 0.001]])
    phi, n, p = cc(c, r, floor, 0.0, margin=0.01)
    assert len(phi) == 1
    assert phi[0] == pytest.approx(0.001, abs=1e-15)
    np.testing.assert_allclose(n[0], [0, 1], atol=1e-14)
    np.testing.assert_allclose(p[0], [c[0, 0], 0.0005], atol=1e-15)
    phi, n, p = cc(c, r, wall, 0.0, margin=0.01)
    assert len(phi) == 1
    assert phi[0] == pytest.approx(0.002, abs=1e-15)
    np.testing.assert_allclose(n[0], [1, 0], atol=1e-14)
    np.testing.assert_allclose(p[0], [-1.0 + 0.001, c[0, 1]], atol=1e-15)


def test_vertex_vertex_regions_give_true_normal():
    # two rounded boxes corner to corner along the diagonal
    a = at(box(0.5, 0.5))
    b = at(box(0.5, 0.5), 1.0 + 0.3, 1.0 + 0.4)
    phi, n, p = cc(b, 0.1, a, 0.05, margin=1.0)
    assert len(phi) == 1
    assert phi[0] == pytest.approx(0.5 - 0.15, abs=1e-14)
    np.testing.assert_allclose(n[0], [0.6, 0.8], atol=1e-14)
    np.testing.assert_allclose(p[0], [0.5, 0.5] + (0.05 + 0.35 / 2) * np.array([0.6, 0.8]), atol=1e-14)
    # capsules end to end (collinear: the SAT separation is 0, the true distance is not)
    c1 = np.array([[0.0, 0.0], [1.0, 0.0]])
    phi, n, p = cc(c1 + [1.5, 0.0], 0.1, c1, 0.1, margin=1.0)
    assert len(phi) == 1
    assert phi[0] == pytest.approx(0.3, abs=1e-14)
    np.testing.assert_allclose(n[0], [1, 0], atol=1e-14)
    np.testing.assert_allclose(p[0], [1.25, 0.0], atol=1e-14)


def test_segments_parallel_and_skew():
    s1 = np.array([[0.0, 0.0], [1.0, 0.0]])
    # parallel, overlapping in x: two contacts at the ends of the overlap
    phi, n, p = cc(s1 + [0.6, 0.3], 0.05, s1, 0.1, margin=0.5)
    assert len(phi) == 2
    np.testing.assert_allclose(phi, 0.15, atol=1e-15)
    np.testing.assert_allclose(n, [[0, 1], [0, 1]], atol=1e-15)
    np.testing.assert_allclose(sorted(p[:, 0]), [0.6, 1.0], atol=1e-15)
    np.testing.assert_allclose(p[:, 1], 0.1 + 0.075, atol=1e-15)
    # skew, T-shaped: one closest-point contact
    s2 = np.array([[0.5, 0.2], [0.8, 1.0]])
    phi, n, p = cc(s2, 0.05, s1, 0.05, margin=0.2)
    assert len(phi) == 1
    assert phi[0] == pytest.approx(0.1, abs=1e-15)
    np.testing.assert_allclose(n[0], [0, 1], atol=1e-15)
    # crossing skew segments beyond the ends: vertex-vertex
    s3 = np.array([[1.3, 0.4], [2.0, 1.5]])
    phi, n, p = cc(s3, 0.0, s1, 0.0)
    assert len(phi) == 1
    assert phi[0] == pytest.approx(0.5, abs=1e-15)
    np.testing.assert_allclose(n[0], [0.6, 0.8], atol=1e-15)


# ---------------------------------------------------------------------------------------------------------------
# invariances
# ---------------------------------------------------------------------------------------------------------------

ALL_PAIRS = SEPARATED_PAIRS + [("box", "capsule"), ("polygon", "disk"), ("rbox", "segment")]


def random_configs(rng, count):
    """Mixed separated / touching / overlapping configurations of every pair type."""
    out = []
    for i in range(count):
        ka, kb = ALL_PAIRS[i % len(ALL_PAIRS)]
        va, ra, vb, rb = rand_pair(ka, kb, rng, flat=(i % 4 == 0))
        vb = vb + rng.uniform(0.0, 0.8) * (va.mean(0) - vb.mean(0))
        out.append((va, ra, vb, rb))
    return out


def test_swap_symmetry_exact():
    rng = np.random.default_rng(3)
    for va, ra, vb, rb in random_configs(rng, 300):
        phi1, n1, p1 = cc(va, ra, vb, rb, margin=0.1)
        phi2, n2, p2 = cc(vb, rb, va, ra, margin=0.1)
        np.testing.assert_array_equal(phi1, phi2)
        np.testing.assert_array_equal(p1, p2)
        np.testing.assert_array_equal(n1, -n2)


def test_first_vertex_does_not_matter():
    rng = np.random.default_rng(4)
    for va, ra, vb, rb in random_configs(rng, 300):
        ref = cc(va, ra, vb, rb, margin=0.1)
        for s in range(1, 4):
            va2 = np.roll(va, s, axis=0)
            vb2 = np.roll(vb, -s, axis=0)
            same_contacts(ref, cc(va2, ra, vb2, rb, margin=0.1), 1e-12)
    # the box lying on the table from any first vertex
    v = at(box(0.4, 0.1), 0.7, 0.1)
    ref = hp(v, 0.0, TABLE_P, TABLE_N)
    for s in range(1, 4):
        got = hp(np.roll(v, s, axis=0), 0.0, TABLE_P, TABLE_N)
        for a, b in zip(ref, got):
            np.testing.assert_array_equal(a, b)


def test_rigid_motion_covariance():
    rng = np.random.default_rng(5)
    for va, ra, vb, rb in random_configs(rng, 300):
        th = rng.uniform(-np.pi, np.pi)
        t = rng.uniform(-3, 3, 2)
        R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        phi, n, p = cc(va, ra, vb, rb, margin=0.1)
        got = cc(va @ R.T + t, ra, vb @ R.T + t, rb, margin=0.1)
        same_contacts((phi, n @ R.T, p @ R.T + t), got, 1e-9)
    # the half-plane too
    for i in range(50):
        local, r = rand_shape(("box", "capsule", "polygon", "rbox")[i % 4], rng)
        v = at(local, rng.uniform(-1, 1), rng.uniform(0.0, 0.8), rng.uniform(-np.pi, np.pi))
        th = rng.uniform(-np.pi, np.pi)
        t = rng.uniform(-3, 3, 2)
        R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        phi, n, p = hp(v, r, TABLE_P, TABLE_N, margin=0.3)
        got = hp(v @ R.T + t, r, TABLE_P @ R.T + t, R @ TABLE_N, margin=0.3)
        same_contacts((phi, n @ R.T, p @ R.T + t), got, 1e-9)


# ---------------------------------------------------------------------------------------------------------------
# degenerate inputs
# ---------------------------------------------------------------------------------------------------------------


def test_degenerate_cases_no_nan():
    pt = np.array([[0.3, 0.2]])
    seg = np.array([[0.0, 0.2], [1.0, 0.2]])
    sq = at(box(0.5, 0.5))
    diamond = at(box(0.5, 0.5), 0.0, 0.0, np.pi / 4)
    cases = [
        (pt, 0.1, pt.copy(), 0.2, 1),  # coincident disk centres
        (pt, 0.1, seg, 0.0, 1),  # centre exactly on a segment core
        (np.array([[0.5, 0.5]]), 0.1, sq, 0.0, 1),  # centre exactly on a polygon vertex
        (np.array([[0.0, 0.5]]), 0.1, sq, 0.0, 1),  # centre exactly on a polygon face
        (np.array([[0.2, 0.3], [0.2, 0.3]]), 0.1, sq, 0.0, 1),  # zero-length segment
        (np.array([[0.2, 0.3], [0.2, 0.3]]), 0.1, np.array([[0.2, 0.3], [0.2, 0.3]]), 0.0, 1),
        (at(box(0.5, 0.5), 0.0, 1.0), 0.0, sq, 0.0, 2),  # exactly touching, exactly parallel
        (at(box(0.5, 0.5), 1.0, 1.0), 0.0, sq, 0.0, 1),  # vertex exactly on a vertex
        (at(box(0.5, 0.5), 0.0, np.sqrt(2)), 0.0, diamond, 0.0, 1),  # tip on tip
        (sq, 0.0, sq.copy(), 0.0, 1),  # identical boxes, fully overlapping
        (seg, 0.05, seg.copy(), 0.05, 1),  # identical segments
        (seg, 0.0, seg + [1.0, 0.0], 0.0, 1),  # collinear, end touching end
        (seg, 0.0, seg + [0.5, 0.0], 0.0, 1),  # collinear, overlapping
        (np.array([[0, 0], [1, 0], [1, 0], [1, 1], [0, 1]], float), 0.0, at(box(0.5, 0.5), 0.5, 1.9), 0.0, 2),
        (np.array([[0, 0], [1, 0], [2, 0]], float), 0.0, at(box(0.5, 0.5), 1.0, 0.6), 0.0, 2),  # zero area
    ]
    for va, ra, vb, rb, min_count in cases:
        for a, r_a, b, r_b in ((va, ra, vb, rb), (vb, rb, va, ra)):
            res = cc(a, r_a, b, r_b, margin=0.5)
            assert len(res[0]) >= min_count, (a, b, res)
            check_basic(res)
    phi, n, _ = cc(pt, 0.1, pt.copy(), 0.2)
    np.testing.assert_array_equal(n, [[0.0, 1.0]])  # documented choice for coincident centres
    assert phi[0] == pytest.approx(-0.3)
    phi, n, _ = cc(pt, 0.1, seg, 0.0)
    np.testing.assert_array_equal(np.abs(n), [[0.0, 1.0]])
    assert phi[0] == pytest.approx(-0.1)
    phi, n, _ = cc(at(box(0.5, 0.5), 0.0, 1.0), 0.0, sq, 0.0)
    np.testing.assert_allclose(phi, 0.0, atol=1e-15)
    np.testing.assert_allclose(n, [[0, 1], [0, 1]], atol=1e-15)
    # collinear capsules with a gap below the tolerance (1e-10 * size): treated as touching, one contact with
    # the SAT normal at B's end vertex (the path that guards the clip against round-off)
    for sgn, (a, b) in ((1.0, (seg, seg + [1.0 + 1e-12, 0.0])), (-1.0, (seg + [1.0 + 1e-12, 0.0], seg))):
        phi, n, p = cc(a, 0.05, b, 0.05, margin=0.01)
        assert len(phi) == 1
        assert phi[0] == pytest.approx(-0.1, abs=1e-12)
        np.testing.assert_array_equal(n, [[0.0, -sgn]])
        np.testing.assert_allclose(p, [[1.0, 0.2]], atol=1e-11)
    # half-plane: a vertical capsule standing on the table gives one contact, not two at the same place
    phi, n, p = hp(np.array([[0.0, 0.1], [0.0, 0.6]]), 0.1, TABLE_P, TABLE_N, margin=10.0)
    assert len(phi) == 1 and phi[0] == pytest.approx(0.0)
    res = hp(np.array([[0.0, 0.0]]), 0.0, TABLE_P, TABLE_N)
    check_basic(res)
    assert len(res[0]) == 1


# ---------------------------------------------------------------------------------------------------------------
# the JIT-less path
# ---------------------------------------------------------------------------------------------------------------


_SCRIPT = r"""
import json, sys
import numpy as np
from planar_lcp.engine import collision
from planar_lcp.engine.collision import contact_core_core, contact_core_halfplane
cases = json.loads(sys.stdin.read())
out = []
for c in cases:
    phi = np.zeros(2); n = np.zeros((2, 2)); p = np.zeros((2, 2))
    if c["b"] is None:
        m = contact_core_halfplane(np.array(c["a"]), len(c["a"]), c["ra"], np.zeros(2), np.array([0.0, 1.0]),
                                   0.3, phi, n, p)
    else:
        m = contact_core_core(np.array(c["a"]), len(c["a"]), c["ra"], np.array(c["b"]), len(c["b"]), c["rb"],
                              0.3, phi, n, p)
    out.append([phi[:m].tolist(), n[:m].tolist(), p[:m].tolist()])
print(json.dumps({"jit": hasattr(contact_core_core, "py_func"), "out": out}))
"""


def test_runs_without_jit_and_matches():
    rng = np.random.default_rng(12)
    cases = [dict(a=va.tolist(), ra=ra, b=vb.tolist(), rb=rb) for va, ra, vb, rb in random_configs(rng, 15)]
    cases.append(dict(a=at(box(0.4, 0.1), 0.7, 0.1).tolist(), ra=0.0, b=None, rb=0.0))
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    proc = subprocess.run([sys.executable, "-c", _SCRIPT], input=json.dumps(cases), capture_output=True,
                          text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout)
    assert res["jit"] is False
    for c, (phi, n, p) in zip(cases, res["out"]):
        if c["b"] is None:
            ref = hp(np.array(c["a"]), c["ra"], TABLE_P, TABLE_N, margin=0.3)
        else:
            ref = cc(np.array(c["a"]), c["ra"], np.array(c["b"]), c["rb"], margin=0.3)
        same_contacts(ref, (np.array(phi), np.array(n).reshape(-1, 2), np.array(p).reshape(-1, 2)), 1e-12)
