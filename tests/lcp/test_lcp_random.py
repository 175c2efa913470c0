"""Lemke against a dense numpy oracle on random LCPs of the classes Lemke is guaranteed to process.

Oracle: brute-force enumeration of all 2^n complementary bases with numpy.linalg.solve. For a P-matrix the
solution is unique, so Lemke's z must equal the oracle's. For PSD and copositive-plus matrices with a feasible q
Lemke must terminate with a solution (Cottle-Pang-Stone, Thm 4.4.13), checked for complementarity and feasibility.
"""

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planar_lcp.lcp import lemke


def enumerate_solutions(M, q, tol=1e-9):
    """All complementary basic solutions of (M, q), by solving every principal subsystem."""
    n = len(q)
    sols = []
    for mask in itertools.product((False, True), repeat=n):
        idx = np.flatnonzero(mask)
        z = np.zeros(n)
        if idx.size:
            try:
                z[idx] = np.linalg.solve(M[np.ix_(idx, idx)], -q[idx])
            except np.linalg.LinAlgError:
                continue
        w = M @ z + q
        if z.min() >= -tol and w.min() >= -tol and np.all(np.abs(z * w) <= tol):
            sols.append(z)
    return sols


def check_solution(M, q, r):
    scale = max(1.0, np.abs(M).max(), np.abs(q).max()) * max(1.0, np.abs(r.z).max())
    w = M @ r.z + q
    assert r.status == "solved", (r.status, r.pivots)
    assert r.z.min() >= -1e-9 * scale
    assert w.min() >= -1e-9 * scale
    assert np.max(np.abs(np.minimum(r.z, w))) <= 1e-9 * scale
    np.testing.assert_allclose(r.w, w, atol=1e-9 * scale)


seeds = st.integers(min_value=0, max_value=2**32 - 1)
sizes = st.integers(min_value=1, max_value=7)
SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(seed=seeds, n=sizes)
def test_p_matrix_matches_unique_enumerated_solution(seed, n):
    rng = np.random.default_rng(seed)
    # positive definite (nonsymmetric) => P-matrix: a unique solution for every q
    A = rng.normal(size=(n, n))
    S = rng.normal(size=(n, n))
    M = A @ A.T + 0.1 * np.eye(n) + (S - S.T)  # symmetric part PD => P-matrix
    q = rng.normal(size=n)
    r = lemke(M, q)
    check_solution(M, q, r)
    sols = enumerate_solutions(M, q)
    assert len(sols) == 1
    np.testing.assert_allclose(r.z, sols[0], rtol=1e-8, atol=1e-9)


@SETTINGS
@given(seed=seeds, n=sizes, rank=st.integers(min_value=0, max_value=7))
def test_symmetric_psd_feasible_is_solved(seed, n, rank):
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(n, min(rank, n)))
    M = B @ B.T
    # a feasible q by construction: q = w* - M z* with complementary z*, w* >= 0
    active = rng.random(n) < 0.5
    zs = np.where(active, rng.random(n), 0.0)
    ws = np.where(active, 0.0, rng.random(n))
    q = ws - M @ zs
    check_solution(M, q, lemke(M, q))


