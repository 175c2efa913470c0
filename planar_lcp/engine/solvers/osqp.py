"""The `osqp` solver: Anitescu's convex relaxation of the contact problem, as a QP solved by OSQP.

Same contacts, same polygonal friction cone and same linear terms as the LCP (the island's force block W = G^T M^-1 G
and the constant vector come from `assemble_lcp`), but instead of the complementarity between each contact's normal
velocity and its impulse, the QP

    minimize 1/2 x^T W x + c^T x    over x = (c_n, beta)  in the cone  {c_n >= 0, beta >= 0, e^T beta <= mu c_n}
                                                           (table friction: e^T beta <= mu h load, the load known)

whose optimality conditions are those of the LCP except that the normal row reads n.v+ + phi/h = mu lambda instead of
0 while sliding (lambda is the sliding speed). Known artefact: a sliding contact separates at the rate mu times its
sliding speed (a box sliding on the table rises by mu |v_t| h per step and falls back under gravity). In exchange
the problem is convex and always solvable. OSQP is a C library called from Python: this solver is a Python-level
step over the jitted stages, far slower than `lemke`, and meant for comparison.
"""

import contextlib
import os
import sys

import numpy as np

from planar_lcp.engine.assemble import apply_impulses, assemble_lcp
from planar_lcp.engine.solvers.lemke import STATUS_INACCURATE, STATUS_SOLVED
from planar_lcp.engine.step import (FORM_VELOCITY, SOLVER_PGS, _contact_velocities, _solve_island, ST_LCP_MAX,
                                    ST_LCP_SIZE, ST_LEMKE_STATUS, ST_RESIDUAL, _problem_sizes, _record_impulses,
                                    begin_step, finish_step, integrate_positions, needs_another_solve, prepare_contacts)


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


def _solve_island_osqp(m, km, w, kw, opt, vk, isl, ncon, h, velocity_form, stats, osqp_eps):
    """One island by OSQP. m, w: the namedtuples (read here in Python); km, kw: the kernels' structs over the same
    buffers (passed to the jitted stages)."""
    import osqp
    from scipy import sparse

    pair_of_con = w.con_pair[:ncon]
    a_of_con = m.shape_body[m.pair_a[pair_of_con]]
    isl_con = np.flatnonzero(w.island[m.body_slot[a_of_con]] == isl).astype(np.int64)
    isl_sup = np.flatnonzero(w.island[m.sup_dyn] == isl).astype(np.int64) if m.sup_dyn.size else \
        np.zeros(0, np.int64)
    nci, nsi = len(isl_con), len(isl_sup)
    if nci == 0 and nsi == 0:
        return STATUS_SOLVED
    n, nf, _ = _problem_sizes(km, isl_con, nci, nsi, w.con_pair)
    k = m.fric_dirs.shape[0]
    A = np.zeros((n, n))
    b = np.zeros(n)
    assemble_lcp(km, w.poses, vk, isl_con, nci, isl_sup, nsi, w.con_pair, w.con_phi, w.con_n, w.con_p, w.v_tilde,
                 w.v_hat, h, velocity_form, w.col_dyn, w.col_g, A, b)
    nforce = nci + 2 * nf + k * nsi
    P = A[:nforce, :nforce]
    c = b[:nforce]
    # cone constraints: x >= 0; mu c_n - beta+ - beta- >= 0 per frictional contact; sum beta_s <= mu h load
    rows, cols, vals = list(range(nforce)), list(range(nforce)), [1.0] * nforce
    lo, hi = [0.0] * nforce, [np.inf] * nforce
    r = nforce
    f = 0
    for a in range(nci):
        mu = m.pair_mu[w.con_pair[isl_con[a]]]
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
        hi.append(m.sup_mu[s] * h * m.sup_load[s])
        r += 1
    C = sparse.csc_matrix((vals, (rows, cols)), shape=(r, nforce))
    solver = osqp.OSQP()
    solver.setup(P=sparse.csc_matrix(np.triu(P)), q=c, A=C, l=np.array(lo), u=np.array(hi), eps_abs=osqp_eps,
                 eps_rel=osqp_eps, max_iter=20000, polishing=True, verbose=False)
    with _quiet_c_stdout():
        res = solver.solve(raise_error=False)  # a failure is reported through the status, never raised
    stats[ST_LCP_SIZE] += nforce
    stats[ST_LCP_MAX] = max(stats[ST_LCP_MAX], nforce)
    x = np.asarray(res.x, dtype=float)
    ok = str(res.info.status).lower().startswith("solved") and np.all(np.isfinite(x))
    if not ok:
        # the same recorded fallback as a Lemke failure: this island is solved by PGS, the step reports it
        stats[ST_LEMKE_STATUS] = max(stats[ST_LEMKE_STATUS], STATUS_INACCURATE)
        stats[ST_RESIDUAL] = np.inf
        _solve_island(km, kw, opt._replace(solver=SOLVER_PGS), w.poses, vk, isl, ncon, h, velocity_form, stats)
        return STATUS_INACCURATE
    # the QP's own primal residual, for the step diagnostics
    stats[ST_RESIDUAL] = max(stats[ST_RESIDUAL], float(res.info.prim_res))
    x = np.ascontiguousarray(np.maximum(x, 0.0))  # OSQP's answer is feasible to eps: remove the -eps entries
    apply_impulses(nforce, w.col_dyn, w.col_g, x, km, w.v_new)
    w.isl_con[:nci] = isl_con
    _record_impulses(km, kw, nci, x, False, nci)
    _contact_velocities(km, kw, opt, w.poses, vk, w.isl_con, nci)
    return STATUS_SOLVED


def osqp_step(m, km, q, v, qk, vk, h, opt, w, kw, q_out, v_out, qk_out, stats, osqp_eps=1e-9):
    """`step_kernel` with each island solved by OSQP instead of Lemke/PGS (same stages, same outputs).

    m, w: ModelArrays and StepWork namedtuples; km, kw: their kernel structs (kernels/structs.py)."""
    begin_step(km, q, v, qk, vk, h, opt, kw, qk_out, stats)
    velocity_form = opt.formulation == FORM_VELOCITY
    qk_lin = qk if velocity_form else qk_out
    fp_iter = 0
    while True:
        ncon, nisl = prepare_contacts(km, kw, opt, qk_lin, stats)
        worst = STATUS_SOLVED
        for isl in range(nisl):
            st = _solve_island_osqp(m, km, w, kw, opt, vk, isl, ncon, h, velocity_form, stats, osqp_eps)
            if st != STATUS_SOLVED:
                worst = st
        integrate_positions(q, h, kw)
        again, it = needs_another_solve(km, kw, opt, q, h, qk_out, fp_iter, stats)
        if it >= 0:
            fp_iter = it
        if not again:
            break
    return int(finish_step(km, kw, opt, vk, ncon, qk_out, q_out, v_out, stats, fp_iter, worst))
