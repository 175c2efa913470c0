"""The step's derivatives by checked central differences of the compiled step: the fast method of `step_derivatives`.

Its first try is the derivatives at the cold step's certified bases (engine/tangent.py `step_tangent`: the LCP's
part by one solve with the bases' matrices, the rest by differences of the step's smooth stages alone), where that
covers the step and its checks hold; where not, the differences of whole steps below.

`step_differences` (engine/rollout.py) runs, in one compiled call, the cold step at the state x, then the step at
x +- eps_k e_k for each of the K inputs, each warm-started on the cold step's final LCP bases and certified to
DIFF_RES_TOL: where the contact modes are strictly complementary those bases stay certified nearby
(`lemke_from_basis`, accepted only as accurate as a cold solve), so both sides lie on the smooth piece the bases
define and no pivot runs; where a basis does not hold (a contact at rest with no tangential load, which any push
makes stick) the perturbed step pivots from it as any step does. Their central differences approximate the
derivatives to about 1e-6 of the Jacobian's scale (truncation eps^2 f''', and round-off of the gaps over the step
size, eps = DIFF_STEP), measured against the dual numbers in tests/derivatives/test_differences.py and
docs/method.md, "Derivatives of the step".

They stand for the step's derivatives only where all of these hold; where one of the first two fails they are
taken again over a smaller step (DIFF_RETRY_SHRINK); where it fails again `checked_differences` returns the reason
and `step_derivatives` runs the dual numbers of forward.py instead (which also say what makes a
state degenerate); where only the last fails, each input's differences hold but the step is not linear in the
inputs together, and the differences are returned as not exact:

- the cold step succeeded, and every perturbed step has its contacts, islands, active-set re-solves and LCP sizes,
  with certified answers (a change is a switch of the step's discrete structure), and its fixed-point iteration
  count, which changes the answer by up to the iteration's tolerance, unless that is below DIFF_FP_RATIO of the
  differences' step;
- the one-sided differences from the cold answer agree: a kink of the step's rows, of the contact geometry or of
  the contact modes at x shows as an O(1) difference, and a warm-started answer that differs from the cold one at x
  as an offset of both;
- the cold steps at x +- d, d a fixed direction moving every input at once (steps free to pick any basis), move as
  the differences predict: a mode the cold solves leave at once shows there.
"""

import numpy as np

from planar_lcp.engine.layout import NSTAT
from planar_lcp.engine.rollout import (DIFF_KINK, DIFF_MOVES, DIFF_NONFINITE, DIFF_OK, DIFF_REASONS, DIFF_SPACE,
                                       DIFF_STRUCTURE, _same_structure, step_differences, step_one_sided)
from planar_lcp.engine.tangent import TANGENT_NOT_COVERED, step_tangent

#: the differences' step along input k: DIFF_STEP * max(1, |x_k|) (m, rad, m/s, rad/s). Truncation (eps^2 times the
#: third derivative) and the round-off of gaps of metre-sized poses over it balance near 1e-6; the change it makes
#: to the LCP's data is far above the perturbed steps' certificate tolerance, DIFF_RES_TOL
DIFF_STEP = 2.0 ** -20
#: the one-sided differences may differ by this much, relative to their column's largest entry (at least
#: DIFF_FLOOR): eps times the second derivative on a smooth piece, O(1) across a kink
DIFF_KINK_RTOL = 1e-3
DIFF_FLOOR = 1e-3
#: the cold steps along the mixed direction agree with the differences' prediction to this, relative to the
#: prediction's size (at least DIFF_FLOOR times the direction's largest step)
DIFF_MIXED_RTOL = 1e-4
#: the certification tolerance of the perturbed and mixed-direction steps (relative, as SimOptions.res_tol), far
#: below the simulator's: Lemke stops where its artificial variable is within res_tol of zero and certifies the basic
#: z it has (engine/solvers/lemke.py), which is the answer at x for a change of the LCP's data within res_tol of its
#: scale; with the simulator's 1e-9 a differences' step that moves the data by less (a pusher's turn of 1e-6 rad/s
#: against a body at rest) falls in that dead zone and sees no change. At 1e-13 the certified answers are those of
#: the exact LCP to 1e-13 of its scale, still far above round-off (about 1e-16 times the LCP's condition)
DIFF_RES_TOL = 1e-13
#: where the one-sided differences over DIFF_STEP differ or a step DIFF_STEP away changes the step's structure, the
#: differences are taken again over DIFF_STEP / DIFF_RETRY_SHRINK: a switch of the contact modes or geometry within
#: DIFF_STEP of x but not at it (a contact that touches a micrometre away) leaves the smaller step on x's smooth piece,
#: a switch at x still shows there. Round-off grows by that factor and truncation shrinks by its square (the
#: oracle states' largest error, retried ones included, stays 1.5e-6: docs/method.md); the change of the LCP's data
#: stays far above DIFF_RES_TOL
DIFF_RETRY_SHRINK = 16.0
#: the fixed-point form's iteration count may differ between the perturbed steps when its tolerance (the largest
#: pose change it stops at, by which two counts' answers differ) is below this fraction of the differences' step:
#: an error of at most 1e-7 in the differences of the poses (1e-7 / h in the velocities')
DIFF_FP_RATIO = 1e-7

