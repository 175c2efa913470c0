"""The step's derivatives at the cold step's certified bases, in one compiled call: the fast path of the checked
differences (planar_lcp/derivatives/differences.py).

Where every island's LCP answer is strictly complementary, its basis B holds on a neighbourhood of the state, and
there the answer is z_B = -A_BB^-1 b_B: the implicit function theorem gives its derivative along an input as
dz_B = -A_BB^-1 d(A z + b)_B, z held. The step's other stages (contacts, the limit surfaces' re-centred columns, the
assembly of A and b, the impulses' velocity change M^-1 G z and the integration) are smooth functions of the inputs
for the contacts and islands fixed; `step_tangent` takes their derivatives with z held by central differences of
that smooth part alone (no LCP is solved there: two evaluations of the contacts, force columns and rows per input),
and adds the LCP's through one solve with A_BB at the state. Only the rows of A and b that depend on the state enter:
the Delassus part G^T M^-1 G z + b over the force unknowns (computed as G^T (M^-1 (G z)), linear in the unknowns),
the friction and slack rows being constant.

It answers for the steps it covers (`_covered`): the position form, every island solved by Lemke's first try from
scratch (no warm start, no retry, no sparse or block solver, no force-limited body in the island), no active-set
re-solve, and no pair outside the contact set penetrating at the step's end pose (a re-solve a perturbation could
start). Everywhere else, and where its checks fail, it returns a code and the checked differences of whole steps
(`step_differences`, engine/rollout.py) answer instead. Its checks:

- each island's basis holds on both sides: every index at the certificate's zero on both sides, z_i and
  w_i = (A z + b)_i (the dual numbers' test of a degenerate index, planar_lcp/derivatives/forward.py), stays there
  along every input (its rate below DEGENERATE_RTOL of the island's: a sticking contact's unloaded friction ray,
  whose w = lambda + t.v has lambda and t.v both held at zero), where a contact touching without load opens or
  closes;
- every evaluation x +- eps_k e_k has x's contacts (the same pairs, in the same order, hence the same islands);
- the one-sided differences of the smooth part agree (a kink of the contact geometry, of max and min in the rows,
  or a body at rest on its limit surface, whose re-centred column jumps);
- the cold steps at x +- d move as J d predicts (d the mixed direction of `step_differences`).
"""

import math

import numpy as np
from numba import njit

from planar_lcp.engine.assemble import (apply_impulses, assemble_columns, assemble_lcp, column_dot,
                                        island_problem_size, island_servo, support_column_count)
from planar_lcp.engine.islands import island_members
from planar_lcp.engine.layout import Stat
from planar_lcp.engine.rollout import (DIFF_FAILED, DIFF_MOVES, DIFF_NONFINITE, DIFF_OK, DIFF_SPACE,
                                       _compiled_recording, _restore_memory, _step_from_flat)
from planar_lcp.engine.step import (FORM_POSITION, STEP_NEEDS_SPACE, STEP_OK, begin_step, check_end_configuration,
                                    kinematic_linearization, prepare_contacts)

#: step_tangent's answers besides the DIFF_* codes it shares with step_differences: the step is not one it covers
#: (`_covered`), an island's answer is not strictly complementary, an evaluation nearby has other contacts, the
#: one-sided differences of the smooth part differ. The checked differences of whole steps answer then.
TANGENT_NOT_COVERED = 10
TANGENT_DEGENERATE = 11
TANGENT_CONTACTS = 12
TANGENT_KINK = 13

#: a degenerate index (z_i = w_i = 0) keeps its basis on both sides where its w (z, if basic) changes along no
#: input: by less than this fraction of the island's largest rate along that input (the smooth part's differences
#: are good to about 1e-7 of it; a mode that switches moves at the scale of the others)
DEGENERATE_RTOL = 1e-6
#: the stats of a cold step a tangent does not cover where nonzero: another try, solver or re-solve than Lemke's
#: first from scratch
_UNCOVERED = np.array([Stat.LEMKE_RETRIES, Stat.WARM_STARTS, Stat.SOLVED_SPARSE, Stat.SOLVED_BLOCK,
                       Stat.PGS_UNCERTIFIED, Stat.SERVO_LIMITED, Stat.RESOLVES, Stat.FP_ITERATIONS],
                      dtype=np.int64)


