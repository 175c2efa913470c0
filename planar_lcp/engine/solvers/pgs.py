"""Projected Gauss-Seidel on per-contact impulses: the fast approximate solver users know from Box2D and ODE.

Unknowns per contact: the normal impulse c_n >= 0 and, if mu > 0, one tangential impulse |f_t| <= mu c_n (the
planar friction "cone" is that interval, exact); per support point a 2-D table-friction impulse in the disk
|f| <= mu h load (the circle itself, not a polygon); per limit-surface element a wrench in an ellipsoid through the
limit surface's sliding force and spin torque (`_limit_surface_block`). A fixed number of sweeps from zero:
deterministic, and not converged in general - the iteration count is the speed/accuracy knob.
"""

import numpy as np
from numba import njit

from planar_lcp.engine.assemble import (apply_impulses, column_dot, contact_velocities, delassus, friction_column,
                                        island_problem_size, island_servo, kinematic_velocity_along, normal_column,
                                        record_impulses, servo_count, servo_direction, table_column)
from planar_lcp.engine.constants import BODY_KINEMATIC, SERVO_FORCE_DIRECTIONS, SUPPORT_POINTS
from planar_lcp.engine.layout import Stat, matrix_view
from planar_lcp.engine.solvers.certificate import STATUS_NEEDS_SPACE, STATUS_SOLVED


@njit(cache=True, _nrt=False)
def assemble_pgs(m, w, vk, nci, nsi, h, velocity_form, W, b):
    """The impulse problem (W, b) of the island w.island_con[:nci], w.island_sup[:nsi] (as `assemble_lcp`, columns
    in w.column_slot / w.column_g): per contact [n, t (if mu > 0)], per support point [x, y], per limit-surface
    element [x, y, torque]. Returns its size."""
    poses, con_pair, con_phi, con_n, con_p = w.body_pose, w.con_pair, w.con_phi, w.con_n, w.con_p
    col_dyn, col_g, v_tilde, isl_sup = w.column_slot, w.column_g, w.v_tilde, w.island_sup
    u = np.int64(0)      # not a literal 0: the column kernels would compile for Literal[int](0) too
    for a in range(nci):
        j, nx, ny = normal_column(m, w, vk, h, velocity_form, a, u, b)
        u += 1
        if m.pair_mu[con_pair[j]] > 0.0:
            friction_column(m, poses, con_pair, con_phi, con_n, con_p, j, -ny, nx, col_dyn, col_g, u)
            b[u] = column_dot(col_dyn, col_g, u, v_tilde) + \
                kinematic_velocity_along(m, poses, vk, con_pair, con_p, j, -ny, nx)
            u += 1
    per_sup = 2 if m.support_model == SUPPORT_POINTS else 3
    for a in range(nsi):
        s = isl_sup[a]
        for c in range(per_sup):
            # a world force (x, y) at the support point; a limit-surface element also a torque about the COM
            table_column(m, poses, s, 1.0 if c == 0 else 0.0, 1.0 if c == 1 else 0.0, 1.0 if c == 2 else 0.0,
                         col_dyn, col_g, u + c)
            b[u + c] = column_dot(col_dyn, col_g, u + c, v_tilde)
        u += per_sup
    delassus(m, u, col_dyn, col_g, W)
    return u


