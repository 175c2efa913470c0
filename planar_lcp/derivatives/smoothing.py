"""Randomized smoothing of the step, for planning and optimisation through contact (docs/method.md, "Smoothed
derivatives").

The step is piecewise smooth: its Jacobian jumps where a contact's mode switches (touching or not, sticking or
sliding), and is zero along directions a sticking contact holds still, so a gradient step near a switch sees only one
side of it. Randomized smoothing replaces the step f(x) by its expectation under Gaussian noise on the inputs,

    f_sigma(x) = E[f(x + w)],  w ~ N(0, diag(sigma^2)),

whose Jacobian blends the modes within a few sigma of x by their probabilities (Suh, Simchowitz, Zhang and Tedrake,
"Do differentiable simulators give better policy gradients?", ICML 2022; Pang, Suh, Yang and Tedrake, "Global
planning for contact-rich manipulation via local smoothing of quasi-dynamic contact models", T-RO 2023). Two
estimators of it, over `samples` antithetic pairs x + w_i, x - w_i:

- "zeroth" (the default): (f(x + w_i) - f(x - w_i)) / 2 times (w_i / sigma^2), averaged; by Stein's identity its mean
  is the Jacobian of f_sigma, also across discontinuities of f. 2 samples compiled steps. Every input needs a
  sigma > 0.
- "first": the step's own Jacobian (`step_derivatives`, the mean of its one-sided derivatives) at x + w_i and
  x - w_i, averaged. Lower variance where f is continuous, but biased where f jumps (a jump has no derivative to
  average). 2 samples times `step_derivatives`' cost. An input with sigma = 0 is not perturbed.

`stderr` is the Monte Carlo standard error of each entry (the spread of the pairs' estimates over sqrt(samples)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planar_lcp.derivatives import StepDerivatives, _check_finite, _check_state, flat_step

SMOOTHING_METHODS = ("zeroth", "first")


@dataclass
class SmoothedDerivatives(StepDerivatives):
    """The Jacobian of the smoothed step f_sigma (module docstring) at (q, v, qk, vk), with the blocks of
    `StepDerivatives` (dq_dq, dv_dv, ...; no parameters). q, v, qk, status: the step at the point itself. `exact` is
    False: this is not the step's derivative. `stderr`: the Monte Carlo standard error of each entry of `jacobian`;
    `sigma`: the noise's standard deviation per input (the columns' order); `samples`: antithetic pairs; `method`;
    `failed`: pairs left out because a step in them failed (their steps' status was not 0)."""

    stderr: np.ndarray | None = None
    sigma: np.ndarray | None = None
    samples: int = 0
    method: str = "zeroth"
    failed: int = 0


def smoothed_derivatives(sim, q, v, qk, vk, sigma, samples=64, seed=0, method="zeroth"):
    """The Jacobian of the randomized smoothing of `sim.step` at (q, v, qk, vk) (a `SmoothedDerivatives`).

    sigma: the noise's standard deviation, one number for every input or one per input in the Jacobian's column
    order (q, v, qk, vk flattened row-major; in their units: m, rad, m/s, rad/s); samples: antithetic pairs; seed:
    numpy's default_rng seed (the same seed, the same answer). The steps are cold (no warm start)."""
    if method not in SMOOTHING_METHODS:
        raise ValueError(f"smoothed_derivatives: method must be one of {', '.join(SMOOTHING_METHODS)}, got "
                         f"{method!r}")
    q, v, qk, vk = _check_state(sim, q, v, qk, vk)
    _check_finite(q, v, qk, vk)
    parts = (q, v, qk, vk)
    x0 = np.concatenate([a.ravel() for a in parts])
    K = len(x0)
    sig = np.broadcast_to(np.asarray(sigma, dtype=np.float64), (K,)).copy() if np.ndim(sigma) == 0 else \
        np.asarray(sigma, dtype=np.float64)
    if sig.shape != (K,) or not np.all(np.isfinite(sig)) or np.any(sig < 0):
        raise ValueError(f"smoothed_derivatives: sigma must be one number or {K} (one per input), finite and >= 0, "
                         f"got {np.asarray(sigma).shape if np.ndim(sigma) else sigma}")
    if method == "zeroth" and np.any(sig == 0):
        raise ValueError("smoothed_derivatives: method 'zeroth' needs sigma > 0 for every input (its estimate of a "
                         "column divides by that input's sigma); use method 'first' to leave inputs unperturbed")
    if int(samples) < 2:
        raise ValueError(f"smoothed_derivatives: samples must be >= 2, got {samples}")
    samples = int(samples)
    sizes = np.cumsum([a.size for a in parts])[:-1]
    step = flat_step(sim, parts)

    def unflat(x):
        return [c.reshape(a.shape) for c, a in zip(np.split(x, sizes), parts)]

    rng = np.random.default_rng(seed)
    eps = rng.standard_normal((samples, K))
    estimates, failed = [], 0
    for e in eps:
        w = sig * e
        if method == "zeroth":
            fp, sp = step(x0 + w)
            fm, sm = step(x0 - w)
            if sp != 0 or sm != 0:
                failed += 1
                continue
            estimates.append(np.outer(0.5 * (fp - fm), e / sig))
        else:
            dp = sim.step_derivatives(*unflat(x0 + w))
            dm = sim.step_derivatives(*unflat(x0 - w))
            if dp.status != 0 or dm.status != 0:
                failed += 1
                continue
            estimates.append(0.5 * (dp.jacobian + dm.jacobian))
    if len(estimates) < 2:
        raise RuntimeError(f"smoothed_derivatives: {failed} of {samples} sample pairs had a failed step")
    est = np.array(estimates)
    sim.reset_warm_start()
    q1, v1, qk1, status = sim.step(q, v, qk, vk)
    sim.reset_warm_start()
    return SmoothedDerivatives(q=q1, v=v1, qk=qk1, status=int(status), jacobian=est.mean(axis=0), ndyn=len(q),
                               nkin=len(qk), exact=False, stderr=est.std(axis=0, ddof=1) / np.sqrt(len(est)),
                               sigma=sig, samples=samples, method=method, failed=failed)