@njit(cache=True)
def _covered(opt, stats):
    """Whether the cold step just taken (its stats) is one `step_tangent` covers (module docstring)."""
    if opt.formulation != FORM_POSITION:
        return False
    for a in _UNCOVERED:
        if stats[a] != 0.0:
            return False
    return True


@njit(cache=True, inline='always')
def _give_way(msize, mbasic, mmodes, w, code):
    """The warm-start memory as the cold step left it, and the code."""
    _restore_memory(msize, mbasic, mmodes, w)
    return code


@njit(cache=True, inline='always')
def _unflatten(x, nd, nk, q, v, qk, vk):
    for i in range(nd):
        for c in range(3):
            q[i, c] = x[3 * i + c]
            v[i, c] = x[3 * nd + 3 * i + c]
    for j in range(nk):
        for c in range(3):
            qk[j, c] = x[6 * nd + 3 * j + c]
            vk[j, c] = x[6 * nd + 3 * nk + 3 * j + c]


@njit(cache=True, inline='always')
def _contacts_at(m, h, opt, w, x, nd, nk, q, v, qk, vk, qk_out, scratch):
    """The step's first stages at the flattened state x: its inputs into q, v, qk, vk, the free motion, the
    linearization pose, the contacts and islands (w.con_*, w.body_island), w.v_new = v_tilde. Returns (contacts,
    islands)."""
    _unflatten(x, nd, nk, q, v, qk, vk)
    begin_step(m, q, v, qk, vk, h, opt, w, qk_out, scratch)
    return prepare_contacts(m, w, opt, kinematic_linearization(w, qk, False), scratch)


@njit(cache=True, inline='always')
def _smooth_part(m, h, opt, w, vk, nisl, ncon, z, zoff, q, qk_out, r, out, dv, scratch):
    """With the contacts and islands of `_contacts_at` and the answers z held (island i's at zoff[i] ...
    zoff[i + 1]): the rows r = (A z + b) of every island over its force unknowns (G^T (M^-1 G z) + b; b alone on the
    constant rows), and the step's outputs out = (q + h v+, v+, qk+) with v+ = v_tilde + M^-1 G z. dv: (ndyn, 3)
    scratch. Returns the pairs the step's end-of-step check adds at that q+ (a re-solve: none where covered)."""
    k = support_column_count(m)
    nd = q.shape[0]
    for isl in range(nisl):
        nci, nsi = island_members(m, w, isl, ncon)
        if nci == 0 and nsi == 0:
            continue
        o = zoff[isl]
        n, nf = assemble_columns(m, w, vk, nci, nsi, h, False, r[o:zoff[isl + 1]], np.bool_(True))
        nforce = nci + 2 * nf + k * nsi
        for d in range(nd):
            for c in range(3):
                dv[d, c] = 0.0
        apply_impulses(nforce, w.column_slot, w.column_g, z[o:o + n], m, dv)
        for u in range(nforce):
            r[o + u] += column_dot(w.column_slot, w.column_g, u, dv)
        for d in range(nd):
            for c in range(3):
                w.v_new[d, c] += dv[d, c]
    for d in range(nd):
        for c in range(3):
            w.q_new[d, c] = q[d, c] + h * w.v_new[d, c]
            out[3 * d + c] = w.q_new[d, c]
            out[3 * nd + 3 * d + c] = w.v_new[d, c]
    for j in range(qk_out.shape[0]):
        for c in range(3):
            out[6 * nd + 3 * j + c] = qk_out[j, c]
    return check_end_configuration(m, w, opt, qk_out, scratch)