@njit(cache=True, _nrt=False)
def solve_pgs(m, w, nci, nsi, n, h, W, b, x, iterations, nsb):
    """Fixed number of projected Gauss-Seidel sweeps on W x + b, the island of `assemble_pgs` of size n, from x = 0;
    with nsb force-limited kinematic bodies in the island (`island_servo`), their contacts' impulses also keep
    within their limits (`_servo_clamp`). Returns the final max |update|."""
    isl_con, isl_sup, con_pair = w.island_con, w.island_sup, w.con_pair
    for i in range(n):
        x[i] = 0.0
    for i in range(nsb):
        for c in range(3):
            w.kin_lag[w.island_servo[i], c] = 0.0    # scratch: each force-limited body's contact impulse C
    last = 0.0
    for it in range(iterations):
        last = 0.0
        u = 0
        for a in range(nci):
            mu = m.pair_mu[con_pair[isl_con[a]]]
            k, bb = _servo_side(m, w, isl_con[a]) if nsb > 0 else (-1, -1)
            r = b[u]
            for c in range(n):
                r += W[u, c] * x[c]
            new = max(0.0, x[u] - r / W[u, u]) if W[u, u] > 0.0 else 0.0
            if k >= 0:
                new = _servo_clamp(m, w, k, isl_con[a], bb, np.bool_(False), x[u], new, 0.0, np.inf, h)
            last = max(last, abs(new - x[u]))
            x[u] = new
            u += 1
            if mu > 0.0:
                r = b[u]
                for c in range(n):
                    r += W[u, c] * x[c]
                lim = mu * x[u - 1]
                new = x[u] - r / W[u, u] if W[u, u] > 0.0 else 0.0
                new = min(lim, max(-lim, new))
                if k >= 0:
                    new = _servo_clamp(m, w, k, isl_con[a], bb, np.bool_(True), x[u], new, -lim, lim, h)
                last = max(last, abs(new - x[u]))
                x[u] = new
                u += 1
        for a in range(nsi):
            s = isl_sup[a]
            if m.support_model != SUPPORT_POINTS:
                u, upd = _limit_surface_block(m, s, u, n, h, W, b, x)
                last = max(last, upd)
                continue
            rx = b[u]
            ry = b[u + 1]
            for c in range(n):
                rx += W[u, c] * x[c]
                ry += W[u + 1, c] * x[c]
            # 2x2 block step, then projection onto the friction disk
            a11 = W[u, u]
            a12 = W[u, u + 1]
            a22 = W[u + 1, u + 1]
            det = a11 * a22 - a12 * a12
            if det > 0.0:
                dx = -(a22 * rx - a12 * ry) / det
                dy = -(-a12 * rx + a11 * ry) / det
            else:
                dx = 0.0
                dy = 0.0
            fx = x[u] + dx
            fy = x[u + 1] + dy
            lim = m.sup_mu[s] * h * m.sup_load[s]
            nrm = np.sqrt(fx * fx + fy * fy)
            if nrm > lim:
                fx *= lim / nrm
                fy *= lim / nrm
            last = max(last, abs(fx - x[u]), abs(fy - x[u + 1]))
            x[u] = fx
            x[u + 1] = fy
            u += 2
    return last


@njit(cache=True, _nrt=False)
def _servo_clamp(m, w, k, j, bb, tangential, old, new, lo, hi, h):
    """PGS's update of a contact impulse on force-limited body k (side B, body bb, of contact j): `new` clamped to
    [lo, hi] and to the values that keep the body's contact impulse C (w.kin_lag[k], kept up to date here) inside its
    force polygon and torque limit with the other impulses as they are: the servo's limits as a constraint of the
    coordinate, as PGS treats every constraint. Returns the clamped value."""
    gx, gy, gt = _servo_vector(w, j, bb, tangential)
    cx = w.kin_lag[k, 0] - gx * old
    cy = w.kin_lag[k, 1] - gy * old
    ct = w.kin_lag[k, 2] - gt * old
    for jd in range(servo_count(m, k)):
        ex, ey, et = servo_direction(jd)
        lim = h * (m.kin_max_force[k] if jd < SERVO_FORCE_DIRECTIONS else m.kin_max_torque[k])
        a = ex * gx + ey * gy + et * gt
        room = lim - (ex * cx + ey * cy + et * ct)
        if a > 0.0:
            hi = min(hi, room / a)
        elif a < 0.0:
            lo = max(lo, room / a)
    val = min(max(new, lo), hi) if lo <= hi else (lo if new < lo else hi)
    w.kin_lag[k, 0] = cx + gx * val
    w.kin_lag[k, 1] = cy + gy * val
    w.kin_lag[k, 2] = ct + gt * val
    return val


@njit(cache=True, inline='always')
def _servo_side(m, w, j):
    """(kinematic slot, body) of contact j's side B when it is a force-limited body, else (-1, -1)."""
    bb = m.shape_body[m.pair_b[w.con_pair[j]]]
    if m.body_kind[bb] == BODY_KINEMATIC and m.kin_max_force[m.body_slot[bb]] > 0.0:
        return m.body_slot[bb], bb
    return -1, -1


