"""What both Lemke variants (lemke.py's tableau, block_lemke.py's Schur-complement pivoting) share: the status codes,
the certificate every answer is tested by (the natural-map residual of M z + q computed from the original data,
relative to the problem's scale), the solve of a basis's z from the original data, and the ratio test's rule once its
candidates are gathered (`keep_ties`, `lexicographic_pick`: both variants pivot on the same path).

Numba kernels only, no allocation: the work arrays are passed in.
"""

import numpy as np
from numba import njit

STATUS_SOLVED = 0
STATUS_RAY = 1
STATUS_MAX_PIVOTS = 2
STATUS_INVALID = 3
STATUS_INACCURATE = 4
STATUS_NEEDS_SPACE = 5   # the island solvers only: the island's dense problem is larger than the dense buffers

STATUS_NAMES = ("solved", "ray_termination", "max_pivots", "invalid_input", "inaccurate", "needs_space")


@njit(cache=True, inline='always')
def natural_residual(z, w, n):
    """Natural-map residual of (z, w = M z + q) over the first n entries: max_i |min(z_i, w_i)| plus infeasibility
    max(0, -min z) + max(0, -min w). The one definition of the residual every certified answer is tested by."""
    comp = 0.0
    zneg = 0.0
    wneg = 0.0
    for i in range(n):
        m = min(z[i], w[i])
        if abs(m) > comp:
            comp = abs(m)
        if -z[i] > zneg:
            zneg = -z[i]
        if -w[i] > wneg:
            wneg = -w[i]
    return comp + zneg + wneg


@njit(cache=True, _nrt=False)
def lcp_residual(M, q, z, w):
    """`natural_residual` of z, with `w` overwritten by M z + q computed from the ORIGINAL data, never taken from a
    tableau."""
    n = q.shape[0]
    for i in range(n):
        s = q[i]
        for k in range(n):
            s += M[i, k] * z[k]
        w[i] = s
    return natural_residual(z, w, n)


@njit(cache=True, _nrt=False)
def lcp_scale(M, q):
    """max(1, max|M|, max|q|): the scale the residual tolerance is relative to."""
    n = q.shape[0]
    s = 1.0
    for i in range(n):
        if abs(q[i]) > s:
            s = abs(q[i])
        for k in range(n):
            if abs(M[i, k]) > s:
                s = abs(M[i, k])
    return s


@njit(cache=True, inline='always')
def partial_pivot(A, c, m):
    """(r, |A[r, c]|) of the largest |A[r, c]| over rows r = c .. m-1, the first of ties: Gaussian elimination's
    partial pivoting."""
    p = c
    big = abs(A[c, c])
    for r in range(c + 1, m):
        if abs(A[r, c]) > big:
            big = abs(A[r, c])
            p = r
    return p, big


@njit(cache=True, inline='always')
def swap_rows(A, i, j, m):
    """Exchange rows i and j of A[:, :m]."""
    for c in range(m):
        tmp = A[i, c]
        A[i, c] = A[j, c]
        A[j, c] = tmp


@njit(cache=True, _nrt=False)
def lu_solve_inplace(A, b, m, perm):
    """Solve A[:m,:m] x = b[:m] by Gaussian elimination with partial pivoting, in place (x in b).

    Returns False when a pivot is exactly zero (singular basis)."""
    for k in range(m):
        perm[k] = k
    for k in range(m):
        p, big = partial_pivot(A, k, m)
        if big == 0.0:
            return False
        if p != k:
            swap_rows(A, k, p, m)
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
        for i in range(k + 1, m):
            f = A[i, k] / A[k, k]
            if f != 0.0:
                for c in range(k, m):
                    A[i, c] -= f * A[k, c]
                b[i] -= f * b[k]
    for k in range(m - 1, -1, -1):
        s = b[k]
        for c in range(k + 1, m):
            s -= A[k, c] * b[c]
        b[k] = s / A[k, k]
    return True


@njit(cache=True, _nrt=False)
def solve_basic_z(M, q, zb, m, z, lu, rhs, perm):
    """z_i for i in zb[:m] from M[Z, Z] z_Z = -q[Z] (w_i = 0 where z_i is basic), z_i = 0 elsewhere; the ORIGINAL
    data. A tiny negative z_i from round-off is set to 0 (as in lemke_kernel's answer); a real one fails the residual.
    Returns (solvable, most negative z_i before clipping, <= 0)."""
    n = q.shape[0]
    for r in range(m):
        for c in range(m):
            lu[r, c] = M[zb[r], zb[c]]
        rhs[r] = -q[zb[r]]
    if not lu_solve_inplace(lu, rhs, m, perm):
        return False, 0.0
    neg = 0.0
    for i in range(n):
        z[i] = 0.0
    for c in range(m):
        z[zb[c]] = rhs[c] if rhs[c] > 0.0 else 0.0
        neg = min(neg, rhs[c])
    return True, neg


@njit(cache=True, inline='always')
def keep_ties(cand, rate, value, nc, best, ratio_tol, rhs_scale, colmax):
    """The ratio test's first level: keep, in order, the candidates cand[:nc] (each with its rate of decrease rate[a]
    and its value value[a], clipped at 0) whose ratio value / rate is at most the minimum ratio `best` plus the tie
    tolerance, ratio_tol of the larger of best and rhs_scale / colmax (the problem's scale over the entering
    column's largest entry). Returns how many are kept (moved to the front of cand and rate); 0 when nc is 0."""
    if nc == 0:
        return 0
    bound = best + ratio_tol * max(best, rhs_scale / colmax)
    m = 0
    for a in range(nc):
        if value[a] / rate[a] <= bound:
            cand[m] = cand[a]
            rate[m] = rate[a]
            m += 1
    return m


@njit(cache=True, inline='always')
def keep_better(res, res_alt, z, w, z_alt, w_alt, n):
    """Of two answers to one LCP, the one with the smaller residual: (z_alt, w_alt) copied into (z, w) when res_alt <
    res. Returns the kept answer's residual."""
    if res_alt < res:
        for i in range(n):
            z[i] = z_alt[i]
            w[i] = w_alt[i]
        return res_alt
    return res


@njit(cache=True, inline='always')
def lexicographic_pick(L, lrow, cand, rate, nc, n, ratio_tol):
    """The ratio test's tie-break among the tied candidates cand[:nc] (nc >= 2, none the artificial variable): the
    lexicographic minimum of their rows of B^-1 divided by their rates, row a being L[lrow[a], :n]; entries tie
    within ratio_tol of the largest |B^-1 / rate| among them (round-off in an entry of B^-1 is relative to the size of
    its row, which grows over the pivots). Still tied (round-off only): the largest rate, the first of equals.
    Returns the chosen candidate. cand, lrow and rate are compacted as the ties are broken (lrow may be cand itself)."""
    lex_scale = 0.0
    for a in range(nc):
        i = lrow[a]
        for k in range(n):
            v = abs(L[i, k]) / rate[a]
            if v > lex_scale:
                lex_scale = v
    tol = ratio_tol * lex_scale
    for k in range(n):
        best = np.inf
        for a in range(nc):
            ratio = L[lrow[a], k] / rate[a]
            if ratio < best:
                best = ratio
        m = 0
        for a in range(nc):
            if L[lrow[a], k] / rate[a] <= best + tol:
                cand[m] = cand[a]
                lrow[m] = lrow[a]
                rate[m] = rate[a]
                m += 1
        nc = m
        if nc == 1:
            return cand[0]
    pick = 0
    for a in range(1, nc):
        if rate[a] > rate[pick]:
            pick = a
    return cand[pick]
