"""Stage 3 of a step: the contact LCP of one island (Stewart & Trinkle eqs. 13-20 in 2D), and the PGS impulse problem.

Unknowns of the LCP, blocked (see docs/method.md):

    z = [ c_n (one per contact) | beta (+t, -t for each contact with mu > 0) | beta (k per support element)
          | lambda (one per contact with mu > 0) | lambda (one per support element) ]

A support element is a support point (points model: k world directions) or a body's limit surface (K fixed
twists' wrenches and the re-centred one, `support_columns`); either way its friction is D beta with
sum beta <= mu h load, chosen by maximal dissipation (docs/method.md, "Table friction").

All impulses (N s). A "generalized column" is the generalized impulse of a unit impulse along a world direction d
at world point p: (d_x, d_y, (p - c) x d) on the body with COM c, and the negative on the other body of the contact.
Static and kinematic bodies carry no unknowns: their velocity enters the constant vector.
"""

# math.cos, math.sin (not np.cos, np.sin): the C library's in Python as compiled, so the kernels run as Python give
# the compiled bits (tests/compilation/test_interpreted_bits.py)

import math

import numpy as np
from numba import njit

from planar_lcp.engine.constants import (BODY_DYNAMIC, BODY_KINEMATIC, BODY_STATIC, MODE_SEPARATED, MODE_SLIDING,
                                         MODE_STICKING, SERVO_FORCE_DIRECTIONS, SERVO_TORQUE_DIRECTIONS,
                                         SUPPORT_POINTS)
from planar_lcp.engine.limit_surface import unit_load_wrench


@njit(cache=True, _nrt=False)
def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


@njit(cache=True, _nrt=False)
def _point_velocity(poses, vel, b, px, py):
    """Velocity (2,) of the material point p of body b moving with (vx, vy, omega) about poses[b, :2]."""
    rx = px - poses[b, 0]
    ry = py - poses[b, 1]
    return vel[0] - vel[2] * ry, vel[1] + vel[2] * rx


@njit(cache=True, _nrt=False)
def contact_column(m, poses, con_pair, con_p, j, dx, dy, col_dyn, col_g, u):
    """Write the generalized column of a unit impulse along (dx, dy) at contact j (on A, minus on B) as column u.

    col_dyn[u, 0:2]: dynamic slots of the two bodies (-1: none); col_g[u, 0:2, 0:3]: their generalized vectors."""
    p = con_pair[j]
    ba = m.shape_body[m.pair_a[p]]
    bb = m.shape_body[m.pair_b[p]]
    px = con_p[j, 0]
    py = con_p[j, 1]
    for side in range(2):
        b = ba if side == 0 else bb
        sgn = 1.0 if side == 0 else -1.0
        if m.body_kind[b] == BODY_DYNAMIC:
            col_dyn[u, side] = m.body_slot[b]
            col_g[u, side, 0] = sgn * dx
            col_g[u, side, 1] = sgn * dy
            col_g[u, side, 2] = sgn * _cross(px - poses[b, 0], py - poses[b, 1], dx, dy)
        else:
            col_dyn[u, side] = -1


@njit(cache=True, _nrt=False)
def friction_column(m, poses, con_pair, con_phi, con_n, con_p, j, dx, dy, col_dyn, col_g, u):
    """The generalized column of a tangential impulse at contact j: at the contact point (physically right), or,
    if the model was compiled with seed_friction_arm, at each shape's core point p +- (phi/2 + r) n (for a
    capsule: the end-cap centre), which is what Stewart & Trinkle's d = [+-1, 0, +-(l/2) sin theta] does."""
    contact_column(m, poses, con_pair, con_p, j, dx, dy, col_dyn, col_g, u)
    if m.seed_friction_arm == 0:
        return
    p = con_pair[j]
    nx = con_n[j, 0]
    ny = con_n[j, 1]
    for side in range(2):
        if col_dyn[u, side] < 0:
            continue
        s = m.pair_a[p] if side == 0 else m.pair_b[p]
        b = m.shape_body[s]
        off = 0.5 * con_phi[j] + m.shape_radius[s]
        sgn = 1.0 if side == 0 else -1.0
        px = con_p[j, 0] + sgn * off * nx
        py = con_p[j, 1] + sgn * off * ny
        col_g[u, side, 2] = sgn * _cross(px - poses[b, 0], py - poses[b, 1], dx, dy)


