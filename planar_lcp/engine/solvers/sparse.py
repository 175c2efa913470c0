"""Large islands: the island's contact LCP solved through its sparse reduced system, by iterating on contact modes.

A contact couples only the bodies it touches, so the LCP's matrix G^T M^-1 G has a block between two contacts only
when they share a body. Given a mode for every contact -- separated, sticking, sliding along +t or -t -- the LCP's
complementarity fixes which of each pair (z_i, w_i) is zero, and what is left is one linear system over the loaded
contacts' impulses (the reduced system, below). Its matrix has the contact graph's pattern: ordered breadth-first over
the island's bodies (Cuthill-McKee), a tower's is a band of width ~8 whatever its height.

    mode         unknowns        equations                 consistent when
    separated    -               -                         n.v+ >= 0
    sticking     c_n, f_t        n.v+ = 0, t.v+ = 0        c_n >= 0, |f_t| <= mu c_n
    sliding +-   c_n (f_t = +-mu c_n)  n.v+ = 0            c_n >= 0, t.v+ on the side opposite the friction

(n.v+ and t.v+ stand for the LCP's normal and friction rows, constants included.) The iteration (block principal
pivoting on modes, Kostreva; Judice & Pires 1994) starts from a guess (the memory below, else the free motion's: a
contact it would close is sticking, the others separated), solves, and switches every contact whose answer is
inconsistent; it stops when the answer passes the certificate, or when no contact switches, or after
SPARSE_ITERATIONS.

The memory: a certified answer's modes are kept per shape pair (w.sparse_pair_mode) and are the next solve's first
guess for the same pairs' contacts, so a pile at rest is solved in one iteration whatever its mode iteration took
the first time. It is forgotten where the dense warm start's bases are (a rollout from scratch, a `step` from a
state that is not the last one's output), so a result depends on the run's inputs only.

Statically indeterminate islands (a box on two boxes, the two corners of one face) make the reduced matrix
singular: the impulses are not unique, the motion is. The factorization is regularized (SPARSE_REGULARIZATION of
the diagonal) and iterative refinement against the unregularized matrix converges to an exact solution of the
consistent system; the iteration then switches unloaded redundant contacts to separated. None of this is trusted:

Every answer is certified by the SAME test as dense Lemke's (`lemke.lcp_residual` <= res_tol * `lemke.lcp_scale`),
evaluated on the LCP as assembled -- its w = M z + q from the force columns (M z = G^T M^-1 G z plus the identity
and mu entries), its scale once per island (`_lcp_scale`). An island it does not certify goes to the dense chain
(engine/solvers/lemke.py) unchanged; `Stat.SOLVED_SPARSE` and `Stat.SPARSE_FALLBACKS` count both outcomes.
"""

import numpy as np
from numba import njit

from planar_lcp.engine.assemble import apply_impulses, assemble_columns, column_dot
from planar_lcp.engine.constants import SPARSE_MAX_BAND

SPARSE_SEP, SPARSE_STICK, SPARSE_SLIDE_POS, SPARSE_SLIDE_NEG = 0, 1, 2, 3
#: most mode iterations (each one factorization of the reduced system)
SPARSE_ITERATIONS = 30
#: the diagonal regularization of the factorization, relative to each diagonal entry (refinement removes it)
SPARSE_REGULARIZATION = 1e-12
#: most refinement passes per solve
SPARSE_REFINE = 8


