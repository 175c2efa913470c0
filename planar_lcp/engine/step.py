"""One time step (seed paper sections 3-4 in 2D): contacts, islands, one LCP per island, integration.

    M (v+ - v) = h f_ext + G z        q+ = q + h v+

Formulations (all over the same contact model):
- position (default, seed 3.1): linearize the gap at q_hat = q + h v:  phi(q_hat)/h + n.(v+ - v) >= 0.
- fixed_point (seed 3.4): re-linearize at q_hat <- q+ until it moves less than fp_tol (or fp_iters times).
- velocity (Anitescu-Potra, seed 3.3): contacts at q; n.v+ >= -max(phi, 0)/h (touching contacts: n.v+ >= 0),
  then a position-only projection removes penetration (velocities untouched: no kinetic energy is added).
Active set (seed 4): contacts with gap < margin at the linearization pose; after the solve the configuration q+ is
checked, and if a shape pair without contacts in the set is penetrating by more than pen_tol it is added and the
step is solved again (at most max_resolves times).
"""

from collections import namedtuple

import numpy as np
from numba import njit

from planar_lcp.engine.assemble import apply_impulses, assemble_lcp, contact_column, delassus
from planar_lcp.engine.constants import BODY_DYNAMIC, BODY_STATIC
from planar_lcp.engine.contacts import body_poses, find_contacts, world_vertices
from planar_lcp.engine.islands import contact_island, find_islands
from planar_lcp.engine.solvers.lemke import STATUS_RAY, STATUS_SOLVED, lemke_from_basis, lemke_kernel
from planar_lcp.engine.solvers.pgs import assemble_pgs, solve_pgs

# Compile time: the stages below are inline='always' into step_kernel. Every separately compiled numba function links
# in and machine-codes its callees' code again, so a stack of stage functions over the collision, assembly and Lemke
# kernels paid for them once per stage: 24.4 -> 20.5 s for the first simulate() with a fresh cache (measured with
# numba's compile events). Python callers (osqp_step) still get them as ordinary dispatchers.

SOLVER_LEMKE, SOLVER_PGS = 0, 1
FORM_POSITION, FORM_FIXED_POINT, FORM_VELOCITY = 0, 1, 2

STEP_OK = 0
STEP_LCP_FAILED = 1      # no method gave a certified answer for an island; PGS's uncertified answer was used
STEP_NONFINITE = 2       # the new state is not finite
STEP_NEEDS_FALLBACK = 3  # step_kernel_lemke only: Lemke failed on an island; nothing was written, run step_kernel

MODE_SEPARATED, MODE_STICKING, MODE_SLIDING = 0, 1, 2

# stats vector layout
ST_LCP_SIZE, ST_LCP_MAX, ST_PIVOTS, ST_LEMKE_STATUS, ST_NCON, ST_NISLAND, ST_FP_ITERS, ST_RESOLVES, \
    ST_RESIDUAL, ST_FP_CHANGE, ST_PGS_UPDATE, ST_PENETRATION, ST_LEMKE_RETRIES, ST_WARM_STARTS, \
    ST_BY_LEMKE, ST_BY_EQUILIBRATED, ST_BY_STRICT, ST_BY_VELOCITY, ST_BY_PGS = range(19)
NSTAT = 19

