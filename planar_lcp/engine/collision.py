"""Contact generation between planar shapes: numba kernels, arrays in, outputs written into passed arrays.

Geometry model
--------------
Every shape except the half-plane is a convex CORE inflated by a radius r >= 0. The core is given by k world-frame
vertices in counter-clockwise order: k = 1 a point (disk), k = 2 a segment (capsule, static segment with radius),
k >= 3 a convex polygon (box, polygon, rounded when r > 0). A segment core has two faces: v0 -> v1 and v1 -> v0,
with opposite normals; a polygon has k faces, face i going from v[i] to v[i+1] with outward normal
(e_y, -e_x) / |e|. The half-plane is a static body whose solid is {x : n0 . (x - p0) <= 0}; n0 points into free
space.

Contact convention (every kernel)
---------------------------------
A contact is (phi, normal, point):

- ``phi``: signed gap between the two INFLATED surfaces along the normal; negative = penetration depth.
- ``normal``: unit vector pointing FROM B TO A (for the half-plane: n0).
- ``point``: midpoint of the two witness points, ``wA = point + (phi / 2) normal`` on A's surface and
  ``wB = point - (phi / 2) normal`` on B's surface.

A contact is written only if ``phi < margin``; at most 2 per pair, rows 0..m-1 of the outputs, and when there
are 2 the deeper one is row 0. Swapping A and B gives the same phi and points and the negated normals: the
core-core kernel puts the pair in a canonical order (by vertex count, radius, then the lexicographically smallest
and largest vertex) before doing any geometry, so the swap symmetry is exact to the bit. Exact ties (two faces
with the same separation, two candidate vertices at the same depth) are broken by geometric keys, never by the
vertex index, so the result does not depend on which vertex is listed first (for k = 2 listing the segment
reversed can change the last bits through rounding only).

Algorithm
---------
- point (k = 1) vs anything: one closest-point contact. A point inside a polygon core gets the face of least
  penetration (phi = -(depth) - ra - rb).
- core vs half-plane: each core vertex v is a candidate with phi = n0.(v - p0) - ra. The deepest is returned,
  and, if another candidate has phi < margin, the one farthest from it along the plane (a box or capsule lying
  flat gets both ends).
- segment/polygon vs segment/polygon: separating-axis test over the face normals of both cores; the face of
  maximum separation is the reference face, the incident edge is the other core's edge most anti-parallel to it,
  clipped to the reference face's side planes (Box2D's b2CollidePolygons idea, written from the description).
  When the cores are separated the true distance d (minimum vertex-edge distance) is computed too; if no clipped
  point lies at separation d (vertex-vertex region: corners of rounded boxes, capsules end to end, collinear
  segments) a single contact with the true closest-point normal and distance is returned instead.
  When the cores overlap, the SAT axis is the minimum-penetration direction (exact for convex polygons).

Tolerances
----------
Only one, derived from the inputs: ``tol = 1e-10 * S`` with S = max |coordinate| of the vertices involved (and
p0 for the half-plane) + ra + rb. The rounding error of the dot products and distances here is a few ulp of S
(~1e-15 S), so 1e-10 S is 5 orders above round-off, yet far below any physical length. It decides:

- separated vs touching: the cores count as separated when the SAT separation > -tol and the true distance > tol
  (below that the closest-point direction is round-off noise, and the SAT face normal is used);
- a face manifold is accepted when its deepest clipped point is within tol of the true distance, so for a
  separated pair the reported minimum phi equals the exact distance to within tol;
- two clipped points closer than tol are merged into one, and the half-plane's second contact must be more than
  tol away along the plane from the first (no duplicate constraint rows);
- a point closer than tol to a segment core takes the segment's perpendicular as normal.

Degenerate inputs never give NaN: coincident disk centres (exact zero distance) take normal (0, 1) (then the
swap symmetry holds for phi and the point, but the normal is (0, 1) both ways); a point on a segment core takes
the perpendicular facing the point (the one with n_y > 0, or n_x > 0 if n_y == 0, when exactly on it); cores whose
vertices all coincide are treated as points; zero-length edges are skipped.

Known limits
------------
- Penetration is the minimum translation of the CORES along a face normal (exact for convex cores). For convex
  cores the deepest incident vertex on the minimum-penetration face always projects inside that face (the foot of
  the origin on the Minkowski difference lies on the face), so the clip always captures the deepest point; the
  one-vertex fallback below only guards touching collinear segments and round-off. But a penetration deeper
  than the thinner shape (two thin planks crossing as an X, a rod driven through a box) is resolved along
  whichever face is shallowest, possibly far along a plank and through to the other side: time steps must keep
  overlaps small, as they do.
- The reference-face manifold's second contact has phi measured along the reference normal; for a tilted incident
  edge that is not the exact distance at that point (as in Box2D); only the deepest contact is exact. With a large
  margin the second point of a tilted edge is reported too (a box resting on one corner gets its next corner
  if it is within the margin); with margin < that height it is not.
- At the boundary between the face region and the vertex-vertex region the count jumps between 2 and 1, and at
  cores touching (distance <= tol) the normal switches from the closest-point direction to a face normal.
- Non-convex or clockwise cores are not detected; the caller guarantees convex CCW input.
"""

