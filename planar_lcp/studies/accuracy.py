"""Stewart & Trinkle's Table 1 error measures of a run against a reference run (`tradeoff`, the studies).

The paper (section 4.2) measures the velocity error by the integral over the run of ||v_h(t) - v(t)||_inf and the
position error by the sup norm of q_h - q, against the finest run as the "exact" solution. In the time stepping
(q_{k+1} = q_k + h v_{k+1}) the velocity v_h(t) on a step (t_k, t_k+1] is v_{k+1}, a step function; its integral is
h sum_{k >= 1} ||v_h(t_k) - v_ref(t_k)||, the reference sampled at the coarse run's step ends. A trapezoidal rule
would integrate a piecewise linear v_h that the scheme does not produce (it weighs the last sample by h / 2 and
interpolates across impacts).
"""

import numpy as np


def grid_ratio(h, h_ref):
    """The whole number h / h_ref; ValueError if the reference step does not divide h."""
    r = int(round(h / h_ref))
    if r < 1 or abs(r * h_ref - h) > 1e-9 * h:
        raise ValueError(f"step size {h} is not a multiple of the reference step size {h_ref}")
    return r


def table1_errors(tr, ref, t_end):
    """(velocity error, position error) of the Trajectory `tr` against `ref` over [0, t_end] (s).

    velocity error = h sum_{k=1..n} ||v_h(t_k) - v_ref(t_k)||_inf (m/s s, rad/s s), position error = max_{k=0..n}
    ||q_h(t_k) - q_ref(t_k)||_inf (m, rad), t_k = k h, n = round(t_end / h); the infinity norm is over every
    coordinate of every dynamic body (the body-frame q and v of the Trajectory).
    """
    h = tr.options.h
    r = grid_ratio(h, ref.options.h)
    n = int(round(t_end / h))
    if len(tr.t) < n + 1 or len(ref.t) < n * r + 1:
        raise ValueError(f"run with h = {h} is shorter than t_end = {t_end}")
    dv = np.abs(tr.v[:n + 1] - ref.v[:n * r + 1:r]).reshape(n + 1, -1).max(axis=1)
    dq = np.abs(tr.q[:n + 1] - ref.q[:n * r + 1:r]).reshape(n + 1, -1).max(axis=1)
    return float(np.sum(dv[1:]) * h), float(dq.max())
