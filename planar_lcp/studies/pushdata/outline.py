"""Planar outlines of real objects: orientation, signed distance, rotational symmetry, convex pieces, registration.

An outline is a simple polygon, an (N, 2) float64 array of vertices in m, in order, not closed (the last vertex is
not the first again). The scene format takes strictly convex counter-clockwise polygons (docs/scene-format.md,
"Shapes"), so a non-convex outline enters a scene as several convex pieces of one body (`convex_pieces`); the mass
properties add the pieces up (spec/massprops.py: a body's shapes are taken as disjoint, which the pieces are).

`register_outline` finds the rigid transform that puts an outline into the frame its object's poses were recorded
in, from points a disk of known radius touched (docs/real_pushes.md, "Registration"). Pure numpy and scipy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Vertex checks relative to the outline's size, as the scene validator's (_POLY_REL_TOL in spec/scene.py): a turn
# whose sine is at most this is "collinear" (the vertex is dropped: the region is the same).
_REL_TOL = 1e-10
#: default tolerance of `rotational_symmetry`, relative to the outline's circumradius about its centroid: 0.5 %, about
#: 0.26 mm on the data set's 52 mm circle, whose 61-gon deviates from its own rotations by up to 0.07 mm (its sagitta)
#: and whose every other symmetry (the 78.6 x 52.4 mm ellipse turned by 1 rad) is off by millimetres
SYMMETRY_REL_TOL = 5e-3


def signed_area(p: np.ndarray) -> float:
    """Shoelace area, m^2: positive for a counter-clockwise polygon (N, 2)."""
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def centroid(p: np.ndarray) -> np.ndarray:
    """(2,) the area centroid of a simple polygon (N, 2) (either orientation)."""
    x, y = p[:, 0], p[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = 0.5 * cross.sum()
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * a)


def _turns(p: np.ndarray) -> tuple:
    """cross[i]: the turn at vertex i (from edge i-1 to edge i), and the threshold below which it is collinear."""
    e_in = p - np.roll(p, 1, axis=0)
    e_out = np.roll(p, -1, axis=0) - p
    cross = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0]
    tol = _REL_TOL * np.linalg.norm(e_in, axis=1) * np.linalg.norm(e_out, axis=1)
    return cross, tol


def clean(p) -> np.ndarray:
    """The outline counter-clockwise, without repeated or collinear vertices (the same region). ValueError if fewer
    than 3 vertices remain or the outline has no area."""
    p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
    if len(p) >= 2 and np.array_equal(p[0], p[-1]):
        p = p[:-1]                                   # a closed ring: the last vertex repeats the first
    size = float(np.max(np.linalg.norm(p - p.mean(axis=0), axis=1))) if len(p) else 0.0
    keep = np.linalg.norm(p - np.roll(p, 1, axis=0), axis=1) > _REL_TOL * size
    p = p[keep]
    while len(p) >= 3:
        cross, tol = _turns(p)
        flat = np.abs(cross) <= tol
        if not flat.any():
            break
        p = np.delete(p, int(np.argmax(flat)), axis=0)
    if len(p) < 3 or signed_area(p) == 0.0:
        raise ValueError(f"an outline needs at least 3 vertices not on one line, got {len(p)}")
    return p if signed_area(p) > 0.0 else p[::-1].copy()


def is_convex_ccw(p: np.ndarray) -> bool:
    """Strictly convex and counter-clockwise (every turn left, beyond the collinear threshold; one revolution)."""
    cross, tol = _turns(p)
    if not np.all(cross > tol):
        return False
    e = np.roll(p, -1, axis=0) - p
    en = np.roll(e, -1, axis=0)
    turning = float(np.sum(np.arctan2(e[:, 0] * en[:, 1] - e[:, 1] * en[:, 0], np.sum(e * en, axis=1))))
    return abs(turning - 2.0 * math.pi) < 1e-6


# ---------------------------------------------------------------------------------------------------------------
# Convex pieces: ear clipping, Lawson's flips to the constrained Delaunay triangulation, Hertel and Mehlhorn's merge


def _in_triangle(q: np.ndarray, a, b, c) -> np.ndarray:
    """Points q (M, 2) inside or on the CCW triangle abc."""
    def side(u, v):
        return (v[0] - u[0]) * (q[:, 1] - u[1]) - (v[1] - u[1]) * (q[:, 0] - u[0])
    return (side(a, b) >= 0.0) & (side(b, c) >= 0.0) & (side(c, a) >= 0.0)


def triangulate(p: np.ndarray) -> list:
    """Ear clipping of a simple CCW polygon (N, 2): N - 2 triangles as index triples (CCW) into p."""
    idx = list(range(len(p)))
    tris = []
    while len(idx) > 3:
        n = len(idx)
        for k in range(n):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % n]
            a, b, c = p[i0], p[i1], p[i2]
            if (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) <= 0.0:
                continue                                  # a reflex (or flat) vertex is no ear
            others = [j for j in idx if j not in (i0, i1, i2)]
            if others and _in_triangle(p[others], a, b, c).any():
                continue
            tris.append((i0, i1, i2))
            del idx[k]
            break
        else:
            raise ValueError("ear clipping found no ear: the outline is not a simple polygon")
    tris.append(tuple(idx))
    return tris


def _in_circumcircle(a, b, c, d) -> bool:
    """Whether d lies strictly inside the circumcircle of the CCW triangle abc (the in-circle determinant)."""
    ax, ay, bx, by, cx, cy = a[0] - d[0], a[1] - d[1], b[0] - d[0], b[1] - d[1], c[0] - d[0], c[1] - d[1]
    det = ((ax * ax + ay * ay) * (bx * cy - cx * by) - (bx * bx + by * by) * (ax * cy - cx * ay)
           + (cx * cx + cy * cy) * (ax * by - bx * ay))
    scale = (ax * ax + ay * ay + bx * bx + by * by + cx * cx + cy * cy) ** 2
    return det > 1e-12 * scale


def delaunay_flips(p: np.ndarray, tris: list) -> list:
    """The constrained Delaunay triangulation of a polygon from any triangulation of it (Lawson's flips: a diagonal
    is replaced by the other diagonal of its quadrilateral while the quadrilateral is convex and the fourth vertex
    lies inside the circumcircle of the other three). Index triples, CCW. Its well-shaped triangles, unlike ear
    clipping's fans at reflex vertices, are what lets the greedy merge of `convex_pieces` make few pieces."""
    tris = [list(t) for t in tris]
    flipped = True
    while flipped:
        flipped = False
        owner = {(t[k], t[(k + 1) % 3]): i for i, t in enumerate(tris) for k in range(3)}
        for (u, v), i in owner.items():
            j = owner.get((v, u))
            if j is None or j < i:
                continue                                   # an outline edge, or the pair seen from the other side
            w = next(x for x in tris[i] if x not in (u, v))
            z = next(x for x in tris[j] if x not in (u, v))
            if not _in_circumcircle(p[u], p[v], p[w], p[z]):
                continue
            t1, t2 = [w, u, z], [z, v, w]
            if signed_area(p[t1]) > 0.0 and signed_area(p[t2]) > 0.0:   # a convex quadrilateral
                tris[i], tris[j] = t1, t2
                flipped = True
                break                                      # the edge map is stale: rebuild it
    return [tuple(t) for t in tris]


