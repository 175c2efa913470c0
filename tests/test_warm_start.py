"""Warm start: each island's LCP is first tried on the previous step's basis (kernels/lemke.py lemke_from_basis),
kept only when certified by the residual; otherwise Lemke solves it cold.

Oracles: a dense numpy solve on the guessed basis and the enumeration of all complementary bases (for the kernel);
the cold-start simulation of the same scene (for the step); bitwise equality where the contract promises it.
"""

import itertools

import numpy as np
import pytest

from planar_lcp import load_scene, simulate
from planar_lcp.kernels.lemke import lemke_from_basis, lemke_kernel, make_lemke_work
from planar_lcp.kernels.step import ST_WARM_STARTS
from planar_lcp.lcp import DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL
from planar_lcp.model import compile_scene
from planar_lcp.scene import list_scenes
from planar_lcp.sim import SimOptions, Simulator


def _from_basis(M, q, mask):
    n = len(q)
    T, basis, z, w, cand, lu, rhs, perm, zb, zalt, walt, prow = make_lemke_work(n)
    ok, res = lemke_from_basis(M, q, np.asarray(mask, np.bool_), DEFAULT_RES_TOL, z, w, lu, rhs, perm, zb)
    return ok, res, z.copy()


def _cold(M, q):
    n = len(q)
    work = make_lemke_work(n)
    status, piv, res = lemke_kernel(M, q, 50 * n + 100, DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL, *work)
    basis = work[1]
    mask = np.zeros(n, np.bool_)
    for k in basis[:n]:
        if n <= k < 2 * n:
            mask[k - n] = True
    return status, work[2][:n].copy(), mask


@pytest.mark.parametrize("seed", range(20))
def test_every_complementary_basis_is_accepted_exactly_when_it_solves_the_lcp(seed):
    """P-matrix LCPs (unique solution): of the 2^n guesses, the one the enumeration oracle finds is accepted with
    the oracle's z, and every other is rejected."""
    rng = np.random.default_rng(seed)
    n = 5
    B = rng.normal(size=(n, n))
    M = B @ B.T + 0.5 * np.eye(n)          # symmetric positive definite: a P-matrix
    q = rng.normal(size=n)
    accepted = []
    for mask in itertools.product((False, True), repeat=n):
        ok, res, z = _from_basis(M, q, mask)
        idx = np.flatnonzero(mask)
        zo = np.zeros(n)
        if idx.size:
            zo[idx] = np.linalg.solve(M[np.ix_(idx, idx)], -q[idx])
        wo = M @ zo + q
        truly = zo.min() >= -1e-12 and wo.min() >= -1e-12
        assert ok == truly, (mask, res)
        if ok:
            accepted.append(mask)
            np.testing.assert_allclose(z, zo, rtol=1e-12, atol=1e-13)
    assert len(accepted) >= 1


def test_the_cold_basis_is_accepted_and_gives_the_cold_answer():
    rng = np.random.default_rng(7)
    for _ in range(30):
        n = 8
        B = rng.normal(size=(n, n))
        M, q = B @ B.T + 0.1 * np.eye(n), rng.normal(size=n)
        status, z_cold, mask = _cold(M, q)
        assert status == 0
        ok, res, z = _from_basis(M, q, mask)
        assert ok and res <= 1e-3 * DEFAULT_RES_TOL * max(1.0, np.abs(M).max(), np.abs(q).max())
        np.testing.assert_allclose(z, z_cold, rtol=1e-10, atol=1e-12)


def test_a_singular_guess_is_rejected_not_raised():
    M = np.array([[1.0, 1.0], [1.0, 1.0]])
    q = np.array([-1.0, -1.0])
    ok, res, _ = _from_basis(M, q, [True, True])
    assert not ok and res == np.inf


@pytest.mark.parametrize("name", [n for n, _ in list_scenes()])
def test_warm_and_cold_runs_agree_to_round_off(name):
    """The warm start changes only how each LCP is solved, not the answer: on every shipped scene the two runs
    agree to 1e-8 (m, rad; chaotic contact sequences amplify round-off, push_t's measured difference is 6e-10)."""
    warm = simulate(name, t_end=min(load_scene(name).sim.t_end, 1.0))
    cold = simulate(name, t_end=min(load_scene(name).sim.t_end, 1.0), warm_start=False)
    assert np.abs(warm.q - cold.q).max() <= 1e-8
    assert warm.stats["warm_starts"].sum() > 0 or warm.stats["lcp_size"].sum() == 0
    assert cold.stats["warm_starts"].sum() == 0


def test_steady_pushing_reuses_the_basis():
    tr = simulate("box_push")
    with_lcp = tr.stats["lcp_size"] > 0
    assert tr.stats["warm_starts"][with_lcp].mean() >= 0.9
    assert tr.stats["pivots"][with_lcp].mean() < 1.0


def _sim(name):
    sc = load_scene(name)
    return Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))


def test_step_continues_only_from_its_own_last_output():
    sim, fresh = _sim("box_push"), _sim("box_push")
    q, v, qk, vk = sim.initial_state()
    out = sim.rollout(q, v, qk, vk[None], 50)
    x = (out["q"][50].copy(), out["v"][50].copy(), out["qk"][50].copy())
    # after a rollout, a step starts cold: bitwise the fresh simulator's step
    a = sim.step(*x, vk)
    assert sim.stats[ST_WARM_STARTS] == 0
    b = fresh.step(*x, vk)
    for u, w in zip(a[:3], b[:3]):
        assert np.array_equal(u, w)
    # continuing from its own output, it warm-starts
    sim.step(*a[:3], vk)
    assert sim.stats[ST_WARM_STARTS] >= 1
    # from any other state it starts cold again
    sim.step(*x, vk)
    assert sim.stats[ST_WARM_STARTS] == 0
    # and reset_warm_start() forgets the basis: a continuation then starts cold
    d = sim.step(*x, vk)
    sim.reset_warm_start()
    sim.step(*d[:3], vk)
    assert sim.stats[ST_WARM_STARTS] == 0


def test_rollout_is_a_function_of_its_inputs_only():
    """Planners call rollout from arbitrary tree states: its result must not depend on earlier calls."""
    sim = _sim("push_t")
    q, v, qk, vk = sim.initial_state()
    first = sim.rollout(q, v, qk, vk[None], 40)
    sim.rollout(first["q"][40], first["v"][40], first["qk"][40], vk[None], 40)   # leaves a basis behind
    again = sim.rollout(q, v, qk, vk[None], 40)
    assert np.array_equal(first["q"], again["q"]) and np.array_equal(first["v"], again["v"])
