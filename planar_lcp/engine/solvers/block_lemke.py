"""Lemke's method on the basis's Schur complement: the pivots of `lemke_kernel`, each O(k^2), not O(n^2).

Problem: find z >= 0 with w = M z + q >= 0 and z.w = 0, M (n x n) dense, as `lemke_kernel` (lemke.py) solves it with
covering vector e. Along Lemke's path every basic variable is a w_i or a z_j (or the artificial z0). Write C for the
rows whose w_i is NOT basic (w_i = 0 there) and S for the basic z_j, z0 included (its column is e): then the basic
z solve the k x k system

    K z_S = -q_C,    K = M[C, S],    k = |C| = |S|,

and every basic w_i follows as w_i = q_i + M[i, S] z_S. So a pivot needs K^-1, not the n x n basis inverse the
tableau keeps: this kernel keeps K^-1 explicitly and changes it by one row and/or column per pivot (a bordered
inverse when K grows, its Schur downdate when it shrinks, Sherman-Morrison when a row or a column is replaced), each
O(k^2). The tableau's pivot costs O(n^2) whatever k is; on a large contact island's LCP (n = 4 per contact) k ends
at about half to two thirds of n and Lemke starts from k = 0 (the bin of 40 shapes: about 3x less a pivot).

The path is the tableau's: the same entering variables and the same ratio test (minimum ratio, ties relative to the
problem's scale, the artificial variable first among tied rows, then the lexicographic rule on the rows of B^-1,
built from K^-1 for the tied rows only), so in exact arithmetic it is `lemke_kernel`'s pivot for pivot; round-off
can split a tie differently. Round-off also accumulates in K^-1 and in the basic values over the pivots: each
pivot's direction is checked on its own equations, and past DRIFT_TOL K^-1 and the values are made anew (an island
whose K is then singular to working precision goes to the tableau). The answer is taken from them only if it
already passes, else recomputed from (M, q) for the final basis
(`certificate.solve_basic_z`), and certified by the residual test of `lemke_kernel` (`lcp_residual` within res_tol of
`lcp_scale`). A problem it does not certify goes on to the tableau (lemke.py `solve_island_lemke`).

Numba kernels, no allocation: the caller passes the work struct (engine/layout.py BLOCK_LAYOUT's and LEMKE_LAYOUT's
fields: a step's work or a BlockLemkeWork; `Kinv` and the values of M's compressed columns borrow the tableau's
buffer).
"""

import numpy as np
from numba import njit

from planar_lcp.engine.layout import matrix_view
from planar_lcp.engine.solvers.certificate import (STATUS_INACCURATE, STATUS_INVALID, STATUS_MAX_PIVOTS,
                                                   STATUS_RAY, STATUS_SOLVED, keep_better, keep_ties, lcp_residual,
                                                   lcp_scale, lexicographic_pick, natural_residual, partial_pivot,
                                                   solve_basic_z, swap_rows)


#: K^-1 is made anew (`_refactor`) when a direction's equations are off by more than this, relative to the scale
DRIFT_TOL = 1e-10
#: an elimination pivot of K below this fraction of its largest entry: K is singular to working precision
SINGULAR_TOL = 1e-13


@njit(cache=True, inline='always')
def _column(M, n, i, s):
    """Entry i of column s of [M | e]: s == n is the artificial variable's column."""
    return 1.0 if s == n else M[i, s]


@njit(cache=True, _nrt=False)
def _add_column(col_val, col_row, col_start, s, f, dw):
    """dw += f M[:, s], from M's compressed columns (a contact couples only the contacts sharing a body with it)."""
    for e in range(col_start[s], col_start[s + 1]):
        dw[col_row[e]] += f * col_val[e]


@njit(cache=True, inline='always')
def _add_basic_columns(col_val, col_row, col_start, n, k, cols, zs, out):
    """out += [M | e][:, S] zs: the basic z's columns (z0's is e, all ones) times their values zs[:k]."""
    for c in range(k):
        f = zs[c]
        if f != 0.0:
            s = cols[c]
            if s == n:
                for i in range(n):
                    out[i] += f
            else:
                _add_column(col_val, col_row, col_start, s, f, out)