@njit(cache=True, inline='always')
def _servo_vector(w, j, bb, tangential):
    """The generalized vector, on side B (body bb, about its frame origin), of contact j's unit normal (or, with
    tangential, its tangent t = (-n_y, n_x)) impulse."""
    nx = w.con_n[j, 0]
    ny = w.con_n[j, 1]
    dx, dy = (-ny, nx) if tangential else (nx, ny)
    rx = w.con_p[j, 0] - w.body_pose[bb, 0]
    ry = w.con_p[j, 1] - w.body_pose[bb, 1]
    return -dx, -dy, -(rx * dy - ry * dx)


@njit(cache=True, inline='always')
def _active_basis(m, w, k, h, basis):
    """An orthonormal basis (rows of basis, returned count) of the directions along which force-limited body k is at
    its limit (its contact impulse C, w.kin_lag[k] from `_servo_clamp`, within 1e-9 of a face): the servo can lag only
    along them (the normal cone of its limits)."""
    nb = 0
    for jd in range(servo_count(m, k)):
        ex, ey, et = servo_direction(jd)
        lim = h * (m.kin_max_force[k] if jd < SERVO_FORCE_DIRECTIONS else m.kin_max_torque[k])
        if ex * w.kin_lag[k, 0] + ey * w.kin_lag[k, 1] + et * w.kin_lag[k, 2] < lim * (1.0 - 1e-9):
            continue
        # Gram-Schmidt against the basis so far
        vx, vy, vt = ex, ey, et
        for i in range(nb):
            d = vx * basis[i, 0] + vy * basis[i, 1] + vt * basis[i, 2]
            vx -= d * basis[i, 0]
            vy -= d * basis[i, 1]
            vt -= d * basis[i, 2]
        nrm = np.sqrt(vx * vx + vy * vy + vt * vt)
        if nb < 3 and nrm > 1e-9:
            basis[nb, 0] = vx / nrm
            basis[nb, 1] = vy / nrm
            basis[nb, 2] = vt / nrm
            nb += 1
    return nb


@njit(cache=True, _nrt=False)
def servo_lag_pgs(m, w, vk, nci, nsb, n, h, W, b, x):
    """The lag of PGS's force-limited bodies: the least motion along the directions where a body is at its limit
    (`_active_basis`; none: no lag) that keeps its contacts from closing under the clamped impulses x
    (`_servo_clamp`): three Kaczmarz passes over their contacts' normal rows. Into w.kin_lag and w.kin_velocity (vk
    plus it); w.kin_lag held each body's contact impulse C on entry."""
    basis = w.servo_basis
    for i in range(nsb):
        k = w.island_servo[i]
        nb = _active_basis(m, w, k, h, basis)
        for c in range(3):
            w.kin_lag[k, c] = 0.0
        if nb == 0:
            continue
        for _ in range(3):
            u = 0
            for a in range(nci):
                j = w.island_con[a]
                p = w.con_pair[j]
                frict = m.pair_mu[p] > 0.0
                bb = m.shape_body[m.pair_b[p]]
                if m.body_kind[bb] == BODY_KINEMATIC and m.body_slot[bb] == k:
                    gx, gy, gt = _servo_vector(w, j, bb, 0)
                    # the row's sensitivity to a lag, restricted to the active directions
                    px = py = pt = 0.0
                    for d in range(nb):
                        dot = gx * basis[d, 0] + gy * basis[d, 1] + gt * basis[d, 2]
                        px += dot * basis[d, 0]
                        py += dot * basis[d, 1]
                        pt += dot * basis[d, 2]
                    r = b[u]
                    for c in range(n):
                        r += W[u, c] * x[c]
                    r += gx * w.kin_lag[k, 0] + gy * w.kin_lag[k, 1] + gt * w.kin_lag[k, 2]
                    gg = px * gx + py * gy + pt * gt
                    if r < 0.0 and gg > 0.0:
                        w.kin_lag[k, 0] -= r * px / gg
                        w.kin_lag[k, 1] -= r * py / gg
                        w.kin_lag[k, 2] -= r * pt / gg
                u += 2 if frict else 1
    for i in range(nsb):
        k = w.island_servo[i]
        for c in range(3):
            w.kin_velocity[k, c] = vk[k, c] + w.kin_lag[k, c]


