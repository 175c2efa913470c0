"""Lemke's complementary pivoting algorithm on an explicit tableau, with lexicographic degeneracy resolution.

Numba kernels only: no exceptions, no allocation inside `lemke_kernel` (its work arrays are passed in as one struct,
engine/layout.py LEMKE_LAYOUT, so the time-stepper can reuse them: its step work holds the same fields), the pivot
cap and tolerances as one LemkeSettings value. `planar_lcp.lcp.lemke` is the validating public wrapper.

Problem: find z >= 0 with w = M z + q >= 0 and z.w = 0.

Tableau (n rows, 2n + 2 columns), the system  I w - M z - e z0 = q  premultiplied by the basis inverse:

    columns 0 .. n-1     w_0 .. w_{n-1}   (initially I, so these columns always hold B^-1)
    columns n .. 2n-1    z_0 .. z_{n-1}   (initially -M)
    column  2n           z0, the artificial variable, covering vector e = (1, ..., 1)
    column  2n + 1       right-hand side: the values of the basic variables

Variable index k means: w_k for k < n, z_{k-n} for n <= k < 2n, the artificial variable for k == 2n.

`solve_island_lemke` (at the end) is the time-stepper's island solver: the certified chain of Lemke methods, behind
the island-solver signature of engine/step.py.
"""

import math

import numpy as np
from numba import njit

from planar_lcp.engine.assemble import (apply_impulses, assemble_lcp, assemble_servo, contact_velocities,
                                        island_is_elastic, island_problem_size, island_servo, record_impulses,
                                        record_servo_lag, servo_within_limits, support_column_count)
from planar_lcp.engine.layout import LemkeSettings, Stat, lemke_struct, matrix_view
from planar_lcp.engine.solvers.certificate import (STATUS_INACCURATE, STATUS_INVALID, STATUS_MAX_PIVOTS,
                                                   STATUS_NEEDS_SPACE, STATUS_RAY, STATUS_SOLVED, keep_better,
                                                   keep_ties, lcp_residual, lcp_scale, lexicographic_pick,
                                                   solve_basic_z)
from planar_lcp.engine.solvers.block_lemke import block_lemke
from planar_lcp.engine.solvers.sparse import solve_island_sparse


@njit(cache=True, _nrt=False)
def _pivot(T, n, r, j, prow):
    """Pivot on (r, j). The normalized pivot row is copied to `prow` first: updating T[i, :] from T[r, :] of the
    same array is a potential alias that keeps LLVM from vectorizing the row update."""
    ncol = 2 * n + 2
    p = T[r, j]
    for c in range(ncol):
        v = T[r, c] / p  # division, not multiplication by 1/p, which can overflow for a subnormal pivot
        prow[c] = v
        T[r, c] = v
    for i in range(n):
        if i == r:
            continue
        f = T[i, j]
        if f != 0.0:
            for c in range(ncol):
                T[i, c] -= f * prow[c]
    # exact zeros in the pivot column remove round-off residue
    for i in range(n):
        T[i, j] = 0.0
    T[r, j] = 1.0


@njit(cache=True, _nrt=False)
def _ratio_test(T, basis, n, j, settings, rhs_scale, cand, rate, value):
    """Lexicographic minimum-ratio test on entering column j; returns the leaving row or -1 (ray).

    Candidates are rows whose pivot entry exceeds settings.piv_tol relative to the column's largest magnitude.
    First level: rhs / pivot (a slightly negative rhs from round-off counts as 0, so it can never win with a
    negative ratio and start a cycle). On a tie the artificial variable leaves if it is among the tied rows
    (this ends the algorithm, and is what Drake's unrevised Lemke does). Remaining ties are broken on the
    columns of B^-1 in order (`lexicographic_pick`): with exact arithmetic two rows of B^-1 are never proportional,
    so the lexicographic order is strict and Lemke cannot cycle.

    What counts as a tie is relative to the problem's own scale, never to 1: two first-level ratios tie when
    they differ by at most ratio_tol * max(|min ratio|, rhs_scale / colmax), i.e. by round-off in the rhs
    (whose magnitude is that of q) divided by the pivot. An absolute floor would merge real differences in
    small problems (DART's 12-D box LCP has ratios 4.8e-5 apart by 1e-12), pick a row that is not the
    minimum, drive a basic variable negative and cycle.

    cand (int64), rate, value (float64): (>=n,) work, the candidate rows with their pivot entries and clipped rhs.
    """
    rhs = 2 * n + 1
    z0 = 2 * n
    colmax = 0.0
    for i in range(n):
        a = abs(T[i, j])
        if a > colmax:
            colmax = a
    thresh = settings.piv_tol * colmax
    if colmax == 0.0:
        return -1
    nc = 0
    best = np.inf
    for i in range(n):
        if T[i, j] > thresh:
            b = T[i, rhs]
            if b < 0.0:
                b = 0.0
            ratio = b / T[i, j]
            if ratio < best:
                best = ratio
            cand[nc] = i
            rate[nc] = T[i, j]
            value[nc] = b
            nc += 1
    nc = keep_ties(cand, rate, value, nc, best, settings.ratio_tol, rhs_scale, colmax)
    if nc <= 1:
        return cand[0] if nc == 1 else -1
    for a in range(nc):
        if basis[cand[a]] == z0:
            return cand[a]
    # Lexicographic tie-break on the columns of B^-1 (tobenna's integer data has exact zero ratios decided there,
    # and cycles otherwise): the rows of B^-1 are the tied rows' first n tableau columns
    return lexicographic_pick(T, cand, cand, rate, nc, n, settings.ratio_tol)


