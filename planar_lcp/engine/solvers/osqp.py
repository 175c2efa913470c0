"""The `osqp` solver: Anitescu's convex relaxation of the contact problem, as a QP solved by OSQP.

Same contacts, same polygonal friction cone and same linear terms as the LCP (the island's force block W = G^T M^-1 G
and the constant vector come from `assemble_lcp`), but instead of the complementarity between each contact's normal
velocity and its impulse, the QP

    minimize 1/2 x^T W x + c^T x    over x = (c_n, beta)  in the cone  {c_n >= 0, beta >= 0, e^T beta <= mu c_n}
                                                           (table friction: e^T beta <= mu h load, the load known)

whose optimality conditions are those of the LCP except that the normal row reads n.v+ + phi/h = mu lambda instead of
0 while sliding (lambda is the sliding speed). Known artefact: a sliding contact separates at the rate mu times its
sliding speed (a box sliding on the table rises by mu |v_t| h per step and falls back under gravity). In exchange
the problem is convex and always solvable. OSQP is a C library called from Python: `solve_island_osqp` is a Python
island solver, run by the step pipeline's Python function over the jitted stages (`osqp_step`), far slower than
`lemke`, and meant for comparison.
"""

import contextlib
import os
import sys

import numpy as np

from planar_lcp.engine.assemble import (apply_impulses, assemble_lcp, contact_velocities, island_problem_size,
                                        island_servo, record_impulses, record_servo_lag, servo_count, servo_direction,
                                        support_column_count)
from planar_lcp.engine.constants import SERVO_FORCE_DIRECTIONS
from planar_lcp.engine.layout import Stat, python_view
from planar_lcp.engine.solvers.certificate import STATUS_INACCURATE, STATUS_SOLVED
from planar_lcp.engine.solvers.pgs import solve_island_pgs
from planar_lcp.engine.rollout import rollout_loop
from planar_lcp.engine.step import project_positions, step_pipeline

#: OSQP's absolute and relative tolerance
OSQP_EPS = 1e-9

# The Python functions of the step pipeline and the rollout loop (numba keeps them as .py_func; without the JIT the
# decorators return them as they are)
STEP_PIPELINE_PY = getattr(step_pipeline, "py_func", step_pipeline)
ROLLOUT_LOOP_PY = getattr(rollout_loop, "py_func", rollout_loop)