@njit(cache=True, _nrt=False)
def _direction(M, work, Kinv, col_val, n, k, entering):
    """How the basic variables change when `entering` rises at unit rate (variable codes: z_j is j, w_i is n + 1 + i,
    z0 is n). Writes dz[:k] (the basic z, by position in S: work.block_dz) and dw[i] for every row i (meaningful
    where w_i is basic: work.block_dw). col_val, work.block_col_row, work.block_col_start: M's nonzero entries by
    column (values, rows, each column's first entry)."""
    col_row, col_start, cols, rows = work.block_col_row, work.block_col_start, work.block_cols, work.block_rows
    row_pos, dz, dw = work.block_row_pos, work.block_dz, work.block_dw
    if entering > n:
        # w_p enters: row p leaves the equations, K z_S = -q_C + e_p t
        p = row_pos[entering - n - 1]
        for c in range(k):
            dz[c] = Kinv[c, p]
        for i in range(n):
            dw[i] = 0.0
    else:
        # z_j (or z0) enters: K dz = -M[C, j]
        for c in range(k):
            dz[c] = 0.0
        for r in range(k):
            a = _column(M, n, rows[r], entering)
            if a != 0.0:       # a contact's column is zero outside the contacts sharing a body with it
                for c in range(k):
                    dz[c] -= Kinv[c, r] * a
        for i in range(n):
            dw[i] = 1.0 if entering == n else 0.0
        if entering < n:
            _add_column(col_val, col_row, col_start, entering, 1.0, dw)
    _add_basic_columns(col_val, col_row, col_start, n, k, cols, dz, dw)


@njit(cache=True, _nrt=False)
def _basis_inverse_row(M, n, k, Kinv, cols, rows, cand_code, out):
    """Row of B^-1 (the tableau's columns 0..n-1) of one basic variable: for the basic z at position c it is -Kinv[c, p]
    at column rows[p]; for a basic w_i it is e_i - ([M | e][i, S] K^-1) at those columns (the system is
    I w - M z - e z0 = q, solved through K as in `_direction`)."""
    for t in range(n):
        out[t] = 0.0
    if cand_code < k:
        for p in range(k):
            out[rows[p]] = -Kinv[cand_code, p]
    else:
        i = cand_code - n - 1
        out[i] = 1.0
        for c in range(k):
            v = _column(M, n, i, cols[c])
            if v != 0.0:
                for p in range(k):
                    out[rows[p]] -= v * Kinv[c, p]


@njit(cache=True, _nrt=False)
def _ratio_test(M, work, Kinv, n, k, settings, rhs_scale):
    """The blocking basic variable: -1 none (a ray), c < k the basic z at position c, n + 1 + i the basic w_i.

    lemke._ratio_test's rule on the same numbers (a tableau entry T[i, j] is the basic variable's rate of DEcrease,
    -dz or -dw here): candidates fall faster than piv_tol of the fastest; the smallest ratio value / rate; ties
    within ratio_tol of the problem's scale go to the artificial variable, then are broken lexicographically on the
    rows of B^-1 (built from K^-1 for the tied candidates only, in work.lemke_lu), then by the largest rate. The
    candidates in work.lemke_perm, their rates in work.lemke_rhs, their values in work.lemke_z_refined."""
    cols, row_pos, xz, xw, dz = work.block_cols, work.block_row_pos, work.block_xz, work.block_xw, work.block_dz
    dw, cand, rate, value = work.block_dw, work.lemke_perm, work.lemke_rhs, work.lemke_z_refined
    colmax = 0.0
    for c in range(k):
        colmax = max(colmax, abs(dz[c]))
    for i in range(n):
        if row_pos[i] < 0:
            colmax = max(colmax, abs(dw[i]))
    if colmax == 0.0:
        return -1
    thresh = settings.piv_tol * colmax
    nc = 0
    best = np.inf
    for c in range(k):
        if -dz[c] > thresh:
            cand[nc] = c
            rate[nc] = -dz[c]
            value[nc] = max(xz[c], 0.0)
            best = min(best, value[nc] / -dz[c])
            nc += 1
    for i in range(n):
        if row_pos[i] < 0 and -dw[i] > thresh:
            cand[nc] = n + 1 + i
            rate[nc] = -dw[i]
            value[nc] = max(xw[i], 0.0)
            best = min(best, value[nc] / -dw[i])
            nc += 1
    nc = keep_ties(cand, rate, value, nc, best, settings.ratio_tol, rhs_scale, colmax)
    if nc <= 1:
        return cand[0] if nc == 1 else -1
    for a in range(nc):
        if cand[a] < k and cols[cand[a]] == n:
            return cand[a]
    # lexicographic on the rows of B^-1, as lemke._ratio_test: the tied candidates' rows, made from K^-1
    lex = work.lemke_lu
    lrow = work.lemke_basic
    for a in range(nc):
        _basis_inverse_row(M, n, k, Kinv, cols, work.block_rows, cand[a], lex[a])
        lrow[a] = a
    return lexicographic_pick(lex, lrow, cand, rate, nc, n, settings.ratio_tol)