@njit(cache=True, _nrt=False)
def refine_from_basis(M, q, basis, n, z, lu, rhs, perm, zb, zmask):
    """Recompute the basic z of the final basis from the original M and q: the z_i that are basic solve
    M[Z, Z] z_Z = -q[Z]. For a complementary basis the rows with w_i = 0 are exactly Z; while the artificial variable
    is still basic one index has neither z_i nor w_i basic: z_i = 0 there and its w_i is left free, so a basis that
    ended with the artificial variable at (nearly) zero refines to the LCP's solution as well. Writes z (clipped at
    0); returns (solvable, most negative basic z before clipping) as `solve_basic_z`. zmask: (>=n,) int64 work."""
    for i in range(n):
        zmask[i] = 0
    for i in range(n):
        k = basis[i]
        if k >= n and k < 2 * n:
            zmask[k - n] = 1
    m = np.int64(0)                     # not a literal: numba would compile solve_basic_z for Literal[int](0) too
    for i in range(n):
        if zmask[i]:
            zb[m] = i
            m += 1
    return solve_basic_z(M, q, zb, m, z, lu, rhs, perm)


@njit(cache=True, _nrt=False)
def lemke_from_basis(M, q, zmask, res_tol, work):
    """Try a guessed complementary basis: z_i basic (w_i = 0) where zmask[i], else z_i = 0 (w_i basic), in Lemke's
    work (a step's work struct or a LemkeWork struct: engine/layout.py LEMKE_LAYOUT).

    Solves M[Z, Z] z_Z = -q[Z] from the original data and certifies the answer by the residual on (M, q), with the
    margin under which `lemke_kernel` skips its own refinement (1e-3 res_tol, relative): an accepted guess is as
    accurate as a cold solve. Used as a warm start with the basis of the previous time step, where contact modes
    rarely change. Returns (accepted, residual); work.lemke_z, work.lemke_w hold the answer only when accepted.
    """
    z = work.lemke_z
    zb = work.lemke_basic
    m = np.int64(0)                     # not a literal: numba would compile solve_basic_z for Literal[int](0) too
    for i in range(q.shape[0]):
        if zmask[i]:
            zb[m] = i
            m += 1
    ok, neg = solve_basic_z(M, q, zb, m, z, work.lemke_lu, work.lemke_rhs, work.lemke_perm)
    if not ok:
        return False, np.inf
    res = max(lcp_residual(M, q, z, work.lemke_w), -neg)
    return res <= 1e-3 * res_tol * lcp_scale(M, q), res


@njit(cache=True, _nrt=False)
def _equilibrate(M, n, d, r):
    """Symmetric diagonal scaling d (powers of two) so that every row and column of D M D has its largest magnitude
    in [1/2, 2] (Ruiz's iteration; rows that are all zero keep d = 1).

    Contact LCPs mix bodies of very different mass: with masses 1e-3 and 1e3 kg the Delassus entries span 1e6 and
    more, and the friction-slack rows hold O(1) entries beside them. Lemke's pivot threshold and tie tolerances are
    relative to a column's largest entry, so an unscaled tableau lets the heavy body's rows decide every comparison
    and round-off of the large entries swamp the small ones. Powers of two make the scaling exact: D M D carries
    the same digits as M. The LCP (D M D, D q) has the solutions z = D z' of (M, q)."""
    for i in range(n):
        d[i] = 1.0
    for _ in range(8):
        for i in range(n):
            big = 0.0
            for k in range(n):
                a = abs(M[i, k]) * d[k]
                if a > big:
                    big = a
            r[i] = big * d[i]
        for i in range(n):
            if r[i] > 0.0:
                d[i] /= np.sqrt(r[i])
    # math.log2, not np.log2: NumPy's SIMD log2 differs from the C library's (tests/compilation/test_interpreted_bits.py)
    for i in range(n):
        d[i] = 2.0 ** np.round(math.log2(d[i]))