@njit(cache=True, _nrt=False)
def table_column_at(d, rx, ry, dx, dy, torque, col_dyn, col_g, u):
    """Generalized column u of a table-friction impulse on dynamic slot d: the world force (dx, dy) at the world
    offset (rx, ry) from the COM plus a pure torque (N s, N s, N m s per unit)."""
    col_dyn[u, 0] = d
    col_dyn[u, 1] = -1
    col_g[u, 0, 0] = dx
    col_g[u, 0, 1] = dy
    col_g[u, 0, 2] = _cross(rx, ry, dx, dy) + torque


@njit(cache=True, inline='always')
def _support_offset(m, poses, s):
    """(cos, sin) of the body's angle at the linearization pose and the support point's world offset from the COM
    (zero for a limit-surface element)."""
    d = m.sup_dyn[s]
    th = poses[m.dyn_body[d], 2]
    c = math.cos(th)
    sn = math.sin(th)
    return c, sn, c * m.sup_local[s, 0] - sn * m.sup_local[s, 1], sn * m.sup_local[s, 0] + c * m.sup_local[s, 1]


@njit(cache=True, _nrt=False)
def table_column(m, poses, s, dx, dy, torque, col_dyn, col_g, u):
    """Generalized column of a table-friction impulse of support element s: the world force (dx, dy) at its support
    point (the COM for a limit-surface element) plus a pure torque."""
    _, _, rx, ry = _support_offset(m, poses, s)
    table_column_at(m.sup_dyn[s], rx, ry, dx, dy, torque, col_dyn, col_g, u)


@njit(cache=True, inline='always')
def support_column_count(m):
    """Friction columns of one support element: the k directions of a support point (points), or the K fixed twists'
    wrenches and the re-centred one (limit surface)."""
    if m.support_model == SUPPORT_POINTS:
        return m.fric_dirs.shape[0]
    return m.ls_wrench.shape[1] + 1


@njit(cache=True, _nrt=False)
def support_columns(m, w, s, u0):
    """The friction columns of support element s as generalized columns u0, u0 + 1, ..., at the linearization pose
    w.body_pose. points: unit impulses along the world directions fric_dirs at the support point. Limit surface: the
    unit-load wrenches of the K fixed twists and (last) the re-centred one, rotated from the body frame to the
    world."""
    c, sn, rx, ry = _support_offset(m, w.body_pose, s)
    d = m.sup_dyn[s]
    if m.support_model == SUPPORT_POINTS:
        for i in range(m.fric_dirs.shape[0]):
            table_column_at(d, rx, ry, m.fric_dirs[i, 0], m.fric_dirs[i, 1], 0.0, w.column_slot, w.column_g, u0 + i)
        return
    nfix = m.ls_wrench.shape[1]
    for i in range(nfix + 1):
        if i < nfix:
            wx, wy, wt = m.ls_wrench[s, i, 0], m.ls_wrench[s, i, 1], m.ls_wrench[s, i, 2]
        else:
            wx, wy, wt = w.sup_recentred[s, 0], w.sup_recentred[s, 1], w.sup_recentred[s, 2]
        table_column_at(d, rx, ry, c * wx - sn * wy, sn * wx + c * wy, wt, w.column_slot, w.column_g, u0 + i)


#: m/s (and rad/s): a body whose free-motion velocity is below this in every component is at rest up to round-off
#: (the velocities a resting body decays to: 1e-20 and less): the derivatives take its table's re-centred column as
#: fixed in the body frame (derivatives/forward.py), and the step's first try takes such a body, touching nothing,
#: as held by its table (engine/tangent.py)
REST_SPEED = 1e-12


@njit(cache=True, _nrt=False)
def recentre_limit_surfaces(m, w):
    """The re-centred column of every limit-surface element: -L(t) for the body's free-motion twist t = v_tilde
    (body frame at the linearization pose), the wrench that opposes a body still sliding the way it slides, exact
    on the limit surface. A body at rest (L = 0) repeats fixed column 0: any point of the limit surface is valid."""
    for s in range(m.sup_dyn.shape[0]):
        d = m.sup_dyn[s]
        th = w.body_pose[m.dyn_body[d], 2]
        c = math.cos(th)
        sn = math.sin(th)
        vx = w.v_tilde[d, 0]
        vy = w.v_tilde[d, 1]
        out = w.sup_recentred[s]
        moving = unit_load_wrench(m, s, c * vx + sn * vy, -sn * vx + c * vy, w.v_tilde[d, 2], out)
        for a in range(3):
            out[a] = -out[a] if moving else m.ls_wrench[s, 0, a]


