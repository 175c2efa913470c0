"""Block Lemke (engine/solvers/block_lemke.py): Lemke's path pivoted on the Schur complement of its basis.

Oracles: the tableau kernel (lemke.py), pivot for pivot, on the third-party LCP corpus and on random problems; numpy's
inverse of the basis block the kernel keeps updated; the dense LCPs of large islands (the bin of 40 shapes), on which
the answers must move the bodies as the tableau's do; and the time-stepper's counts.
"""

import numpy as np
import pytest

from planar_lcp.engine.layout import LemkeSettings, Stat, lemke_work_struct, make_lemke_work
from planar_lcp.engine.solvers.block_lemke import block_lemke
from planar_lcp.engine.solvers.certificate import STATUS_MAX_PIVOTS, STATUS_SOLVED
from planar_lcp.engine.solvers.lemke import default_max_pivots, lemke_solve
from planar_lcp.benchmarks.lcp_corpus import find_corpus_dir, load_corpus
from planar_lcp.lcp import DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec import piles
from planar_lcp.spec.scene import parse_scene

from test_piles import island_problems, largest_island_problem

TOLS = (DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL)
_dir = find_corpus_dir()
IDS = [inst.id for inst in load_corpus(_dir)] if _dir else ["<corpus absent>"]


def _block(M, q, max_pivots=None):
    """(status, pivots, residual, z, work) of block_lemke on (M, q); work a BlockLemkeWork (engine/layout.py)."""
    n = len(q)
    wk = make_lemke_work(n, block=True)
    st, piv, res = block_lemke(M, q, LemkeSettings(max_pivots or default_max_pivots(n), *TOLS, False),
                               lemke_work_struct(wk))
    return st, piv, res, wk.lemke_z[:n].copy(), wk


def _kinv(wk, n):
    """The K^-1 block Lemke keeps, n x n (its first n * n tableau entries)."""
    return wk.lemke_tableau[:n * n].reshape((n, n))


def _residual(M, q, z):
    w = M @ z + q
    return float(np.abs(np.minimum(z, w)).max() + max(0.0, -z.min()) + max(0.0, -w.min()))


def _scale(M, q):
    return max(1.0, float(np.abs(M).max()), float(np.abs(q).max()))


@pytest.mark.parametrize("inst_id", IDS)
def test_the_corpus_takes_the_tableaus_path(corpus, inst_id):
    """Every corpus instance, the degenerate ones included (Kostreva's cycling example, DART's 12-D box, tobenna,
    Murty's 2^n path): the same status and the same number of pivots as the tableau, and a certified answer."""
    inst = corpus[inst_id]
    M, q = np.ascontiguousarray(inst.M, float), np.ascontiguousarray(inst.q, float)
    zd, _, std, pivd, _ = lemke_solve(M, q, default_max_pivots(len(q)), *TOLS, False)
    st, piv, res, z, _ = _block(M, q)
    assert (st, piv) == (std, pivd)
    if st == STATUS_SOLVED:
        assert _residual(M, q, z) <= DEFAULT_RES_TOL * _scale(M, q)