# np.hypot, not math.hypot: CPython's math.hypot is its own algorithm, numba's and NumPy's np.hypot call the C
# library's; and x * x, not x ** 2 (the C pow in Python): the kernels run as Python give the compiled bits
# (tests/compilation/test_interpreted_bits.py)

import numpy as np
from numba import njit


# ----------------------------------------------------------------------------------------------------------------
# small helpers (scalars in, tuples out: nothing allocates)
# ----------------------------------------------------------------------------------------------------------------


@njit(cache=True, _nrt=False)
def _key_gt(ax, ay, bx, by):
    """Geometric tie-break between two directions: larger y first, then larger x."""
    return ay > by or (ay == by and ax > bx)


@njit(cache=True, _nrt=False)
def _face_normal(v, n, i):
    """Outward unit normal of face i (v[i] -> v[(i+1) % n]) of a CCW core; ok=False for a zero-length edge."""
    j = i + 1
    if j >= n:
        j = 0
    ex = v[j, 0] - v[i, 0]
    ey = v[j, 1] - v[i, 1]
    ln = np.hypot(ex, ey)
    if not ln > 0.0:
        return 0.0, 0.0, False
    return ey / ln, -ex / ln, True


@njit(cache=True, _nrt=False)
def _closest_on_segment(px, py, ax, ay, bx, by):
    """Closest point to p on segment [a, b] (a zero-length segment returns a)."""
    ex = bx - ax
    ey = by - ay
    ee = ex * ex + ey * ey
    if not ee > 0.0:
        return ax, ay
    t = ((px - ax) * ex + (py - ay) * ey) / ee
    if t <= 0.0:
        return ax, ay
    if t >= 1.0:
        return bx, by
    return ax + t * ex, ay + t * ey


@njit(cache=True, _nrt=False)
def _effective_n(v, n):
    """n, or 1 when all n vertices coincide (a collapsed segment or polygon is a point); 0 for n <= 0."""
    if n <= 1:
        return max(n, 0)
    x0 = v[0, 0]
    y0 = v[0, 1]
    for i in range(1, n):
        if v[i, 0] != x0 or v[i, 1] != y0:
            return n
    return 1


@njit(cache=True, _nrt=False)
def _abs_max(v, n):
    s = 0.0
    for i in range(n):
        a = abs(v[i, 0])
        if a > s:
            s = a
        a = abs(v[i, 1])
        if a > s:
            s = a
    return s