@njit(cache=True, _nrt=False)
def delassus(m, nu, col_dyn, col_g, A):
    """A[:nu, :nu] = G^T M^-1 G over the first nu columns (M is diagonal per body: m, m, J)."""
    for u in range(nu):
        for v in range(u, nu):
            s = 0.0
            for su in range(2):
                du = col_dyn[u, su]
                if du < 0:
                    continue
                for sv in range(2):
                    if col_dyn[v, sv] != du:
                        continue
                    s += (col_g[u, su, 0] * col_g[v, sv, 0] + col_g[u, su, 1] * col_g[v, sv, 1]) * m.dyn_inv_mass[du]
                    # J: divided, as recorded in the golden runs (the mass term multiplied, as recorded)
                    s += col_g[u, su, 2] * col_g[v, sv, 2] / m.dyn_inertia[du]
            A[u, v] = s
            A[v, u] = s


@njit(cache=True, _nrt=False)
def column_dot(col_dyn, col_g, u, vel):
    """g_u . vel over the dynamic bodies, vel (ndyn, 3)."""
    s = 0.0
    for side in range(2):
        d = col_dyn[u, side]
        if d >= 0:
            s += col_g[u, side, 0] * vel[d, 0] + col_g[u, side, 1] * vel[d, 1] + col_g[u, side, 2] * vel[d, 2]
    return s


@njit(cache=True, _nrt=False)
def kinematic_velocity_along(m, poses, vk, con_pair, con_p, j, dx, dy):
    """Relative velocity along (dx, dy) at contact j contributed by kinematic bodies (A minus B)."""
    p = con_pair[j]
    s = 0.0
    for side in range(2):
        b = m.shape_body[m.pair_a[p]] if side == 0 else m.shape_body[m.pair_b[p]]
        if m.body_kind[b] == BODY_KINEMATIC:
            k = m.body_slot[b]
            vx, vy = _point_velocity(poses, vk[k], b, con_p[j, 0], con_p[j, 1])
            sgn = 1.0 if side == 0 else -1.0
            s += sgn * (vx * dx + vy * dy)
    return s


@njit(cache=True, inline='always')
def normal_column(m, w, vk, h, velocity_form, a, u, b, elastic=True):
    """Contact j = w.island_con[a]'s unit normal impulse as generalized column u, and the constant of its normal
    row, b[u]: position forms (linearized at q_hat = q + h v_hat) phi/h + n.(v_tilde - v_hat); velocity form
    n.v_tilde + max(phi, 0)/h + the kinematic bodies' normal velocity. With restitution e > 0 (docs/method.md,
    "Restitution"): an impact's row is at most n.v_tilde + (kinematic normal velocity) + e v_n-, an open contact's row
    at least that; elastic=False: the e = 0 rows for every pair. Returns (j, n_x, n_y)."""
    j = w.island_con[a]
    nx = w.con_n[j, 0]
    ny = w.con_n[j, 1]
    contact_column(m, w.body_pose, w.con_pair, w.con_p, j, nx, ny, w.column_slot, w.column_g, u)
    n_free = column_dot(w.column_slot, w.column_g, u, w.v_tilde)
    e = m.pair_e[w.con_pair[j]] if elastic else 0.0
    kin = 0.0
    if velocity_form or e > 0.0:
        kin = kinematic_velocity_along(m, w.body_pose, vk, w.con_pair, w.con_p, j, nx, ny)
    if velocity_form:
        b[u] = n_free + max(w.con_phi[j], 0.0) / h + kin
    else:
        b[u] = w.con_phi[j] / h + n_free - column_dot(w.column_slot, w.column_g, u, w.v_hat)
    if e > 0.0:
        # Newton's impact law at the velocity level (Moreau). v_n- is the start-of-step normal velocity, not v_tilde's:
        # gravity's h g within the step would otherwise make a resting contact bounce.
        vn_start = column_dot(w.column_slot, w.column_g, u, w.v_start) + kin
        free = n_free + kin
        if b[u] < 0.0:
            if vn_start < 0.0:
                # an impact: free motion closes the contact within the step and it was approaching. It leaves at
                # n.v+ >= -e v_n-; the stronger of that and the gap's row, so the gap's row still holds.
                b[u] = min(b[u], free + e * vn_start)
        else:
            # free motion keeps the contact open, yet the step's impacts may drive it in (a struck rod's far end):
            # the weaker of the gap's row and the same law n.v+ >= -e v_n-, so that the law, not the gap, sets what an
            # impulse there does (where the law binds at every contact with an impulse, Moreau's identity keeps a
            # frictionless step from gaining kinetic energy; docs/method.md, "Restitution")
            b[u] = max(b[u], free + e * vn_start)
    return j, nx, ny