def _random_lcp(rng, kind, n):
    G = rng.normal(size=(n, n))
    if kind == "pd":
        M = G @ G.T + 0.1 * np.eye(n)
    elif kind == "psd_skew":
        M = G @ G.T + (G - G.T)
    elif kind == "low_rank":
        H = rng.normal(size=(n, max(1, n // 2)))
        M = H @ H.T
    else:
        M = G
    return M, rng.normal(size=n)


@pytest.mark.parametrize("kind", ["pd", "psd_skew", "low_rank", "general"])
def test_random_problems_take_the_tableaus_path(kind):
    """200 random LCPs of 1 to 40 unknowns of each kind: the same status and pivots as the tableau; where the
    solution is unique (positive definite M) the same z; every answer reported solved is certified."""
    rng = np.random.default_rng(7)
    solved = 0
    for _ in range(200):
        n = int(rng.integers(1, 41))
        M, q = _random_lcp(rng, kind, n)
        zd, _, std, pivd, _ = lemke_solve(M, q, default_max_pivots(n), *TOLS, False)
        st, piv, res, z, _ = _block(M, q)
        assert (st, piv) == (std, pivd)
        if st == STATUS_SOLVED:
            solved += 1
            assert _residual(M, q, z) <= DEFAULT_RES_TOL * _scale(M, q)
            if kind == "pd":
                np.testing.assert_allclose(z, zd, rtol=1e-9, atol=1e-9 * _scale(M, q))
    # positive (semi)definite: Lemke always solves; general random M mostly ends on a ray, as the tableau does
    assert solved >= {"pd": 200, "psd_skew": 200, "low_rank": 40, "general": 5}[kind]


def test_the_updated_inverse_is_the_inverse_of_the_basis_block():
    """Stopped after 10 to 250 pivots on a settled bin's LCP (grown, shrunk, row- and column-replaced K): the K^-1 it
    keeps equals numpy's inverse of K = [M | e][rows, cols] within 1e-8, relative."""
    ok, its, z, A, b, nci, nf = island_problems(piles.bin_scene(40), 60, 60)[0]
    n = len(b)
    Ae = np.hstack([A, np.ones((n, 1))])
    for m in (10, 50, 100, 150, 200, 250):
        st, piv, res, z, wk = _block(A, b, max_pivots=m)
        assert st == STATUS_MAX_PIVOTS and piv == m
        row_pos = wk.block_row_pos[:n]
        k = int((row_pos >= 0).sum())
        cols, rows = wk.block_cols[:k], wk.block_rows[:k]
        K = Ae[np.ix_(rows, cols)]
        Kinv = np.linalg.inv(K)
        assert np.abs(_kinv(wk, n)[:k, :k] - Kinv).max() <= 1e-8 * np.abs(Kinv).max(), m


def test_a_bins_lcps_are_solved_as_the_tableau_solves_them():
    """The largest island of a bin of 40 shapes falling and settled (LCPs of 300 to 372 unknowns): certified, the
    tableau's number of pivots, and the same velocity rows (the bodies move the same) to 1e-9 of the scale."""
    probs = island_problems(piles.bin_scene(40), 90, 30)
    for ok, its, zs, A, b, nci, nf in probs:
        n = len(b)
        assert n >= 300
        assert np.count_nonzero(A) <= 0.05 * n * n       # docs/method.md: 4 % of the matrix (contacts sharing a body)
        zd, _, std, pivd, _ = lemke_solve(A, b, default_max_pivots(n), *TOLS, False)
        st, piv, res, z, _ = _block(A, b)
        assert st == std == STATUS_SOLVED
        assert abs(piv - pivd) <= 0.05 * pivd      # round-off can split a tie differently
        scale = _scale(A, b)
        assert _residual(A, b, z) <= DEFAULT_RES_TOL * scale
        np.testing.assert_allclose(A[:nci] @ z + b[:nci], A[:nci] @ zd + b[:nci], atol=1e-9 * scale)


def test_the_time_stepper_solves_a_bins_large_islands_by_block_lemke():
    """A bin of 40 shapes for 60 steps (the fall and the pile) with the defaults: its large islands, which the mode
    iteration leaves (statically indeterminate), are solved by block Lemke, the rest by the tableau; no step fails,
    and a second run is the same bit for bit."""
    sc = parse_scene(piles.bin_scene(40))
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
    q, v, qk, vk = sim.initial_state()
    out = sim.rollout(q, v, qk, vk[None], 60)
    st = out["stats"]
    large = int(st[:, Stat.SPARSE_FALLBACKS].sum())
    assert large >= 30
    assert st[:, Stat.SOLVED_BLOCK].sum() >= 0.9 * large
    assert st[:, Stat.PGS_UNCERTIFIED].sum() == 0 and st[:, Stat.LEMKE_STATUS].max() == 0
    again = sim.rollout(q, v, qk, vk[None], 60)
    assert np.array_equal(again["q"], out["q"]) and np.array_equal(again["stats"], out["stats"])
    dense = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, sparse_min_unknowns=0))
    assert dense.rollout(q, v, qk, vk[None], 60)["stats"][:, Stat.SOLVED_BLOCK].sum() == 0



def test_a_block_solve_leaves_its_own_basis_for_the_warm_start():
    """With the warm start on, an island solved by block Lemke keeps block Lemke's final basis (z_j basic where it
    holds a column of K) as the next step's guess, not the basis some earlier tableau solve left in the buffers."""
    sc = parse_scene(piles.bin_scene(40))
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, warm_start=True))
    q, v, qk, vk = sim.initial_state()
    out = sim.rollout(q, v, qk, vk[None], 60)
    assert out["stats"][-1, Stat.SOLVED_BLOCK] == 1 and out["stats"][-1, Stat.WARM_STARTS] == 0
    w = sim.work
    n = int(w.warm_size.max())
    assert n >= 300
    isl = int(np.argmax(w.warm_size))
    basic = w.block_col_pos[:n] >= 0
    assert 100 <= basic.sum() < n
    np.testing.assert_array_equal(w.warm_basic_z[isl, :n], basic)