@njit(cache=True, _nrt=False)
def _lex_extremes(v, n):
    """The lexicographically (x, then y) smallest and largest of the n >= 1 vertices: (xmin, ymin, xmax, ymax)."""
    x0 = x1 = v[0, 0]
    y0 = y1 = v[0, 1]
    for i in range(1, n):
        x = v[i, 0]
        y = v[i, 1]
        if x < x0 or (x == x0 and y < y0):
            x0 = x
            y0 = y
        if x > x1 or (x == x1 and y > y1):
            x1 = x
            y1 = y
    return x0, y0, x1, y1


@njit(cache=True, _nrt=False)
def _a_after_b(va, na, ra, vb, nb, rb):
    """Canonical pair order: True if (A, B) must be swapped. Keys, compared in turn: vertex count, radius,
    lexicographically smallest vertex, largest vertex; all invariant under the choice of first vertex."""
    if na != nb:
        return na > nb
    if ra != rb:
        return ra > rb
    ka = _lex_extremes(va, na)
    kb = _lex_extremes(vb, nb)
    for i in range(4):
        if ka[i] != kb[i]:
            return ka[i] > kb[i]
    return False


@njit(cache=True, _nrt=False)
def _write(out_phi, out_normal, out_point, row, phi, nx, ny, px, py):
    out_phi[row] = phi
    out_normal[row, 0] = nx
    out_normal[row, 1] = ny
    out_point[row, 0] = px
    out_point[row, 1] = py


@njit(cache=True, _nrt=False)
def _order_two(out_phi, out_normal, out_point):
    """Put the deeper of two contacts in row 0."""
    if out_phi[1] < out_phi[0]:
        for c in range(2):
            t = out_normal[0, c]
            out_normal[0, c] = out_normal[1, c]
            out_normal[1, c] = t
            t = out_point[0, c]
            out_point[0, c] = out_point[1, c]
            out_point[1, c] = t
        t = out_phi[0]
        out_phi[0] = out_phi[1]
        out_phi[1] = t


# ----------------------------------------------------------------------------------------------------------------
# point vs core
# ----------------------------------------------------------------------------------------------------------------


@njit(cache=True, _nrt=False)
def _point_core(va, ra, vb, nb, rb, margin, tol, out_phi, out_normal, out_point):
    """Point core A = va[0] inflated by ra against core B (nb >= 1, effective). Returns 0 or 1."""
    px = va[0, 0]
    py = va[0, 1]
    if nb == 1:
        dx = px - vb[0, 0]
        dy = py - vb[0, 1]
        s = np.hypot(dx, dy)
        if s > 0.0:
            nx = dx / s
            ny = dy / s
        else:
            nx = 0.0
            ny = 1.0
    elif nb == 2:
        qx, qy = _closest_on_segment(px, py, vb[0, 0], vb[0, 1], vb[1, 0], vb[1, 1])
        dx = px - qx
        dy = py - qy
        s = np.hypot(dx, dy)
        if s > tol:
            nx = dx / s
            ny = dy / s
        else:
            # on the segment (within round-off): its perpendicular, on the side of the point
            nx, ny, ok = _face_normal(vb, np.int64(2), np.int64(0))
            side = nx * (px - vb[0, 0]) + ny * (py - vb[0, 1])
            if side < 0.0 or (side == 0.0 and not _key_gt(nx, ny, -nx, -ny)):
                nx = -nx
                ny = -ny
    else:
        # the face of least penetration (inside) or of most separation (outside): the SAT of the point
        s, _, nx, ny, _ = _max_separation(vb, nb, va, np.int64(1))
        if s > 0.0:
            # outside: the closest point on the boundary
            _, _, _, bx, by = _closest_vertex_edge(va, np.int64(1), vb, nb, np.inf, px, py, 0.0, 0.0)
            d = np.hypot(px - bx, py - by)
            if d > tol:
                nx = (px - bx) / d
                ny = (py - by) / d
                s = d
    phi = s - ra - rb
    if not phi < margin:
        return 0
    h = 0.5 * (s + ra - rb)
    _write(out_phi, out_normal, out_point, np.int64(0), phi, nx, ny, px - h * nx, py - h * ny)
    return 1