@njit(cache=True, _nrt=False)
def assemble_columns(m, w, vk, nci, nsi, h, velocity_form, b, elastic=True):
    """The island's force columns (w.column_slot / w.column_g) and the LCP's constant vector b, without its matrix:
    all a sparse solver needs (engine/solvers/sparse.py). `assemble_lcp` is this and the matrix. Returns (LCP size
    n, number of frictional contacts)."""
    poses, con_pair, con_phi, con_n, con_p = w.body_pose, w.con_pair, w.con_phi, w.con_n, w.con_p
    col_dyn, col_g, v_tilde, isl_sup = w.column_slot, w.column_g, w.v_tilde, w.island_sup
    k = support_column_count(m)
    n, nf, _ = island_problem_size(m, w.island_con, nci, nsi, con_pair)
    o_bc = nci
    o_bs = o_bc + 2 * nf
    o_lc = o_bs + k * nsi
    o_ls = o_lc + nf
    # generalized columns of the force unknowns (and the normal rows' constants)
    f = 0
    for a in range(nci):
        j, nx, ny = normal_column(m, w, vk, h, velocity_form, a, a, b, elastic)
        if m.pair_mu[con_pair[j]] > 0.0:
            # tangent t = (-n_y, n_x); the two rays +t and -t make the 2-D friction "cone" exact
            if m.seed_friction_arm == 0:     # friction_column's columns without its call: the contact point's
                contact_column(m, poses, con_pair, con_p, j, -ny, nx, col_dyn, col_g, o_bc + 2 * f)
                contact_column(m, poses, con_pair, con_p, j, ny, -nx, col_dyn, col_g, o_bc + 2 * f + 1)
            else:
                friction_column(m, poses, con_pair, con_phi, con_n, con_p, j, -ny, nx, col_dyn, col_g, o_bc + 2 * f)
                friction_column(m, poses, con_pair, con_phi, con_n, con_p, j, ny, -nx, col_dyn, col_g,
                                o_bc + 2 * f + 1)
            f += 1
    for a in range(nsi):
        support_columns(m, w, isl_sup[a], o_bs + k * a)
    # the friction and slack rows' constants
    f = 0
    for a in range(nci):
        j = w.island_con[a]
        if m.pair_mu[con_pair[j]] <= 0.0:
            continue
        nx = con_n[j, 0]
        ny = con_n[j, 1]
        u = o_bc + 2 * f
        vt = kinematic_velocity_along(m, poses, vk, con_pair, con_p, j, -ny, nx)
        b[u] = column_dot(col_dyn, col_g, u, v_tilde) + vt
        b[u + 1] = column_dot(col_dyn, col_g, u + 1, v_tilde) - vt
        b[o_lc + f] = 0.0
        f += 1
    for a in range(nsi):
        s = isl_sup[a]
        for i in range(k):
            u = o_bs + k * a + i
            b[u] = column_dot(col_dyn, col_g, u, v_tilde)
        # the normal impulse on the table is known: h * load
        b[o_ls + a] = m.sup_mu[s] * h * m.sup_load[s]
    return n, nf