# How an island's LCP was solved, in the order tried (stats ST_BY_*, one count per island LCP solved; ST_WARM_STARTS
# counts the warm start). Every answer is certified by its residual on the island's original LCP before it is accepted.
#   lemke         Lemke on the problem as assembled, covering vector e: the method as published, the default path
#   equilibrated  Lemke on the exactly (power-of-two) equilibrated problem: another pivot path, on which the rows of
#                 light and heavy bodies weigh the same (docs/lcp.md)
#   strict        as assembled, with the stricter pivot tolerances RETRY_PIV_TOLS: a nearly degenerate contact LCP (a
#                 rod lying flat: two friction columns that differ by round-off-sized lever arms) can offer a pivot
#                 ~1e-7 of its column that blows the tableau up and ends on a false ray; rejecting such pivots solves it
#   velocity      position forms only: the same island (same contacts, same geometry) with the velocity form's
#                 normal rows, n.v+ >= -max(phi, 0)/h: no drift correction in this step and no linearization about
#                 v_hat. With no kinematic body in the island, Lemke processes this LCP (Anitescu & Potra 1997; the
#                 seed's section 3.3; docs/method.md), while the position form's need not have a solution (a body
#                 pressed into a corner it cannot leave in one step) or can end Lemke on a secondary ray
#   pgs           uncertified: the step is reported as failed (raised, or recorded with on_failure="record")
RETRY_PIV_TOLS = (1e-6, 1e-4)
# The chain, in order: (stats counter, pivot tolerance (-1: the options'), equilibrate, velocity-form normal rows)
CHAIN = ((ST_BY_LEMKE, -1.0, False, False), (ST_BY_EQUILIBRATED, -1.0, True, False),
         (ST_BY_STRICT, RETRY_PIV_TOLS[0], False, False), (ST_BY_STRICT, RETRY_PIV_TOLS[1], False, False),
         (ST_BY_VELOCITY, -1.0, False, True), (ST_BY_VELOCITY, -1.0, True, True))

StepOptions = namedtuple("StepOptions", [
    "solver", "formulation", "fp_iters", "fp_tol", "pgs_iters", "margin", "pen_tol", "max_resolves",
    "piv_tol", "ratio_tol", "res_tol", "slip_tol", "impulse_tol", "warm_start",
])

StepWork = namedtuple("StepWork", [
    "poses", "vw", "force_pair", "set_count",
    "con_pair", "con_phi", "con_n", "con_p", "tmp_phi", "tmp_n", "tmp_p",
    "chk_pair", "chk_phi", "chk_n", "chk_p",
    "parent", "island", "isl_con", "isl_sup", "col_dyn", "col_g", "Abuf", "bvec", "zvec",
    "lT", "lbasis", "lz", "lw", "lcand", "llu", "lrhs", "lperm", "lzb", "lzalt", "lwalt", "lprow", "ld",
    "v_tilde", "v_hat", "q_hat", "v_new", "q_new",
    "con_cn", "con_ft", "con_vt", "con_mode",
    "ws_n", "ws_zmask", "ws_n_saved", "ws_zmask_saved",
])


def make_step_work(model):
    """Allocate every buffer a step needs, sized from the model (no allocation happens inside the kernels)."""
    a = model.arrays
    nbody = a.body_kind.shape[0]
    nvert = a.vert_local.shape[0]
    npair = a.pair_a.shape[0]
    C = max(1, 2 * npair)
    U = max(1, model.max_unknowns())
    nd = max(1, model.ndyn)
    nsup = max(1, a.sup_dyn.shape[0])
    i = np.int64
    return StepWork(
        poses=np.zeros((nbody, 3)), vw=np.zeros((max(1, nvert), 2)),
        force_pair=np.zeros(max(1, npair), np.bool_), set_count=np.zeros(max(1, npair), np.int64),
        con_pair=np.zeros(C, i), con_phi=np.zeros(C), con_n=np.zeros((C, 2)), con_p=np.zeros((C, 2)),
        tmp_phi=np.zeros(2), tmp_n=np.zeros((2, 2)), tmp_p=np.zeros((2, 2)),
        chk_pair=np.zeros(C, i), chk_phi=np.zeros(C), chk_n=np.zeros((C, 2)), chk_p=np.zeros((C, 2)),
        parent=np.zeros(nd, i), island=np.zeros(nd, i), isl_con=np.zeros(C, i), isl_sup=np.zeros(nsup, i),
        col_dyn=np.zeros((U, 2), i), col_g=np.zeros((U, 2, 3)), Abuf=np.zeros(U * U), bvec=np.zeros(U),
        zvec=np.zeros(U),
        lT=np.zeros(U * (2 * U + 2)), lbasis=np.zeros(U, i), lz=np.zeros(U), lw=np.zeros(U), lcand=np.zeros(U, i),
        llu=np.zeros((U, U)), lrhs=np.zeros(U), lperm=np.zeros(U, i), lzb=np.zeros(U, i), lzalt=np.zeros(U),
        lwalt=np.zeros(U), lprow=np.zeros(2 * U + 2), ld=np.zeros(U),
        v_tilde=np.zeros((nd, 3)), v_hat=np.zeros((nd, 3)), q_hat=np.zeros((nd, 3)), v_new=np.zeros((nd, 3)),
        q_new=np.zeros((nd, 3)),
        con_cn=np.zeros(C), con_ft=np.zeros(C), con_vt=np.zeros(C), con_mode=np.zeros(C, i),
        # warm start, per island index: the size of the last LCP solved (-1: none) and which z were basic
        ws_n=np.full(nd, -1, i), ws_zmask=np.zeros((nd, U), np.bool_),
        ws_n_saved=np.full(nd, -1, i), ws_zmask_saved=np.zeros((nd, U), np.bool_),
    )