# ----------------------------------------------------------------------------------------------------------------
# segment/polygon vs segment/polygon
# ----------------------------------------------------------------------------------------------------------------


@njit(cache=True, _nrt=False)
def _max_separation(v1, n1, v2, n2):
    """Max over the faces of core 1 of the min over core 2's vertices of the signed distance to the face line.

    Returns (sep, face, nx, ny, k): the face index, its unit normal and the index k of core 2's deepest vertex
    along -n. face == -1 if core 1 has no non-degenerate face. Exact ties go by _key_gt (face normal) and by
    the tangential coordinate (vertex), never by index."""
    best = -np.inf
    bi = -1
    bnx = 0.0
    bny = 0.0
    bk = 0
    for i in range(n1):
        nx, ny, ok = _face_normal(v1, n1, i)
        if not ok:
            continue
        s = np.inf
        kk = 0
        tk = 0.0
        for k in range(n2):
            dx = v2[k, 0] - v1[i, 0]
            dy = v2[k, 1] - v1[i, 1]
            d = nx * dx + ny * dy
            t = ny * dx - nx * dy
            if d < s or (d == s and t < tk):
                s = d
                kk = k
                tk = t
        if bi < 0 or s > best or (s == best and _key_gt(nx, ny, bnx, bny)):
            best = s
            bi = i
            bnx = nx
            bny = ny
            bk = kk
    return best, bi, bnx, bny, bk


@njit(cache=True, _nrt=False)
def _closest_vertex_edge(v1, n1, v2, n2, best, p1x, p1y, p2x, p2y):
    """The closest (vertex of core 1, point on an edge of core 2) pair if its squared distance is below `best`.

    Returns (best, p1x, p1y, p2x, p2y): the inputs unchanged when no pair is strictly closer than `best`, so two
    calls chained through `best` give the first closest pair of both directions (the order is part of the result
    when distances tie)."""
    ne2 = n2 if n2 >= 3 else n2 - 1     # a segment core has one edge, a polygon n
    for i in range(n1):
        for j in range(ne2):
            k = j + 1
            if k >= n2:
                k = 0
            qx, qy = _closest_on_segment(v1[i, 0], v1[i, 1], v2[j, 0], v2[j, 1], v2[k, 0], v2[k, 1])
            ex = v1[i, 0] - qx
            ey = v1[i, 1] - qy
            d2 = ex * ex + ey * ey
            if d2 < best:
                best = d2
                p1x = v1[i, 0]
                p1y = v1[i, 1]
                p2x = qx
                p2y = qy
    return best, p1x, p1y, p2x, p2y


@njit(cache=True, _nrt=False)
def _segment_point(c1x, c1y, c2x, c2y, s):
    """c1 + s (c2 - c1) for s in [0, 1], with the endpoints themselves (not a rounded sum) at s = 0 and s = 1."""
    if s == 0.0:
        return c1x, c1y
    if s == 1.0:
        return c2x, c2y
    return c1x + s * (c2x - c1x), c1y + s * (c2y - c1y)


@njit(cache=True, _nrt=False)
def _clip_segment(c1x, c1y, c2x, c2y, r1x, r1y, ux, uy, hi):
    """Clip segment [c1, c2] to the slab 0 <= u.(x - r1) <= hi. Returns (count 0 or 2, p1x, p1y, p2x, p2y).

    Endpoints inside the slab are returned bit-exact (the slab test is monotone in floating point)."""
    t1 = ux * (c1x - r1x) + uy * (c1y - r1y)
    t2 = ux * (c2x - r1x) + uy * (c2y - r1y)
    if t1 == t2:
        if 0.0 <= t1 <= hi:
            return 2, c1x, c1y, c2x, c2y
        return 0, c1x, c1y, c2x, c2y
    dt = t2 - t1
    sa = (0.0 - t1) / dt
    sb = (hi - t1) / dt
    s_in = min(sa, sb)
    s_out = max(sa, sb)
    if s_in < 0.0:
        s_in = 0.0
    if s_out > 1.0:
        s_out = 1.0
    if s_in > s_out:
        return 0, c1x, c1y, c2x, c2y
    p1x, p1y = _segment_point(c1x, c1y, c2x, c2y, s_in)
    p2x, p2y = _segment_point(c1x, c1y, c2x, c2y, s_out)
    return 2, p1x, p1y, p2x, p2y