@njit(cache=True, _nrt=False)
def assemble_lcp(m, w, vk, nci, nsi, h, velocity_form, A, b, elastic=True):
    """Build the LCP (A, b) of the island whose contacts and support points are w.island_con[:nci],
    w.island_sup[:nsi] (geometry at the linearization pose w.body_pose); the generalized columns of its force
    unknowns go to w.column_slot / w.column_g. Returns (LCP size n, number of frictional contacts).

    Normal rows: position forms (linearized at the pose q_hat = q + h v_hat):  phi/h + n.(v+ - v_hat) >= 0;
    velocity form (contacts at q):  n.v+ + (kinematic normal velocity) + max(phi, 0)/h >= 0.
    Friction rows: lambda e + D^T v+ (+ kinematic tangential velocity) >= 0.  Slack rows: mu c_n - e^T beta >= 0.
    Restitution changes the normal rows' constants (`normal_column`); elastic=False assembles them as at e = 0.
    """
    n, nf = assemble_columns(m, w, vk, nci, nsi, h, velocity_form, b, elastic)
    k = support_column_count(m)
    o_bc = nci
    o_bs = o_bc + 2 * nf
    o_lc = o_bs + k * nsi
    o_ls = o_lc + nf
    for i in range(n):
        for c in range(n):
            A[i, c] = 0.0
    delassus(m, o_lc, w.column_slot, w.column_g, A)
    # the friction and slack rows
    f = 0
    for a in range(nci):
        mu = m.pair_mu[w.con_pair[w.island_con[a]]]
        if mu <= 0.0:
            continue
        u = o_bc + 2 * f
        A[u, o_lc + f] = 1.0
        A[u + 1, o_lc + f] = 1.0
        A[o_lc + f, a] = mu
        A[o_lc + f, u] = -1.0
        A[o_lc + f, u + 1] = -1.0
        f += 1
    for a in range(nsi):
        for i in range(k):
            u = o_bs + k * a + i
            A[u, o_ls + a] = 1.0
            A[o_ls + a, u] = -1.0
    return n, nf


@njit(cache=True, _nrt=False)
def apply_impulses(nforce, col_dyn, col_g, z, m, v):
    """v += M^-1 G z over the force unknowns (in place), v (ndyn, 3)."""
    for u in range(nforce):
        zu = z[u]
        if zu == 0.0:
            continue
        for side in range(2):
            d = col_dyn[u, side]
            if d >= 0:
                v[d, 0] += col_g[u, side, 0] * zu / m.dyn_mass[d]
                v[d, 1] += col_g[u, side, 1] * zu / m.dyn_mass[d]
                v[d, 2] += col_g[u, side, 2] * zu / m.dyn_inertia[d]


@njit(cache=True, _nrt=False)
def island_is_elastic(m, isl_con, nci, con_pair):
    """Whether a contact of the island belongs to a pair with restitution (e > 0)."""
    for a in range(nci):
        if m.pair_e[con_pair[isl_con[a]]] > 0.0:
            return True
    return False


@njit(cache=True, _nrt=False)
def island_problem_size(m, isl_con, nci, nsi, con_pair):
    """(LCP size, number of frictional contacts, PGS size) of an island with nci contacts and nsi support elements.
    PGS takes a support point's friction as a 2-D force, a limit-surface element's as a wrench (3 unknowns)."""
    nf = 0
    for a in range(nci):
        if m.pair_mu[con_pair[isl_con[a]]] > 0.0:
            nf += 1
    k = support_column_count(m)
    per_sup = 2 if m.support_model == SUPPORT_POINTS else 3
    return nci + 3 * nf + (k + 1) * nsi, nf, nci + nf + per_sup * nsi


@njit(cache=True, _nrt=False)
def record_impulses(m, w, nci, z, per_contact, nf_offset):
    """Per-contact normal and tangential impulses (w.con_cn, w.con_ft) from a solver's unknowns z.

    per_contact: PGS layout, z = [c_n, f_t (if mu > 0)] contact after contact; else the LCP layout
    z = [c_n..., (beta+, beta-)...] with the friction pairs from z[nf_offset]."""
    f = 0
    u = 0
    for a in range(nci):
        j = w.island_con[a]
        frict = m.pair_mu[w.con_pair[j]] > 0.0
        if per_contact:
            w.con_cn[j] = z[u]
            u += 1
            if frict:
                w.con_ft[j] = z[u]
                u += 1
            else:
                w.con_ft[j] = 0.0
        else:
            w.con_cn[j] = z[a]
            if frict:
                w.con_ft[j] = z[nf_offset + 2 * f] - z[nf_offset + 2 * f + 1]
                f += 1
            else:
                w.con_ft[j] = 0.0


