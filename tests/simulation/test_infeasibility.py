"""Certified infeasibility (planar_lcp/infeasibility.py): when no method certifies an island's LCP, the
branch and bound decides whether it has a solution at all, with a certificate checked here independently of the
code that made it.

Oracles: the third-party corpus's own enumeration of every complementary basis (which instances have no solution),
an exhaustive enumeration of seeded random small LCPs written here, and a check of the certificate itself: its
branches cover every complementary choice, and each branch's Farkas vector proves its set empty in exact
arithmetic up to the rounding bound."""

import itertools

import numpy as np
import pytest

from planar_lcp.engine.solvers.certificate import lcp_scale
from planar_lcp.infeasibility import branch_and_bound, branch_system, farkas_certificate, impulse_bound

pytest.importorskip("scipy")


def enumerate_lcp(M, q, tol=1e-9):
    """Every complementary basis of a small LCP: the solutions found (a dense numpy oracle)."""
    n = q.shape[0]
    sols = []
    for mask in itertools.product([False, True], repeat=n):
        Z = np.array(mask)
        z = np.zeros(n)
        if Z.any():
            try:
                z[Z] = np.linalg.solve(M[np.ix_(Z, Z)], -q[Z])
            except np.linalg.LinAlgError:
                continue
        w = M @ z + q
        scale = max(1.0, np.abs(z).max())
        if z.min() >= -tol * scale and w.min() >= -tol * scale * max(1.0, np.abs(M).max()):
            sols.append(z)
    return sols


def check_certificate(M, q, search):
    """The certificate as a reader checks it: every complementary choice (z_i = 0 or w_i = 0 for each i) falls in
    a branch (its decided pairs are among the choice's), and each branch's y proves its set empty."""
    n = q.shape[0]
    leaves = [(frozenset(zz), frozenset(zw)) for zz, zw, _ in search.leaves]
    for choice in itertools.product([0, 1], repeat=n):       # 0: z_i = 0, 1: w_i = 0
        zero_z = {i for i in range(n) if choice[i] == 0}
        zero_w = {i for i in range(n) if choice[i] == 1}
        assert any(zz <= zero_z and zw <= zero_w for zz, zw in leaves), choice
    for zero_z, zero_w, y in search.leaves:
        G, g, _, _ = branch_system(M, q, zero_z, zero_w)
        assert np.all(y >= 0)
        assert impulse_bound(G, g, y) >= search.bound > 0


def test_farkas_certifies_a_head_on_jam_and_nothing_feasible():
    # the frictionless head-on jam in two rows: the pusher needs v >= 1, the wall v <= 0 (w = M z + q, z the impulses)
    M = np.array([[1.0, -1.0], [-1.0, 1.0]])
    q = np.array([-1.0, 0.0])
    y = farkas_certificate(M, q)
    assert y is not None and np.all(y >= 0) and np.all(M.T @ y <= 1e-12) and q @ y < 0
    assert impulse_bound(M, q, y) > 1e10
    assert farkas_certificate(np.eye(2), np.array([-1.0, 2.0])) is None      # z = (1, 0) is feasible
    assert impulse_bound(M, q, np.zeros(2)) == 0.0 and impulse_bound(M, q, np.array([0.0, 1.0])) == 0.0


def test_branch_and_bound_agrees_with_the_corpus_enumeration():
    from planar_lcp.benchmarks.lcp_corpus import find_corpus_dir, load_corpus
    corpus = find_corpus_dir()
    if corpus is None:
        pytest.skip("the LCP corpus (../shared/data/lcp) is absent")
    checked = {"infeasible": 0, "solution": 0}
    for inst in load_corpus(corpus):
        enum = (inst.extra or {}).get("enumeration")
        if not enum or inst.M.shape[0] > 12:
            continue
        r = branch_and_bound(inst.M, inst.q)
        if enum["num_distinct_basic_solutions"] == 0:
            assert r.outcome == "infeasible", inst.id
            check_certificate(inst.M, inst.q, r)
        else:
            assert r.outcome == "solution", inst.id
            # certified as the step certifies an answer: the natural residual within 1e-9 of lcp_scale (SimOptions)
            assert r.z.min() >= 0 and r.residual <= 1e-9 * lcp_scale(inst.M, inst.q), inst.id
        checked[r.outcome] += 1
    assert checked["infeasible"] >= 4 and checked["solution"] >= 30, checked


@pytest.mark.parametrize("seed", range(60))
def test_branch_and_bound_agrees_with_enumeration_on_random_lcps(seed):
    """Seeded random LCPs of 2 to 7 unknowns: indefinite matrices, so that some have no solution and some several.
    The outcome is the enumeration's, and an infeasible one's certificate checks."""
    rng = np.random.default_rng([20261203, seed])
    n = int(rng.integers(2, 8))
    M = rng.integers(-4, 5, (n, n)).astype(float)
    q = rng.integers(-4, 5, n).astype(float)
    sols = enumerate_lcp(M, q)
    r = branch_and_bound(M, q)
    assert r.outcome in ("infeasible", "solution")
    if r.outcome == "infeasible":
        assert not sols
        check_certificate(M, q, r)
    else:
        assert sols
        w = M @ r.z + q
        assert r.z.min() >= 0 and w.min() >= -1e-9 and np.abs(r.z * w).max() <= 1e-9 * max(1, np.abs(r.z).max())


def test_the_random_lcps_have_both_outcomes():
    outcomes = set()
    for seed in range(60):
        rng = np.random.default_rng([20261203, seed])
        n = int(rng.integers(2, 8))
        M = rng.integers(-4, 5, (n, n)).astype(float)
        q = rng.integers(-4, 5, n).astype(float)
        outcomes.add(bool(enumerate_lcp(M, q)))
    assert outcomes == {True, False}


def test_the_search_says_when_it_runs_out_of_branches():
    """An LCP whose certificate takes several branches, given fewer: the question stays open, never a wrong answer."""
    for seed in range(60):
        rng = np.random.default_rng([20261203, seed])
        n = int(rng.integers(2, 8))
        M = rng.integers(-4, 5, (n, n)).astype(float)
        q = rng.integers(-4, 5, n).astype(float)
        full = branch_and_bound(M, q)
        if full.outcome == "infeasible" and full.branches >= 3:
            short = branch_and_bound(M, q, max_branches=full.branches - 1)
            assert short.outcome == "open" and short.branches == full.branches - 1
            return
    pytest.fail("no random LCP whose certificate takes 3 branches or more")


def test_the_jam_scan_example_runs_end_to_end():
    """docs/method.md's jam table: `python examples/measurements/jam_scan.py` end to end, on a few seeds."""
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, str(root / "examples" / "measurements" / "jam_scan.py"), "--seeds", "6"], capture_output=True,
                         text=True, timeout=900)
    assert run.returncode == 0, run.stderr
    rows = [line for line in run.stdout.splitlines() if line.startswith("| position") or line.startswith("| velocity")]
    assert len(rows) == 2 and all(r.split("|")[5].strip() == "0" for r in rows), run.stdout