_settings = {}


def kernel_settings(sim):
    """(the perturbed steps' options: the warm start on, DIFF_RES_TOL; the checks' tolerances at DIFF_STEP, and at
    the retry's smaller step), as `step_tangent` and `step_differences` take them, made once per simulator's
    options."""
    got = _settings.get(id(sim.kopt))
    if got is None or got[0] is not sim.kopt:
        step2 = DIFF_STEP / DIFF_RETRY_SHRINK
        got = (sim.kopt, sim.kopt._replace(warm_start=True, res_tol=min(sim.kopt.res_tol, DIFF_RES_TOL)),
               [np.array([step, DIFF_KINK_RTOL, DIFF_MIXED_RTOL, DIFF_FLOOR,
                          float(sim.options.fixed_point_tol <= DIFF_FP_RATIO * step)]) for step in (DIFF_STEP, step2)])
        _settings.clear()
        _settings[id(sim.kopt)] = got
    return got[1], got[2][0], got[2][1]


def tangent_at_bases(sim, q, v, qk, vk):
    """(code, jacobian) of the first try alone, the derivatives at the cold step's bases (engine/tangent.py
    `step_tangent`): DIFF_OK where it answers (for measurements and tests; `checked_differences` is the method).
    The state's arrays as `checked_differences` takes them."""
    warm_opt, tols, _ = kernel_settings(sim)
    nd, nk = len(q), len(qk)
    jac = np.full((6 * nd + 3 * nk, 6 * nd + 6 * nk), np.nan)
    sim.reset_warm_start()
    code = step_tangent(sim.kmodel, sim.h, sim.kopt, warm_opt, sim.kwork, q, v, qk, vk, tols, jac, np.empty((nd, 3)),
                        np.empty((nd, 3)), np.empty((nk, 3)), np.empty(NSTAT))
    sim.reset_warm_start()
    return int(code), jac


class FirstTry:
    """The first try (`step_tangent`) bound to one simulator: its entry point and the arguments every call repeats
    (the model, the options, the differences' settings), looked up once instead of at every call from Python
    (`first_try`). Called with the simulator and a state `takes` accepts, it returns (code, (q+, v+, qk+),
    jacobian), the cold step's stats in sim.stats."""

    __slots__ = ("entry", "warm_opt", "tols", "dyn", "kin", "nd", "nk", "jac_shape")

    def __init__(self, sim, entry):
        self.entry = entry
        self.warm_opt, self.tols, _ = kernel_settings(sim)
        self.nd, self.nk = sim.model.ndyn, sim.model.nkin
        self.dyn, self.kin = (self.nd, 3), (self.nk, 3)
        self.jac_shape = (6 * self.nd + 3 * self.nk, 6 * self.nd + 6 * self.nk)

    def takes(self, q, v, qk, vk):
        """Whether the state's arrays are as the entry point was compiled for: float64 ndarrays of the model's
        shapes, C-contiguous, aligned and writeable (numba types a read-only array apart); any other goes the general
        way, which makes them so (`step_derivatives`). One expression: this runs at every call."""
        dyn, kin, f8, nd = self.dyn, self.kin, _FLOAT64, np.ndarray
        return (type(q) is nd and type(v) is nd and type(qk) is nd and type(vk) is nd
                and q.shape == dyn and v.shape == dyn and qk.shape == kin and vk.shape == kin
                and q.dtype is f8 and v.dtype is f8 and qk.dtype is f8 and vk.dtype is f8
                and q.flags.carray and v.flags.carray and qk.flags.carray and vk.flags.carray)

    def __call__(self, sim, q, v, qk, vk):
        jac = np.empty(self.jac_shape)
        q1, v1, qk1 = np.empty(self.dyn), np.empty(self.dyn), np.empty(self.kin)
        # the kernel's cold step forgets the warm-start memory itself (`reset_warm_start`'s work); the next `step`
        # starts cold, as after any cold step
        sim.forget_last_step()
        code = self.entry(sim.kmodel, sim.h, sim.kopt, self.warm_opt, sim.kwork, q, v, qk, vk, self.tols, jac, q1, v1,
                          qk1, sim.stats)
        return code, (q1, v1, qk1), jac


