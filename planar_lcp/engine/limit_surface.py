"""The table's friction wrench of one support element in the limit-surface model (docs/method.md, "Table friction").

A support element is one dynamic body's support pressure: polygon pieces given by their directed edges, full disks,
and curved pieces or given support points as quadrature nodes (spec/limit_surface.py `support_pressure`). For a
twist t = (v_x, v_y, omega) in the body's COM frame, `unit_load_wrench` is

    L(t) = integral p (u, r x u) dA / integral p dA,   u = v(r) / |v(r)|,

the wrench per unit mu m g that the table opposes t with: the friction on a body sliding with t is -mu m g L(t).
The compile step (the fixed twists' columns) and the kernels (the re-centred column) share this one definition.

Twist with omega != 0: every point moves about the centre of rotation c = (-v_y, v_x) / omega, with
u = sign(omega) perp(r - c) / |r - c|. With Phi = integral |r - c| dA and G = integral (r - c) / |r - c| dA:

    integral u dA = sign(omega) perp(G),   integral r x u dA = sign(omega) (Phi + c x perp(G)).

Polygon pieces: Phi and G are sums over the directed edges (a, b) of the triangles (c, a, b), each in closed form
(polar coordinates about c; p is c's signed distance to the edge line, s the coordinate along it,
L = sqrt(p^2 + s^2)):

    Phi_e = [p s L + p^3 asinh(s / |p|)] / 6,   G_e = [p^2 asinh(s / |p|) n + p L t] / 2,   from s_a to s_b.

Edges shared by two pieces cancel. The edge terms grow as |c|^3 while their sum grows as |c|, so for a centre of
rotation farther than FAR_RATIO body sizes (and a translation) the polygon pieces are integrated by their "far"
Gauss nodes instead: there the integrand is analytic over the whole body and a few nodes per triangle are exact to
round-off (tests/simulation/test_limit_surface.py checks the two agree where they meet).

Full disks: Phi and G depend only on c's distance from the centre, tabulated once for the unit disk and scaled
(R^3 Phi(d / R), R^2 G(d / R)); beyond the table (8 radii) and for translations, the disk's polar Gauss nodes.
"""

import math

import numpy as np
from numba import njit

#: |c| / size beyond which polygon pieces are integrated by their far nodes, not the closed form
FAR_RATIO = 10.0


@njit(cache=True, _nrt=False)
def unit_load_wrench(m, s, vx, vy, om, out):
    """out[:] = L(t) of support element s of model m (struct or ModelArrays) for the twist t = (vx, vy, om)
    (m/s, m/s, rad/s; COM frame): polygon pieces in closed form (or far nodes), disks by the unit disk's table (or
    their nodes), curved pieces and support points by their nodes. Returns False if L(t) = 0 (t = 0)."""
    size = m.sup_size[s]
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    # Phi and G about the centre of rotation, summed over the pieces that take the closed form
    phi = 0.0
    gx = 0.0
    gy = 0.0
    closed = False
    cx = 0.0
    cy = 0.0
    if om != 0.0:
        cx = -vy / om
        cy = vx / om
    if m.sup_edge_num[s] > 0:
        # |c| = |v| / |om| <= (|vx| + |vy|) / |om|: no squares, which underflow for a body at rest up to round-off
        if om != 0.0 and abs(vx) + abs(vy) <= FAR_RATIO * size * abs(om):
            e0 = m.sup_edge_adr[s]
            phi, gx, gy = _edges_phi_g(m.ls_edge, e0, e0 + m.sup_edge_num[s], cx, cy)
            closed = True
        else:
            f0 = m.sup_far_adr[s]
            _add_nodes(m.ls_node, f0, f0 + m.sup_far_num[s], vx, vy, om, out)
    tab_max = m.ls_disk_step * (m.ls_disk_table.shape[0] - 1)
    for k in range(m.sup_disk_adr[s], m.sup_disk_adr[s] + m.sup_disk_num[s]):
        ox = m.ls_disk[k, 0]
        oy = m.ls_disk[k, 1]
        rad = m.ls_disk[k, 2]
        ex = cx - ox
        ey = cy - oy
        if om != 0.0 and abs(ex) + abs(ey) <= tab_max * rad:
            dist = np.sqrt(ex * ex + ey * ey)
            p1, g1 = _disk_phi_g(m.ls_disk_table, m.ls_disk_step, dist / rad)
            phi += rad * rad * rad * p1
            if dist > 0.0:
                gx += rad * rad * g1 * ex / dist
                gy += rad * rad * g1 * ey / dist
            closed = True
        else:
            n0 = m.ls_disk_node_adr[k]
            _add_nodes(m.ls_node, n0, n0 + m.ls_disk_node_num[k], vx, vy, om, out)
    if closed:
        sg = m.sup_edge_scale[s] if om > 0.0 else -m.sup_edge_scale[s]
        # integral u dA = sign(om) perp(G), perp(x, y) = (-y, x); integral r x u dA = sign(om) (Phi + c x perp(G))
        ux = -gy * sg
        uy = gx * sg
        out[0] += ux
        out[1] += uy
        out[2] += sg * phi + (cx * uy - cy * ux)
    n0 = m.sup_node_adr[s]
    _add_nodes(m.ls_node, n0, n0 + m.sup_node_num[s], vx, vy, om, out)
    return out[0] != 0.0 or out[1] != 0.0 or out[2] != 0.0