@njit(cache=True, _nrt=False)
def _certify(M, q, T, n, work, res_tol, scale):
    """The LCP answer at the current basis, certified on the ORIGINAL (M, q): the basic z of the tableau T (unscaled
    by work.lemke_scaling), and, unless that is already well inside the tolerance, the basic z recomputed from (M, q)
    for the same basis. Writes the better one into work.lemke_z (work.lemke_w = M z + q) and returns its residual.
    Valid whether or not the artificial variable is still basic: the residual, not the pivoting, decides whether the
    answer is a solution."""
    basis, d, z, w, zalt = work.lemke_basis, work.lemke_scaling, work.lemke_z, work.lemke_w, work.lemke_z_refined
    walt = work.lemke_w_refined
    rhs_col = 2 * n + 1
    for i in range(n):
        z[i] = 0.0
    for i in range(n):
        k = basis[i]
        if k >= n and k < 2 * n:
            z[k - n] = max(T[i, rhs_col], 0.0) * d[k - n]
    res = lcp_residual(M, q, z, w)
    # Refine from the original data: the tableau accumulates round-off over the pivots, the basis does not.
    # Skipped when the tableau's answer is already well inside the tolerance (it then costs more than it gains).
    if res > 1e-3 * res_tol * scale:
        ok, neg = refine_from_basis(M, q, basis, n, zalt, work.lemke_lu, work.lemke_rhs, work.lemke_perm,
                                    work.lemke_basic, work.lemke_rows)
        if ok:
            res = keep_better(res, max(lcp_residual(M, q, zalt, walt), -neg), z, w, zalt, walt, n)
    return res