@njit(cache=True, _nrt=False)
def _poly_poly(va, na, ra, vb, nb, rb, margin, tol, out_phi, out_normal, out_point):
    """Two cores with na, nb >= 2 (effective), canonical order. Returns the contact count 0..2."""
    sa, ia, nax, nay, ka = _max_separation(va, na, vb, nb)
    sb, ib, nbx, nby, kb = _max_separation(vb, nb, va, na)
    if ia < 0 and ib < 0:
        return 0  # unreachable for effective n >= 2: kept so a bad input cannot index -1
    # reference face: max separation; an exact tie keeps A (the canonical first) as reference
    # R: the reference core (its face fi, normal n_ref = (ux_n, uy_n), separation sep); I: the incident core (its
    # vertex kdeep is the deepest along -n_ref)
    ref_b = ib >= 0 and (ia < 0 or sb > sa)
    if ref_b:
        vR, nR, rR, vI, nI, rI = vb, nb, rb, va, na, ra
        fi, ux_n, uy_n, sep, kdeep = ib, nbx, nby, sb, kb
    else:
        vR, nR, rR, vI, nI, rI = va, na, ra, vb, nb, rb
        fi, ux_n, uy_n, sep, kdeep = ia, nax, nay, sa, ka
    # output normal points from B to A; n_ref points from R towards I
    sgn = 1.0 if ref_b else -1.0
    if not sep - ra - rb < margin:
        return 0  # the true distance is >= the SAT separation

    # incident edge: most anti-parallel to n_ref
    ie, best, bmx, bmy = -1, np.inf, 0.0, 0.0
    for e in range(nI):
        mx, my, ok = _face_normal(vI, nI, e)
        dd = mx * ux_n + my * uy_n
        if ok and (ie < 0 or dd < best or (dd == best and _key_gt(mx, my, bmx, bmy))):
            ie, best, bmx, bmy = e, dd, mx, my
    je = ie + 1
    if je >= nI:
        je = 0
    fj = fi + 1
    if fj >= nR:
        fj = 0
    r1x = vR[fi, 0]
    r1y = vR[fi, 1]
    # face tangent: n = (u_y, -u_x)  =>  u = (-n_y, n_x)
    tx = -uy_n
    ty = ux_n
    hi = tx * (vR[fj, 0] - r1x) + ty * (vR[fj, 1] - r1y)
    cnt, p1x, p1y, p2x, p2y = _clip_segment(vI[ie, 0], vI[ie, 1], vI[je, 0], vI[je, 1], r1x, r1y, tx, ty, hi)
    s1 = ux_n * (p1x - r1x) + uy_n * (p1y - r1y)
    s2 = ux_n * (p2x - r1x) + uy_n * (p2y - r1y)
    if cnt == 2 and np.hypot(p1x - p2x, p1y - p2y) <= tol:
        cnt = 1  # one point: keep the deeper in slot 1
        if s2 < s1:
            p1x, p1y, s1 = p2x, p2y, s2
    smin = np.inf
    if cnt >= 1:
        smin = s1
    if cnt == 2 and s2 < smin:
        smin = s2

    if sep > -tol:
        # the distance d between the cores, with its witness points pa on A and pb on B: the closest (vertex, edge)
        # pair, A's vertices first. For intersecting cores d is not 0: it is computed only when the SAT finds the cores
        # apart or touching (sep > -tol).
        best, pax, pay, pbx, pby = _closest_vertex_edge(va, na, vb, nb, np.inf, va[0, 0], va[0, 1], vb[0, 0],
                                                        vb[0, 1])
        best, pbx, pby, pax, pay = _closest_vertex_edge(vb, nb, va, na, best, pbx, pby, pax, pay)
        d = np.hypot(pax - pbx, pay - pby)
        if d > tol:
            # separated cores: the face manifold is right only if it reaches the true distance
            if not (cnt > 0 and smin <= d + tol):
                phi = d - ra - rb
                if not phi < margin:
                    return 0
                nx = (pax - pbx) / d
                ny = (pay - pby) / d
                h = 0.5 * (rb - ra)
                _write(out_phi, out_normal, out_point, np.int64(0), phi, nx, ny,
                       0.5 * (pax + pbx) + h * nx, 0.5 * (pay + pby) + h * ny)
                return 1
        elif cnt == 0 or smin > sep + tol:
            cnt = 0
    elif cnt == 0 or smin > sep + tol:
        cnt = 0
    if cnt == 0:
        # touching cores with nothing to clip (collinear segments end to end within tol), or a deepest vertex the
        # clip missed through round-off: one contact at the SAT-deepest vertex
        phi = sep - ra - rb
        if not phi < margin:
            return 0
        h = 0.5 * (rI + sep - rR)
        cx = vI[kdeep, 0]
        cy = vI[kdeep, 1]
        _write(out_phi, out_normal, out_point, np.int64(0), phi, sgn * ux_n, sgn * uy_n, cx - h * ux_n,
               cy - h * uy_n)
        return 1

    m = np.int64(0)          # the row: an int64 at every call of _write, so numba compiles it once
    for c in range(cnt):
        if c == 0:
            cx, cy, s = p1x, p1y, s1
        else:
            cx, cy, s = p2x, p2y, s2
        phi = s - rR - rI
        if phi < margin:
            h = 0.5 * (rI + s - rR)
            _write(out_phi, out_normal, out_point, m, phi, sgn * ux_n, sgn * uy_n, cx - h * ux_n, cy - h * uy_n)
            m += 1
    if m == 2:
        _order_two(out_phi, out_normal, out_point)
    return m