@njit(cache=True)
def _problem_sizes(m, isl_con, nci, nsi, con_pair):
    """(LCP size, number of frictional contacts, PGS size) of an island."""
    nf = 0
    for a in range(nci):
        if m.pair_mu[con_pair[isl_con[a]]] > 0.0:
            nf += 1
    k = m.fric_dirs.shape[0]
    return nci + 3 * nf + (k + 1) * nsi, nf, nci + nf + 2 * nsi


@njit(cache=True)
def _record_impulses(m, w, nci, z, friction_pairs_interleaved, nf_offset):
    """Per-contact normal and tangential impulses from the solver's unknowns.

    LCP layout: z = [c_n..., (beta+, beta-)...]; PGS layout: z = [c_n, f_t (if mu > 0)] per contact."""
    f = 0
    u = 0
    for a in range(nci):
        j = w.isl_con[a]
        frict = m.pair_mu[w.con_pair[j]] > 0.0
        if friction_pairs_interleaved:
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


@njit(cache=True, inline='always')
def _island_members(m, w, isl, ncon):
    """Fill w.isl_con / w.isl_sup with the contacts and support points of island isl; returns their counts."""
    nci = 0
    for j in range(ncon):
        if contact_island(m, w.island, w.con_pair, j) == isl:
            w.isl_con[nci] = j
            nci += 1
    nsi = 0
    for s in range(m.sup_dyn.shape[0]):
        if w.island[m.sup_dyn[s]] == isl:
            w.isl_sup[nsi] = s
            nsi += 1
    return nci, nsi


@njit(cache=True, inline='always')
def _lemke(w, A, bvec, n, opt, piv_tol, equilibrate):
    T = w.lT[:n * (2 * n + 2)].reshape((n, 2 * n + 2))
    return lemke_kernel(A, bvec, 50 * n + 100, piv_tol, opt.ratio_tol, opt.res_tol, equilibrate, T, w.lbasis, w.lz,
                        w.lw, w.lcand, w.llu, w.lrhs, w.lperm, w.lzb, w.lzalt, w.lwalt, w.lprow, w.ld)


