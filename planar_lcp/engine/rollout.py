"""Many steps in one jitted call (for planners and `simulate`): exactly a loop of a step variant (engine/step.py).

`rollout_loop` is the one loop; the kernels below are its compiled variants, one per step variant. It is resumable
(a rollout run in pieces equals one call, warm-start memory included), which is how `Simulator.rollout` returns to
Python between chunks and re-runs a step that a variant without fallback handed back (STEP_NEEDS_FALLBACK).
"""

from collections import namedtuple

import numpy as np
from numba import njit

from planar_lcp.engine.layout import INT_STATS, NSTAT, Stat
from planar_lcp.engine.solvers.lemke import solve_island_lemke, solve_island_lemke_small
from planar_lcp.engine.solvers.pgs import solve_island_pgs
from planar_lcp.engine.step import (STEP_NEEDS_FALLBACK, STEP_NEEDS_SPACE, STEP_OK, step_lemke, step_lemke_full,
                                    step_lemke_full_small, step_lemke_small, step_pgs, step_pipeline)

#: A rollout's output buffers. States q, v (nsteps + 1, ndyn, 3) and qk (nsteps + 1, nkin, 3), row 0 the initial
#: state; per step: stats (nsteps, NSTAT), status (nsteps,) STEP_* codes, and the contacts of the step's active set
#: (rows nsteps, columns the capacity C; C = 0 records none): con_count (nsteps,), con_pair, con_phi (m),
#: con_n (unit normal from B to A, world), con_p (m, world), con_cn, con_ft (N s), con_vt (m/s), con_mode (MODE_*).
#: A Trajectory's rows (`simulate`; empty arrays record none): the stats by stat, stat_rows (NSTAT, nsteps), the
#: integer-valued ones as integers, stat_ints (len(INT_STATS), nsteps), and the energy of each state, energy
#: (nsteps + 1,) J. A chunk of a run gets these three whole: the kernel writes them at the run's step index
#: (step0 + i), where it writes the others at the chunk's own.
Recording = namedtuple("Recording", ["q", "v", "qk", "stats", "status", "con_count", "con_pair", "con_phi", "con_n",
                                     "con_p", "con_cn", "con_ft", "con_vt", "con_mode", "stat_rows", "stat_ints",
                                     "energy"])
#: the Recording fields a chunk of a run gets whole (see Recording)
RUN_ROWS = ("stat_rows", "stat_ints", "energy")

#: numpy's pairwise summation works in blocks of this many terms (numpy/_core/src/umath/loops_utils.h.src)
PAIRWISE_BLOCK = 128


@njit(cache=True, inline='always')
def _energy_term(m, q, v, b, kinetic):
    """Body b's kinetic energy 0.5 m |v|^2 + 0.5 I omega^2, or m (g . x) (the potential energy's negative), as
    planar_lcp.trajectory computes them elementwise: the same operations in the same order."""
    if kinetic:
        return (0.5 * m.dyn_mass[b] * (v[b, 0] * v[b, 0] + v[b, 1] * v[b, 1])
                + 0.5 * m.dyn_inertia[b] * (v[b, 2] * v[b, 2]))
    return m.dyn_mass[b] * (m.gravity[0] * q[b, 0] + m.gravity[1] * q[b, 1])


@njit(cache=True, _nrt=False)
def _pairwise_energy(m, q, v, lo, n, kinetic):
    """The sum of the energy terms of bodies lo .. lo + n - 1 as numpy's pairwise summation adds them (`np.sum` of
    a row: sequential below 8 terms, 8 partial sums up to a block, halves above), so that the Trajectory's energy
    is `planar_lcp.trajectory.energy` bit for bit (tests/test_sim_scenes.py)."""
    if n < 8:
        res = -0.0
        for b in range(lo, lo + n):
            res += _energy_term(m, q, v, b, kinetic)
        return res
    if n <= PAIRWISE_BLOCK:
        r0 = _energy_term(m, q, v, lo, kinetic)
        r1 = _energy_term(m, q, v, lo + 1, kinetic)
        r2 = _energy_term(m, q, v, lo + 2, kinetic)
        r3 = _energy_term(m, q, v, lo + 3, kinetic)
        r4 = _energy_term(m, q, v, lo + 4, kinetic)
        r5 = _energy_term(m, q, v, lo + 5, kinetic)
        r6 = _energy_term(m, q, v, lo + 6, kinetic)
        r7 = _energy_term(m, q, v, lo + 7, kinetic)
        i = 8
        while i < n - n % 8:
            r0 += _energy_term(m, q, v, lo + i, kinetic)
            r1 += _energy_term(m, q, v, lo + i + 1, kinetic)
            r2 += _energy_term(m, q, v, lo + i + 2, kinetic)
            r3 += _energy_term(m, q, v, lo + i + 3, kinetic)
            r4 += _energy_term(m, q, v, lo + i + 4, kinetic)
            r5 += _energy_term(m, q, v, lo + i + 5, kinetic)
            r6 += _energy_term(m, q, v, lo + i + 6, kinetic)
            r7 += _energy_term(m, q, v, lo + i + 7, kinetic)
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += _energy_term(m, q, v, lo + i, kinetic)
            i += 1
        return res
    half = n // 2
    half -= half % 8
    return _pairwise_energy(m, q, v, lo, half, kinetic) + _pairwise_energy(m, q, v, lo + half, n - half, kinetic)


