"""The table's friction wrench of one support element in the limit-surface model (docs/method.md, "Table friction").

A support element is one dynamic body's support pressure: polygon pieces given by their directed edges (closed form,
exact) and curved pieces or given support points as quadrature nodes (spec/limit_surface.py makes both). For a twist
t = (v_x, v_y, omega) in the body's COM frame, `unit_load_wrench` is

    L(t) = integral p (u, r x u) dA / integral p dA,   u = v(r) / |v(r)|,

the wrench per unit mu m g that the table opposes t with: the friction on a body sliding with t is -mu m g L(t).
Plain arrays and scalars in, so Python (compile time: the fixed columns) and the kernels share this one definition.

Polygon pieces, twist with omega != 0: every point moves about the centre of rotation c = (-v_y, v_x) / omega, with
u = sign(omega) perp(r - c) / |r - c|. With Phi = integral |r - c| dA and G = integral (r - c) / |r - c| dA:

    integral u dA = sign(omega) perp(G),   integral r x u dA = sign(omega) (Phi + c x perp(G)),

and Phi, G are sums over the directed edges (a, b) of the triangles (c, a, b), each in closed form (polar
coordinates about c; p is c's signed distance to the edge line, s the coordinate along it, L = sqrt(p^2 + s^2)):

    Phi_e = [p s L + p^3 asinh(s / |p|)] / 6,   G_e = [p^2 asinh(s / |p|) n + p L t] / 2,   from s_a to s_b.

Edges shared by two pieces cancel. The edge terms grow as |c|^3 while their sum grows as |c|, so for a centre of
rotation farther than FAR_RATIO body sizes (and a translation) the polygon pieces are integrated by their "far"
Gauss nodes instead: there the integrand is analytic over the whole body and a few nodes per triangle are exact to
round-off (tests/test_limit_surface.py checks the two agree where they meet).
"""

import numpy as np
from numba import njit

#: |c| / size beyond which polygon pieces are integrated by their far nodes, not the closed form
FAR_RATIO = 10.0


@njit(cache=True)
def unit_load_wrench(edges, e0, ne, edge_scale, nodes, n0, nn, f0, nf, size, vx, vy, om, out):
    """out[:] = L(t) for t = (vx, vy, om) (m/s, m/s, rad/s; COM frame) of the element with edges[e0:e0 + ne]
    (ax, ay, bx, by, m, COM frame; their integrals scaled by edge_scale = 1 / area), curved-piece nodes
    nodes[n0:n0 + nn] and far nodes of the polygon pieces nodes[f0:f0 + nf] (x, y, weight). size: the element's
    largest distance from the COM (m). Returns False if L(t) = 0 (t = 0)."""
    fx = 0.0
    fy = 0.0
    tq = 0.0
    lo = n0
    hi = n0 + nn
    if ne > 0:
        # |c| = |v| / |om| <= (|vx| + |vy|) / |om|: no squares, which underflow for a body at rest up to round-off
        if om != 0.0 and abs(vx) + abs(vy) <= FAR_RATIO * size * abs(om):
            cx = -vy / om
            cy = vx / om
            phi = 0.0
            gx = 0.0
            gy = 0.0
            for e in range(e0, e0 + ne):
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
                asa = np.arcsinh(sa / ap)
                asb = np.arcsinh(sb / ap)
                phi += (p * (sb * lb - sa * la) + p * p * p * (asb - asa)) / 6.0
                gn = 0.5 * p * p * (asb - asa)
                gt = 0.5 * p * (lb - la)
                gx += gn * nx + gt * tx
                gy += gn * ny + gt * ty
            sg = edge_scale if om > 0.0 else -edge_scale
            # integral u dA = sign(om) perp(G), perp(x, y) = (-y, x)
            ux = -gy * sg
            uy = gx * sg
            fx += ux
            fy += uy
            tq += sg * phi + (cx * uy - cy * ux)
        else:
            _add_nodes(nodes, f0, f0 + nf, vx, vy, om, out)
            fx += out[0]
            fy += out[1]
            tq += out[2]
    _add_nodes(nodes, lo, hi, vx, vy, om, out)
    fx += out[0]
    fy += out[1]
    tq += out[2]
    out[0] = fx
    out[1] = fy
    out[2] = tq
    return fx != 0.0 or fy != 0.0 or tq != 0.0


@njit(cache=True, inline='always')
def _add_nodes(nodes, lo, hi, vx, vy, om, out):
    """out[:] = sum over nodes[lo:hi] of w (u, r x u), u the unit velocity of the node under (vx, vy, om)."""
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
    out[0] = fx
    out[1] = fy
    out[2] = tq