@njit(cache=True, _nrt=False)
def _band_order(m, w, nci):
    """The island's contacts in band order (w.sparse_order[:nci]) and each body's contact lists.

    Bodies are ranked breadth-first from one of least degree (Cuthill-McKee), each contact keyed by the lower rank
    of its dynamic bodies, the contacts sorted by key (stable). Contact-to-body lists: w.sparse_body_start (CSR over
    dynamic slots) and w.sparse_body_con."""
    ndyn = w.sparse_rank.shape[0]
    start = w.sparse_body_start
    for d in range(ndyn + 1):
        start[d] = 0
    for a in range(nci):
        for s in range(2):
            d = w.column_slot[a, s]
            if d >= 0:
                start[d + 1] += 1
    for d in range(ndyn):
        start[d + 1] += start[d]
    cur = w.sparse_cursor
    for d in range(ndyn):
        cur[d] = start[d]
        w.sparse_rank[d] = -1
    for a in range(nci):
        for s in range(2):
            d = w.column_slot[a, s]
            if d >= 0:
                w.sparse_body_con[cur[d]] = a
                cur[d] += 1
    # breadth-first ranks, from a body of least degree (each connected part of the contact graph in turn)
    rank = 0
    while True:
        root = -1
        best = 1 << 60
        for d in range(ndyn):
            deg = start[d + 1] - start[d]
            if w.sparse_rank[d] < 0 and deg > 0 and deg < best:
                best = deg
                root = d
        if root < 0:
            break
        head = 0
        tail = 0
        w.sparse_queue[tail] = root
        tail += 1
        w.sparse_rank[root] = rank
        rank += 1
        while head < tail:
            d = w.sparse_queue[head]
            head += 1
            for e in range(start[d], start[d + 1]):
                a = w.sparse_body_con[e]
                for s in range(2):
                    o = w.column_slot[a, s]
                    if o >= 0 and w.sparse_rank[o] < 0:
                        w.sparse_rank[o] = rank
                        rank += 1
                        w.sparse_queue[tail] = o
                        tail += 1
    # contacts by key, stable
    for a in range(nci):
        key = 1 << 60
        for s in range(2):
            d = w.column_slot[a, s]
            if d >= 0 and w.sparse_rank[d] < key:
                key = w.sparse_rank[d]
        w.sparse_key[a] = key
    for a in range(nci):
        w.sparse_order[a] = a
    _stable_sort_by_key(w.sparse_order, w.sparse_key, nci, w.sparse_unknown)


@njit(cache=True, _nrt=False)
def _stable_sort_by_key(order, key, n, tmp):
    """Sort order[:n] by key[order[i]], stable (bottom-up merge sort; tmp: (>= n,) int64 work)."""
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i, j, k = lo, mid, lo
            while i < mid and j < hi:
                if key[order[j]] < key[order[i]]:
                    tmp[k] = order[j]
                    j += 1
                else:
                    tmp[k] = order[i]
                    i += 1
                k += 1
            while i < mid:
                tmp[k] = order[i]
                i += 1
                k += 1
            while j < hi:
                tmp[k] = order[j]
                j += 1
                k += 1
        for i in range(n):
            order[i] = tmp[i]
        width *= 2


@njit(cache=True, inline='always')
def _unknowns_of(mode, fric, a):
    """Reduced unknowns of contact a: c_n and f_t sticking with friction, c_n alone loaded otherwise (0 if
    separated: not asked)."""
    return 2 if (mode[a] == SPARSE_STICK and fric[a] >= 0) else 1


@njit(cache=True, _nrt=False)
def _number_unknowns(m, w, nci):
    """Reduced unknowns of the current modes in band order; returns (count, half-bandwidth)."""
    p = 0
    for i in range(nci):
        a = w.sparse_order[i]
        md = w.sparse_mode[a]
        if md == SPARSE_SEP:
            w.sparse_unknown[a] = -1
            continue
        w.sparse_unknown[a] = p
        p += _unknowns_of(w.sparse_mode, w.sparse_fric, a)
    ndyn = w.sparse_rank.shape[0]
    bw = 0
    for d in range(ndyn):
        lo = 1 << 60
        hi = -1
        for e in range(w.sparse_body_start[d], w.sparse_body_start[d + 1]):
            a = w.sparse_body_con[e]
            u = w.sparse_unknown[a]
            if u < 0:
                continue
            last = u + _unknowns_of(w.sparse_mode, w.sparse_fric, a) - 1
            lo = min(lo, u)
            hi = max(hi, last)
        if hi >= 0:
            bw = max(bw, hi - lo)
    return p, bw


@njit(cache=True, inline='always')
def _body_contact(bcon, unk, slot, mode, fric, nci, d, e):
    """Entry e of body d's island contacts (bcon: w.sparse_body_con): the contact a, its first reduced unknown (-1:
    separated), the side (0 or 1) of its columns that is body d's, its number of reduced unknowns and the index of
    its +t friction column."""
    a = bcon[e]
    return a, unk[a], 0 if slot[a, 0] == d else 1, _unknowns_of(mode, fric, a), nci + 2 * fric[a]