@njit(cache=True, inline='always')
def state_energy(m, q, v):
    """Kinetic + potential energy (J) of the dynamic bodies at COM poses q and velocities v (ndyn, 3): what
    `planar_lcp.trajectory.energy` gives for the row (numpy's sum over the bodies starts from 0.0)."""
    nb = q.shape[0]
    if nb < 8:       # numpy's sum of fewer than 8 terms, in place of a call of _pairwise_energy (issue M)
        kinetic = -0.0
        potential = -0.0
        for b in range(nb):
            kinetic += _energy_term(m, q, v, b, True)
            potential += _energy_term(m, q, v, b, False)
    else:
        # np.int64 and np.bool_: one compilation of _pairwise_energy (literal arguments would each make another)
        kinetic = _pairwise_energy(m, q, v, np.int64(0), nb, np.bool_(True))
        potential = _pairwise_energy(m, q, v, np.int64(0), nb, np.bool_(False))
    return (0.0 + kinetic) + -(0.0 + potential)


@njit(cache=True, _nrt=False)
def record_rows(m, step0, done, rec):
    """The Trajectory rows of a rollout call's `done` steps at the run's step indices step0 ... (none if rec.energy
    is empty): the stats by stat, the integer-valued ones as integers (truncated, as numpy's astype(int)), the energy
    of each state from the call's first. Once per call, after its steps."""
    if rec.energy.shape[0] > 0:
        for k in range(NSTAT):
            for i in range(done):
                rec.stat_rows[k, step0 + i] = rec.stats[i, k]
        for a in range(INT_STATS.shape[0]):
            k = INT_STATS[a]
            for i in range(done):
                rec.stat_ints[a, step0 + i] = int(rec.stats[i, k])
        for i in range(done + 1):
            rec.energy[step0 + i] = state_energy(m, rec.q[i], rec.v[i])


@njit(cache=True, inline='always')
def record_contacts(w, i, nc, rec):
    """Copy the step's nc contacts (w.con_*) into row i of the recording (at most its capacity; none if it is 0)."""
    ccap = rec.con_phi.shape[1]
    if ccap > 0:
        rec.con_count[i] = nc
        for j in range(min(nc, ccap)):
            rec.con_pair[i, j] = w.con_pair[j]
            rec.con_phi[i, j] = w.con_phi[j]
            rec.con_n[i, j, 0] = w.con_n[j, 0]
            rec.con_n[i, j, 1] = w.con_n[j, 1]
            rec.con_p[i, j, 0] = w.con_p[j, 0]
            rec.con_p[i, j, 1] = w.con_p[j, 1]
            rec.con_cn[i, j] = w.con_cn[j]
            rec.con_ft[i, j] = w.con_ft[j]
            rec.con_vt[i, j] = w.con_vt[j]
            rec.con_mode[i, j] = w.con_mode[j]


@njit(cache=True, inline='always')
def start_rollout(w, q0, v0, qk0, rec, reset_warm_start):
    """Row 0 of the recording is the initial state; a rollout from scratch forgets the warm-start memory (so its
    result depends on its inputs only), a resumed one keeps it."""
    if reset_warm_start:
        for i in range(w.warm_size.shape[0]):
            w.warm_size[i] = -1
        for p in range(w.sparse_pair_mode.shape[0]):
            w.sparse_pair_mode[p, 0] = -1
            w.sparse_pair_mode[p, 1] = -1
    for d in range(q0.shape[0]):
        for c in range(3):
            rec.q[0, d, c] = q0[d, c]
            rec.v[0, d, c] = v0[d, c]
    for k in range(qk0.shape[0]):
        for c in range(3):
            rec.qk[0, k, c] = qk0[k, c]