@njit(cache=True, _nrt=False)
def contact_velocities(m, w, opt, vk, nci):
    """Post-solve tangential relative velocity (A minus B) of the island's contacts w.island_con[:nci], and their mode:
    separated (normal impulse <= impulse_tol), sliding (|tangential velocity| > slip_tol), else sticking.

    Measured with the geometry the LCP used (lever arms at the linearization pose w.body_pose), so that a contact the
    LCP solved as sticking has zero slip here, not the O(h) difference of the end-of-step geometry."""
    for a in range(nci):
        j = w.island_con[a]
        p = w.con_pair[j]
        nx = w.con_n[j, 0]
        ny = w.con_n[j, 1]
        vt = 0.0
        for side in range(2):
            b = m.shape_body[m.pair_a[p]] if side == 0 else m.shape_body[m.pair_b[p]]
            sgn = 1.0 if side == 0 else -1.0
            kind = m.body_kind[b]
            if kind == BODY_STATIC:
                continue
            if kind == BODY_DYNAMIC:
                vel = w.v_new[m.body_slot[b]]
            else:
                vel = vk[m.body_slot[b]]
            rx = w.con_p[j, 0] - w.body_pose[b, 0]
            ry = w.con_p[j, 1] - w.body_pose[b, 1]
            px = vel[0] - vel[2] * ry
            py = vel[1] + vel[2] * rx
            vt += sgn * (-px * ny + py * nx)
        w.con_vt[j] = vt
        if w.con_cn[j] <= opt.impulse_tol:
            w.con_mode[j] = MODE_SEPARATED
        elif abs(vt) > opt.slip_tol:
            w.con_mode[j] = MODE_SLIDING
        else:
            w.con_mode[j] = MODE_STICKING


# --- force-limited kinematic bodies (a velocity servo) ------------------------------------------------------------
# A kinematic body with max_force is massless and follows its prescribed velocity vk while the contact impulse it
# needs stays within its limits; beyond them it lags: its velocity is vk + u, with u along the outward normal of the
# active face of its force polygon (docs/method.md, "Force-limited kinematic bodies"). In the island's LCP, per such
# body, one unknown a_j >= 0 per direction e_j (the lag u = sum a_j e_j, m/s or rad/s) and one row each:
#     w_j = h F_j - e_j . C >= 0   _|_   a_j >= 0,     C = sum_c g_c z_c  the contact impulse on the body (N s),
# where g_c is column c's generalized vector on the body's side; u enters the rows of its contacts as g_c . u (its
# end pose moves by h u). The two blocks are minus each other's transpose, as friction's are.


@njit(cache=True, inline='always')
def servo_direction(j):
    """Direction j of a servo's force polygon (exact components: two along x, two along y) or, for j >= 8, of its
    torque: (x, y, spin)."""
    r = 0.7071067811865476
    if j == 0:
        return 1.0, 0.0, 0.0
    if j == 1:
        return r, r, 0.0
    if j == 2:
        return 0.0, 1.0, 0.0
    if j == 3:
        return -r, r, 0.0
    if j == 4:
        return -1.0, 0.0, 0.0
    if j == 5:
        return -r, -r, 0.0
    if j == 6:
        return 0.0, -1.0, 0.0
    if j == 7:
        return r, -r, 0.0
    return 0.0, 0.0, 1.0 if j == 8 else -1.0


@njit(cache=True, inline='always')
def servo_count(m, k):
    """The lag unknowns of kinematic slot k: its force directions, and its torque's two with max_torque."""
    return SERVO_FORCE_DIRECTIONS + (SERVO_TORQUE_DIRECTIONS if m.kin_max_torque[k] > 0.0 else 0)