@njit(cache=True, inline='always')
def _solve_island_lemke(m, w, opt, poses, vk, isl, nci, nsi, h, velocity_form, stats):
    """The island's LCP by Lemke: the warm start, then the certified chain of ST_BY_* methods. When solved, its
    impulses are added to w.v_new and recorded; returns the Lemke status (a failure leaves w.v_new unchanged)."""
    n, nf, _ = _problem_sizes(m, w.isl_con, nci, nsi, w.con_pair)
    k = m.fric_dirs.shape[0]
    A = w.Abuf[:n * n].reshape((n, n))
    bvec = w.bvec[:n]
    assemble_lcp(m, poses, vk, w.isl_con, nci, w.isl_sup, nsi, w.con_pair, w.con_phi, w.con_n, w.con_p,
                 w.v_tilde, w.v_hat, h, velocity_form, w.col_dyn, w.col_g, A, w.bvec)
    warm = False
    if opt.warm_start and w.ws_n[isl] == n:
        # the previous step's basis for this island: contact modes rarely change from one step to the next
        warm, res = lemke_from_basis(A, bvec, w.ws_zmask[isl], opt.res_tol, w.lz, w.lw, w.llu, w.lrhs,
                                     w.lperm, w.lzb)
    piv = 0
    if warm:
        status = STATUS_SOLVED
        stats[ST_WARM_STARTS] += 1
    else:
        # One call site for the whole chain (each inlined call of lemke_kernel costs compile time)
        status = STATUS_RAY
        method = ST_BY_LEMKE
        velocity_rows = False
        for attempt in range(len(CHAIN)):
            method, piv_tol, equilibrate, in_velocity_form = CHAIN[attempt]
            if piv_tol < 0.0:
                piv_tol = opt.piv_tol
            elif piv_tol <= opt.piv_tol:
                continue                     # not stricter than the first try
            if in_velocity_form and not velocity_rows:
                if velocity_form:
                    break                    # the velocity form's rows were the first try's
                # the island's LCP in the velocity form over the same contacts: only the normal rows' constants change
                assemble_lcp(m, poses, vk, w.isl_con, nci, w.isl_sup, nsi, w.con_pair, w.con_phi, w.con_n, w.con_p,
                             w.v_tilde, w.v_hat, h, True, w.col_dyn, w.col_g, A, w.bvec)
                velocity_rows = True
            if attempt > 0:
                stats[ST_LEMKE_RETRIES] += 1
            status, p, res = _lemke(w, A, bvec, n, opt, piv_tol, equilibrate)
            piv += p
            if status == STATUS_SOLVED:
                break
        if status == STATUS_SOLVED:
            stats[method] += 1
    stats[ST_LCP_SIZE] += n
    stats[ST_LCP_MAX] = max(stats[ST_LCP_MAX], n)
    stats[ST_PIVOTS] += piv
    stats[ST_RESIDUAL] = max(stats[ST_RESIDUAL], res)
    if status != STATUS_SOLVED:
        stats[ST_LEMKE_STATUS] = max(stats[ST_LEMKE_STATUS], status)
        w.ws_n[isl] = -1
        return status
    if not warm:
        # remember the final basis (z_i basic) for the next step's warm start
        w.ws_n[isl] = n
        for i in range(n):
            w.ws_zmask[isl, i] = False
        if piv > 0:  # with no pivot (q >= 0: z = 0) lemke_kernel leaves lbasis as it was
            for i in range(n):
                kb = w.lbasis[i]
                if kb >= n and kb < 2 * n:
                    w.ws_zmask[isl, kb - n] = True
    apply_impulses(nci + 2 * nf + k * nsi, w.col_dyn, w.col_g, w.lz, m, w.v_new)
    _record_impulses(m, w, nci, w.lz, False, nci)
    _contact_velocities(m, w, opt, poses, vk, w.isl_con, nci)
    return status