@njit(cache=True, inline='always')
def rollout_loop(step, m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure, reset_warm_start):
    """THE rollout: nsteps steps of `step` from (q0, v0, qk0), recorded into `rec`.

    Parameters
    ----------
    step : a step variant (engine/step.py), or any function with its arguments
    m, opt, w, h : as the step takes them
    q0, v0 : (ndyn, 3) float64;  qk0 : (nkin, 3) float64
        The initial state (row 0 of the recording).
    vk_seq : (nvk, nkin, 3) float64
        Kinematic velocities: step i uses vk_seq[min(step0 + i, nvk - 1)].
    step0 : int
        Index of the first step in vk_seq (a resumed rollout).
    nsteps : int
    rec : Recording
        Output buffers with nsteps + 1 state rows and nsteps step rows.
    stop_on_failure, reset_warm_start : bool

    Returns
    -------
    int
        The steps done: nsteps, or fewer when stop_on_failure and a step failed (that step included), or when a step
        returned STEP_NEEDS_FALLBACK or STEP_NEEDS_SPACE (that step excluded: nothing of it was written but its status).
    """
    start_rollout(w, q0, v0, qk0, rec, reset_warm_start)
    nvk = vk_seq.shape[0]
    done = nsteps
    for i in range(nsteps):
        vk = vk_seq[min(step0 + i, nvk - 1)]
        st = step(m, rec.q[i], rec.v[i], rec.qk[i], vk, h, opt, w, rec.q[i + 1], rec.v[i + 1], rec.qk[i + 1],
                  rec.stats[i])
        rec.status[i] = st
        if st == STEP_NEEDS_FALLBACK or st == STEP_NEEDS_SPACE:
            done = i
            break
        record_contacts(w, i, int(rec.stats[i, Stat.N_CONTACTS]), rec)
        if st != STEP_OK and stop_on_failure:
            done = i + 1
            break
    record_rows(m, step0, done, rec)
    return done


# The compiled variants, one per step variant (same arguments as `rollout_loop` without `step`).

@njit(cache=True, _nrt=False)
def rollout_lemke(m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure, reset_warm_start):
    return rollout_loop(step_lemke, m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure,
                        reset_warm_start)


@njit(cache=True, _nrt=False)
def rollout_lemke_full(m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure, reset_warm_start):
    return rollout_loop(step_lemke_full, m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure,
                        reset_warm_start)


@njit(cache=True, _nrt=False)
def rollout_lemke_small(m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure, reset_warm_start):
    return rollout_loop(step_lemke_small, m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure,
                        reset_warm_start)


@njit(cache=True, _nrt=False)
def rollout_lemke_full_small(m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure,
                             reset_warm_start):
    return rollout_loop(step_lemke_full_small, m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec,
                        stop_on_failure, reset_warm_start)


@njit(cache=True, _nrt=False)
def rollout_pgs(m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure, reset_warm_start):
    return rollout_loop(step_pgs, m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure,
                        reset_warm_start)


# The planners' kernels (`SimOptions(single_kernel=True)` or the warm start, position forms: sim.py `_variants`): the
# warm start and the PGS fallback, without the velocity form's projection (a velocity-form step is handed back,
# STEP_NEEDS_FALLBACK, to the full kernel), and the step inlined into the loop instead of a kernel of its own. A
# position-form step never reaches the projection, so they step as `rollout_lemke_full(_small)` bit for bit; a cold
# cache compiles the step once (not as a kernel, then again linked into the rollout) and without the projection:
# 8.1 s of CPU against 13.0 s with every other kernel cached (docs/performance.md, "Compile time").

@njit(cache=True, inline='always')
def _step_lemke_warm(m, q, v, qk, vk, h, opt, w, q_out, v_out, qk_out, stats):
    return step_pipeline(solve_island_lemke, solve_island_pgs, None, m, q, v, qk, vk, h, opt, w, q_out, v_out, qk_out,
                         stats)


@njit(cache=True, inline='always')
def _step_lemke_warm_small(m, q, v, qk, vk, h, opt, w, q_out, v_out, qk_out, stats):
    return step_pipeline(solve_island_lemke_small, solve_island_pgs, None, m, q, v, qk, vk, h, opt, w, q_out, v_out,
                         qk_out, stats)


@njit(cache=True, _nrt=False)
def rollout_lemke_warm(m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure, reset_warm_start):
    return rollout_loop(_step_lemke_warm, m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure,
                        reset_warm_start)


@njit(cache=True, _nrt=False)
def rollout_lemke_warm_small(m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec, stop_on_failure,
                             reset_warm_start):
    return rollout_loop(_step_lemke_warm_small, m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, rec,
                        stop_on_failure, reset_warm_start)