@njit(cache=True, _nrt=False)
def _build_band(m, w, nci, p, bw):
    """W = R^T M^-1 C of the current modes, band storage (row i, column j at i * (2 bw + 1) + j - i + bw), and the
    right-hand side -(row constants). A reduced unknown's row vector is its normal column (kind 0) or its +t
    friction column (kind 1); its column vector the same, plus or minus mu times the +t column for a sliding
    contact's normal unknown. (Struct fields are read into locals once: each field access in a loop costs a
    reference count.)"""
    ld = 2 * bw + 1
    W = w.sparse_band
    for i in range(p * ld):
        W[i] = 0.0
    g, slot, fric, mode, unk = w.column_g, w.column_slot, w.sparse_fric, w.sparse_mode, w.sparse_unknown
    start, bcon, mu_c, pair_mu, con_pair = w.sparse_body_start, w.sparse_body_con, w.sparse_mu, m.pair_mu, w.con_pair
    isl = w.island_con
    for a in range(nci):
        md = mode[a]
        mu = pair_mu[con_pair[isl[a]]]
        mu_c[a] = mu if md == SPARSE_SLIDE_POS else (-mu if md == SPARSE_SLIDE_NEG else 0.0)
    ndyn = w.sparse_rank.shape[0]
    inv_mass = m.dyn_inv_mass
    inertia = m.dyn_inertia
    for d in range(ndyn):
        im = inv_mass[d]
        J = inertia[d]
        for e in range(start[d], start[d + 1]):
            a, ua, sa, na, ta = _body_contact(bcon, unk, slot, mode, fric, nci, d, e)
            if ua < 0:
                continue
            for e2 in range(start[d], start[d + 1]):
                b, ub, sb, nb, tb = _body_contact(bcon, unk, slot, mode, fric, nci, d, e2)
                if ub < 0:
                    continue
                for ka in range(na):
                    ra = a if ka == 0 else ta
                    r0 = g[ra, sa, 0]
                    r1 = g[ra, sa, 1]
                    r2 = g[ra, sa, 2]
                    i = ua + ka
                    for kb in range(nb):
                        if kb == 0:
                            c0 = g[b, sb, 0]
                            c1 = g[b, sb, 1]
                            c2 = g[b, sb, 2]
                            mc = mu_c[b]
                            if mc != 0.0:
                                c0 += mc * g[tb, sb, 0]
                                c1 += mc * g[tb, sb, 1]
                                c2 += mc * g[tb, sb, 2]
                        else:
                            c0 = g[tb, sb, 0]
                            c1 = g[tb, sb, 1]
                            c2 = g[tb, sb, 2]
                        j = ub + kb
                        W[i * ld + j - i + bw] += (r0 * c0 + r1 * c1) * im + r2 * c2 / J
    rhs, b_lcp, order = w.sparse_rhs, w.lcp_vector, w.sparse_order
    for i in range(nci):
        a = order[i]
        u = unk[a]
        if u < 0:
            continue
        rhs[u] = -b_lcp[a]
        if mode[a] == SPARSE_STICK and fric[a] >= 0:
            rhs[u + 1] = -b_lcp[nci + 2 * fric[a]]


@njit(cache=True, _nrt=False)
def _factor_band(w, p, bw):
    """LU without pivoting of W + SPARSE_REGULARIZATION diag|W| in band storage (w.sparse_lu); the band is kept
    (no pivoting, so no fill outside it). Returns False on a zero pivot."""
    ld = 2 * bw + 1
    W = w.sparse_band
    L = w.sparse_lu
    for i in range(p * ld):
        L[i] = W[i]
    for i in range(p):
        dii = abs(W[i * ld + bw])
        L[i * ld + bw] += SPARSE_REGULARIZATION * dii if dii > 0.0 else SPARSE_REGULARIZATION
    for k in range(p):
        piv = L[k * ld + bw]
        if piv == 0.0 or not np.isfinite(piv):
            return False
        top = min(p, k + bw + 1)
        for i in range(k + 1, top):
            f = L[i * ld + k - i + bw]
            if f == 0.0:
                continue
            f = f / piv
            L[i * ld + k - i + bw] = f
            for j in range(k + 1, top):
                L[i * ld + j - i + bw] -= f * L[k * ld + j - k + bw]
    return True


@njit(cache=True, _nrt=False)
def _solve_band(w, p, bw, x):
    """x <- (LU)^-1 x with the factors of `_factor_band`."""
    ld = 2 * bw + 1
    L = w.sparse_lu
    for i in range(p):
        s = x[i]
        for k in range(max(0, i - bw), i):
            s -= L[i * ld + k - i + bw] * x[k]
        x[i] = s
    for i in range(p - 1, -1, -1):
        s = x[i]
        for j in range(i + 1, min(p, i + bw + 1)):
            s -= L[i * ld + j - i + bw] * x[j]
        x[i] = s / L[i * ld + bw]