@njit(cache=True, inline='always')
def _solve_island_pgs(m, w, opt, poses, vk, isl, nci, nsi, h, velocity_form, stats):
    """The island's impulses by projected Gauss-Seidel, added to w.v_new and recorded."""
    _, _, n = _problem_sizes(m, w.isl_con, nci, nsi, w.con_pair)
    W = w.Abuf[:n * n].reshape((n, n))
    assemble_pgs(m, poses, vk, w.isl_con, nci, w.isl_sup, nsi, w.con_pair, w.con_phi, w.con_n, w.con_p,
                 w.v_tilde, w.v_hat, h, velocity_form, w.col_dyn, w.col_g, W, w.bvec)
    upd = solve_pgs(m, w.isl_con, nci, w.isl_sup, nsi, w.con_pair, h, W, w.bvec, w.zvec, opt.pgs_iters)
    stats[ST_PGS_UPDATE] = max(stats[ST_PGS_UPDATE], upd)
    stats[ST_LCP_SIZE] += n
    stats[ST_LCP_MAX] = max(stats[ST_LCP_MAX], n)
    apply_impulses(n, w.col_dyn, w.col_g, w.zvec, m, w.v_new)
    _record_impulses(m, w, nci, w.zvec, True, 0)
    _contact_velocities(m, w, opt, poses, vk, w.isl_con, nci)


@njit(cache=True, inline='always')
def _solve_island(m, w, opt, poses, vk, isl, ncon, h, velocity_form, stats):
    """Assemble and solve one island's problem, add its impulses to w.v_new, record contact impulses.

    Returns the Lemke status (STATUS_SOLVED when PGS was asked for). When Lemke fails the island is solved by PGS
    instead and the failure is returned, so that the step reports it."""
    nci, nsi = _island_members(m, w, isl, ncon)
    if nci == 0 and nsi == 0:
        return STATUS_SOLVED
    status = STATUS_SOLVED
    if opt.solver == SOLVER_LEMKE:
        status = _solve_island_lemke(m, w, opt, poses, vk, isl, nci, nsi, h, velocity_form, stats)
        if status == STATUS_SOLVED:
            return status
    # PGS: asked for, or, uncertified, when no Lemke method solved this island (the failure is returned)
    if status != STATUS_SOLVED:
        stats[ST_BY_PGS] += 1
    _solve_island_pgs(m, w, opt, poses, vk, isl, nci, nsi, h, velocity_form, stats)
    return status


@njit(cache=True, inline='always')
def _solve_island_lemke_only(m, w, opt, poses, vk, isl, ncon, h, velocity_form, stats):
    """`_solve_island` without the PGS fallback (for step_kernel_lemke): returns the Lemke status."""
    nci, nsi = _island_members(m, w, isl, ncon)
    if nci == 0 and nsi == 0:
        return STATUS_SOLVED
    return _solve_island_lemke(m, w, opt, poses, vk, isl, nci, nsi, h, velocity_form, stats)


@njit(cache=True, inline='always')
def _check_end_configuration(m, w, opt, qk_new, stats):
    """Seed section 4: check q+ for penetrating shape pairs that had no contact in the set and mark them for the
    re-solve. Also records the deepest penetration at q+ (stats[ST_PENETRATION], m, >= 0). Returns how many pairs
    were added."""
    body_poses(m, w.q_new, qk_new, w.poses)
    world_vertices(m, w.poses, w.vw)
    nchk = find_contacts(m, w.vw, 0.0, w.force_pair, w.chk_pair, w.chk_phi, w.chk_n, w.chk_p,
                         w.tmp_phi, w.tmp_n, w.tmp_p)
    added = 0
    deepest = 0.0
    for j in range(nchk):
        deepest = max(deepest, -w.chk_phi[j])
        p = w.chk_pair[j]
        # The set is per contact, not per pair: a pair with one contact in the set can penetrate at another feature
        # (the far end of a rod at slap-down). Forcing the pair adds all its candidates (at most 2) at any gap.
        if w.chk_phi[j] < -opt.pen_tol and w.set_count[p] < 2 and not w.force_pair[p]:
            w.force_pair[p] = True
            added += 1
    stats[ST_PENETRATION] = deepest
    return added