@njit(cache=True, _nrt=False)
def _core_core_ordered(va, na, ra, vb, nb, rb, margin, tol, out_phi, out_normal, out_point):
    """The pair in canonical order. contact_core_core calls this from both of its branches (not once after a swap):
    with two call sites LLVM keeps the point and polygon kernels out of line in every module that links them, and the
    first simulate() compiles faster (planar_lcp.benchmarks.bench.measure_step_compile_time)."""
    if na == 1:
        return _point_core(va, ra, vb, nb, rb, margin, tol, out_phi, out_normal, out_point)
    return _poly_poly(va, na, ra, vb, nb, rb, margin, tol, out_phi, out_normal, out_point)


# ----------------------------------------------------------------------------------------------------------------
# public kernels
# ----------------------------------------------------------------------------------------------------------------


@njit(cache=True, _nrt=False)
def contact_core_core(va, na, ra, vb, nb, rb, margin, out_phi, out_normal, out_point):
    """Contacts between two inflated convex cores A and B.

    Parameters
    ----------
    va : float64 array (>= na, 2)
        World vertices of core A, CCW (only rows 0..na-1 are read); na = 1 point, 2 segment, >= 3 polygon.
    na : int
    ra : float
        Radius A's core is inflated by (m), >= 0.
    vb, nb, rb :
        The same for B.
    margin : float
        Contacts with phi >= margin are not reported (m).
    out_phi : float64 array (2,)
        Signed gaps (m), negative = penetration.
    out_normal : float64 array (2, 2)
        Unit normals from B to A.
    out_point : float64 array (2, 2)
        World contact points: midpoints of the witness points on A's and B's inflated surfaces.

    Returns
    -------
    int
        Number m in {0, 1, 2} of contacts written to rows 0..m-1 (deeper first). 0 also for na or nb <= 0.

    Tolerance: 1e-10 * (max |vertex coordinate| + ra + rb), see the module docstring.
    """
    na = _effective_n(va, na)
    nb = _effective_n(vb, nb)
    if na <= 0 or nb <= 0:
        return 0
    tol = 1e-10 * (max(_abs_max(va, na), _abs_max(vb, nb)) + abs(ra) + abs(rb))
    if _a_after_b(va, na, ra, vb, nb, rb):
        m = _core_core_ordered(vb, nb, rb, va, na, ra, margin, tol, out_phi, out_normal, out_point)
        for i in range(m):
            out_normal[i, 0] = -out_normal[i, 0]
            out_normal[i, 1] = -out_normal[i, 1]
        return m
    return _core_core_ordered(va, na, ra, vb, nb, rb, margin, tol, out_phi, out_normal, out_point)