@njit(cache=True, _nrt=False)
def _drift(n, k, rows, entering, dz, dw):
    """How far the direction misses its equations (K dz = -M[C, j], or e_p for w_p entering), relative to its size."""
    err = 0.0
    big = 1.0
    for c in range(k):
        big = max(big, abs(dz[c]))
    for r in range(k):
        unit = 1.0 if entering > n and rows[r] == entering - n - 1 else 0.0
        err = max(err, abs(dw[rows[r]] - unit))
    return err / big


@njit(cache=True, _nrt=False)
def _refactor(M, q, work, Kinv, col_val, n, k):
    """K^-1 anew from M (Gauss-Jordan with partial pivoting, O(k^3), K's elimination in work.lemke_lu), and the basic
    values from it (work.block_xz, block_xw): the updates' round-off grows with every pivot. Returns False if K is
    singular to working precision (an elimination pivot below SINGULAR_TOL of K's largest entry): the path has taken
    a pivot the updates could not resolve."""
    cols, rows, xz, xw, lu = work.block_cols, work.block_rows, work.block_xz, work.block_xw, work.lemke_lu
    kmax = 0.0
    for r in range(k):
        for c in range(k):
            lu[r, c] = _column(M, n, rows[r], cols[c])
            kmax = max(kmax, abs(lu[r, c]))
            Kinv[r, c] = 1.0 if r == c else 0.0
    # lu is K with its rows permuted as eliminated; Kinv accumulates the same row operations (its rows then index
    # K's columns: the inverse)
    for c in range(k):
        p, big = partial_pivot(lu, c, k)
        if big <= SINGULAR_TOL * kmax:
            return False
        if p != c:
            swap_rows(lu, c, p, k)
            swap_rows(Kinv, c, p, k)
        piv = lu[c, c]
        for t in range(k):
            lu[c, t] /= piv
            Kinv[c, t] /= piv
        for r in range(k):
            if r == c:
                continue
            f = lu[r, c]
            if f != 0.0:
                for t in range(k):
                    lu[r, t] -= f * lu[c, t]
                    Kinv[r, t] -= f * Kinv[c, t]
    for c in range(k):
        s = 0.0
        for r in range(k):
            s -= Kinv[c, r] * q[rows[r]]
        xz[c] = s
    for i in range(n):
        xw[i] = q[i]
    _add_basic_columns(col_val, work.block_col_row, work.block_col_start, n, k, cols, xz, xw)
    return True


@njit(cache=True, _nrt=False)
def _row_times_inverse(M, n, k, Kinv, cols, r, y):
    """y[:k] = [M | e][r, S] K^-1: the row entering K (grown or replaced) times the inverse, over its nonzeros."""
    for t in range(k):
        y[t] = 0.0
    for a in range(k):
        v = _column(M, n, r, cols[a])
        if v != 0.0:
            for t in range(k):
                y[t] += v * Kinv[a, t]


@njit(cache=True, _nrt=False)
def _remove_position(Kinv, k, cols, rows, col_pos, row_pos, xz, n, c, p):
    """Drop column position c and row position p of K (row c and column p of K^-1), moving the last into them."""
    last = k - 1
    if c != last:
        for t in range(k):
            Kinv[c, t] = Kinv[last, t]
        cols[c] = cols[last]
        xz[c] = xz[last]
        if cols[c] < n:
            col_pos[cols[c]] = c
    if p != last:
        for t in range(k):
            Kinv[t, p] = Kinv[t, last]
        rows[p] = rows[last]
        row_pos[rows[p]] = p