@njit(cache=True, _nrt=False)
def _solve_reduced(w, p, bw):
    """x solving W x = rhs: the regularized factors' answer refined against W itself (iterative refinement, which
    also converges on a singular consistent W). Returns False if the factorization failed, x is not finite or the
    refinement did not converge: an inconsistent system (the modes ask for motions the contacts cannot all have, as
    in a falling pile's impacts), from which the iteration does not recover (measured on bins)."""
    if not _factor_band(w, p, bw):
        return False
    ld = 2 * bw + 1
    W, x, r, rhs = w.sparse_band, w.sparse_x, w.sparse_r, w.sparse_rhs
    rmax = 0.0
    for i in range(p):
        x[i] = 0.0
        rmax = max(rmax, abs(rhs[i]))
    big = rmax
    for _ in range(SPARSE_REFINE):
        big = 0.0
        for i in range(p):
            s = rhs[i]
            for j in range(max(0, i - bw), min(p, i + bw + 1)):
                s -= W[i * ld + j - i + bw] * x[j]
            r[i] = s
            big = max(big, abs(s))
        if big <= 1e-16 * rmax:
            break
        _solve_band(w, p, bw, r)
        for i in range(p):
            x[i] += r[i]
    if not big <= 1e-9 * rmax:
        return False
    for i in range(p):
        if not np.isfinite(x[i]):
            return False
    return True


@njit(cache=True, _nrt=False)
def _lcp_scale(m, w, nci, n, nf):
    """`lemke.lcp_scale` of the LCP as assembled, without its matrix: 1, |q|, mu and the Delassus diagonal (the
    largest entry of a positive semidefinite matrix lies on its diagonal)."""
    b = w.lcp_vector
    scale = 1.0
    for i in range(n):
        scale = max(scale, abs(b[i]))
    for u in range(nci + 2 * nf):
        s = 0.0
        for side in range(2):
            d = w.column_slot[u, side]
            if d >= 0:
                g = w.column_g[u, side]
                s += (g[0] * g[0] + g[1] * g[1]) * m.dyn_inv_mass[d] + g[2] * g[2] / m.dyn_inertia[d]
        scale = max(scale, s)
    for a in range(nci):
        if w.sparse_fric[a] >= 0:
            scale = max(scale, m.pair_mu[w.con_pair[w.island_con[a]]])
    return scale


@njit(cache=True, _nrt=False)
def _answer(m, w, nci, n, nf):
    """The LCP's z and w = M z + q (w.lemke_z, w.lemke_w) of the current modes' reduced solution, each contact's
    tangential velocity w.sparse_vt; returns `lemke.lcp_residual` of it on the LCP as assembled (its matrix never
    formed: module docstring)."""
    z = w.lemke_z
    wv = w.lemke_w
    o_lc = nci + 2 * nf
    for i in range(n):
        z[i] = 0.0
    for a in range(nci):
        u = w.sparse_unknown[a]
        if u < 0:
            continue
        cn = w.sparse_x[u]
        z[a] = cn
        f = w.sparse_fric[a]
        if f < 0:
            continue
        md = w.sparse_mode[a]
        up = nci + 2 * f
        if md == SPARSE_STICK:
            ft = w.sparse_x[u + 1]
            z[up] = ft if ft > 0.0 else 0.0
            z[up + 1] = -ft if ft < 0.0 else 0.0
        elif md == SPARSE_SLIDE_POS:
            z[up] = m.pair_mu[w.con_pair[w.island_con[a]]] * cn
        else:
            z[up + 1] = m.pair_mu[w.con_pair[w.island_con[a]]] * cn
    dv = w.sparse_dv
    for d in range(dv.shape[0]):
        for c in range(3):
            dv[d, c] = 0.0
    apply_impulses(o_lc, w.column_slot, w.column_g, z, m, dv)
    b = w.lcp_vector
    for u in range(o_lc):
        wv[u] = b[u] + column_dot(w.column_slot, w.column_g, u, dv)
    for a in range(nci):
        f = w.sparse_fric[a]
        if f < 0:
            continue
        mu = m.pair_mu[w.con_pair[w.island_con[a]]]
        up = nci + 2 * f
        vt = wv[up]
        w.sparse_vt[a] = vt
        md = w.sparse_mode[a]
        if md == SPARSE_SLIDE_POS:
            lam = -vt                      # w_+ = t.v+ + lambda = 0
        elif md == SPARSE_SLIDE_NEG:
            lam = vt                       # w_- = -t.v+ + lambda = 0
        elif md == SPARSE_SEP:
            lam = abs(vt)                  # unloaded: the smaller friction row at 0
        else:
            lam = 0.0
        if lam < 0.0:
            lam = 0.0
        z[o_lc + f] = lam
        wv[up] += lam
        wv[up + 1] += lam
        wv[o_lc + f] = mu * z[a] - z[up] - z[up + 1]
    comp, zneg, wneg = 0.0, 0.0, 0.0
    for i in range(n):
        mn = min(z[i], wv[i])
        comp = max(comp, abs(mn))
        zneg = max(zneg, -z[i])
        wneg = max(wneg, -wv[i])
    return comp + zneg + wneg