#: float64 as numpy makes it (`is`, not ==: an equal dtype of another byte order or with metadata goes the general
#: way)
_FLOAT64 = np.dtype(np.float64)


def first_try(sim):
    """The simulator's `FirstTry`, kept with its entry points (engine/entry.py `EntryPoints.bound`) once its first
    call through `checked_differences` has compiled or loaded the kernel's; None before."""
    calls = sim.kernel_calls
    got = calls.bound.get(step_tangent)
    if got is None and step_tangent in calls:
        got = calls.bound[step_tangent] = FirstTry(sim, calls.entry(step_tangent))
    return got


def checked_differences(sim, q, v, qk, vk, tangent_code=None):
    """((q+, v+, qk+), status, jacobian (6 ndyn + 3 nkin, 6 ndyn + 6 nkin)) of the cold step by its checked
    differences and "", where they stand for its derivatives (module docstring); the same and the reason where only
    the mixed direction's check failed (each input's differences hold, the step is not linear in them together:
    not differentiable); else (None, why), the reason DIFF_REASONS[DIFF_NONFINITE] where an input is not finite.
    The state's arrays: float64, C-contiguous, of the model's shapes. tangent_code: the first try's code where the
    caller ran it (`FirstTry`) and it did not answer (neither DIFF_OK nor DIFF_MOVES), else None: it runs here."""
    nd, nk = len(q), len(qk)
    warm_opt, tols, retry_tols = kernel_settings(sim)
    jac = np.empty((6 * nd + 3 * nk, 6 * nd + 6 * nk))
    q1, v1, qk1 = np.empty((nd, 3)), np.empty((nd, 3)), np.empty((nk, 3))
    stats = np.empty(NSTAT)

    def run(kernel, tols):
        # the kernel's cold step forgets the warm-start memory itself (`reset_warm_start`'s work); the next `step`
        # starts cold, as after any cold step
        sim.forget_last_step()
        return sim.kernel_calls.call(kernel, sim.kmodel, sim.h, sim.kopt, warm_opt, sim.kwork, q, v, qk, vk, tols, jac,
                                     q1, v1, qk1, stats)

    # the derivatives at the cold step's bases first (engine/tangent.py), where they cover the step and its checks
    # hold; else the differences of whole steps
    code = run(step_tangent, tols) if tangent_code is None else tangent_code
    if code == DIFF_SPACE:
        # an island larger than the dense buffers: a step grows them (as often as it needs), then again
        sim.step(q, v, qk, vk)
        code = run(step_tangent, tols)
    if code >= TANGENT_NOT_COVERED:
        code = run(step_differences, tols)
        if code in (DIFF_KINK, DIFF_STRUCTURE):
            # a switch within DIFF_STEP of x, or at x: the smaller step tells them apart (DIFF_RETRY_SHRINK)
            code = run(step_differences, retry_tols)
    if code == DIFF_SPACE:
        return None, "a step nearby needs larger dense buffers than the state's"
    if code == DIFF_NONFINITE:
        return None, DIFF_REASONS[code]             # nothing ran
    sim.stats[:] = stats
    if code == DIFF_MOVES:
        return ((q1, v1, qk1), 0, jac), DIFF_REASONS[code]
    if code != DIFF_OK:
        return None, DIFF_REASONS[code]
    return ((q1, v1, qk1), 0, jac), ""