def _merge(poly_a: list, poly_b: list, u: int, v: int) -> list:
    """The polygon (vertex indices, CCW) of two CCW polygons sharing the diagonal u-v (u->v in a, v->u in b)."""
    ia = poly_a.index(u)
    a = poly_a[ia:] + poly_a[:ia]                          # a starts at u: u, v, ...
    ib = poly_b.index(v)
    b = poly_b[ib:] + poly_b[:ib]                          # b starts at v: v, u, ...
    return a[1:] + [u] + b[2:] if a[1] == v and b[1] == u else None


def convex_pieces(outline) -> list:
    """Convex pieces whose union is the outline: a list of (k, 2) float64 arrays, each strictly convex and
    counter-clockwise (what a scene's polygon takes), disjoint but for shared edges.

    A convex outline is one piece (cleaned: counter-clockwise, no collinear vertex). Otherwise Hertel and
    Mehlhorn's greedy method on the constrained Delaunay triangulation (ear clipping, then `delaunay_flips`): every
    diagonal removed whose removal leaves the two pieces beside it one convex polygon; at most 4 times the minimum
    number of pieces. The outline is not
    simplified: the pieces' areas add up to its area exactly (to round-off)."""
    p = clean(outline)
    if is_convex_ccw(p):
        return [p]
    pieces = [list(t) for t in delaunay_flips(p, triangulate(p))]
    n = len(p)
    merged = True
    while merged:
        merged = False
        for i in range(len(pieces)):
            for j in range(i + 1, len(pieces)):
                a, b = pieces[i], pieces[j]
                # a shared diagonal u->v in a is v->u in b; polygon edges (consecutive outline vertices) are not
                # diagonals and are shared by no two pieces
                for k in range(len(a)):
                    u, v = a[k], a[(k + 1) % len(a)]
                    if (v - u) % n in (1, n - 1):
                        continue
                    if v not in b or b[(b.index(v) + 1) % len(b)] != u:
                        continue
                    m = _merge(a, b, u, v)
                    if m is None:
                        continue
                    poly = p[m]
                    cross, tol = _turns(poly)
                    keep = np.abs(cross) > tol                # a vertex made flat by the merge is dropped
                    if is_convex_ccw(poly[keep]):
                        pieces[i] = [x for x, kept in zip(m, keep) if kept]
                        del pieces[j]
                        merged = True
                        break
                if merged:
                    break
            if merged:
                break
    return [p[q] for q in pieces]