@njit(cache=True, inline='always')
def _residual(W, b, x, n, u):
    """Row u of W x + b."""
    r = b[u]
    for j in range(n):
        r += W[u, j] * x[j]
    return r


@njit(cache=True, inline='always')
def _limit_surface_block(m, s, u, n, h, W, b, x):
    """PGS on a limit-surface element's wrench x[u:u+3] = (f_x, f_y, torque): the block step (its three columns are
    M^-1-orthogonal on one body, so its block of W is diagonal), then a radial scaling onto the ellipsoid
    (f_x^2 + f_y^2) / F^2 + torque^2 / T^2 <= 1 with F = mu h m g and T = F L_spin: the limit surface's exact sliding
    force and spin torque, an ellipsoid in between (Howe & Cutkosky's approximation; PGS is the uncertified solver).
    Returns (the next unknown's index, the largest update)."""
    fx = x[u] - _residual(W, b, x, n, u) / W[u, u] if W[u, u] > 0.0 else 0.0
    fy = x[u + 1] - _residual(W, b, x, n, u + 1) / W[u + 1, u + 1] if W[u + 1, u + 1] > 0.0 else 0.0
    ft = x[u + 2] - _residual(W, b, x, n, u + 2) / W[u + 2, u + 2] if W[u + 2, u + 2] > 0.0 else 0.0
    lim_f = m.sup_mu[s] * h * m.sup_load[s]
    lim_t = lim_f * m.ls_wrench[s, 2, 2]          # fixed twist 2 is the pure spin
    if lim_f <= 0.0:
        fx = fy = ft = 0.0                        # no friction (mu = 0 or no load)
    else:
        g = (fx * fx + fy * fy) / (lim_f * lim_f) + (ft * ft / (lim_t * lim_t) if lim_t > 0.0 else 0.0)
    if lim_f > 0.0 and g > 1.0:
        sc = 1.0 / np.sqrt(g)
        fx *= sc
        fy *= sc
        ft *= sc
    upd = max(abs(fx - x[u]), abs(fy - x[u + 1]), abs(ft - x[u + 2]))
    x[u] = fx
    x[u + 1] = fy
    x[u + 2] = ft
    return u + 3, upd


@njit(cache=True, inline='always')
def solve_island_pgs(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    """Island solver (signature: engine/step.py): the island's impulses by opt.pgs_iters projected Gauss-Seidel
    sweeps, added to w.v_new and recorded in w.con_*. Uncertified, and never fails: returns STATUS_SOLVED
    (STATUS_NEEDS_SPACE when the dense buffers are too small)."""
    _, _, n = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)
    if n > w.lemke_lu.shape[0]:
        w.dense_needed[0] = max(w.dense_needed[0], n)
        return STATUS_NEEDS_SPACE
    W = matrix_view(w.lcp_matrix, n, n)
    assemble_pgs(m, w, vk, nci, nsi, h, velocity_form, W, w.lcp_vector)
    _, nf, _ = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)
    nsb, _ = island_servo(m, w, nci, nf)
    upd = solve_pgs(m, w, nci, nsi, n, h, W, w.lcp_vector, w.pgs_impulse, opt.pgs_iters, nsb)
    if nsb > 0:
        servo_lag_pgs(m, w, vk, nci, nsb, n, h, W, w.lcp_vector, w.pgs_impulse)
        for i in range(nsb):
            kk = w.island_servo[i]
            if w.kin_lag[kk, 0] != 0.0 or w.kin_lag[kk, 1] != 0.0 or w.kin_lag[kk, 2] != 0.0:
                stats[Stat.SERVO_LIMITED] += 1
                break
    stats[Stat.PGS_UPDATE] = max(stats[Stat.PGS_UPDATE], upd)
    stats[Stat.LCP_SIZE] += n
    stats[Stat.LCP_MAX] = max(stats[Stat.LCP_MAX], n)
    apply_impulses(n, w.column_slot, w.column_g, w.pgs_impulse, m, w.v_new)
    record_impulses(m, w, nci, w.pgs_impulse, np.bool_(True), np.int64(0))   # typed as Lemke's call: compiled once
    contact_velocities(m, w, opt, w.kin_velocity, nci)
    return STATUS_SOLVED