@njit(cache=True, _nrt=False)
def block_lemke(M, q, settings, work):
    """Solve the LCP (M, q) by Lemke's method (covering vector e) on the Schur complement of its basis.

    M : (n, n), q : (n,) -- not modified. settings : LemkeSettings (engine/layout.py; equilibrate is not read).
    work : a struct with LEMKE_LAYOUT's and BLOCK_LAYOUT's fields for problems of at least n unknowns (a step's work
    struct, or `lemke_work_struct(make_lemke_work(n, block=True))`): K^-1 is the first n * n entries of
    work.lemke_tableau (row-major), the values of M's compressed columns the next n * n. The answer is work.lemke_z,
    with work.lemke_w = M z + q.
    Returns (status, pivots, residual) with lemke_kernel's meaning: STATUS_SOLVED only when certified.
    """
    n = q.shape[0]
    if n == 0:
        return STATUS_SOLVED, 0, 0.0
    Kinv = matrix_view(work.lemke_tableau, n, n)
    col_val = work.lemke_tableau[n * n:2 * n * n]
    col_row, col_start, cols, rows = work.block_col_row, work.block_col_start, work.block_cols, work.block_rows
    col_pos, row_pos, xz, xw, dz = work.block_col_pos, work.block_row_pos, work.block_xz, work.block_xw, work.block_dz
    dw, y, z, w, res_tol = work.block_dw, work.block_y, work.lemke_z, work.lemke_w, settings.res_tol
    for i in range(n):
        if not np.isfinite(q[i]):
            return STATUS_INVALID, 0, np.inf
    # M's compressed columns, its finiteness checked on the same pass
    nnz = 0
    for j in range(n):
        col_start[j] = nnz
        for i in range(n):
            if not np.isfinite(M[i, j]):
                return STATUS_INVALID, 0, np.inf
            if M[i, j] != 0.0:
                col_val[nnz] = M[i, j]
                col_row[nnz] = i
                nnz += 1
    col_start[n] = nnz
    scale = lcp_scale(M, q)
    rhs_scale = 0.0
    r = -1
    qmin = 0.0
    for i in range(n):
        rhs_scale = max(rhs_scale, abs(q[i]))
        if q[i] <= qmin and q[i] < 0.0:   # ties: the last index, as lemke_kernel
            qmin = q[i]
            r = i
        z[i] = 0.0
        col_pos[i] = -1
        row_pos[i] = -1
        xw[i] = q[i]
    if r < 0:
        return STATUS_SOLVED, 0, lcp_residual(M, q, z, w)
    # z0 enters at -q_r: every w_i rises by it, w_r is the one at zero and leaves (K = [1])
    t = -q[r]
    for i in range(n):
        xw[i] += t
    k = np.int64(1)                     # not a literal: numba would compile the helpers for Literal[int](1) too
    cols[0] = n
    rows[0] = r
    row_pos[r] = 0
    Kinv[0, 0] = 1.0
    xz[0] = t
    leaving = n + 1 + r
    pivots = 1
    status = STATUS_MAX_PIVOTS
    while pivots < settings.max_pivots:
        # the complement of the variable that just left enters
        entering = leaving - n - 1 if leaving > n else n + 1 + leaving
        _direction(M, work, Kinv, col_val, n, k, entering)
        # dw is computed on every row: where w_i = 0 stays an equation (the rows C) it must vanish, and what is left
        # there is the updated K^-1's error. Past DRIFT_TOL of the scale, K^-1 and the values are made anew.
        if _drift(n, k, rows, entering, dz, dw) > DRIFT_TOL * scale:
            if not _refactor(M, q, work, Kinv, col_val, n, k):
                status = STATUS_INACCURATE
                break
            _direction(M, work, Kinv, col_val, n, k, entering)
            if _drift(n, k, rows, entering, dz, dw) > DRIFT_TOL * scale:
                status = STATUS_INACCURATE      # ill-conditioned even when made anew: leave it to the tableau
                break
        blk = _ratio_test(M, work, Kinv, n, k, settings, rhs_scale)
        if blk < 0:
            status = STATUS_RAY
            break
        if blk < k:
            t = max(xz[blk], 0.0) / -dz[blk]
        else:
            t = max(xw[blk - n - 1], 0.0) / -dw[blk - n - 1]
        for c in range(k):
            xz[c] += t * dz[c]
        for i in range(n):
            if row_pos[i] < 0:
                xw[i] += t * dw[i]
        if entering <= n:
            j = entering
            if blk < k:
                # z_j replaces z_s in column position c: Sherman-Morrison, K^-1 a = -dz, pivot -dz_c
                c = blk
                s = cols[c]
                piv = -dz[c]
                for t2 in range(k):
                    y[t2] = Kinv[c, t2] / piv
                for a in range(k):
                    f = -dz[a] - (1.0 if a == c else 0.0)
                    if f != 0.0:
                        for t2 in range(k):
                            Kinv[a, t2] -= f * y[t2]
                leaving = s
                if s < n:
                    col_pos[s] = -1
                cols[c] = j
                xz[c] = t
                if j < n:
                    col_pos[j] = c
            else:
                # w_r leaves: K grows by row r and column j; Schur complement s = dw_r
                rr = blk - n - 1
                sc = dw[rr]
                _row_times_inverse(M, n, k, Kinv, cols, rr, y)
                for a in range(k):
                    f = -dz[a] / sc
                    if f != 0.0:
                        for t2 in range(k):
                            Kinv[a, t2] += f * y[t2]
                    Kinv[a, k] = dz[a] / sc
                for t2 in range(k):
                    Kinv[k, t2] = -y[t2] / sc
                Kinv[k, k] = 1.0 / sc
                cols[k] = j
                xz[k] = t
                if j < n:
                    col_pos[j] = k
                rows[k] = rr
                row_pos[rr] = k
                k += 1
                leaving = n + 1 + rr
        else:
            jr = entering - n - 1          # w_jr enters: row position p leaves the equations
            p = row_pos[jr]
            if blk < k:
                # z_s leaves: K shrinks by row p and column c (Schur downdate of K^-1 on its pivot Kinv[c, p])
                c = blk
                s = cols[c]
                piv = Kinv[c, p]
                for a in range(k):
                    if a == c:
                        continue
                    f = Kinv[a, p] / piv
                    if f != 0.0:
                        for t2 in range(k):
                            Kinv[a, t2] -= f * Kinv[c, t2]
                row_pos[jr] = -1
                if s < n:
                    col_pos[s] = -1
                _remove_position(Kinv, k, cols, rows, col_pos, row_pos, xz, n, c, p)
                k -= 1
                leaving = s
            else:
                # w_r leaves, w_jr enters: row p of K replaced by row r; K^-1 e_p = dz, pivot dw_r
                rr = blk - n - 1
                sc = dw[rr]
                _row_times_inverse(M, n, k, Kinv, cols, rr, y)
                y[p] -= 1.0
                for a in range(k):
                    f = dz[a] / sc
                    if f != 0.0:
                        for t2 in range(k):
                            Kinv[a, t2] -= f * y[t2]
                row_pos[jr] = -1
                rows[p] = rr
                row_pos[rr] = p
                leaving = n + 1 + rr
            xw[jr] = t
        pivots += 1
        if leaving == n:
            status = STATUS_SOLVED
            break
        # the artificial variable at zero while still basic: the basic z may already solve the LCP (lemke_kernel)
        c0 = -1
        for c in range(k):
            if cols[c] == n:
                c0 = c
        if c0 >= 0 and xz[c0] <= res_tol * scale:
            if _certify(M, q, work, Kinv, col_val, k, res_tol, scale) <= res_tol * scale:
                status = STATUS_SOLVED
                break
    res = _certify(M, q, work, Kinv, col_val, k, res_tol, scale)
    if res <= res_tol * scale:
        return STATUS_SOLVED, pivots, res
    if status == STATUS_SOLVED:
        return STATUS_INACCURATE, pivots, res
    return status, pivots, res