@njit(cache=True, _nrt=False)
def contact_core_halfplane(va, na, ra, p0, n0, margin, out_phi, out_normal, out_point):
    """Contacts between an inflated core A and the static half-plane {x : n0.(x - p0) <= 0}.

    Parameters
    ----------
    va : float64 array (>= na, 2)
        World vertices of core A (only rows 0..na-1 are read).
    na : int
    ra : float
        A's radius (m), >= 0.
    p0 : float64 array (2,)
        A point of the plane's boundary line (m).
    n0 : float64 array (2,)
        UNIT outward normal of the solid (pointing into free space); used as given, not renormalized.
    margin : float
        Contacts with phi >= margin are not reported (m).
    out_phi, out_normal, out_point :
        As for `contact_core_core`; every normal is n0, each point is v - (ra + phi / 2) n0.

    Returns
    -------
    int
        0, 1 or 2. Row 0 is the deepest vertex (exact ties: the one with the smaller coordinate along
        t = (-n0_y, n0_x)); row 1, if any other vertex has phi < margin, the one farthest from it along t
        (ties: deeper, then smaller t), provided that distance exceeds tol = 1e-10 * (max |coordinate| of
        the vertices and p0 + ra).
    """
    if na <= 0:
        return 0
    nx = n0[0]
    ny = n0[1]
    tx = -ny
    ty = nx
    tol = 1e-10 * (max(_abs_max(va, na), abs(p0[0]), abs(p0[1])) + abs(ra))
    kd = -1
    pd = np.inf
    td = 0.0
    for i in range(na):
        dx = va[i, 0] - p0[0]
        dy = va[i, 1] - p0[1]
        phi = nx * dx + ny * dy - ra
        t = tx * dx + ty * dy
        if kd < 0 or phi < pd or (phi == pd and t < td):
            kd = i
            pd = phi
            td = t
    if not pd < margin:
        return 0
    h = ra + 0.5 * pd
    _write(out_phi, out_normal, out_point, np.int64(0), pd, nx, ny, va[kd, 0] - h * nx, va[kd, 1] - h * ny)
    k2 = -1
    best = tol
    p2 = np.inf
    t2 = 0.0
    for i in range(na):
        if i == kd:
            continue
        dx = va[i, 0] - p0[0]
        dy = va[i, 1] - p0[1]
        phi = nx * dx + ny * dy - ra
        if not phi < margin:
            continue
        t = tx * dx + ty * dy
        dt = abs(t - td)
        if dt > best or (k2 >= 0 and dt == best and (phi < p2 or (phi == p2 and t < t2))):
            k2 = i
            best = dt
            p2 = phi
            t2 = t
    if k2 < 0:
        return 1
    h = ra + 0.5 * p2
    _write(out_phi, out_normal, out_point, np.int64(1), p2, nx, ny, va[k2, 0] - h * nx, va[k2, 1] - h * ny)
    return 2