# ---------------------------------------------------------------------------------------------------------------
# Signed distance


def signed_distance(points, outline) -> tuple:
    """Signed distance from points to a simple polygon's boundary: positive outside, negative inside.

    Parameters
    ----------
    points : (P, 2) float64, m
    outline : (N, 2) float64, m; either orientation.

    Returns
    -------
    (P,) float64 m, and (P, 2) the gradient of the distance (a unit vector: outward at points outside).
    """
    q = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    a = np.asarray(outline, dtype=np.float64)
    b = np.roll(a, -1, axis=0)
    e = b - a                                              # (N, 2)
    rel = q[:, None, :] - a[None, :, :]                    # (P, N, 2)
    s = np.clip(np.einsum("pnk,nk->pn", rel, e) / np.einsum("nk,nk->n", e, e), 0.0, 1.0)
    close = a[None] + s[..., None] * e[None]               # the closest point of each edge
    d2 = np.sum((q[:, None, :] - close) ** 2, axis=2)
    k = np.argmin(d2, axis=1)
    rows = np.arange(len(q))
    d = np.sqrt(d2[rows, k])
    # even-odd rule: count the edges a ray from the point towards +x crosses
    ay, by = a[:, 1][None], b[:, 1][None]
    straddle = (ay > q[:, 1:2]) != (by > q[:, 1:2])
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[:, 0][None] + (q[:, 1:2] - ay) * (b[:, 0] - a[:, 0])[None] / (by - ay)
    inside = (np.sum(straddle & (q[:, 0:1] < xc), axis=1) % 2) == 1
    sign = np.where(inside, -1.0, 1.0)
    diff = q - close[rows, k]
    grad = np.zeros_like(q)
    nz = d > 0.0
    grad[nz] = diff[nz] / d[nz, None] * sign[nz, None]
    if (~nz).any():                                        # on the boundary: the edge's outward normal
        ek = e[k[~nz]]
        normal = np.stack([ek[:, 1], -ek[:, 0]], axis=1) * (1.0 if signed_area(a) > 0.0 else -1.0)
        grad[~nz] = normal / np.linalg.norm(normal, axis=1)[:, None]
    return sign * d, grad


# ---------------------------------------------------------------------------------------------------------------
# Symmetry and registration