@njit(cache=True, _nrt=False)
def _residual_csc(col_val, col_row, col_start, q, z, w):
    """`lcp_residual` (lemke.py) from M's compressed columns: the same sums in the same order, the zero terms
    left out (w = M z + q summed over the columns j with z_j != 0, in increasing j), so the same value in O(nnz)."""
    n = q.shape[0]
    for i in range(n):
        w[i] = q[i]
    for j in range(n):
        if z[j] != 0.0:
            f = z[j]
            for a in range(col_start[j], col_start[j + 1]):
                w[col_row[a]] += col_val[a] * f
    return natural_residual(z, w, n)


@njit(cache=True, _nrt=False)
def _complementary_negativity(q, k, Kinv, cols, rows, col_pos):
    """With the artificial variable still basic, the most negative z of the complementary system M[Z, Z] z_Z =
    -q[Z] over the basic z (what `_certify` would recompute), from K^-1 in O(k^2); 0 when the artificial variable is
    not basic, inf when that system is singular.

    M[Z, Z] is K without the artificial variable's column c0 and without the row p of the one index whose z and w
    are both nonbasic: M[Z, Z]^-1 = Kinv' - Kinv[:, p] Kinv[c0, :] / Kinv[c0, p] (Kinv' without row c0 and column p;
    the Schur downdate of a shrinking pivot)."""
    n = q.shape[0]
    c0 = -1
    for c in range(k):
        if cols[c] == n:
            c0 = c
    p = -1
    for a in range(k):
        if col_pos[rows[a]] < 0:
            p = a
    if c0 < 0 or p < 0:
        return 0.0
    piv = Kinv[c0, p]
    if piv == 0.0:
        return np.inf
    # t = Kinv[c0, :] q', q' = -q over the rows but p
    t = 0.0
    for a in range(k):
        if a != p:
            t -= Kinv[c0, a] * q[rows[a]]
    neg = 0.0
    for c in range(k):
        if c == c0:
            continue
        s = 0.0
        for a in range(k):
            if a != p:
                s -= Kinv[c, a] * q[rows[a]]
        s -= Kinv[c, p] * t / piv
        neg = max(neg, -s)
    return neg