@njit(cache=True)
def _contact_velocities(m, w, opt, poses, vk, isl_con, nci):
    """Post-solve tangential relative velocity (A minus B) of an island's contacts, and their mode:
    separated (normal impulse <= impulse_tol), sliding (|tangential velocity| > slip_tol), else sticking.

    Measured with the geometry the LCP used (lever arms at the linearization pose `poses`), so that a contact the
    LCP solved as sticking has zero slip here, not the O(h) difference of the end-of-step geometry."""
    for a in range(nci):
        j = isl_con[a]
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
            rx = w.con_p[j, 0] - poses[b, 0]
            ry = w.con_p[j, 1] - poses[b, 1]
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


@njit(cache=True, inline='always')
def _project_positions(m, w, opt, qk_new, stats):
    """Velocity form's drift correction: move q+ (positions only) out of penetration by the smallest
    mass-weighted displacement, dq = M^-1 N y with 0 <= y _|_ phi(q+) + N^T M^-1 N y >= 0 (normal rows only).
    Velocities are not touched, so no kinetic energy is added."""
    body_poses(m, w.q_new, qk_new, w.poses)
    world_vertices(m, w.poses, w.vw)
    # Every contact within the margin is a constraint of the projection, not only the penetrating ones: lifting one
    # end of a rod by rotating it would otherwise push its resting other end into the table.
    n = find_contacts(m, w.vw, opt.margin, w.force_pair, w.chk_pair, w.chk_phi, w.chk_n, w.chk_p,
                      w.tmp_phi, w.tmp_n, w.tmp_p)
    deepest = 0.0
    for j in range(n):
        deepest = max(deepest, -w.chk_phi[j])
    if deepest <= opt.pen_tol:
        return
    for j in range(n):
        contact_column(m, w.poses, w.chk_pair, w.chk_p, j, w.chk_n[j, 0], w.chk_n[j, 1], w.col_dyn, w.col_g, j)
    A = w.Abuf[:n * n].reshape((n, n))
    delassus(m, n, w.col_dyn, w.col_g, A)
    for j in range(n):
        w.bvec[j] = w.chk_phi[j]
    st, piv, res = _lemke(w, A, w.bvec[:n], n, opt, opt.piv_tol, True)
    if st != STATUS_SOLVED:
        stats[ST_LEMKE_STATUS] = max(stats[ST_LEMKE_STATUS], st)
        return
    # dq = M^-1 G y (reuse the impulse application on a zeroed buffer)
    ndyn = w.q_new.shape[0]
    for d in range(ndyn):
        for c in range(3):
            w.v_hat[d, c] = 0.0
    apply_impulses(n, w.col_dyn, w.col_g, w.lz, m, w.v_hat)
    for d in range(ndyn):
        for c in range(3):
            w.q_new[d, c] += w.v_hat[d, c]


@njit(cache=True, inline='always')
def begin_step(m, q, v, qk, vk, h, opt, w, qk_out, stats):
    """Free-motion velocity v_tilde = v + h M^-1 f_ext, the first linearization pose, the kinematic end poses."""
    for i in range(stats.shape[0]):
        stats[i] = 0.0
    velocity_form = opt.formulation == FORM_VELOCITY
    for d in range(q.shape[0]):
        w.v_tilde[d, 0] = v[d, 0] + h * m.gravity[0]
        w.v_tilde[d, 1] = v[d, 1] + h * m.gravity[1]
        w.v_tilde[d, 2] = v[d, 2]
        for c in range(3):
            w.v_hat[d, c] = 0.0 if velocity_form else v[d, c]
            w.q_hat[d, c] = q[d, c] + h * w.v_hat[d, c]
    for kk in range(qk.shape[0]):
        for c in range(3):
            qk_out[kk, c] = qk[kk, c] + h * vk[kk, c]
    for p in range(w.force_pair.shape[0]):
        w.force_pair[p] = False