@njit(cache=True, inline='always')
def _edges_phi_g(edges, lo, hi, cx, cy):
    """(Phi, G_x, G_y) of the triangles (c, a, b) over the directed edges edges[lo:hi] (module docstring)."""
    phi = 0.0
    gx = 0.0
    gy = 0.0
    for e in range(lo, hi):
        ax = edges[e, 0] - cx
        ay = edges[e, 1] - cy
        bx = edges[e, 2] - cx
        by = edges[e, 3] - cy
        dx = bx - ax
        dy = by - ay
        ln = np.sqrt(dx * dx + dy * dy)
        if ln == 0.0:
            continue                 # a degenerate edge bounds no area
        tx = dx / ln
        ty = dy / ln
        nx = ty                      # (n, t) is right-handed; n points outward of a CCW piece
        ny = -tx
        p = ax * nx + ay * ny
        if p == 0.0:
            continue                 # c on the edge's line: the triangle (c, a, b) has no area
        sa = ax * tx + ay * ty
        sb = bx * tx + by * ty
        la = np.sqrt(p * p + sa * sa)
        lb = np.sqrt(p * p + sb * sb)
        ap = abs(p)
        # math.asinh, not np.arcsinh: NumPy's own SIMD arcsinh differs from the C library's, which numba calls for
        # both, so the kernels run as Python would not give the compiled bits (tests/compilation/test_interpreted_bits.py)
        asa = math.asinh(sa / ap)
        asb = math.asinh(sb / ap)
        phi += (p * (sb * lb - sa * la) + p * p * p * (asb - asa)) / 6.0
        gn = 0.5 * p * p * (asb - asa)
        gt = 0.5 * p * (lb - la)
        gx += gn * nx + gt * tx
        gy += gn * ny + gt * ty
    return phi, gx, gy


@njit(cache=True, inline='always')
def _disk_phi_g(table, step, d):
    """(Phi, G along c - o) of the unit disk for a centre of rotation at distance d (spec/limit_surface.py
    `disk_table`): Phi by cubic Hermite with its exact slope -G, G by Catmull-Rom (one-sided at the ends)."""
    last = table.shape[0] - 1
    x = d / step
    i = min(int(x), last - 1)
    t = x - i
    t2 = t * t
    t3 = t2 * t
    p0 = table[i, 0]
    p1 = table[i + 1, 0]
    g0 = table[i, 1]
    g1 = table[i + 1, 1]
    phi = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * step * (-g0) + (-2 * t3 + 3 * t2) * p1 + \
        (t3 - t2) * step * (-g1)
    gm = table[i - 1, 1] if i > 0 else 2.0 * g0 - g1
    gp = table[i + 2, 1] if i + 2 <= last else 2.0 * g1 - g0
    g = 0.5 * ((2.0 * g0) + (-gm + g1) * t + (2.0 * gm - 5.0 * g0 + 4.0 * g1 - gp) * t2 +
               (-gm + 3.0 * g0 - 3.0 * g1 + gp) * t3)
    return phi, g


@njit(cache=True, _nrt=False)
def _add_nodes(nodes, lo, hi, vx, vy, om, out):
    """out[:] += sum over nodes[lo:hi] of w (u, r x u), u the unit velocity of the node under (vx, vy, om)."""
    fx = 0.0
    fy = 0.0
    tq = 0.0
    for i in range(lo, hi):
        rx = nodes[i, 0]
        ry = nodes[i, 1]
        ux = vx - om * ry
        uy = vy + om * rx
        sp = np.sqrt(ux * ux + uy * uy)
        if sp > 0.0:                         # the node at the centre of rotation carries no force
            wi = nodes[i, 2] / sp
            fx += wi * ux
            fy += wi * uy
            tq += wi * (rx * uy - ry * ux)
    out[0] += fx
    out[1] += fy
    out[2] += tq