@njit(cache=True, _nrt=False)
def _certify(M, q, work, Kinv, col_val, k, res_tol, scale):
    """The answer at the current basis: the basic z as the pivots left them, or, unless that is already well inside
    the tolerance, recomputed from (M, q) (M[Z, Z] z_Z = -q[Z] over the basic z); the better one in work.lemke_z,
    work.lemke_w = M z + q. Returns its residual (`lcp_residual`'s value, summed over M's compressed columns).

    With the artificial variable still basic the recomputation, an O(k^3) factorization, is tried only if the
    answer it would give, predicted from K^-1 in O(k^2), could be the better one: its most negative z no more than
    twice the residual in hand (M[Z, Z] not singular). A statically indeterminate pile (the settled bin) checks its
    answer about ten times a solve with the artificial variable basic and below the tolerance; the recomputation
    never gave the answer there (M[Z, Z] singular, or its answer negative) and was 40 % of the solve. A skip that
    was wrong costs a few more pivots or the tableau, never a wrong answer: what is returned is certified."""
    n = q.shape[0]
    cols, rows, col_pos, col_row = work.block_cols, work.block_rows, work.block_col_pos, work.block_col_row
    col_start, xz, z, w, zb = work.block_col_start, work.block_xz, work.lemke_z, work.lemke_w, work.lemke_basic
    zalt, walt = work.lemke_z_refined, work.lemke_w_refined
    for i in range(n):
        z[i] = 0.0
    m = np.int64(0)                     # not a literal: numba would compile solve_basic_z for Literal[int](0) too
    for c in range(k):
        if cols[c] < n:
            z[cols[c]] = max(xz[c], 0.0)
            zb[m] = cols[c]
            m += 1
    res = _residual_csc(col_val, col_row, col_start, q, z, w)
    if res > 1e-3 * res_tol * scale and _complementary_negativity(q, k, Kinv, cols, rows, col_pos) <= 2.0 * res:
        ok, neg = solve_basic_z(M, q, zb, m, zalt, work.lemke_lu, work.lemke_rhs, work.lemke_perm)
        if ok:
            res_alt = max(_residual_csc(col_val, col_row, col_start, q, zalt, walt), -neg)
            res = keep_better(res, res_alt, z, w, zalt, walt, n)
    return res