def _rot(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def rotational_symmetry(outline, rel_tol: float = SYMMETRY_REL_TOL, max_order: int = 12) -> int:
    """The order k of the outline's rotational symmetry about its area centroid: 0 for a continuous one (a circle:
    every rotation maps it onto itself), else the largest k <= max_order such that the rotation by 2 pi / k does
    (1: none). "Maps onto itself": every rotated vertex within rel_tol times the circumradius of the boundary."""
    p = clean(outline)
    c = centroid(p)
    tol = rel_tol * float(np.max(np.linalg.norm(p - c, axis=1)))

    def maps_onto_itself(angle):
        rotated = (p - c) @ _rot(angle).T + c
        return float(np.max(np.abs(signed_distance(rotated, p)[0]))) <= tol

    if all(maps_onto_itself(a) for a in (1.0, math.sqrt(2.0), 0.3 * math.pi / math.e)):
        return 0
    for k in range(max_order, 1, -1):
        if maps_onto_itself(2.0 * math.pi / k):
            return k
    return 1


@dataclass(frozen=True)
class Registration:
    """A rigid transform of an outline into a pose frame: p_pose = R(dtheta) p_outline + (dx, dy).

    Attributes
    ----------
    dx, dy : m; dtheta : rad, in the outline's fundamental interval (-pi / k, pi / k] for a k-fold rotational
        symmetry (0 when the symmetry is continuous: the angle is then unidentifiable and fixed)
    symmetry : k of `rotational_symmetry` (0 continuous, 1 none)
    residuals : (P,) m, the signed distance of each contact point to the transformed outline less the radius
    rms : m, root mean square of the residuals
    std : (3,) the standard deviations of the shift of the outline's centroid (x, y, m) and of dtheta (rad): the
        fit's posterior covariance, its prior included, with the contact points' noise (`register_outline`'s
        noise_sd with a prior, else the residuals' RMS); nan for a fixed angle
    unidentified : tuple of str, the directions the points alone do not determine (their Jacobian's singular
        value below 1e-6 of the largest): "dtheta" when fixed by symmetry, a combination such as "1.00 dx + 0.04 dy"
        for a slide along a flat side that every push touched; the prior decided them (zero shift of the centroid)
    """

    dx: float
    dy: float
    dtheta: float
    symmetry: int
    residuals: np.ndarray
    rms: float
    std: tuple
    unidentified: tuple

    def apply(self, outline) -> np.ndarray:
        """The outline (N, 2) in the pose frame."""
        return np.asarray(outline, dtype=np.float64) @ _rot(self.dtheta).T + np.array([self.dx, self.dy])


#: weight of the weakest prior (zero displacement of the outline's centroid, zero turn times the outline's size)
#: against a residual of the contact points: small enough to move an identified parameter by about 1e-12 of its
#: value, large enough to pin an unidentified one (a flat direction of the fit) instead of wherever the solver stops
_PRIOR_WEIGHT = 1e-6


def register_outline(outline, points, radius: float, symmetry: int | None = None, shift_sd: float | None = None,
                     noise_sd: float = 5e-4) -> Registration:
    """The rigid transform of `outline` into the frame in which a disk of radius `radius` centred at each of
    `points` touched it: least squares over (dx, dy, dtheta) of sum_j (sd(p_j) - radius)^2, sd the signed distance
    to the transformed outline.

    Parameters
    ----------
    outline : (N, 2) m, in its own frame (any orientation).
    points : (P, 2) m, the disk's centre at each touch, in the pose frame.
    radius : m, >= 0.
    symmetry : k of `rotational_symmetry` (computed when None). k = 0 (a circle): the angle is not identifiable and
        is fixed at 0, only (dx, dy) are fitted; k >= 1: the angle is searched from 8 starts over its fundamental
        interval (16 for k = 1) and reported within (-pi / k, pi / k].
    shift_sd : m, optional
        A prior on the shift of the outline's centroid: zero, with this standard deviation, against contact points
        of `noise_sd` (m) standard deviation (a residual row (noise_sd / shift_sd) d per coordinate): for an outline
        known to be centred on its pose frame's origin but not known to be aligned with its axes, this picks among
        transforms that fit the points equally (pushes on one side of a square fit any shift along that side and
        the other sides turned onto it). None: no prior but `_PRIOR_WEIGHT`'s.

    The rotation is about the outline's area centroid c (so the turn and the shift are nearly independent). A weak
    prior towards no shift of c and no turn (`_PRIOR_WEIGHT`, a relative 1e-6) decides only the directions the
    points leave open, reported in `unidentified`. scipy.optimize.least_squares with the analytic Jacobian; of the
    starts, the least total cost (the prior's rows included) wins."""
    from scipy.optimize import least_squares

    p = clean(outline)
    q = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    c = centroid(p)
    size = float(np.max(np.linalg.norm(p - c, axis=1)))
    k = rotational_symmetry(p) if symmetry is None else int(symmetry)
    fit_angle = k != 0
    w_shift = _PRIOR_WEIGHT if shift_sd is None else noise_sd / shift_sd

    def unpack(z):
        return z[0], z[1], (z[2] if fit_angle else 0.0)

    def local(z):
        # the points in the outline's frame: p = R^T (q - c - d) + c
        d0, d1, th = unpack(z)
        rel = q - c - np.array([d0, d1])
        return rel @ _rot(th) + c, rel

    def fun(z):
        x, _ = local(z)
        sd, _ = signed_distance(x, p)
        prior = [w_shift * z[0], w_shift * z[1]] + ([_PRIOR_WEIGHT * size * z[2]] if fit_angle else [])
        return np.concatenate([sd - radius, prior])

    def jac(z):
        d0, d1, th = unpack(z)
        x, rel = local(z)
        _, g = signed_distance(x, p)
        R = _rot(th)
        # d x / d d = -R^T; d x / d theta = d(R^T)/d theta rel = [[-s, c], [-c, -s]] rel
        cs, sn = math.cos(th), math.sin(th)
        dx_dth = np.stack([-sn * rel[:, 0] + cs * rel[:, 1], -cs * rel[:, 0] - sn * rel[:, 1]], axis=1)
        cols = [-(g @ R.T)[:, 0], -(g @ R.T)[:, 1]]
        if fit_angle:
            cols.append(np.sum(g * dx_dth, axis=1))
        J = np.column_stack(cols)
        return np.vstack([J, np.diag([w_shift, w_shift] + ([_PRIOR_WEIGHT * size] if fit_angle else []))])

    period = 2.0 * math.pi / k if k >= 1 else 0.0
    nstart = 16 if k == 1 else 8
    starts = [np.array([0.0, 0.0, a]) for a in np.arange(nstart) * period / nstart] if fit_angle else [np.zeros(2)]
    best = None
    for z0 in starts:
        r = least_squares(fun, z0, jac=jac, method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
        if best is None or r.cost < best.cost:
            best = r
    z = best.x
    d0, d1, th = unpack(z)
    if fit_angle:
        th = math.remainder(th, period)                    # [-period/2, period/2]: the same outline
        if th <= -0.5 * period:
            th += period
        z = np.array([d0, d1, th])
    # the transform about the origin: R (o - c) + c + d = R o + (c + d - R c)
    shift = c + np.array([d0, d1]) - _rot(th) @ c
    res = fun(z)[:len(q)]
    rms = float(np.sqrt(np.mean(res ** 2)))
    J = jac(z)[:len(q)]
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    flat = sv <= 1e-6 * sv.max() if sv.size else np.array([], bool)
    unidentified = [] if fit_angle else ["dtheta"]
    labels = ["dx", "dy", "dtheta"]
    for i in np.flatnonzero(flat):
        v = vt[i] / np.abs(vt[i]).max()
        unidentified.append(" + ".join(f"{w:.2f} {lab}" for w, lab in zip(v, labels) if abs(w) >= 0.005))
    # the posterior covariance, the prior's rows included: an unidentified direction is known to the prior's width
    Jf = jac(z)
    var = (noise_sd if shift_sd is not None else rms) ** 2 * np.diag(np.linalg.pinv(Jf.T @ Jf))
    std = np.sqrt(var).tolist() + ([] if fit_angle else [math.nan])
    return Registration(dx=float(shift[0]), dy=float(shift[1]), dtheta=float(th), symmetry=k, residuals=res,
                        rms=rms, std=tuple(float(s) for s in std), unidentified=tuple(unidentified))