@njit(cache=True, _nrt=False)
def lemke_kernel(M, q, settings, work):
    """Solve the LCP (M, q) in place. Never raises, never allocates.

    Parameters
    ----------
    M : (n, n) float64;  q : (n,) float64 -- not modified.
    settings : LemkeSettings (engine/layout.py)
        max_pivots; piv_tol, ratio_tol, res_tol (res_tol relative to lcp_scale(M, q)); equilibrate: pivot on the
        symmetrically equilibrated problem (D M D, D q) (see `_equilibrate`).
    work : a struct with LEMKE_LAYOUT's fields (engine/layout.py), for problems of at least n unknowns: a step's
        work struct, or `lemke_work_struct(make_lemke_work(n))`. The tableau is the first n (2n + 2) entries of
        work.lemke_tableau (row-major); the answer is work.lemke_z, with work.lemke_w = M z + q (first n entries).

    Returns
    -------
    (status, pivots, residual) -- status one of the STATUS_* codes; residual on the original M and q.
    STATUS_SOLVED means the residual passes res_tol * lcp_scale(M, q), whatever ended the pivoting: Lemke's path can
    reach a solution with the artificial variable still basic at (round-off) zero, where a degenerate step then ends
    on a ray that exact arithmetic would not take; that point is a solution and is certified as one.
    """
    n = q.shape[0]
    if n == 0:
        return STATUS_SOLVED, 0, 0.0
    basis, z, w, d, prow = work.lemke_basis, work.lemke_z, work.lemke_w, work.lemke_scaling, work.lemke_pivot_row
    res_tol = settings.res_tol
    # the finiteness check and `lcp_scale(M, q)` in one pass over (M, q): the same comparisons in the same order
    scale = 1.0
    for i in range(n):
        a = q[i]
        if not np.isfinite(a):
            return STATUS_INVALID, 0, np.inf
        if abs(a) > scale:
            scale = abs(a)
        for k in range(n):
            a = M[i, k]
            if not np.isfinite(a):
                return STATUS_INVALID, 0, np.inf
            if abs(a) > scale:
                scale = abs(a)
    for i in range(n):
        z[i] = 0.0
    if settings.equilibrate:
        _equilibrate(M, n, d, work.lemke_rhs)
    else:
        for i in range(n):
            d[i] = 1.0

    rhs_scale = 0.0
    for i in range(n):
        rhs_scale = max(rhs_scale, abs(d[i] * q[i]))
    qmin = 0.0
    r = np.int64(-1)                    # not a literal: numba would compile _pivot for Literal[int](-1) too
    for i in range(n):
        # ties: the LAST index keeps the initial tableau lexicographically positive
        qi = d[i] * q[i]
        if qi <= qmin and qi < 0.0:
            qmin = qi
            r = i
    if r < 0:
        res = lcp_residual(M, q, z, w)
        return STATUS_SOLVED, 0, res

    # The scaled system D w = (D M D) z' + D q + e z0 with z = D z', covering vector e in the SCALED problem (D^-1 e
    # in the original one): every row weighs the same in the path, whatever its body's mass. A different covering
    # vector is a different pivot path; for the copositive contact LCPs any positive one reaches a solution in exact
    # arithmetic, for other matrices it can decide whether Lemke succeeds (Murty's examples: docs/lcp.md).
    rhs_col = 2 * n + 1
    z0 = 2 * n
    T = matrix_view(work.lemke_tableau, n, 2 * n + 2)
    for i in range(n):
        for c in range(n):               # B^-1 = I; the other columns are all written below
            T[i, c] = 0.0
        T[i, i] = 1.0
        for k in range(n):
            T[i, n + k] = -d[i] * M[i, k] * d[k]
        T[i, z0] = -1.0
        T[i, rhs_col] = d[i] * q[i]
        basis[i] = i

    _pivot(T, n, r, z0, prow)
    leaving = basis[r]
    basis[r] = z0
    z0_row = r           # the artificial variable stays in this row until it leaves (then the loop ends)
    pivots = 1
    status = STATUS_MAX_PIVOTS
    while pivots < settings.max_pivots:
        # complement of the variable that just left
        if leaving < n:
            entering = leaving + n
        else:
            entering = leaving - n
        r = _ratio_test(T, basis, n, entering, settings, rhs_scale, work.lemke_rows, work.lemke_rhs,
                        work.lemke_z_refined)
        if r < 0:
            status = STATUS_RAY
            break
        _pivot(T, n, r, entering, prow)
        leaving = basis[r]
        basis[r] = entering
        pivots += 1
        if leaving == z0:
            status = STATUS_SOLVED
            break
        # The artificial variable at zero while still basic: the basic z already solves the LCP (w = M z + q + e z0
        # with z0 = 0). Exact arithmetic would now let z0 leave on a tie; round-off can instead offer no pivot in
        # its row and end on a ray. Certify the point as it is (rare: only then is the O(n^2) residual computed).
        if T[z0_row, rhs_col] <= res_tol * scale:
            if _certify(M, q, T, n, work, res_tol, scale) <= res_tol * scale:
                status = STATUS_SOLVED
                break

    res = _certify(M, q, T, n, work, res_tol, scale)
    if res <= res_tol * scale:
        return STATUS_SOLVED, pivots, res
    if status == STATUS_SOLVED:
        return STATUS_INACCURATE, pivots, res
    # report the basic z the pivoting stopped at (useful for diagnosis), never as solved
    return status, pivots, res


@njit(cache=True, inline='always')
def default_max_pivots(n):
    """The pivot cap for a problem of size n: Lemke typically needs O(n) pivots, Murty's exponential examples 2^n."""
    return 50 * n + 100


@njit(cache=True)
def _make_work(n):
    """LEMKE_LAYOUT's buffers (engine/layout.py) for problems of size n, in its order, allocated in a kernel (the
    public solver's per call; `make_lemke_work` allocates the same from Python, tests/lcp/test_lemke_work.py
    checks that they agree)."""
    return (np.empty(n * (2 * n + 2)), np.empty(n, np.int64), np.zeros(n), np.zeros(n), np.empty(n, np.int64),
            np.empty((n, n)), np.empty(n), np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n), np.empty(n),
            np.empty(2 * n + 2), np.empty(n))


@njit(cache=True)
def lemke_solve(M, q, max_pivots, piv_tol, ratio_tol, res_tol, equilibrate):
    """Allocate the work arrays and call `lemke_kernel`. Returns (z, w, status, pivots, residual)."""
    arrays = _make_work(q.shape[0])
    status, pivots, res = lemke_kernel(M, q, LemkeSettings(max_pivots, piv_tol, ratio_tol, res_tol, equilibrate),
                                       lemke_struct(arrays))
    return arrays[2], arrays[3], status, pivots, res


# ---------------------------------------------------------------------------------------------------------------
# The island solver
# ---------------------------------------------------------------------------------------------------------------