@njit(cache=True, _nrt=False)
def _switch_modes(m, w, nci, tol):
    """Switch every contact whose answer is inconsistent with its mode (module docstring); returns how many."""
    changed = 0
    for a in range(nci):
        md = w.sparse_mode[a]
        u = w.sparse_unknown[a]
        f = w.sparse_fric[a]
        new = md
        if md == SPARSE_SEP:
            if w.lemke_w[a] < -tol:
                new = SPARSE_STICK
        elif w.lemke_z[a] < 0.0:
            new = SPARSE_SEP
        elif f >= 0:
            mu = m.pair_mu[w.con_pair[w.island_con[a]]]
            vt = w.sparse_vt[a]
            if md == SPARSE_STICK:
                ft = w.sparse_x[u + 1]
                if abs(ft) > mu * w.lemke_z[a]:
                    new = SPARSE_SLIDE_POS if ft > 0.0 else SPARSE_SLIDE_NEG
            elif md == SPARSE_SLIDE_POS:
                if vt > tol:
                    new = SPARSE_STICK
            elif vt < -tol:
                new = SPARSE_STICK
        if new != md:
            w.sparse_mode[a] = new
            changed += 1
    return changed


@njit(cache=True, inline='always')
def _pair_place(w, a):
    """(pair, place) of island contact a: a pair's contacts are consecutive in the active set (engine/contacts.py
    `find_contacts`), the place 0 or 1 in that order. A guess's key only: if a pair's two contacts trade places
    between steps, the guess is wrong and the iteration corrects it."""
    c = w.island_con[a]
    p = w.con_pair[c]
    return p, (1 if c > 0 and w.con_pair[c - 1] == p else 0)


@njit(cache=True, _nrt=False)
def solve_island_sparse(m, w, opt, vk, nci, nsi, h, velocity_form):
    """The island's LCP (its rows as the formulation assembles them, restitution's included) by the mode iteration on
    its reduced system. The LCP's constants and force columns are assembled here (`assemble_columns`), never its
    matrix. Returns (certified, iterations, residual); when certified, w.lemke_z holds the answer in the LCP's
    layout (engine/assemble.py), w.lemke_w its w. Islands with table friction (nsi > 0) are not handled."""
    if nsi > 0:
        return False, 0, np.inf
    n, nf = assemble_columns(m, w, vk, nci, nsi, h, velocity_form, w.lcp_vector, np.bool_(True))  # as assemble_lcp
    f = 0
    for a in range(nci):
        if m.pair_mu[w.con_pair[w.island_con[a]]] > 0.0:
            w.sparse_fric[a] = f
            f += 1
        else:
            w.sparse_fric[a] = -1
    _band_order(m, w, nci)
    # the first guess: the contact's mode in the last sparse answer (w.sparse_pair_mode, by pair and its contact's
    # place in the pair), else the free motion's (a contact it closes, or keeps closed, is loaded)
    scale0 = 1.0
    for i in range(n):
        scale0 = max(scale0, abs(w.lcp_vector[i]))
    for a in range(nci):
        p, k = _pair_place(w, a)
        md = w.sparse_pair_mode[p, k]
        if md < 0:
            md = SPARSE_STICK if w.lcp_vector[a] <= opt.res_tol * scale0 else SPARSE_SEP
        w.sparse_mode[a] = md
    res = np.inf
    scale = _lcp_scale(m, w, nci, n, nf)
    cap = w.sparse_rhs.shape[0]
    for it in range(SPARSE_ITERATIONS):
        p, bw = _number_unknowns(m, w, nci)
        if p > cap or bw > SPARSE_MAX_BAND:
            return False, it, res
        if p > 0:
            _build_band(m, w, nci, p, bw)
            if not _solve_reduced(w, p, bw):
                return False, it + 1, res
        res = _answer(m, w, nci, n, nf)
        if res <= opt.res_tol * scale:
            for a in range(nci):
                p, k = _pair_place(w, a)
                w.sparse_pair_mode[p, k] = w.sparse_mode[a]
            return True, it + 1, res
        if _switch_modes(m, w, nci, 1e-3 * opt.res_tol * scale) == 0:
            return False, it + 1, res
    return False, SPARSE_ITERATIONS, res