@njit(cache=True)
def step_tangent(m, h, cold_opt, warm_opt, w, q, v, qk, vk, tols, jac, q1, v1, qk1, stats):
    """The derivatives of the cold step at the state (q, v, qk, vk) at its certified bases (module docstring) into
    jac (6 nd + 3 nk, K), columns the K inputs (x: q, v, qk, vk flattened row-major), the smooth part's central
    differences over eps_k = tols[0] max(1, |x_k|); the cold step's state into q1, v1, qk1 and its stats into stats.
    Returns DIFF_OK where every check holds, DIFF_MOVES where only the mixed direction's fails (jac written), else a
    DIFF_* or TANGENT_* code. tols as step_differences takes them. The warm-start memory is left as the cold step
    left it."""
    nd, nk = q.shape[0], qk.shape[0]
    K = 6 * nd + 6 * nk
    x = np.empty(K)
    for i in range(nd):
        for c in range(3):
            x[3 * i + c] = q[i, c]
            x[3 * nd + 3 * i + c] = v[i, c]
    for j in range(nk):
        for c in range(3):
            x[6 * nd + 3 * j + c] = qk[j, c]
            x[6 * nd + 3 * nk + 3 * j + c] = vk[j, c]
    for k in range(K):
        if not np.isfinite(x[k]):
            return DIFF_NONFINITE
    # the steps along each input and the mixed direction's, as step_differences takes them
    steps = np.empty((2, K))
    for k in range(K):
        steps[0, k] = tols[0] * max(1.0, abs(x[k]))
        steps[1, k] = steps[0, k] if math.sin(k + 1.0) >= 0.0 else -steps[0, k]
    rtol_kink, rtol_mixed, floor = tols[1], tols[2], tols[3]
    nout = 6 * nd + 3 * nk
    base = np.empty(nout)
    rec = _compiled_recording(1, nd, nk)
    st = _step_from_flat(m, x, nd, nk, h, cold_opt, w, rec, True, base)
    for s in range(stats.shape[0]):
        stats[s] = rec.stats[0, s]
    if st == STEP_NEEDS_SPACE:
        return DIFF_SPACE
    if st != STEP_OK:
        return DIFF_FAILED
    if not _covered(cold_opt, stats):
        return TANGENT_NOT_COVERED
    msize, mbasic, mmodes = w.warm_size.copy(), w.warm_basic_z.copy(), w.sparse_pair_mode.copy()
    qa, va, qka, vka = np.empty((nd, 3)), np.empty((nd, 3)), np.empty((nk, 3)), np.empty((nk, 3))
    qk_out = np.empty((nk, 3))
    scratch = np.zeros(stats.shape[0])
    dv = np.empty((nd, 3))
    # x's contacts, islands and each island's LCP at the cold step's basis
    ncon, nisl = _contacts_at(m, h, cold_opt, w, x, nd, nk, qa, va, qka, vka, qk_out, scratch)
    pairs = w.con_pair[:ncon].copy()
    zoff = np.zeros(nisl + 1, np.int64)
    for isl in range(nisl):
        nci, nsi = island_members(m, w, isl, ncon)
        n = 0
        if nci > 0 or nsi > 0:
            n, nf, _ = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)
            nsb, _ = island_servo(m, w, nci, nf)
            if nsb > 0 or msize[isl] != n:
                _restore_memory(msize, mbasic, mmodes, w)
                return TANGENT_NOT_COVERED
        zoff[isl + 1] = zoff[isl] + n
    N = zoff[nisl]
    z = np.zeros(N)
    lu = np.zeros((N, N))            # each island's A_BB, on its diagonal block
    afull = np.zeros((N, N))         # each island's A
    basic = np.zeros(N, np.bool_)
    degenerate = np.zeros(N, np.bool_)
    r0 = np.empty(N)
    res_tol = cold_opt.res_tol
    for isl in range(nisl):
        o, n = zoff[isl], zoff[isl + 1] - zoff[isl]
        if n == 0:
            continue
        nci, nsi = island_members(m, w, isl, ncon)
        A = np.empty((n, n))
        b = np.empty(n)
        assemble_lcp(m, w, vka, nci, nsi, h, False, A, b, np.bool_(True))
        nb = 0
        for i in range(n):
            basic[o + i] = mbasic[isl, i]
            nb += basic[o + i]
        idx = np.empty(nb, np.int64)
        c = 0
        for i in range(n):
            if basic[o + i]:
                idx[c] = i
                c += 1
        if nb > 0:
            Abb = np.empty((nb, nb))
            rhs = np.empty(nb)
            for a in range(nb):
                rhs[a] = -b[idx[a]]
                for c in range(nb):
                    Abb[a, c] = A[idx[a], idx[c]]
            zb = np.linalg.solve(Abb, rhs)
            for a in range(nb):
                z[o + idx[a]] = zb[a]
                for c in range(nb):
                    lu[o + a, o + c] = Abb[a, c]
        # the indices at the certificate's zero on both sides (forward.py `degenerate_indices`): z_i = w_i = 0
        scale = 1.0
        zmax = 1.0
        for i in range(n):
            scale = max(scale, abs(b[i]))
            zmax = max(zmax, abs(z[o + i]))
            for c in range(n):
                scale = max(scale, abs(A[i, c]))
                afull[o + i, o + c] = A[i, c]
        for i in range(n):
            wi = b[i]
            for c in range(n):
                wi += A[i, c] * z[o + c]
            if basic[o + i]:
                if z[o + i] < -res_tol * zmax:
                    return _give_way(msize, mbasic, mmodes, w, TANGENT_DEGENERATE)
                degenerate[o + i] = z[o + i] <= res_tol * zmax
            else:
                if wi < -res_tol * scale:
                    return _give_way(msize, mbasic, mmodes, w, TANGENT_DEGENERATE)
                degenerate[o + i] = wi <= res_tol * scale
    # the smooth part at x, then at x +- eps_k e_k
    f0 = np.empty(nout)
    if _smooth_part(m, h, cold_opt, w, vka, nisl, ncon, z, zoff, qa, qk_out, r0, f0, dv, scratch) != 0:
        _restore_memory(msize, mbasic, mmodes, w)
        return TANGENT_CONTACTS
    rp, rm = np.empty(N), np.empty(N)
    fp, fm = np.empty(nout), np.empty(nout)
    dr = np.zeros((N, K))
    xx = x.copy()
    code = DIFF_OK
    for k in range(K):
        e = steps[0, k]
        for sgn in range(2):
            xx[k] = x[k] + e if sgn == 0 else x[k] - e
            nc, ni = _contacts_at(m, h, cold_opt, w, xx, nd, nk, qa, va, qka, vka, qk_out, scratch)
            if nc != ncon or ni != nisl:
                code = TANGENT_CONTACTS
            else:
                for j in range(ncon):
                    if w.con_pair[j] != pairs[j]:
                        code = TANGENT_CONTACTS
            if code != DIFF_OK:
                break
            if _smooth_part(m, h, cold_opt, w, vka, nisl, ncon, z, zoff, qa, qk_out, rp if sgn == 0 else rm,
                            fp if sgn == 0 else fm, dv, scratch) != 0:
                code = TANGENT_CONTACTS
                break
        xx[k] = x[k]
        if code != DIFF_OK:
            break
        # one-sided differences of the smooth part, its rows and its outputs each against their own scale
        for part in range(2):
            big = 0.0
            gap = 0.0
            for i in range(N if part == 0 else nout):
                p0 = r0[i] if part == 0 else f0[i]
                pp = rp[i] if part == 0 else fp[i]
                pm = rm[i] if part == 0 else fm[i]
                right, left = (pp - p0) / e, (p0 - pm) / e
                big = max(big, abs(right), abs(left))
                gap = max(gap, abs(right - left))
                if part == 0:
                    dr[i, k] = (pp - pm) / (2.0 * e)
                else:
                    jac[i, k] = (pp - pm) / (2.0 * e)
            if gap > rtol_kink * max(big, floor):
                code = TANGENT_KINK
        if code != DIFF_OK:
            break
    if code != DIFF_OK:
        _restore_memory(msize, mbasic, mmodes, w)
        return code
    # the LCP's part: dz_B = -A_BB^-1 dr_B per island, and its velocity change M^-1 G dz at x's columns
    _contacts_at(m, h, cold_opt, w, x, nd, nk, qa, va, qka, vka, qk_out, scratch)
    dz = np.zeros((N, K))
    for isl in range(nisl):
        o, n = zoff[isl], zoff[isl + 1] - zoff[isl]
        nb = 0
        for i in range(n):
            nb += basic[o + i]
        if nb == 0:
            continue
        idx = np.empty(nb, np.int64)
        c = 0
        for i in range(n):
            if basic[o + i]:
                idx[c] = i
                c += 1
        rhs = np.empty((nb, K))
        for a in range(nb):
            for k in range(K):
                rhs[a, k] = -dr[o + idx[a], k]
        sol = np.linalg.solve(np.ascontiguousarray(lu[o:o + nb, o:o + nb]), rhs)
        for a in range(nb):
            for k in range(K):
                dz[o + idx[a], k] = sol[a, k]
    # a degenerate index holds its basis on both sides only where its w (z, if basic) stays at zero along every
    # input: a sticking contact's unloaded friction ray, w = lambda + t.v = 0 with lambda and t.v both held at 0
    for isl in range(nisl):
        o, n = zoff[isl], zoff[isl + 1] - zoff[isl]
        for k in range(K):
            size = 0.0
            for i in range(o, o + n):
                size = max(size, abs(dr[i, k]), abs(dz[i, k]))
            for i in range(o, o + n):
                if not degenerate[i]:
                    continue
                if basic[i]:
                    rate = dz[i, k]
                else:
                    rate = dr[i, k]
                    for c in range(o, o + n):
                        rate += afull[i, c] * dz[c, k]
                if abs(rate) > DEGENERATE_RTOL * size:
                    return _give_way(msize, mbasic, mmodes, w, TANGENT_DEGENERATE)
    k_sup = support_column_count(m)
    zk = np.empty(N)
    for isl in range(nisl):
        o, n = zoff[isl], zoff[isl + 1] - zoff[isl]
        if n == 0:
            continue
        nci, nsi = island_members(m, w, isl, ncon)
        n, nf = assemble_columns(m, w, vka, nci, nsi, h, False, rp[o:zoff[isl + 1]], np.bool_(True))
        nforce = nci + 2 * nf + k_sup * nsi
        for k in range(K):
            for d in range(nd):
                for c in range(3):
                    dv[d, c] = 0.0
            for i in range(n):
                zk[o + i] = dz[o + i, k]
            apply_impulses(nforce, w.column_slot, w.column_g, zk[o:o + n], m, dv)
            for d in range(nd):
                for c in range(3):
                    jac[3 * d + c, k] += h * dv[d, c]
                    jac[3 * nd + 3 * d + c, k] += dv[d, c]
    # the cold steps at x +- d against the Jacobian's prediction J d
    for sgn in range(2):
        for k in range(K):
            xx[k] = x[k] + steps[1, k] if sgn == 0 else x[k] - steps[1, k]
        st = _step_from_flat(m, xx, nd, nk, h, warm_opt, w, rec, True, fp if sgn == 0 else fm)
        if st != STEP_OK:
            code = DIFF_MOVES
    _restore_memory(msize, mbasic, mmodes, w)
    for i in range(nd):
        for c in range(3):
            q1[i, c] = base[3 * i + c]
            v1[i, c] = base[3 * nd + 3 * i + c]
    for j in range(nk):
        for c in range(3):
            qk1[j, c] = base[6 * nd + 3 * j + c]
    if code != DIFF_OK:
        return code
    worst = 0.0
    size = floor * np.max(np.abs(steps[1]))
    for r in range(nout):
        pred = 0.0
        for k in range(K):
            pred += jac[r, k] * steps[1, k]
        size = max(size, abs(pred))
        worst = max(worst, abs(0.5 * (fp[r] - fm[r]) - pred))
    return DIFF_MOVES if worst > rtol_mixed * size else DIFF_OK