# How an island's LCP is solved, in the order tried (one Stat.SOLVED_* count per island LCP solved;
# Stat.WARM_STARTS counts the warm start). Every answer is certified by its residual on the island's original LCP
# before it is accepted.
#   lemke         Lemke on the problem as assembled, covering vector e: the method as published, the default path
#   equilibrated  Lemke on the exactly (power-of-two) equilibrated problem: another pivot path, on which the rows of
#                 light and heavy bodies weigh the same (docs/lcp.md)
#   strict        as assembled, with the stricter pivot tolerances RETRY_PIV_TOLS: a nearly degenerate contact LCP (a
#                 rod lying flat: two friction columns that differ by round-off-sized lever arms) can offer a pivot
#                 ~1e-7 of its column that blows the tableau up and ends on a false ray; rejecting such pivots solves it
#   velocity      position forms only: the same island (same contacts, same geometry) with the velocity form's
#                 normal rows, n.v+ >= -max(phi, 0)/h: no drift correction in this step and no linearization about
#                 v_hat. With no kinematic body in the island, Lemke processes this LCP (Anitescu & Potra 1997; Stewart &
#                 Trinkle's section 3.3; docs/method.md), while the position form's need not have a solution (a body
#                 pressed into a corner it cannot leave in one step) or can end Lemke on a secondary ray
#   inelastic     islands with restitution only: the same island with every pair's e = 0, in the formulation's rows
#                 and then in the velocity form's. Newton's law can ask the impossible of a simultaneous impact (a body
#                 struck towards a contact it cannot leave must still separate from both at once), and then its LCP has
#                 no solution; the inelastic problem is Stewart & Trinkle's, and the velocity form's always has one. The step
#                 loses that island's bounce; `solved_inelastic` counts it.
# When none is certified the step pipeline hands the island to its fallback (PGS: uncertified, the step is reported
# as failed) or, in the variant without one, hands the step back to the caller.
RETRY_PIV_TOLS = (1e-6, 1e-4)
#: block Lemke's pivot cap per unknown: Lemke's path on a contact island takes under one pivot per unknown (the bin
#: of 40: about 260 for 360); where round-off splits a tie into a cycle the tableau takes over after 2 n + 100
#: pivots, not after its own cap of 50 n + 100. The same cap is the first sweep's of the tableau's tries on those
#: islands (`solve_island_lemke`)
BLOCK_PIVOTS_PER_UNKNOWN = 2
# The chain, in order: (stats counter, pivot tolerance (-1: the options'), equilibrate, velocity-form normal rows,
# the impact law of restitution)
LEMKE_CHAIN = ((int(Stat.SOLVED_LEMKE), -1.0, False, False, True),
               (int(Stat.SOLVED_EQUILIBRATED), -1.0, True, False, True),
               (int(Stat.SOLVED_STRICT), RETRY_PIV_TOLS[0], False, False, True),
               (int(Stat.SOLVED_STRICT), RETRY_PIV_TOLS[1], False, False, True),
               (int(Stat.SOLVED_VELOCITY), -1.0, False, True, True),
               (int(Stat.SOLVED_VELOCITY), -1.0, True, True, True),
               (int(Stat.SOLVED_INELASTIC), -1.0, False, False, False),
               (int(Stat.SOLVED_INELASTIC), -1.0, True, False, False),
               (int(Stat.SOLVED_INELASTIC), -1.0, False, True, False),
               (int(Stat.SOLVED_INELASTIC), -1.0, True, True, False))


@njit(cache=True, inline='always')
def lemke_in_work(w, A, b, n, opt, piv_tol, equilibrate, max_pivots=-1):
    """`lemke_kernel` on the LCP (A, b) of size n, in the step's work buffers (answer in w.lemke_z), with the options'
    ratio and residual tolerances, the pivot tolerance piv_tol and the pivot cap max_pivots (-1: default_max_pivots).
    Returns (status, pivots, residual)."""
    if max_pivots < 0:
        max_pivots = default_max_pivots(n)
    return lemke_kernel(A, b, LemkeSettings(max_pivots, piv_tol, opt.ratio_tol, opt.res_tol, equilibrate), w)


@njit(cache=True, inline='always')
def block_lemke_in_work(w, A, b, n, opt):
    """`block_lemke` on the LCP (A, b) of size n in the step's work buffers (answer in w.lemke_z), with the options'
    tolerances. At most BLOCK_PIVOTS_PER_UNKNOWN pivots per unknown: a cycle costs little before the tableau takes
    over."""
    return block_lemke(A, b, LemkeSettings(BLOCK_PIVOTS_PER_UNKNOWN * n + 100, opt.piv_tol, opt.ratio_tol,
                                           opt.res_tol, np.bool_(False)), w)