@njit(cache=True, inline='always')
def prepare_contacts(m, w, opt, qk_lin, stats):
    """Contacts at (w.q_hat, qk_lin), the per-pair count of the set, islands; w.v_new = v_tilde.
    Returns (number of contacts, number of islands)."""
    body_poses(m, w.q_hat, qk_lin, w.poses)
    world_vertices(m, w.poses, w.vw)
    ncon = find_contacts(m, w.vw, opt.margin, w.force_pair, w.con_pair, w.con_phi, w.con_n, w.con_p,
                         w.tmp_phi, w.tmp_n, w.tmp_p)
    for p in range(w.set_count.shape[0]):
        w.set_count[p] = 0
    for j in range(ncon):
        w.set_count[w.con_pair[j]] += 1
        w.con_cn[j] = 0.0
        w.con_ft[j] = 0.0
    nisl = find_islands(m, ncon, w.con_pair, w.parent, w.island)
    stats[ST_NISLAND] = nisl
    for d in range(w.v_new.shape[0]):
        for c in range(3):
            w.v_new[d, c] = w.v_tilde[d, c]
    return ncon, nisl


@njit(cache=True, inline='always')
def integrate_positions(q, h, w):
    for d in range(q.shape[0]):
        for c in range(3):
            w.q_new[d, c] = q[d, c] + h * w.v_new[d, c]


@njit(cache=True, inline='always')
def needs_another_solve(m, w, opt, q, h, qk_out, fp_iter, stats):
    """After a solve: (True, fp_iter) to re-linearize at q+ (fixed point, not converged, under the cap);
    (True, -1) if the active-set check added a pair; (False, fp_iter) when the step is done."""
    if opt.formulation == FORM_FIXED_POINT and fp_iter < opt.fp_iters:
        change = 0.0
        for d in range(q.shape[0]):
            for c in range(3):
                change = max(change, abs(w.q_new[d, c] - w.q_hat[d, c]))
                w.q_hat[d, c] = w.q_new[d, c]
                w.v_hat[d, c] = (w.q_hat[d, c] - q[d, c]) / h
        fp_iter += 1
        stats[ST_FP_CHANGE] = change
        if change > opt.fp_tol:
            return True, fp_iter
    if _check_end_configuration(m, w, opt, qk_out, stats) > 0 and stats[ST_RESOLVES] < opt.max_resolves:
        stats[ST_RESOLVES] += 1
        return True, -1
    return False, fp_iter


@njit(cache=True, inline='always')
def finish_step(m, w, opt, vk, ncon, qk_out, q_out, v_out, stats, fp_iter, worst):
    """Velocity-form projection, contact velocities and modes, outputs and status."""
    if opt.formulation == FORM_VELOCITY:
        _project_positions(m, w, opt, qk_out, stats)
        # re-measure the penetration after the projection (no pair is added: the step is done)
        for p in range(w.set_count.shape[0]):
            w.set_count[p] = 2
        _check_end_configuration(m, w, opt, qk_out, stats)
    return _write_outputs(w, ncon, q_out, v_out, stats, fp_iter, worst)


@njit(cache=True, inline='always')
def _write_outputs(w, ncon, q_out, v_out, stats, fp_iter, worst):
    """The step's outputs and status (finish_step without the velocity form's projection)."""
    stats[ST_NCON] = ncon
    stats[ST_FP_ITERS] = fp_iter
    finite = True
    for d in range(q_out.shape[0]):
        for c in range(3):
            q_out[d, c] = w.q_new[d, c]
            v_out[d, c] = w.v_new[d, c]
            if not (np.isfinite(q_out[d, c]) and np.isfinite(v_out[d, c])):
                finite = False
    if not finite:
        return STEP_NONFINITE
    if worst != STATUS_SOLVED:
        return STEP_LCP_FAILED
    return STEP_OK


