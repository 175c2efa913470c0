"""Public LCP solvers: find z >= 0 with w = M z + q >= 0 and z.w = 0.

`lemke` validates its arguments and calls the numba kernel in `planar_lcp.engine.solvers.lemke`.
"""

from dataclasses import dataclass

import numpy as np

from planar_lcp.compilation.background import wait_for
from planar_lcp.engine.solvers.certificate import STATUS_NAMES, lcp_scale
from planar_lcp.engine.solvers.lemke import default_max_pivots, lemke_solve

#: Default tolerances (see docs/lcp.md for what each one governs).
DEFAULT_PIV_TOL = 1e-9
DEFAULT_RATIO_TOL = 1e-12
DEFAULT_RES_TOL = 1e-9


@dataclass(frozen=True)
class LCPResult:
    """Outcome of an LCP solve.

    Attributes
    ----------
    z, w : (n,) float64
        The final iterate and w = M z + q computed from the original M and q (for a failed solve, the basic
        solution the pivoting stopped at, for diagnosis).
    status : str
        "solved" (residual below tolerance), "ray_termination" (Lemke stopped on a secondary ray: no
        solution was reached from this start), "max_pivots", "invalid_input" (non-finite data reached the
        kernel), or "inaccurate" (Lemke terminated but the residual of the result on the original data is
        above tolerance: the answer is NOT trusted).
    pivots : int
    residual : float
        max_i |min(z_i, w_i)| + max(0, -min z) + max(0, -min w), on the original M and q.
    tolerance : float
        The absolute residual bound that "solved" was judged against: res_tol * max(1, max|M|, max|q|).
    """

    z: np.ndarray
    w: np.ndarray
    status: str
    pivots: int
    residual: float
    tolerance: float

    @property
    def solved(self) -> bool:
        return self.status == "solved"


def _as_problem(M, q):
    # C-contiguous float64: the kernel's one signature, whatever layout the caller's arrays have
    M = np.ascontiguousarray(M, dtype=np.float64)
    q = np.ascontiguousarray(q, dtype=np.float64)
    if q.ndim != 1:
        raise ValueError(f"lemke: q must be a 1-D array of shape (n,), got shape {q.shape}")
    n = q.shape[0]
    if M.shape != (n, n):
        raise ValueError(f"lemke: M must have shape (n, n) = ({n}, {n}) to match q, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        i, k = np.argwhere(~np.isfinite(M))[0]
        raise ValueError(f"lemke: M must be finite, got M[{i}, {k}] = {M[i, k]}")
    if not np.all(np.isfinite(q)):
        i = int(np.argwhere(~np.isfinite(q))[0][0])
        raise ValueError(f"lemke: q must be finite, got q[{i}] = {q[i]}")
    return np.ascontiguousarray(M), np.ascontiguousarray(q)


def lemke(M, q, *, max_pivots=None, piv_tol=DEFAULT_PIV_TOL, ratio_tol=DEFAULT_RATIO_TOL,
          res_tol=DEFAULT_RES_TOL, equilibrate=False) -> LCPResult:
    """Solve the LCP (M, q) by Lemke's algorithm with covering vector e and lexicographic degeneracy resolution.

    Parameters
    ----------
    M : (n, n) array_like;  q : (n,) array_like
    max_pivots : int, optional
        Pivot cap; default `default_max_pivots(n)` = 50 n + 100 (the time-stepper's too, after a first sweep capped
        at 2 n + 100 on the large islands block Lemke leaves; docs/method.md, "Large islands").
    piv_tol : float
        A tableau entry is an admissible pivot only if it exceeds piv_tol times the largest magnitude in the
        entering column.
    ratio_tol : float
        Two ratios of the minimum-ratio test are tied when they differ by at most
        ratio_tol * max(|min ratio|, max|q'| / max|column|) (q' the scaled q): round-off in the right-hand side
        divided by the pivot, relative to the problem's own scale, never to 1. On a tie the artificial variable
        leaves if its row is among the tied ones (which ends the pivoting); other ties are broken lexicographically
        on the columns of the basis inverse.
    res_tol : float
        "solved" requires residual <= res_tol * max(1, max|M|, max|q|), whatever ended the pivoting (a point where
        the artificial variable is still basic at round-off zero is a solution, and reported as one).
    equilibrate : bool
        Pivot on D M D, D q with D a power-of-two diagonal scaling that brings every row's largest entry to about 1
        (exact in floating point; the solution is z = D z'), with covering vector e in the scaled problem: another
        pivot path, on which rows of very different magnitude weigh the same (the time-stepper's first try on contact
        LCPs). Off by default: the classic algorithm, covering vector e on (M, q) (docs/lcp.md).

    Raises
    ------
    ValueError
        On wrong shapes or non-finite entries; the message names the argument and the expected and actual value.
    """
    M, q = _as_problem(M, q)
    n = q.shape[0]
    if max_pivots is None:
        max_pivots = default_max_pivots(n)
    if int(max_pivots) < 1:
        raise ValueError(f"lemke: max_pivots must be >= 1, got {max_pivots}")
    for name, val in (("piv_tol", piv_tol), ("ratio_tol", ratio_tol), ("res_tol", res_tol)):
        if not (np.isfinite(val) and val >= 0.0):
            raise ValueError(f"lemke: {name} must be a finite number >= 0, got {val}")
    # a cold numba cache: the kernel compiles once, in the background, for every later call and run
    wait_for(lemke_solve)
    z, w, status, pivots, res = lemke_solve(M, q, int(max_pivots), float(piv_tol), float(ratio_tol), float(res_tol),
                                            bool(equilibrate))
    return LCPResult(z=z, w=w, status=STATUS_NAMES[status], pivots=int(pivots), residual=float(res),
                     tolerance=float(res_tol * lcp_scale(M, q)))