@njit(cache=True, _nrt=False)
def block_lemke_equilibrated(m, w, opt, vk, nci, nsi, h, velocity_form, n):
    """`block_lemke_in_work` on the equilibrated LCP (D A D, D b) (`_equilibrate`: powers of two, so exact) of the
    island's LCP (A, b) of size n in w.lcp_matrix, w.lcp_vector (assembled from vk, nci, nsi, h, velocity_form as
    `assemble_lcp` takes them), its answer z = D z' certified on (A, b) by the residual test of every other answer.
    Leaves (A, b) as assembled (made anew: the block kernel overwrites nothing of them, but the scaling is undone by
    assembling again, bit for bit, not by dividing). Returns (status, pivots, residual on (A, b)).

    Why: where round-off splits a degenerate tie, the pivot path as assembled can run K singular (the block kernel
    gives up) and the tableau's own path can wander to its cap of 50 n + 100 pivots (the settled bin of 40, step 36:
    16,900 tableau pivots, 1.4 s), while the equilibrated problem's path, another pivot sequence, reaches an answer in
    about n pivots."""
    A = matrix_view(w.lcp_matrix, n, n)
    b = w.lcp_vector[:n]
    d = w.lemke_scaling
    _equilibrate(A, n, d, w.lemke_rhs)
    for i in range(n):
        b[i] *= d[i]
        for j in range(n):
            A[i, j] *= d[i] * d[j]
    status, p, res = block_lemke_in_work(w, A, b, n, opt)
    assemble_lcp(m, w, vk, nci, nsi, h, velocity_form, A, b, np.bool_(True))
    if status != STATUS_SOLVED:
        return status, p, res
    for i in range(n):
        w.lemke_z[i] *= d[i]
    res = lcp_residual(A, b, w.lemke_z, w.lemke_w)
    if res > opt.res_tol * lcp_scale(A, b):
        return STATUS_INACCURATE, p, res
    return STATUS_SOLVED, p, res


@njit(cache=True, _nrt=False)
def record_failed_island(m, w, vk, nci, nsi, h, velocity_form, sizes):
    """Keep the LCP of an island no method certified, as the chain's first try assembled it (its rows as the
    formulation states them, with restitution; with the force-limited bodies' lag blocks when ns > 0: the last n - ns
    ... n rows), with its contacts and support elements: w.fail_* (the step's first such island; begin_step forgets
    it). For the diagnosis of the failure (planar_lcp/infeasibility.py). sizes: (n, nf, nsb, ns), the LCP's size,
    the island's friction contacts and its force-limited bodies (`island_problem_size`, `island_servo`)."""
    n, nf, nsb, ns = sizes
    A = matrix_view(w.lcp_matrix, n, n)
    assemble_lcp(m, w, vk, nci, nsi, h, velocity_form, A, w.lcp_vector, np.bool_(True))
    if ns > 0:
        assemble_servo(m, w, nci, nf, n - ns, nsb, h, A, w.lcp_vector)
    w.fail_size[0] = n
    w.fail_size[1] = nci
    w.fail_size[2] = nsi
    w.fail_size[3] = nf
    w.fail_size[4] = ns
    for i in range(n):
        w.fail_vector[i] = w.lcp_vector[i]
        for c in range(n):
            w.fail_matrix[i * n + c] = A[i, c]
    for a in range(nci):
        w.fail_con[a] = w.con_pair[w.island_con[a]]
    for a in range(nsi):
        w.fail_sup[a] = w.island_sup[a]
    for a in range(nsb):
        w.fail_servo[a] = w.island_servo[a]


