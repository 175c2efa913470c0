"""Many steps in one jitted call (for planners, `simulate` and `Simulator.step`): exactly a loop of a step function
(engine/step.py).

`rollout_loop` is the one loop; the kernels below compile it with each step function. It is resumable (a rollout
run in pieces equals one call, warm-start memory included), which is how `Simulator.rollout` returns to Python
between chunks and runs a step again after growing the dense buffers (STEP_NEEDS_SPACE).
"""

import math
from collections import namedtuple

import numpy as np
from numba import njit

from planar_lcp.engine.layout import INT_STATS, NSTAT, Stat
from planar_lcp.engine.step import (STEP_NEEDS_FALLBACK, STEP_NEEDS_SPACE, STEP_OK, copy_pair_modes, copy_warm_start,
                                   lemke_step, pgs_step)

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

#: A rollout's inputs: the initial state q0, v0 (ndyn, 3) and qk0 (nkin, 3) float64 (row 0 of the recording); the
#: kinematic velocities vk_seq (nvk, nkin, 3) float64, step i using vk_seq[min(step0 + i, nvk - 1)]; step0, the index
#: of the first step in vk_seq (a resumed rollout), and nsteps (int); stop_on_failure, reset_warm_start (bool).
#: A namedtuple passed by value (scalars and four arrays: no struct needed to keep a call's arguments few).
RolloutRun = namedtuple("RolloutRun", ["q0", "v0", "qk0", "vk_seq", "step0", "nsteps", "stop_on_failure",
                                       "reset_warm_start"])


def make_recording(nsteps, ndyn, nkin, contacts=0, rows=False):
    """The Recording of a rollout of nsteps steps of ndyn dynamic and nkin kinematic bodies, with room for
    `contacts` contacts a step (0: none recorded) and, with `rows`, the Trajectory's rows (written up to the steps
    done, all that simulate reads: not zeroed)."""
    C, R = contacts, (nsteps if rows else 0)
    return Recording(q=np.zeros((nsteps + 1, ndyn, 3)), v=np.zeros((nsteps + 1, ndyn, 3)),
                     qk=np.zeros((nsteps + 1, nkin, 3)), stats=np.zeros((nsteps, NSTAT)),
                     status=np.zeros(nsteps, np.int64), con_count=np.zeros(nsteps if C else 0, np.int64),
                     con_pair=np.zeros((nsteps, C), np.int64), con_phi=np.zeros((nsteps, C)),
                     con_n=np.zeros((nsteps, C, 2)), con_p=np.zeros((nsteps, C, 2)), con_cn=np.zeros((nsteps, C)),
                     con_ft=np.zeros((nsteps, C)), con_vt=np.zeros((nsteps, C)),
                     con_mode=np.zeros((nsteps, C), np.int64), stat_rows=np.empty((NSTAT if R else 0, R)),
                     stat_ints=np.empty((len(INT_STATS) if R else 0, R), np.int64), energy=np.empty(R + 1 if R else 0))

#: numpy's pairwise summation works in blocks of this many terms (numpy/_core/src/umath/loops_utils.h.src)
PAIRWISE_BLOCK = 128