@SETTINGS
@given(seed=seeds, n=sizes)
def test_copositive_plus_feasible_is_solved(seed, n):
    rng = np.random.default_rng(seed)
    # PSD symmetric part plus a skew part: copositive-plus (the structure of frictional-contact LCPs' couplings)
    B = rng.normal(size=(n, max(1, n // 2)))
    S = rng.normal(size=(n, n))
    M = B @ B.T + (S - S.T)
    active = rng.random(n) < 0.5
    zs = np.where(active, rng.random(n), 0.0)
    ws = np.where(active, 0.0, rng.random(n))
    q = ws - M @ zs
    check_solution(M, q, lemke(M, q))


@SETTINGS
@given(seed=seeds, n=sizes)
def test_nonnegative_matrix_with_positive_diagonal(seed, n):
    """Strictly copositive (positive entries): a solution exists for every q and Lemke finds it."""
    rng = np.random.default_rng(seed)
    M = rng.random((n, n)) + np.eye(n)
    q = rng.normal(size=n)
    check_solution(M, q, lemke(M, q))


@SETTINGS
@given(seed=seeds, n=sizes)
def test_infeasible_is_never_reported_solved(seed, n):
    """M = -(PSD) with q < 0 has no solution: w = M z + q < 0 for every z >= 0."""
    rng = np.random.default_rng(seed)
    B = rng.random((n, n))
    M = -(B @ B.T)
    q = -rng.random(n) - 0.1
    r = lemke(M, q)
    assert r.status in ("ray_termination", "max_pivots")


def test_input_validation_names_the_argument():
    with pytest.raises(ValueError, match=r"q must be a 1-D array of shape \(n,\), got shape \(2, 1\)"):
        lemke(np.eye(2), np.ones((2, 1)))
    with pytest.raises(ValueError, match=r"M must have shape \(n, n\) = \(2, 2\) to match q, got shape \(3, 3\)"):
        lemke(np.eye(3), np.ones(2))
    with pytest.raises(ValueError, match=r"M must be finite, got M\[0, 1\] = nan"):
        lemke(np.array([[1.0, np.nan], [0.0, 1.0]]), np.ones(2))
    with pytest.raises(ValueError, match=r"q must be finite, got q\[1\] = inf"):
        lemke(np.eye(2), np.array([1.0, np.inf]))
    with pytest.raises(ValueError, match=r"max_pivots must be >= 1, got 0"):
        lemke(np.eye(2), np.ones(2), max_pivots=0)


def test_kernel_reports_invalid_input_instead_of_raising():
    """The stepper calls the kernel directly: non-finite data must come back as a status, not an exception."""
    from planar_lcp.engine.solvers.certificate import STATUS_INVALID
    from planar_lcp.engine.solvers.lemke import lemke_solve
    z, w, status, pivots, res = lemke_solve(np.array([[np.nan]]), np.array([-1.0]), 10, 1e-12, 1e-12, 1e-9, False)
    assert status == STATUS_INVALID and pivots == 0


def test_trivial_cases():
    r = lemke(np.eye(3), np.array([1.0, 0.0, 2.0]))
    assert r.status == "solved" and r.pivots == 0 and np.all(r.z == 0)
    r = lemke(np.zeros((0, 0)), np.zeros(0))
    assert r.status == "solved" and r.z.shape == (0,)


@SETTINGS
@given(seed=seeds, n=sizes)
def test_basis_refinement_matches_numpy_solve_on_the_support(seed, n):
    """The refinement step re-solves the final complementary basis from the original data; oracle: numpy."""
    from planar_lcp.engine.layout import LemkeSettings, lemke_work_struct, make_lemke_work
    from planar_lcp.engine.solvers.lemke import lemke_kernel, refine_from_basis
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    S = rng.normal(size=(n, n))
    M = A @ A.T + 0.1 * np.eye(n) + (S - S.T)
    q = rng.normal(size=n)
    work = make_lemke_work(n)
    status, pivots, res = lemke_kernel(M, q, LemkeSettings(1000, 1e-12, 1e-12, 1e-9, True), lemke_work_struct(work))
    basis, z = work.lemke_basis, work.lemke_z
    assert status == 0
    out = np.empty(n)
    if pivots == 0:
        return
    ok, _ = refine_from_basis(M, q, basis, n, out, work.lemke_lu, work.lemke_rhs, work.lemke_perm, work.lemke_basic,
                              work.lemke_rows)
    assert ok
    support = [basis[i] - n for i in range(n) if n <= basis[i] < 2 * n]
    expect = np.zeros(n)
    if support:
        expect[support] = np.linalg.solve(M[np.ix_(support, support)], -q[support])
    np.testing.assert_allclose(out, expect, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(out, z, rtol=1e-7, atol=1e-9)