@contextlib.contextmanager
def _quiet_c_stdout():
    """osqp 1.1.3 prints "Polishing not needed ..." from C even with verbose=False: silence fd 1 around solve()."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def solve_island_osqp(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    """Island solver (signature: engine/step.py), in Python: the island's QP by OSQP. m, w are the kernels' structs,
    passed on to the jitted stages; their arrays are read here through their Python views. A QP OSQP does not solve
    returns STATUS_INACCURATE (the pipeline's fallback then solves the island and the step reports it)."""
    import osqp
    from scipy import sparse

    mv, wv = python_view(m), python_view(w)
    n, nf, _ = island_problem_size(m, wv.island_con, nci, nsi, wv.con_pair)
    isl_con, isl_sup = wv.island_con[:nci], wv.island_sup[:nsi]
    k = support_column_count(m)
    A = np.zeros((n, n))
    b = np.zeros(n)
    assemble_lcp(m, w, vk, nci, nsi, h, velocity_form, A, b)
    nforce = nci + 2 * nf + k * nsi
    P = A[:nforce, :nforce]
    c = b[:nforce]
    # cone constraints: x >= 0; mu c_n - beta+ - beta- >= 0 per frictional contact; sum beta_s <= mu h load
    rows, cols, vals = list(range(nforce)), list(range(nforce)), [1.0] * nforce
    lo, hi = [0.0] * nforce, [np.inf] * nforce
    r = nforce
    f = 0
    for a in range(nci):
        mu = mv.pair_mu[wv.con_pair[isl_con[a]]]
        if mu <= 0.0:
            continue
        u = nci + 2 * f
        rows += [r, r, r]
        cols += [a, u, u + 1]
        vals += [mu, -1.0, -1.0]
        lo.append(0.0)
        hi.append(np.inf)
        r += 1
        f += 1
    for a in range(nsi):
        s = isl_sup[a]
        base = nci + 2 * nf + k * a
        rows += [r] * k
        cols += list(range(base, base + k))
        vals += [1.0] * k
        lo.append(-np.inf)
        hi.append(mv.sup_mu[s] * h * mv.sup_load[s])
        r += 1
    # force-limited kinematic bodies (engine/assemble.py): the contact impulse C each takes within its polygon and
    # torque limit, e_j . C <= h F_j; the constraints' multipliers are its lag along e_j (the LCP's lag unknowns)
    nsb, ns = island_servo(m, w, nci, nf)
    servo_rows = r
    for i in range(nsb):
        kk = wv.island_servo[i]
        for jd in range(int(servo_count(m, kk))):
            ex, ey, et = servo_direction(jd)
            for col in range(nci + 2 * nf):
                if wv.column_servo[col] == i:
                    g = wv.column_gk[col, 0] * ex + wv.column_gk[col, 1] * ey + wv.column_gk[col, 2] * et
                    rows.append(r)
                    cols.append(col)
                    vals.append(g)
            lo.append(-np.inf)
            hi.append(h * (mv.kin_max_force[kk] if jd < SERVO_FORCE_DIRECTIONS else mv.kin_max_torque[kk]))
            r += 1
    C = sparse.csc_matrix((vals, (rows, cols)), shape=(r, nforce))
    solver = osqp.OSQP()
    solver.setup(P=sparse.csc_matrix(np.triu(P)), q=c, A=C, l=np.array(lo), u=np.array(hi), eps_abs=OSQP_EPS,
                 eps_rel=OSQP_EPS, max_iter=20000, polishing=True, verbose=False)
    with _quiet_c_stdout():
        res = solver.solve(raise_error=False)  # a failure is reported through the status, never raised
    stats[Stat.LCP_SIZE] += nforce
    stats[Stat.LCP_MAX] = max(stats[Stat.LCP_MAX], nforce)
    x = np.asarray(res.x, dtype=float)
    ok = str(res.info.status).lower().startswith("solved") and np.all(np.isfinite(x))
    if not ok:
        stats[Stat.LEMKE_STATUS] = max(stats[Stat.LEMKE_STATUS], STATUS_INACCURATE)
        stats[Stat.RESIDUAL] = np.inf
        return STATUS_INACCURATE
    # the QP's own primal residual, for the step diagnostics
    stats[Stat.RESIDUAL] = max(stats[Stat.RESIDUAL], float(res.info.prim_res))
    x = np.ascontiguousarray(np.maximum(x, 0.0))  # OSQP's answer is feasible to eps: remove the -eps entries
    if nsb > 0:
        y = np.maximum(np.asarray(res.y, dtype=float)[servo_rows:], 0.0)
        lag = np.zeros(max(ns, 1))
        lag[:ns] = y
        record_servo_lag(m, w, vk, 0, nsb, lag)
        if y.size and y.max() > 0.0:
            stats[Stat.SERVO_LIMITED] += 1
    apply_impulses(nforce, wv.column_slot, wv.column_g, x, m, wv.v_new)
    record_impulses(m, w, nci, x, False, nci)
    contact_velocities(m, w, opt, wv.kin_velocity, nci)
    return STATUS_SOLVED


def osqp_step(m, state, h, opt, w, out, stats):
    """The step variant of solver osqp (a step variant's arguments): the step pipeline run as Python, each island
    solved by OSQP, PGS as the fallback, the velocity form's projection."""
    return int(STEP_PIPELINE_PY(solve_island_osqp, solve_island_pgs, project_positions, m, state, h, opt, w, out,
                                stats))


def osqp_rollout(m, run, h, opt, w, rec):
    """The rollout variant of solver osqp (a rollout variant's arguments): the rollout loop run as Python."""
    return ROLLOUT_LOOP_PY(osqp_step, m, run, h, opt, w, rec)