def test_the_certificates_shortcuts_equal_what_they_replace():
    """`_certify`'s two shortcuts against what they stand for. The residual from M's compressed columns equals
    `lcp_residual` bit for bit (the bin's LCP, answers with zeros). The predicted negativity of the complementary
    system (from K^-1, artificial variable basic) equals numpy's solve of M[Z, Z] z = -q[Z] (random positive definite
    LCPs stopped mid-path), so the recomputation it skips would have given a negative z."""
    from planar_lcp.engine.solvers.block_lemke import _complementary_negativity, _residual_csc
    from planar_lcp.engine.solvers.certificate import lcp_residual
    ok, its, z, A, b, nci, nf = island_problems(piles.bin_scene(40), 60, 60)[0]
    n = len(b)
    st, piv, res, zb, wk = _block(A, b)
    assert st == STATUS_SOLVED
    rng = np.random.default_rng(3)
    for zt in (zb, np.where(rng.random(n) < 0.5, 0.0, rng.random(n)), np.zeros(n)):
        w1, w2 = np.empty(n), np.empty(n)
        col_val = wk.lemke_tableau[n * n:2 * n * n]
        assert _residual_csc(col_val, wk.block_col_row, wk.block_col_start, b, zt, w1) == lcp_residual(A, b, zt, w2)
        assert np.array_equal(w1, w2)
    checked = 0
    for _ in range(60):
        m = 12
        G = rng.standard_normal((m, m))
        M, q = G @ G.T + 0.1 * np.eye(m), rng.standard_normal(m)
        for stop in range(1, m + 1):
            st, piv, res, _, wk = _block(M, q, max_pivots=stop)
            if st != STATUS_MAX_PIVOTS:
                break
            row_pos, col_pos = wk.block_row_pos[:m], wk.block_col_pos[:m]
            k = int((row_pos >= 0).sum())
            cols, rows = wk.block_cols[:k], wk.block_rows[:k]
            got = _complementary_negativity(q, k, _kinv(wk, m), cols, rows, col_pos)
            if m not in cols:
                assert got == 0.0
                continue
            Z = np.array([c for c in cols if c != m], dtype=int)
            want = max(0.0, -np.linalg.solve(M[np.ix_(Z, Z)], -q[Z]).min()) if len(Z) else 0.0
            assert abs(got - want) <= 1e-9 * max(1.0, want), (stop, got, want)
            checked += 1
    assert checked >= 100


def _state_and_largest_lcp(scene_dict, steps):
    """A default run's simulator, its state after `steps` steps and its largest island's LCP (A, b) there (the step's
    first solve), assembled densely. (`step` from that state starts cold, as the run's step did not: its memory of
    the modes and bases is reset, so the probe's use of the work buffers changes nothing of it.)"""
    sc = parse_scene(scene_dict)
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
    q, v, qk, vk = sim.initial_state()
    run = sim.rollout(q, v, qk, vk[None], steps)
    state = tuple(np.ascontiguousarray(run[k][steps]) for k in ("q", "v", "qk"))
    _, _, _, A, b, _, _ = largest_island_problem(sim, *state, vk)
    return sim, state, vk, A, b


def test_a_large_island_block_lemke_leaves_is_tried_again_equilibrated():
    """The bin of 40 at step 36: block Lemke on the island's LCP as assembled ends with K singular after 39 pivots,
    and the tableau's own path wanders to its cap (16,900 pivots, measured). On the exactly equilibrated problem
    (another pivot path) block Lemke solves it in about n pivots: the step's islands are all solved by block Lemke,
    certified, none by the tableau."""
    sim, state, vk, A, b = _state_and_largest_lcp(piles.bin_scene(40), 36)
    n = len(b)
    st, piv, res, z, _ = _block(A, b, max_pivots=2 * n + 100)
    assert st != STATUS_SOLVED, "this state no longer exercises the equilibrated retry: pick another"
    sim.step(*state, vk)
    s = sim.stats
    assert s[Stat.LEMKE_STATUS] == 0 and s[Stat.N_ISLANDS] == 1
    assert s[Stat.SOLVED_BLOCK] == s[Stat.RESOLVES] + 1 and s[Stat.SOLVED_LEMKE] + s[Stat.SOLVED_EQUILIBRATED] == 0
    assert s[Stat.PIVOTS] <= 4 * (2 * n + 100)


def test_a_large_islands_tableau_tries_are_capped_before_they_wander():
    """pyramid(8) at step 51: block Lemke fails as assembled and equilibrated, and the tableau as assembled wanders
    (its full cap of 50 n + 100 = 25,700 pivots ended uncertified, 9.3 s, measured). For islands past block Lemke
    each try of the chain is first capped at 2 n + 100 pivots (the equilibrated try then solves it) and only the tries
    that reached that cap are run again with the full cap, if no try was certified."""
    sim, state, vk, A, b = _state_and_largest_lcp(piles.pyramid(8), 51)
    n = len(b)
    zd, _, std, pivd, _ = lemke_solve(A, b, 2 * n + 100, *TOLS, False)
    assert std == STATUS_MAX_PIVOTS, "this state no longer exercises the capped first sweep: pick another"
    sim.step(*state, vk)
    s = sim.stats
    assert s[Stat.LEMKE_STATUS] == 0
    assert s[Stat.SOLVED_EQUILIBRATED] >= 1
    assert s[Stat.PIVOTS] < default_max_pivots(n)