@njit(cache=True, inline='always')
def lemke_chain(m, w, opt, vk, nci, nsi, h, velocity_form, n, short_cap):
    """The LEMKE_CHAIN's tries on the island LCP (A, b) of size n in w.lcp_matrix, w.lcp_vector (assembled in its
    first form, and with the force-limited bodies' lag blocks after the contacts' rows when it has them:
    `assemble_servo`, which the tries' other row constants leave as they are), until one is certified. short_cap
    (-1: none): a large island's first sweep caps each try at that many pivots, and a second sweep runs the tries
    that reached it with the full cap. Returns (status, pivots, residual, the stats counter of the method that solved
    it, the tries after the first)."""
    A = matrix_view(w.lcp_matrix, n, n)
    b = w.lcp_vector[:n]
    # One call site for the whole chain: each inlined call of lemke_kernel costs compile time
    status = STATUS_RAY
    piv = 0
    res = np.inf
    method = LEMKE_CHAIN[0][0]
    rows_velocity = velocity_form       # the rows (A, b) now hold
    rows_elastic = True
    elastic_island = island_is_elastic(m, w.island_con, nci, w.con_pair)
    retries = 0
    capped = 0                           # bit `attempt`: that try ended at the short cap
    for sweep_attempt in range(2 * len(LEMKE_CHAIN) if short_cap >= 0 else len(LEMKE_CHAIN)):
        attempt = sweep_attempt % len(LEMKE_CHAIN)
        second_sweep = sweep_attempt >= len(LEMKE_CHAIN)
        if second_sweep and not (capped >> attempt) & 1:
            continue
        method, piv_tol, equilibrate, in_velocity_form, elastic = LEMKE_CHAIN[attempt]
        if piv_tol < 0.0:
            piv_tol = opt.piv_tol
        elif piv_tol <= opt.piv_tol:
            continue                     # not stricter than the first try
        if not elastic and not elastic_island:
            continue                     # without restitution the inelastic rows were tried already
        want_velocity = in_velocity_form or velocity_form
        if in_velocity_form and velocity_form:
            # the velocity form's rows were the first try's (inelastic: the try before)
            continue
        if want_velocity != rows_velocity or elastic != rows_elastic:
            # the island's LCP over the same contacts: only the normal rows' constants change (the lag blocks
            # are the same)
            assemble_lcp(m, w, vk, nci, nsi, h, want_velocity, A, w.lcp_vector, elastic)
            rows_velocity = want_velocity
            rows_elastic = elastic
        if sweep_attempt > 0:
            retries += 1
        status, p, res = lemke_in_work(w, A, b, n, opt, piv_tol, equilibrate, -1 if second_sweep else short_cap)
        piv += p
        if status == STATUS_SOLVED:
            break
        if status == STATUS_MAX_PIVOTS and short_cap >= 0 and not second_sweep:
            capped |= 1 << attempt
    return status, piv, res, method, retries