@njit(cache=True, _nrt=False)
def island_servo(m, w, nci, nf):
    """The force-limited kinematic bodies of the island w.island_con[:nci] (w.island_servo[:nsb], kinematic slots)
    and, per force column c of its contacts (normal and friction), w.column_servo[c] (the body's index among them,
    -1: none) and w.column_gk[c] (the column's generalized vector on that body: side B of the pair, about its frame
    origin at the linearization pose). Returns (nsb, its lag unknowns)."""
    nsb = np.int64(0)
    ns = np.int64(0)
    # an island without a force-limited body: nothing to write (column_servo and column_gk are read for nsb > 0 only)
    servo = False
    for a in range(nci):
        bb = m.shape_body[m.pair_b[w.con_pair[w.island_con[a]]]]
        if m.body_kind[bb] == BODY_KINEMATIC and m.kin_max_force[m.body_slot[bb]] > 0.0:
            servo = True
            break
    if not servo:
        return nsb, ns
    f = np.int64(0)
    for a in range(nci):
        j = w.island_con[a]
        p = w.con_pair[j]
        frict = m.pair_mu[p] > 0.0
        bb = m.shape_body[m.pair_b[p]]
        idx = -1
        if m.body_kind[bb] == BODY_KINEMATIC and m.kin_max_force[m.body_slot[bb]] > 0.0:
            k = m.body_slot[bb]
            for i in range(nsb):
                if w.island_servo[i] == k:
                    idx = i
            if idx < 0:
                idx = nsb
                w.island_servo[nsb] = k
                nsb += 1
                ns += servo_count(m, k)
        nx = w.con_n[j, 0]
        ny = w.con_n[j, 1]
        rx = w.con_p[j, 0] - w.body_pose[bb, 0]
        ry = w.con_p[j, 1] - w.body_pose[bb, 1]
        for c in range(3 if frict else 1):
            u = a if c == 0 else nci + 2 * f + c - 1
            dx, dy = (nx, ny) if c == 0 else ((-ny, nx) if c == 1 else (ny, -nx))
            w.column_servo[u] = idx
            # side B of the pair: the negative of the unit impulse's generalized vector
            w.column_gk[u, 0] = -dx
            w.column_gk[u, 1] = -dy
            w.column_gk[u, 2] = -_cross(rx, ry, dx, dy)
        if frict:
            f += 1
    return nsb, ns


@njit(cache=True, _nrt=False)
def assemble_servo(m, w, nci, nf, n, nsb, h, A, b):
    """The lag blocks of the island's force-limited bodies (above) in the (n + ns)-square LCP A, b whose first n
    rows and columns `assemble_lcp` wrote (island_servo first). Their constants: h F_j, h T."""
    N = A.shape[0]
    for i in range(n, N):
        for c in range(N):
            A[i, c] = 0.0
    for i in range(n):
        for c in range(n, N):
            A[i, c] = 0.0
    ncol = nci + 2 * nf
    off = n
    for i in range(nsb):
        k = w.island_servo[i]
        for jd in range(servo_count(m, k)):
            ex, ey, et = servo_direction(jd)
            U = off + jd
            b[U] = h * (m.kin_max_force[k] if jd < SERVO_FORCE_DIRECTIONS else m.kin_max_torque[k])
            for c in range(ncol):
                if w.column_servo[c] == i:
                    g = w.column_gk[c, 0] * ex + w.column_gk[c, 1] * ey + w.column_gk[c, 2] * et
                    A[c, U] = g
                    A[U, c] = -g
        off += servo_count(m, k)


@njit(cache=True, _nrt=False)
def servo_within_limits(m, w, nci, nf, nsb, h, z):
    """Whether the contact impulses z (a solution without lag unknowns) stay within every island servo's limits:
    then its bodies keep their prescribed velocities, exactly."""
    ncol = nci + 2 * nf
    for i in range(nsb):
        k = w.island_servo[i]
        cx = cy = ct = 0.0
        for c in range(ncol):
            if w.column_servo[c] == i:
                cx += w.column_gk[c, 0] * z[c]
                cy += w.column_gk[c, 1] * z[c]
                ct += w.column_gk[c, 2] * z[c]
        for jd in range(servo_count(m, k)):
            ex, ey, et = servo_direction(jd)
            lim = h * (m.kin_max_force[k] if jd < SERVO_FORCE_DIRECTIONS else m.kin_max_torque[k])
            if ex * cx + ey * cy + et * ct > lim:
                return False
    return True


@njit(cache=True, _nrt=False)
def record_servo_lag(m, w, vk, n, nsb, z):
    """Each island servo's lag u = sum a_j e_j from the LCP's lag unknowns z[n:], into w.kin_lag, and its velocity
    vk + u into w.kin_velocity."""
    off = n
    for i in range(nsb):
        k = w.island_servo[i]
        ux = uy = ut = 0.0
        for jd in range(servo_count(m, k)):
            ex, ey, et = servo_direction(jd)
            ux += z[off + jd] * ex
            uy += z[off + jd] * ey
            ut += z[off + jd] * et
        off += servo_count(m, k)
        w.kin_lag[k, 0] = ux
        w.kin_lag[k, 1] = uy
        w.kin_lag[k, 2] = ut
        w.kin_velocity[k, 0] = vk[k, 0] + ux
        w.kin_velocity[k, 1] = vk[k, 1] + uy
        w.kin_velocity[k, 2] = vk[k, 2] + ut
