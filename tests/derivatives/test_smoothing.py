"""Randomized smoothing of the step (planar_lcp.derivatives.smoothing): the Jacobian of E[step(x + w)] for Gaussian
w, against its closed form where the step is piecewise linear (a disk at a wall: the modes blended by their
probability) and against the step's own Jacobian far from any switch."""

import math

import numpy as np
import pytest

from planar_lcp import SimOptions, Simulator
from planar_lcp.derivatives import scene_with_param, step_derivatives
from planar_lcp.model import compile_scene
from planar_lcp.spec.scene import load_scene

from derivative_scenes import disk_at_wall


def _phi(t):
    return 0.5 * (1.0 + math.erf(t / math.sqrt(2.0)))


@pytest.mark.parametrize("method, samples", [("zeroth", 400), ("first", 100)])
def test_at_a_wall_the_modes_blend_by_their_probability(method, samples):
    """E[min(vx + w_v, -w_x / h)]: its derivative along vx is P(vx + w_v < -w_x / h) = Phi(-vx / s) with
    s^2 = sigma_v^2 + (sigma_x / h)^2, and along x -(1 - that) / h. The step's own derivative at vx = 0.01 > 0 is 0
    (the disk stops at the wall): the smoothed one sees the other mode within a few sigma."""
    sim = disk_at_wall()
    q, v, qk, vk = sim.initial_state()
    v = v.copy()
    v[0, 0] = 0.01
    h = sim.h
    sigma = np.array([1e-4, 1e-4, 0.01, 0.02, 0.02, 0.1])             # x, y, angle, vx, vy, omega
    d = sim.smoothed_derivatives(q, v, qk, vk, sigma, samples=samples, seed=1, method=method)
    p = _phi(-0.01 / math.hypot(0.02, 1e-4 / h))
    assert d.failed == 0 and d.samples == samples and d.method == method and not d.exact
    # precise enough that the step's own derivative (0 and -1 / h) is many standard errors away
    assert d.stderr[3, 3] < 0.15 * p and d.stderr[3, 0] < 0.15 * (1 - p) / h
    assert abs(d.dv_dv[0, 0] - p) < 4 * d.stderr[3, 3]
    assert abs(d.dv_dq[0, 0] + (1 - p) / h) < 4 * d.stderr[3, 0]
    assert abs(d.dq_dv[0, 0] - h * p) < 4 * d.stderr[0, 3]           # q+ = q + h v+
    assert step_derivatives(sim, q, v, qk, vk).dv_dv[0, 0] == pytest.approx(0.0, abs=1e-12)


def test_far_from_any_switch_it_is_the_steps_jacobian():
    """A block sliding down an incline (an exact state, linear in the inputs over a range far wider than sigma):
    the first-order estimate averages equal Jacobians, the zeroth-order one is that Jacobian within its error."""
    scene = scene_with_param(load_scene("block_on_incline"), "world.friction", 0.3)
    sim = Simulator(compile_scene(scene), SimOptions())
    q, v, qk, vk = sim.initial_state()
    v = v.copy()
    v[0, :2] = 0.3 * np.array([-math.cos(math.radians(30)), -math.sin(math.radians(30))])
    exact = step_derivatives(sim, q, v, qk, vk)
    assert exact.exact
    sigma = 1e-5
    first = sim.smoothed_derivatives(q, v, qk, vk, sigma, samples=8, seed=3, method="first")
    # the Jacobians averaged differ from the point's by O(sigma^2) of the entry's row or column scale (the pairs cancel
    # the first order), and a row and column of round-off zeros (d(angle+)/d(omega)) by round-off of the whole's
    big = np.abs(exact.jacobian)
    scale = np.maximum(np.max(big, axis=0)[None, :], np.max(big, axis=1)[:, None])
    assert np.all(np.abs(first.jacobian - exact.jacobian) <= 1e-9 * scale + 1e-12 * big.max())
    zeroth = sim.smoothed_derivatives(q, v, qk, vk, sigma, samples=200, seed=3)
    assert np.all(np.abs(zeroth.jacobian - exact.jacobian) <= 4 * zeroth.stderr + 1e-9)
    assert np.max(zeroth.stderr) > 0                                  # a Monte Carlo estimate, not the Jacobian copied
    np.testing.assert_array_equal(zeroth.q, exact.q)                  # the step at the point itself


def test_the_same_seed_gives_the_same_answer_and_bad_input_is_named():
    sim = disk_at_wall()
    q, v, qk, vk = sim.initial_state()
    a = sim.smoothed_derivatives(q, v, qk, vk, 1e-3, samples=4, seed=7)
    b = sim.smoothed_derivatives(q, v, qk, vk, 1e-3, samples=4, seed=7)
    np.testing.assert_array_equal(a.jacobian, b.jacobian)
    for kwargs, words in ((dict(sigma=[1e-3] * 5), "one per input"), (dict(sigma=-1.0), ">= 0"),
                          (dict(sigma=[0, 1, 1, 1, 1, 1]), "needs sigma > 0"),
                          (dict(sigma=1e-3, method="second"), "zeroth, first"),
                          (dict(sigma=1e-3, samples=1), ">= 2")):
        with pytest.raises(ValueError, match=words):
            sim.smoothed_derivatives(q, v, qk, vk, **kwargs)
    # an input left unperturbed (sigma 0) by the first-order method keeps the step's own column there
    d = sim.smoothed_derivatives(q, v, qk, vk, [0, 0, 0, 0, 0, 0], samples=2, method="first")
    np.testing.assert_allclose(d.jacobian, step_derivatives(sim, q, v, qk, vk).jacobian, atol=1e-12)