@njit(cache=True, _nrt=False)
def pairwise_sum(a, lo, n):
    """a[lo] + ... + a[lo + n - 1] as numpy's pairwise summation adds them (what `np.sum` of a row does: sequential
    below 8 terms, 8 partial sums up to a block of PAIRWISE_BLOCK, halves above), so that the Trajectory's energy is
    `planar_lcp.trajectory.energy` bit for bit (tests/simulation/test_sim_scenes.py)."""
    if n < 8:
        res = -0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    if n <= PAIRWISE_BLOCK:
        r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
        r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
        i = 8
        while i < n - n % 8:
            r0 += a[lo + i]
            r1 += a[lo + i + 1]
            r2 += a[lo + i + 2]
            r3 += a[lo + i + 3]
            r4 += a[lo + i + 4]
            r5 += a[lo + i + 5]
            r6 += a[lo + i + 6]
            r7 += a[lo + i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[lo + i]
            i += 1
        return res
    half = n // 2
    half -= half % 8
    return pairwise_sum(a, lo, half) + pairwise_sum(a, lo + half, n - half)


@njit(cache=True, inline='always')
def sum_terms(terms, n):
    """`pairwise_sum(terms, 0, n)`, its sequential case (fewer than 8 terms: every shipped scene but the piles) in
    place of a call."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += terms[i]
        return res
    return pairwise_sum(terms, np.int64(0), n)     # np.int64: one compilation (a literal 0 would make another)


@njit(cache=True, inline='always')
def state_energy(m, q, v, terms):
    """Kinetic + potential energy (J) of the dynamic bodies at COM poses q and velocities v (ndyn, 3), with `terms`
    (ndyn,) as scratch: what `planar_lcp.trajectory.energy` gives for the row, each body's term computed by the same
    operations in the same order and summed in numpy's order (its sum over the bodies starts from 0.0)."""
    nb = q.shape[0]
    for b in range(nb):
        terms[b] = (0.5 * m.dyn_mass[b] * (v[b, 0] * v[b, 0] + v[b, 1] * v[b, 1])
                    + 0.5 * m.dyn_inertia[b] * (v[b, 2] * v[b, 2]))
    kinetic = 0.0 + sum_terms(terms, nb)
    for b in range(nb):
        terms[b] = m.dyn_mass[b] * (m.gravity[0] * q[b, 0] + m.gravity[1] * q[b, 1])   # -(its potential energy)
    potential = -(0.0 + sum_terms(terms, nb))
    return kinetic + potential


@njit(cache=True, _nrt=False)
def record_rows(m, w, step0, done, rec):
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
            rec.energy[step0 + i] = state_energy(m, rec.q[i], rec.v[i], w.body_energy)


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
def start_rollout(w, run, rec):
    """Row 0 of the recording is the run's initial state; a rollout from scratch (run.reset_warm_start) forgets the
    warm-start memory (so its result depends on its inputs only), a resumed one keeps it."""
    q0, v0, qk0 = run.q0, run.v0, run.qk0
    if run.reset_warm_start:
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
def rollout_loop(step, m, run, h, opt, w, rec):
    """THE rollout: run.nsteps steps of `step` from (run.q0, run.v0, run.qk0), recorded into `rec`.

    Parameters
    ----------
    step : a step variant (engine/step.py), or any function with its arguments
    m, opt, w, h : as the step takes them
    run : RolloutRun
        The initial state, the kinematic velocities, the steps (step0, nsteps) and the flags stop_on_failure,
        reset_warm_start.
    rec : Recording
        Output buffers with nsteps + 1 state rows and nsteps step rows.

    Returns
    -------
    int
        The steps done: nsteps, or fewer when stop_on_failure and a step failed (that step included), or when a step
        returned STEP_NEEDS_FALLBACK or STEP_NEEDS_SPACE (that step excluded: nothing of it was written but its status).
    """
    start_rollout(w, run, rec)
    vk_seq = run.vk_seq
    step0 = run.step0
    nsteps = run.nsteps
    nvk = vk_seq.shape[0]
    done = nsteps
    for i in range(nsteps):
        vk = vk_seq[min(step0 + i, nvk - 1)]
        st = step(m, (rec.q[i], rec.v[i], rec.qk[i], vk), h, opt, w, (rec.q[i + 1], rec.v[i + 1], rec.qk[i + 1]),
                  rec.stats[i])
        rec.status[i] = st
        if st == STEP_NEEDS_FALLBACK or st == STEP_NEEDS_SPACE:
            done = i
            break
        record_contacts(w, i, int(rec.stats[i, Stat.N_CONTACTS]), rec)
        if st != STEP_OK and run.stop_on_failure:
            done = i + 1
            break
    record_rows(m, w, step0, done, rec)
    return done


# The rollout kernels, one per step function (engine/step.py), each with its step inlined into the loop: every Lemke
# run takes `rollout_lemke`, solver = "pgs" `rollout_pgs`. `Simulator.step` runs them one step a call, so these two
# are the whole of what a cold cache compiles for the steps, whatever the scene.

@njit(cache=True, _nrt=False)
def rollout_lemke(m, run, h, opt, w, rec):
    return rollout_loop(lemke_step, m, run, h, opt, w, rec)


@njit(cache=True, _nrt=False)
def rollout_pgs(m, run, h, opt, w, rec):
    return rollout_loop(pgs_step, m, run, h, opt, w, rec)


# The step's checked central differences (planar_lcp/derivatives/differences.py): the cold step at x, then the
# step at x +- eps_k e_k for each input, warm-started on the cold step's final bases, in one compiled call.

#: step_differences' answers: the differences are the step's derivatives (DIFF_OK), or why not
DIFF_OK = 0
DIFF_FAILED = 1          # the cold step did not succeed
DIFF_SPACE = 2           # a step asked for larger dense buffers (w.dense_needed)
DIFF_STRUCTURE = 3       # a step nearby failed or has another structure (`_same_structure`)
DIFF_KINK = 4            # the one-sided differences differ
DIFF_MOVES = 5           # the cold steps along the mixed direction move otherwise than the Jacobian predicts (the
                         # differences are written: each input's holds, their sum does not)
DIFF_NONFINITE = 6       # an input is not finite (nothing ran: the caller names it)
DIFF_REASONS = ("", "the step failed", "",
                "a step nearby failed or has other contacts, islands, fixed-point iterations, re-solves or LCP sizes",
                "the one-sided differences differ (a kink at the state)",
                "a cold step nearby moves otherwise than the differences predict",
                "an input is not finite")

#: the stats a perturbed step shares with the cold one: the same contacts, islands and active-set re-solves (a change
#: is a switch of the step's discrete structure), the same fixed-point iterations (a jump of its stopping rule) and,
#: summed over them, the same LCP sizes, restitution's choice and force-limited pushers'; and those that are zero in
#: it (answers not certified)
DIFF_SAME = np.array([Stat.N_CONTACTS, Stat.N_ISLANDS, Stat.RESOLVES], dtype=np.int64)
DIFF_PER_SOLVE = np.array([Stat.LCP_SIZE, Stat.SOLVED_INELASTIC, Stat.SERVO_LIMITED], dtype=np.int64)
DIFF_ZERO = np.array([Stat.PGS_UNCERTIFIED], dtype=np.int64)


@njit(cache=True, inline='always')
def _same_structure(stats, other, fp_free):
    """Whether a step's stats `other` show the cold step's structure `stats` (DIFF_SAME, DIFF_PER_SOLVE, DIFF_ZERO);
    fp_free: its fixed-point iteration count may differ (a tolerance far below the differences' step), and with it
    the sums over the iterations."""
    for a in DIFF_SAME:
        if other[a] != stats[a]:
            return False
    for a in DIFF_ZERO:
        if other[a] != 0.0:
            return False
    if fp_free:
        return True
    if other[Stat.FP_ITERATIONS] != stats[Stat.FP_ITERATIONS]:
        return False
    for a in DIFF_PER_SOLVE:
        if other[a] != stats[a]:
            return False
    return True


@njit(cache=True, inline='always')
def _restore_memory(size, basic_z, modes, w):
    """Put the kept warm-start memory back into the work (engine/step.py's copies, unconditionally: the perturbed
    steps warm-start on it whatever the simulator's options)."""
    copy_warm_start(size, basic_z, w.warm_size, w.warm_basic_z)
    copy_pair_modes(modes, w.sparse_pair_mode)


@njit(cache=True, inline='always')
def flat_inputs(q, v, qk, vk, x):
    """The step's inputs flattened into x (q, v, qk, vk row-major: the derivatives' columns). Returns whether every
    entry is finite."""
    nd, nk = q.shape[0], qk.shape[0]
    finite = True
    for i in range(nd):
        for c in range(3):
            x[3 * i + c] = q[i, c]
            x[3 * nd + 3 * i + c] = v[i, c]
    for j in range(nk):
        for c in range(3):
            x[6 * nd + 3 * j + c] = qk[j, c]
            x[6 * nd + 3 * nk + 3 * j + c] = vk[j, c]
    for k in range(x.shape[0]):
        if not np.isfinite(x[k]):
            finite = False
    return finite


@njit(cache=True, inline='always')
def unflatten_state(x, nd, nk, q, v, qk):
    """The first 6 nd + 3 nk entries of a flattened state or input (q, v, qk row-major: `flat_inputs`, a step's
    flattened output) into q, v (nd, 3) and qk (nk, 3)."""
    for i in range(nd):
        for c in range(3):
            q[i, c] = x[3 * i + c]
            v[i, c] = x[3 * nd + 3 * i + c]
    for j in range(nk):
        for c in range(3):
            qk[j, c] = x[6 * nd + 3 * j + c]


@njit(cache=True, inline='always')
def unflatten_inputs(x, nd, nk, q, v, qk, vk):
    """`flat_inputs` undone: x into q, v (nd, 3) and qk, vk (nk, 3)."""
    unflatten_state(x, nd, nk, q, v, qk)
    for j in range(nk):
        for c in range(3):
            vk[j, c] = x[6 * nd + 3 * nk + 3 * j + c]


@njit(cache=True, inline='always')
def difference_steps(x, step):
    """(2, K): the differences' step along each input, step max(1, |x_k|), and the mixed direction's, the same
    magnitudes with the signs of sin(k + 1)."""
    K = x.shape[0]
    steps = np.empty((2, K))
    for k in range(K):
        steps[0, k] = step * max(1.0, abs(x[k]))
        steps[1, k] = steps[0, k] if math.sin(k + 1.0) >= 0.0 else -steps[0, k]
    return steps


@njit(cache=True)
def _step_from_flat(m, x, nd, nk, h, opt, w, rec, cold, f):
    """One step from the flattened inputs x (q, v, qk, vk row-major), cold (the warm-start memory forgotten) or on
    the memory as it is; its (q+, v+, qk+) flattened into f. Returns its status."""
    vk = np.empty((1, nk, 3))
    unflatten_inputs(x, nd, nk, rec.q[0], rec.v[0], rec.qk[0], vk[0])
    rollout_lemke(m, RolloutRun(rec.q[0], rec.v[0], rec.qk[0], vk, 0, 1, False, cold), h, opt, w, rec)
    o = 0
    for i in range(nd):
        for c in range(3):
            f[o] = rec.q[1, i, c]
            o += 1
    for i in range(nd):
        for c in range(3):
            f[o] = rec.v[1, i, c]
            o += 1
    for j in range(nk):
        for c in range(3):
            f[o] = rec.qk[1, j, c]
            o += 1
    return rec.status[0]


@njit(cache=True)
def mixed_direction_check(m, h, opt, w, rec, x, steps, jac, base, memory, tols, fp, fm, q1, v1, qk1):
    """The differences' last check, shared by step_differences and engine/tangent.py's step_tangent: the cold steps
    at x +- d (d = steps[1], on opt from no memory) against the Jacobian's prediction J d, to tols[2] of the
    prediction's size (at least tols[3] times d's largest entry). The cold step's state `base` goes into q1, v1, qk1
    and the warm-start memory (msize, mbasic, mmodes) back into the work whatever the answer. Returns DIFF_OK, or
    DIFF_MOVES (jac and the state written: the step is not linear in its inputs there). fp, fm: scratch like base."""
    nd, nk = q1.shape[0], qk1.shape[0]
    K = x.shape[0]
    xx = x.copy()
    code = DIFF_OK
    for sgn in range(2):
        for k in range(K):
            xx[k] = x[k] + steps[1, k] if sgn == 0 else x[k] - steps[1, k]
        if _step_from_flat(m, xx, nd, nk, h, opt, w, rec, True, fp if sgn == 0 else fm) != STEP_OK:
            code = DIFF_MOVES
    msize, mbasic, mmodes = memory
    _restore_memory(msize, mbasic, mmodes, w)
    unflatten_state(base, nd, nk, q1, v1, qk1)
    if code != DIFF_OK:
        return code
    worst = 0.0
    size = tols[3] * np.max(np.abs(steps[1]))
    for r in range(base.shape[0]):
        pred = 0.0
        for k in range(K):
            pred += jac[r, k] * steps[1, k]
        size = max(size, abs(pred))
        worst = max(worst, abs(0.5 * (fp[r] - fm[r]) - pred))
    return DIFF_MOVES if worst > tols[2] * size else DIFF_OK


@njit(cache=True)
def cold_step_at(m, h, cold_opt, w, q, v, qk, vk, step, stats):
    """The first stage of the step's derivatives, shared by step_differences and engine/tangent.py's step_tangent:
    the inputs flattened (x: q, v, qk, vk row-major), the differences' steps along each input and the mixed
    direction's (`difference_steps`, step max(1, |x_k|)), and the cold step at x: its state flattened (base), its
    stats into stats, its recording (rec) and the warm-start memory it left (msize, mbasic, mmodes). Returns (code,
    x, steps, base, rec, memory), code DIFF_OK, DIFF_NONFINITE (an input not finite: no step taken), DIFF_SPACE or
    DIFF_FAILED."""
    nd, nk = q.shape[0], qk.shape[0]
    x = np.empty(6 * nd + 6 * nk)
    finite = flat_inputs(q, v, qk, vk, x)
    steps = difference_steps(x, step)
    base = np.empty(6 * nd + 3 * nk)
    rec = _compiled_recording(1, nd, nk)
    code = DIFF_NONFINITE
    if finite:
        st = _step_from_flat(m, x, nd, nk, h, cold_opt, w, rec, True, base)
        for s in range(stats.shape[0]):
            stats[s] = rec.stats[0, s]
        code = DIFF_SPACE if st == STEP_NEEDS_SPACE else (DIFF_FAILED if st != STEP_OK else DIFF_OK)
    return code, x, steps, base, rec, (w.warm_size.copy(), w.warm_basic_z.copy(), w.sparse_pair_mode.copy())


@njit(cache=True)
def _perturbed_step(m, h, warm_opt, w, rec, xx, k, xk, memory, stats, tols, f):
    """One of the differences' steps: the inputs xx with xx[k] = xk, warm-started (warm_opt) on the cold step's final
    bases (memory: msize, mbasic, mmodes, put back into the work first), its (q+, v+, qk+) flattened into f.
    Returns DIFF_OK where it keeps the cold step's structure (stats: `_same_structure`, the fixed-point iteration
    count free where tols[4] > 0), DIFF_SPACE where it needs larger dense buffers, else DIFF_STRUCTURE."""
    msize, mbasic, mmodes = memory
    xx[k] = xk
    _restore_memory(msize, mbasic, mmodes, w)
    st = _step_from_flat(m, xx, rec.q.shape[1], rec.qk.shape[1], h, warm_opt, w, rec, False, f)
    if st == STEP_NEEDS_SPACE:
        return DIFF_SPACE
    if st != STEP_OK or not _same_structure(stats, rec.stats[0], tols[4] > 0.0):
        return DIFF_STRUCTURE
    return DIFF_OK


@njit(cache=True)
def _sides_differ(fp, fm, base, e, tols):
    """The differences' kink test along one input: its one-sided differences from the cold answer base,
    (fp - base) / e and (base - fm) / e, differ by more than tols[1] (DIFF_KINK_RTOL) of their largest entry (at
    least tols[3], DIFF_FLOOR). A kink, or warm-started answers that differ from the cold one at x (an offset), make
    them differ."""
    big = 0.0
    gap = 0.0
    for r in range(base.shape[0]):
        right, left = (fp[r] - base[r]) / e, (base[r] - fm[r]) / e
        big = max(big, abs(right), abs(left))
        gap = max(gap, abs(right - left))
    return gap > tols[1] * max(big, tols[3])


@njit(cache=True)
def step_differences(m, h, cold_opt, warm_opt, w, q, v, qk, vk, tols, jac, q1, v1, qk1, stats):
    """The central differences of the step at the state (q, v, qk, vk) along +- eps_k e_k for each of its K inputs
    (x: q, v, qk, vk flattened row-major; eps_k = tols[0] max(1, |x_k|)), each step warm-started (warm_opt) on the
    cold step's (cold_opt) final bases, into jac (6 nd + 3 nk, K); the cold step's state into q1, v1, qk1 and its
    stats into stats; the mixed direction's steps run on warm_opt from no memory (cold, at its tolerances). Returns
    DIFF_OK where the checks of planar_lcp/derivatives/differences.py hold, else the DIFF_* reason. tols: (step,
    kink, mixed, floor, whether the fixed-point iteration count may differ) of differences.py. The warm-start memory
    is left as the cold step left it."""
    code, x, steps, base, rec, memory = cold_step_at(m, h, cold_opt, w, q, v, qk, vk, tols[0], stats)
    if code != DIFF_OK:
        return code
    K, nout = x.shape[0], base.shape[0]
    # the cold step's final bases (and the sparse solver's modes), which every perturbed step starts from
    msize, mbasic, mmodes = memory
    xx = x.copy()
    fp, fm = np.empty(nout), np.empty(nout)
    code = DIFF_OK
    for k in range(K):
        e = steps[0, k]
        code = _perturbed_step(m, h, warm_opt, w, rec, xx, k, x[k] + e, memory, stats, tols, fp)
        if code == DIFF_OK:
            code = _perturbed_step(m, h, warm_opt, w, rec, xx, k, x[k] - e, memory, stats, tols, fm)
        xx[k] = x[k]
        if code != DIFF_OK:
            break
        for r in range(nout):
            jac[r, k] = (fp[r] - fm[r]) / (2.0 * e)
        if _sides_differ(fp, fm, base, e, tols):
            code = DIFF_KINK
            break
    # the memory as the cold step at x left it (what `Simulator.step` leaves)
    _restore_memory(msize, mbasic, mmodes, w)
    if code != DIFF_OK:
        return code
    return mixed_direction_check(m, h, warm_opt, w, rec, x, steps, jac, base, (msize, mbasic, mmodes), tols, fp, fm,
                                 q1, v1, qk1)


#: which one-sided differences `step_one_sided` took along an input: both, agreeing or differing (the kink test,
#: `_sides_differ`), or one side only (the step on the other has another structure than the cold step's:
#: `_same_structure`)
SIDES_BOTH = 0
SIDE_RIGHT_ONLY = 1
SIDE_LEFT_ONLY = 2
SIDES_DIFFER = 3


@njit(cache=True)
def step_one_sided(m, h, cold_opt, warm_opt, w, q, v, qk, vk, tols, right, left, sides, q1, v1, qk1, stats):
    """The one-sided differences of the step at the state (q, v, qk, vk) along +- eps_k e_k for each of its K inputs,
    as `step_differences` takes its steps (warm-started on the cold step's final bases), without its checks: into
    right and left (6 nd + 3 nk, K) the differences (f(x + eps_k e_k) - f(x)) / eps_k and (f(x) - f(x - eps_k e_k)) /
    eps_k from the cold answer f(x). Where the step on one side fails or has another structure than the cold step's
    (`_same_structure`: a contact that appears, an active-set re-solve: the step may jump there), both are the other
    side's, and sides[k] says which were taken (SIDES_BOTH, SIDES_DIFFER where the two differ by the checked
    differences' kink test, SIDE_RIGHT_ONLY, SIDE_LEFT_ONLY). The cold step's state
    into q1, v1, qk1 and its stats into stats. Returns DIFF_OK, or DIFF_FAILED, DIFF_NONFINITE, DIFF_SPACE, or
    DIFF_STRUCTURE where neither side of an input keeps the cold step's structure. The warm-start memory is left as
    the cold step left it."""
    nd, nk = q.shape[0], qk.shape[0]
    code, x, steps, base, rec, memory = cold_step_at(m, h, cold_opt, w, q, v, qk, vk, tols[0], stats)
    if code != DIFF_OK:
        return code
    K, nout = x.shape[0], base.shape[0]
    msize, mbasic, mmodes = memory
    xx = x.copy()
    fp, fm = np.empty(nout), np.empty(nout)
    for k in range(K):
        e = steps[0, k]
        got_p = _perturbed_step(m, h, warm_opt, w, rec, xx, k, x[k] + e, memory, stats, tols, fp)
        got_m = _perturbed_step(m, h, warm_opt, w, rec, xx, k, x[k] - e, memory, stats, tols, fm)
        xx[k] = x[k]
        kept_p, kept_m = got_p == DIFF_OK, got_m == DIFF_OK
        if got_p == DIFF_SPACE or got_m == DIFF_SPACE:
            code = DIFF_SPACE
        elif not (kept_p or kept_m):
            code = DIFF_STRUCTURE
        if code != DIFF_OK:
            break
        if kept_p and kept_m:
            sides[k] = SIDES_DIFFER if _sides_differ(fp, fm, base, e, tols) else SIDES_BOTH
        else:
            sides[k] = SIDE_RIGHT_ONLY if kept_p else SIDE_LEFT_ONLY
        for r in range(nout):
            rate_p = (fp[r] - base[r]) / e
            rate_m = (base[r] - fm[r]) / e
            right[r, k] = rate_p if kept_p else rate_m
            left[r, k] = rate_m if kept_m else rate_p
    # the memory as the cold step at x left it (what `Simulator.step` leaves)
    _restore_memory(msize, mbasic, mmodes, w)
    unflatten_state(base, nd, nk, q1, v1, qk1)
    return code


@njit(cache=True)
def _compiled_recording(nsteps, ndyn, nkin):
    """`make_recording`'s Recording without contacts or rows, made in compiled code."""
    return Recording(np.zeros((nsteps + 1, ndyn, 3)), np.zeros((nsteps + 1, ndyn, 3)), np.zeros((nsteps + 1, nkin, 3)),
                     np.zeros((nsteps, NSTAT)), np.zeros(nsteps, np.int64), np.zeros(0, np.int64),
                     np.zeros((nsteps, 0), np.int64), np.zeros((nsteps, 0)), np.zeros((nsteps, 0, 2)),
                     np.zeros((nsteps, 0, 2)), np.zeros((nsteps, 0)), np.zeros((nsteps, 0)), np.zeros((nsteps, 0)),
                     np.zeros((nsteps, 0), np.int64), np.empty((0, 0)), np.empty((0, 0), np.int64), np.empty(0))