@njit(cache=True, inline='always')
def solve_island_lemke(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    """Island solver (signature: engine/step.py): the island's LCP by the warm start (opt.warm_start), then the
    certified LEMKE_CHAIN, large islands (opt.sparse_min) by the sparse solver and block Lemke first. When solved,
    its impulses are added to w.v_new and recorded in w.con_*; returns the Lemke status (a failure leaves w.v_new
    unchanged and forgets the island's warm-start basis).

    An island with force-limited kinematic bodies (max_force) is solved first with their velocities prescribed, as
    any island; when that answer asks more of a servo than its limits (or there is none), the island is solved again
    with their lag unknowns (engine/assemble.py `assemble_servo`), so that a servo within its limits gives the
    prescribed motion bit for bit."""
    n, nf, _ = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)
    nsb, ns = island_servo(m, w, nci, nf)
    for i in range(nsb):
        # prescribed until the servo solve below says otherwise (contact_velocities reads w.kin_velocity)
        kk = w.island_servo[i]
        for c in range(3):
            w.kin_lag[kk, c] = 0.0
            w.kin_velocity[kk, c] = vk[kk, c]
    k = support_column_count(m)
    status = STATUS_RAY
    piv = 0
    res = np.inf
    warm = False
    sparse = False
    block = False
    servo = False
    tried_block = np.bool_(False)
    large = ns == 0 and opt.sparse_min > 0 and n >= opt.sparse_min and nsi == 0
    if large:
        # a large island: its sparse reduced system first (engine/solvers/sparse.py), dense Lemke if not certified
        sparse, _, res = solve_island_sparse(m, w, opt, vk, nci, nsi, h, velocity_form)
        if sparse:
            status = STATUS_SOLVED
            stats[Stat.SOLVED_SPARSE] += 1
        else:
            stats[Stat.SPARSE_FALLBACKS] += 1
    N = n
    # phase 0: the island's LCP; phase 1, only when its force-limited bodies cannot all keep their prescribed
    # velocities (the answer asks more than a limit, or there is none): the LCP with their lag unknowns (one call
    # site of the chain for both: each inlined copy costs compile time)
    for phase in range(2):
        if sparse:
            break
        if phase == 1:
            servo = ns > 0 and (status != STATUS_SOLVED or not servo_within_limits(m, w, nci, nf, nsb, h,
                                                                                    w.lemke_z))
            if not servo:
                break
            N = n + ns
            warm = False
            block = False
        if N > w.lemke_lu.shape[0]:
            # the dense buffers are too small: the step is handed back, to be run again with larger ones
            w.dense_needed[0] = max(w.dense_needed[0], N)
            return STATUS_NEEDS_SPACE
        A = matrix_view(w.lcp_matrix, N, N)
        b = w.lcp_vector[:N]
        # np.bool_: every call site passes `elastic` typed alike, else numba compiles assemble_lcp once for the
        # omitted default, once for Literal[bool](True) and once for bool
        assemble_lcp(m, w, vk, nci, nsi, h, velocity_form, A, w.lcp_vector, np.bool_(True))
        if servo:
            assemble_servo(m, w, nci, nf, n, nsb, h, A, w.lcp_vector)
        if phase == 0 and opt.warm_start and w.warm_size[isl] == n:
            # the previous step's basis for this island: contact modes rarely change from one step to the next
            warm, res = lemke_from_basis(A, b, w.warm_basic_z[isl], opt.res_tol, w)
        if warm:
            status = STATUS_SOLVED
            stats[Stat.WARM_STARTS] += 1
        elif phase == 0 and large:
            # a large island: Lemke's path pivoted on its basis's Schur complement (block_lemke.py), O(k^2) a pivot
            # where the tableau's costs O(n^2); the tableau if it is not certified (a cycle on a degenerate tie)
            tried_block = np.bool_(True)
            status, p, res = block_lemke_in_work(w, A, b, n, opt)
            piv += p
            if status != STATUS_SOLVED:
                status, p, res = block_lemke_equilibrated(m, w, opt, vk, nci, nsi, h, velocity_form, n)
                piv += p
            if status == STATUS_SOLVED:
                block = True
                stats[Stat.SOLVED_BLOCK] += 1
        if not warm and not block:
            # a large island's chain runs twice: first each try capped at BLOCK_PIVOTS_PER_UNKNOWN pivots per
            # unknown, then, if none was certified, the tries that reached that cap with the full one
            short_cap = BLOCK_PIVOTS_PER_UNKNOWN * N + 100 if tried_block else -1
            status, p, res, method, retries = lemke_chain(m, w, opt, vk, nci, nsi, h, velocity_form, N, short_cap)
            stats[Stat.LEMKE_RETRIES] += retries
            piv += p
            if status == STATUS_SOLVED:
                stats[method] += 1
        if servo and status == STATUS_SOLVED:
            stats[Stat.SERVO_LIMITED] += 1
            record_servo_lag(m, w, vk, n, nsb, w.lemke_z)
    n = N
    stats[Stat.LCP_SIZE] += n
    stats[Stat.LCP_MAX] = max(stats[Stat.LCP_MAX], n)
    stats[Stat.PIVOTS] += piv
    stats[Stat.RESIDUAL] = max(stats[Stat.RESIDUAL], res)
    if status != STATUS_SOLVED:
        stats[Stat.LEMKE_STATUS] = max(stats[Stat.LEMKE_STATUS], status)
        w.warm_size[isl] = -1
        if w.fail_size[0] < 0 and not sparse:
            record_failed_island(m, w, vk, nci, nsi, h, velocity_form, (n, nf, nsb, ns))
        return status
    if sparse or servo:
        w.warm_size[isl] = -1                # no basis to keep (a servo's: the next step tries its LCP first)
    elif not warm:
        # remember the final basis (z_i basic) for the next step's warm start
        w.warm_size[isl] = n
        for i in range(n):
            w.warm_basic_z[isl, i] = False
        if block:
            # block Lemke's final basis: z_j is basic where it holds a column position of K
            for i in range(n):
                w.warm_basic_z[isl, i] = w.block_col_pos[i] >= 0
        elif piv > 0:  # with no pivot (q >= 0: z = 0) lemke_kernel leaves lbasis as it was
            for i in range(n):
                kb = w.lemke_basis[i]
                if kb >= n and kb < 2 * n:
                    w.warm_basic_z[isl, kb - n] = True
    apply_impulses(nci + 2 * nf + k * nsi, w.column_slot, w.column_g, w.lemke_z, m, w.v_new)
    record_impulses(m, w, nci, w.lemke_z, np.bool_(False), nci)   # np.bool_: one compilation with PGS's call
    contact_velocities(m, w, opt, w.kin_velocity, nci)
    return status