@njit(cache=True)
def step_kernel(m, q, v, qk, vk, h, opt, w, q_out, v_out, qk_out, stats):
    """Advance (q, v, qk) by one step of size h with kinematic velocities vk.

    q, v : (ndyn, 3) COM poses and velocities; qk, vk : (nkin, 3) kinematic poses and (prescribed) velocities.
    Writes q_out, v_out, qk_out (must not alias the inputs) and stats (NSTAT,). Returns a STEP_* code.
    Contacts of the step stay in w.con_* (count in stats[ST_NCON]).
    """
    begin_step(m, q, v, qk, vk, h, opt, w, qk_out, stats)
    velocity_form = opt.formulation == FORM_VELOCITY
    # the velocity form evaluates contacts at the current configuration, the position forms at the end of the step
    qk_lin = qk if velocity_form else qk_out
    fp_iter = 0
    # a step fails if any of its solves had an island without a certified answer: a fixed-point iterate or an
    # active-set re-solve that starts from an uncertified answer is not trusted either, even if its own LCP solves
    worst = STATUS_SOLVED
    while True:
        ncon, nisl = prepare_contacts(m, w, opt, qk_lin, stats)
        for isl in range(nisl):
            st = _solve_island(m, w, opt, w.poses, vk, isl, ncon, h, velocity_form, stats)
            if st != STATUS_SOLVED:
                worst = st
        integrate_positions(q, h, w)
        again, it = needs_another_solve(m, w, opt, q, h, qk_out, fp_iter, stats)
        if it >= 0:
            fp_iter = it
        if not again:
            break
    return finish_step(m, w, opt, vk, ncon, qk_out, q_out, v_out, stats, fp_iter, worst)


@njit(cache=True, inline='always')
def _copy_warm_start(n_from, zmask_from, n_to, zmask_to):
    """Copy the warm-start memory (per island: LCP size and basic-z mask)."""
    for i in range(n_from.shape[0]):
        n_to[i] = n_from[i]
        for c in range(zmask_from.shape[1]):
            zmask_to[i, c] = zmask_from[i, c]


@njit(cache=True)
def step_kernel_lemke(m, q, v, qk, vk, h, opt, w, q_out, v_out, qk_out, stats):
    """`step_kernel` for solver lemke and the position forms, without the PGS fallback and the velocity form's
    projection compiled in, so that the first call compiles less (docs/performance.md). When Lemke fails on an
    island it returns STEP_NEEDS_FALLBACK at once, with the warm-start memory as it was before the step and nothing
    written: run `step_kernel` on the same inputs, which does exactly what this kernel would have done up to the
    failure and then solves the island by PGS. Other solvers and the velocity form: STEP_NEEDS_FALLBACK."""
    if opt.solver != SOLVER_LEMKE or opt.formulation == FORM_VELOCITY:
        return STEP_NEEDS_FALLBACK
    if opt.warm_start:
        _copy_warm_start(w.ws_n, w.ws_zmask, w.ws_n_saved, w.ws_zmask_saved)
    begin_step(m, q, v, qk, vk, h, opt, w, qk_out, stats)
    velocity_form = opt.formulation == FORM_VELOCITY
    qk_lin = qk if velocity_form else qk_out
    fp_iter = 0
    while True:
        ncon, nisl = prepare_contacts(m, w, opt, qk_lin, stats)
        for isl in range(nisl):
            st = _solve_island_lemke_only(m, w, opt, w.poses, vk, isl, ncon, h, velocity_form, stats)
            if st != STATUS_SOLVED:
                if opt.warm_start:
                    _copy_warm_start(w.ws_n_saved, w.ws_zmask_saved, w.ws_n, w.ws_zmask)
                return STEP_NEEDS_FALLBACK
        integrate_positions(q, h, w)
        again, it = needs_another_solve(m, w, opt, q, h, qk_out, fp_iter, stats)
        if it >= 0:
            fp_iter = it
        if not again:
            break
    return _write_outputs(w, ncon, q_out, v_out, stats, fp_iter, STATUS_SOLVED)