def one_sided_differences(sim, q, v, qk, vk):
    """((q+, v+, qk+), right, left, sides) of the cold step: its one-sided differences of whole steps along each
    input (engine/rollout.py `step_one_sided`, its `sides`) over the retry's smaller step, DIFF_STEP /
    DIFF_RETRY_SHRINK, where the checked differences find a switch at the state itself; (None, why) where the cold
    step fails, a step needs larger dense buffers than the state's, or neither side of an input keeps the cold
    step's structure. The state's arrays as `checked_differences` takes them."""
    nd, nk = len(q), len(qk)
    warm_opt, _, tols = kernel_settings(sim)
    K = 6 * nd + 6 * nk
    right, left = np.empty((6 * nd + 3 * nk, K)), np.empty((6 * nd + 3 * nk, K))
    sides = np.empty(K, np.int64)
    q1, v1, qk1 = np.empty((nd, 3)), np.empty((nd, 3)), np.empty((nk, 3))
    stats = np.empty(NSTAT)
    sim.forget_last_step()
    code = sim.kernel_calls.call(step_one_sided, sim.kmodel, sim.h, sim.kopt, warm_opt, sim.kwork, q, v, qk, vk, tols,
                                 right, left, sides, q1, v1, qk1, stats)
    if code == DIFF_SPACE:
        return None, "a step nearby needs larger dense buffers than the state's"
    if code == DIFF_STRUCTURE:
        return None, "a step nearby on either side has other contacts, islands, re-solves or LCP sizes"
    if code != DIFF_OK:
        return None, DIFF_REASONS[code]
    sim.stats[:] = stats
    return ((q1, v1, qk1), right, left, sides), ""


def param_differences(sim, q, v, qk, vk, compiles, base):
    """The Jacobian's columns of scene parameters ((6 ndyn + 3 nkin, len(compiles)), "") by central differences of
    the cold step (certified to DIFF_RES_TOL) with the model's arrays compiled at each parameter's lo and hi
    (compiles: `param_compiles`' list of (name, lo, hi, {field: (array at hi, array at lo, array as compiled)}),
    written into the simulator's model in place and put back), after `checked_differences` gave the state's columns
    and the cold step's (q+, v+, qk+), base (its stats in sim.stats); or (None, why) where its checks fail (the same
    as the state's: the step's structure on both sides, the one-sided differences)."""
    arrays = sim.model.arrays
    # the perturbed steps certified to DIFF_RES_TOL, as the state's (a twin: sim's warm-start memory stays)
    tight = sim.twin(res_tol=min(sim.options.res_tol, DIFF_RES_TOL))
    base_stats = sim.stats.copy()
    x1 = np.concatenate([a.ravel() for a in base])
    cols = np.empty((len(x1), len(compiles)))
    for i, (name, lo, hi, changed) in enumerate(compiles):
        p0 = 0.5 * (lo + hi)
        outs = []
        try:
            for side in (0, 1):
                for fname, pair in changed.items():
                    getattr(arrays, fname)[...] = pair[side]
                tight.reset_warm_start()
                q1, v1, qk1, st = tight.step(q, v, qk, vk)
                # the kernel's structure check, the fixed-point iteration count included
                if st != 0 or not _same_structure(base_stats, tight.stats, False):
                    return None, f"the step's structure changes with {name}"
                outs.append(np.concatenate((q1.ravel(), v1.ravel(), qk1.ravel())))
        finally:
            for fname, pair in changed.items():
                getattr(arrays, fname)[...] = pair[2]
            sim.reset_warm_start()
        fp, fm = outs
        cols[:, i] = (fp - fm) / (hi - lo)
        right, left = (fp - x1) / (hi - p0), (x1 - fm) / (p0 - lo)
        big = max(np.max(np.abs(right)), np.max(np.abs(left)), DIFF_FLOOR)
        if np.max(np.abs(right - left)) > DIFF_KINK_RTOL * big:
            return None, f"the one-sided differences along {name} differ (a kink at the state)"
    sim.stats[:] = base_stats
    return cols, ""
