"""Public simulation API: validate, allocate, call a kernel.

- `simulate(scene, ...)` -> `Trajectory`: the whole run, with diagnostics per step.
- `Simulator` (model + options + work buffers) with `step()` and `rollout()` over flat state arrays, for planners.
  `rollout` equals a Python loop of `step` bit for bit (tested).
"""

import contextlib
import dataclasses
import functools
import os
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from planar_lcp.engine import copying_inlined_ir_once
from planar_lcp.engine.constants import SPARSE_MIN_UNKNOWNS, SUPPORT_POINTS
from planar_lcp.engine.entry import EntryPoints
from planar_lcp.engine.interpreted import compiled, python_version
from planar_lcp.engine.layout import (INT_STATS, NSTAT, STATS, Stat, StepOptions, make_step_work,
                                      work_struct)
from planar_lcp.engine.rollout import RUN_ROWS, Recording, RolloutRun, make_recording, rollout_lemke, rollout_pgs
from planar_lcp.engine.solvers.certificate import STATUS_NAMES
from planar_lcp.engine.step import STEP_LCP_FAILED, STEP_NEEDS_SPACE, STEP_NONFINITE, STEP_OK
from planar_lcp.errors import NoRigidSolution, SimulationError
from planar_lcp.model import Model, compile_scene
from planar_lcp.spec.path import kinematic_velocities
from planar_lcp.spec.scene import FORMULATIONS as FORMULATION_NAMES
from planar_lcp.spec.scene import (SOLVERS, Scene, SceneError, load_scene, parse_scene, restitution_setting,
                                   scene_path, sim_settings, support_model_setting)
from planar_lcp.compilation.background import start_background
from planar_lcp.frames import frame_state
from planar_lcp.infeasibility import diagnose_step
from planar_lcp.interrupt import raise_if_interrupted
from planar_lcp.trajectory import Trajectory

#: formulation name (the scene format's list) -> the kernels' FORM_* code, which is its index in that list
FORMULATIONS = {name: code for code, name in enumerate(FORMULATION_NAMES)}


@dataclass(frozen=True)
class SimOptions:
    """Numerical settings of a step (the scene's [sim] gives h, solver, formulation and the iteration counts).

    h (s): None (the default) takes the scene's [sim] h: `Simulator(model, options)` and `simulate` resolve it from the
    model's scene (`for_model`), so `Simulator(model, SimOptions(warm_start=True))` steps at the scene's h."""

    h: float | None = None
    solver: str = "lemke"
    formulation: str = "position"
    fixed_point_iterations: int = 10
    fixed_point_tol: float = 1e-9          # m / rad: stop re-linearizing when q_hat moves less than this
    pgs_iterations: int = 20
    contact_margin: float = 2e-3           # m: contacts with a gap below this at the linearization pose enter the LCP
    penetration_tol: float = 1e-6          # m: the active-set check adds a pair penetrating by more than this
    max_resolves: int = 3
    piv_tol: float = 1e-9
    ratio_tol: float = 1e-12
    res_tol: float = 1e-9
    slip_tol: float = 1e-6                 # m/s: a loaded contact slipping faster than this is "sliding"
    impulse_tol: float = 1e-12             # N s: a contact with a smaller normal impulse is "separated"
    # Try each island's previous LCP basis before Lemke (certified, else a cold solve). Off by default: where the
    # LCP has several solutions the warm start can keep a different one than Lemke's (docs/method.md, "Warm start"),
    # so the default is the method as published; the planners turn it on for speed.
    warm_start: bool = False
    # Islands without table friction whose LCP has at least this many unknowns try the sparse solver first (certified
    # by the same residual test; dense Lemke when it gives no certified answer): docs/method.md, "Large islands".
    # 0: never. Smaller islands take the dense path as before, so the goldens and the committed plans are unchanged.
    sparse_min_unknowns: int = SPARSE_MIN_UNKNOWNS

    def for_model(self, model):
        """These options with h taken from the model's scene ([sim] h) if h is None; ValueError if there is none."""
        if self.h is not None:
            return self
        sim = getattr(getattr(model, "scene", None), "sim", None)
        if sim is None:
            raise ValueError("SimOptions: h is None and the model has no scene whose [sim] h it could take; give "
                             "SimOptions(h=...) in seconds")
        return dataclasses.replace(self, h=float(sim.h))

    def kernel_options(self):
        if self.h is None:
            raise ValueError("SimOptions: h is None; give SimOptions(h=...) in seconds, or pass the options to "
                             "Simulator(model, options), which takes the model's scene's [sim] h")
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {self.solver!r}")
        if self.formulation not in FORMULATIONS:
            raise ValueError(f"formulation must be one of {', '.join(FORMULATIONS)}, got {self.formulation!r}")
        if not (np.isfinite(self.h) and self.h > 0):
            raise ValueError(f"h must be > 0, got {self.h}")
        if int(self.fixed_point_iterations) < 1:
            raise ValueError(f"fixed_point_iterations must be >= 1, got {self.fixed_point_iterations}")
        if int(self.pgs_iterations) < 1:
            raise ValueError(f"pgs_iterations must be >= 1, got {self.pgs_iterations}")
        if int(self.sparse_min_unknowns) < 0:
            raise ValueError(f"sparse_min_unknowns must be >= 0, got {self.sparse_min_unknowns}")
        return StepOptions(
            formulation=FORMULATIONS[self.formulation],
            fp_iters=int(self.fixed_point_iterations), fp_tol=float(self.fixed_point_tol),
            pgs_iters=int(self.pgs_iterations), margin=float(self.contact_margin), pen_tol=float(self.penetration_tol),
            max_resolves=int(self.max_resolves), piv_tol=float(self.piv_tol), ratio_tol=float(self.ratio_tol),
            res_tol=float(self.res_tol), slip_tol=float(self.slip_tol), impulse_tol=float(self.impulse_tol),
            warm_start=bool(self.warm_start), sparse_min=int(self.sparse_min_unknowns))


def _cause(status, stats, stopped, diagnosis=None):
    """What went wrong in a failed step; `stopped`: the run ends there (else PGS's answer was used and it went on);
    diagnosis: the step's `infeasibility.StepDiagnosis` (an LCP failure's)."""
    if status == STEP_NONFINITE:
        return "the new state is not finite (NaN or inf)"
    if status == STEP_LCP_FAILED:
        went_on = "" if stopped else "; that island took PGS's uncertified answer"
        if diagnosis is not None and diagnosis.infeasible:
            return diagnosis.reason + went_on
        ls = int(stats[Stat.LEMKE_STATUS])
        return (f"no method gave a certified solution of an island's contact LCP (size up to "
                f"{int(stats[Stat.LCP_MAX])}; Lemke ended with '{STATUS_NAMES[ls]}', residual "
                f"{stats[Stat.RESIDUAL]:.3e}, after every fallback: "
                "docs/method.md, 'Certified solves')"
                + (f"; {diagnosis.reason}" if diagnosis is not None else "") + went_on)
    return "ok"


def rollout_kernel(options):
    """The rollout kernel a simulator with these options runs: `rollout_lemke` for every Lemke run (whatever the
    scene, formulation or options: one compilation serves them all), `rollout_pgs` for solver "pgs", the osqp
    solver's Python rollout for "osqp". `Simulator.step` runs the same kernel, one step a call."""
    if options.solver == "osqp":
        from planar_lcp.engine.solvers.osqp import osqp_rollout
        return osqp_rollout
    return rollout_pgs if options.solver == "pgs" else rollout_lemke


@functools.cache
def _derivatives():
    """planar_lcp.derivatives, imported at the first derivatives call (its import takes about 70 ms, which a
    simulation without derivatives does not pay), then by a cached call (an import statement at every call costs
    about a microsecond, which a small scene's derivatives count)."""
    import planar_lcp.derivatives
    return planar_lcp.derivatives


class Simulator:
    """A compiled model, step options, and the work buffers of its kernel.

    State arrays: q, v (ndyn, 3) centre-of-mass poses and velocities of the dynamic bodies in scene order;
    qk, vk (nkin, 3) kinematic body poses (body frame) and velocities (the controls).

    On a cold numba cache (the kernel neither compiled in this process nor in numba's on-disk cache), the kernels
    compile in a background process (planar_lcp/compilation/background.py) that this simulator starts, or joins when another
    process started it: a run then waits for it (Ctrl-C stops the wait at once; the compilation goes on for the next
    run), or, with python_while_cold, runs as Python meanwhile (`simulate`'s setting: the same results bit for bit,
    engine/interpreted.py) and switches to the compiled kernel when it is ready. Where no background process can run
    (one CPU, no cache directory, PLANAR_LCP_PRECOMPILE=0) the first call compiles in this process.
    """

    def __init__(self, model: Model, options: SimOptions, python_while_cold=False):
        options = options.for_model(model)        # h=None: the scene's [sim] h
        self.model = model
        self.options = options
        self.kopt = options.kernel_options()
        self.work = make_step_work(model)
        self._kwork = None          # the kernels' view of the work buffers (`kwork`), made on first use
        #: the derivatives' kernels called without numba's dispatch (engine/entry.py): their arguments are this
        #: simulator's structs and options and float64 arrays, the same types at every call
        self.kernel_calls = EntryPoints()
        self.stats = np.zeros(NSTAT)
        self._last_step_out = None  # (q, v, qk) returned by the last `step`, for its warm start
        self._kernel = rollout_kernel(options)
        #: called as progress(steps_done, nsteps) after each of a rollout's kernel calls (CHUNK_SECONDS apart), or None
        self.progress = None
        self._chunk = 64            # steps of a rollout's first kernel call: measured and kept by each call
        self._step_rec = None       # `step`'s one-step recording, made on first use
        self._python_while_cold = python_while_cold
        self._python_rate = None    # steps per second of the kernel run as Python (a cold cache)
        # the background compilation (planar_lcp/compilation/background.py) this simulator waits for or runs Python beside, or
        # None: the kernel is compiled (or cached), or it compiles in this process at its first call
        self._ready = compiled(self._kernel)
        self._background = None if self._ready else start_background(self._kernel)
        self._twins = (None, {})    # `twin`'s simulators: (the options they were made from, {changes: simulator})

    @property
    def kmodel(self):
        """The kernels' view of model.arrays (the same buffers): engine/layout.py."""
        return self.model.struct

    @property
    def kwork(self):
        """The kernels' view of the work buffers `work` (the same buffers), made on first use: on a cold cache its
        constructor compiles, which a rollout run as Python does not need."""
        if self._kwork is None:
            self._kwork = work_struct(self.work, check=False)
        return self._kwork

    @kwork.setter
    def kwork(self, struct):
        self._kwork = struct

    @property
    def h(self):
        return self.options.h

    def twin(self, **changes):
        """This simulator where its options already have the values `changes` names, else a simulator of the same
        model (its arrays shared) with those options replaced, made once per simulator and changes and kept: the
        steps a computation takes aside with other options (the derivatives' at a tighter certificate tolerance, or
        on the dense path) leave this simulator's warm-start memory and stats alone, and cost no construction after
        the first."""
        made_from, twins = self._twins
        if made_from is not self.options:
            made_from, twins = self.options, {}
            self._twins = (made_from, twins)
        key = tuple(sorted(changes.items()))
        got = twins.get(key)
        if got is None:
            same = all(getattr(self.options, k) == x for k, x in changes.items())
            got = twins[key] = self if same else type(self)(self.model, dataclasses.replace(self.options, **changes))
        return got

    def initial_state(self):
        m = self.model
        return m.q0.copy(), m.v0.copy(), m.qk0.copy(), m.vk0.copy()

    def _grow_dense(self):
        """Larger dense buffers after a step asked for them (STEP_NEEDS_SPACE: work.dense_needed unknowns): at least
        double, at most the model's bound. Every other buffer is carried over (the warm-start memory with it)."""
        needed = int(self.work.dense_needed[0])
        have = self.work.lemke_lu.shape[0]
        if needed <= have:
            raise RuntimeError(f"a step asked for dense buffers of {needed} unknowns, and they hold {have}")
        new = make_step_work(self.model, min(self.model.max_unknowns(), max(needed, 2 * have)))
        for old, fresh in zip(self.work, new):
            if old.shape == fresh.shape:
                fresh[...] = old
        self.work, self._kwork = new, None

    def reset_warm_start(self):
        """Forget the LCP bases kept for warm starts and the sparse solver's modes: the next `step` starts cold."""
        self.work.warm_size[:] = -1
        self.work.sparse_pair_mode[:] = -1
        self.forget_last_step()

    def forget_last_step(self):
        """The next `step` starts cold, whatever its state: it does not continue the last one. The warm-start
        memory itself is left to whoever runs a cold step next (a kernel's cold step clears it, as `step` does)."""
        self._last_step_out = None

    def step(self, q, v, qk, vk):
        """One step. Returns (q+, v+, qk+, status code); self.stats holds the step's diagnostics.

        The rollout kernel makes it, one step a call, so a loop of `step` is a `rollout` bit for bit.
        Warm start (SimOptions.warm_start): when (q, v, qk) is bitwise the state the previous `step` returned, each
        island's LCP is first tried on that step's final basis, kept only if certified as accurate as a cold solve;
        any other state starts cold, as every `rollout` does. The sparse solver's first guess of the contact modes
        (the previous step's, on large islands) follows the same rule. So a loop of `step` started on a fresh
        simulator, after a rollout or after `reset_warm_start()`, equals `rollout` bit for bit."""
        last = self._last_step_out
        if last is None or not (np.array_equal(q, last[0]) and np.array_equal(v, last[1])
                                and np.array_equal(qk, last[2])):
            self.work.warm_size[:] = -1
            self.work.sparse_pair_mode[:] = -1
        rec = self._step_rec
        if rec is None:
            rec = self._step_rec = self.recording(1)
        rec.q[0], rec.v[0], rec.qk[0] = q, v, qk
        nk = self.model.nkin
        vk_seq = np.ascontiguousarray(np.asarray(vk, dtype=float).reshape(1, nk, 3))
        while True:
            self._call(rec, vk_seq, 0, 1, False, False, 1)
            st = int(rec.status[0])
            if st != STEP_NEEDS_SPACE:
                break
            self._grow_dense()
        self.stats[:] = rec.stats[0]
        q_out, v_out, qk_out = rec.q[1].copy(), rec.v[1].copy(), rec.qk[1].copy()
        self._last_step_out = (q_out.copy(), v_out.copy(), qk_out.copy())
        return q_out, v_out, qk_out, st

    def step_derivatives(self, q, v, qk, vk, params=(), method="dual"):
        """The Jacobians of one (cold) step with respect to q, v, qk, vk and the named scene parameters:
        `planar_lcp.derivatives.StepDerivatives` (dq_dq, dq_dv, dq_dvk, dv_dq, dv_dv, dv_dvk, dv_dp, ..., `exact`,
        `degenerate`). docs/method.md, "Derivatives of the step". method: "dual" (the step on dual numbers, exact to
        round-off) or "differences" (checked central differences of the compiled step, about 1e-6 of the Jacobian's
        scale and tens of times faster; the dual numbers where their checks fail, the reason in `fallback`) or
        "one_sided" (as "differences", but at a switch the compiled step's one-sided differences, not exact). The
        step differentiated is the cold one (no warm start), and the simulator's warm-start memory is reset as by
        `reset_warm_start()`."""
        return _derivatives().step_derivatives(self, q, v, qk, vk, params, method)

    def smoothed_derivatives(self, q, v, qk, vk, sigma, samples=64, seed=0, method="zeroth"):
        """The Jacobian of the step smoothed by Gaussian noise of standard deviation `sigma` on its inputs (randomized
        smoothing, for planning and optimisation through contact): `planar_lcp.derivatives.smoothing.
        SmoothedDerivatives`, with its Monte Carlo standard error. docs/method.md, "Smoothed derivatives"."""
        from planar_lcp.derivatives.smoothing import smoothed_derivatives
        return smoothed_derivatives(self, q, v, qk, vk, sigma, samples, seed, method)

    def rollout_derivatives(self, q, v, qk, vk_seq, nsteps, params=(), method="dual"):
        """A rollout's final state and its Jacobians with respect to the initial state, every step's kinematic
        velocities and the named scene parameters (the chain over `step_derivatives`, each by `method`):
        `planar_lcp.derivatives.RolloutDerivatives`."""
        from planar_lcp.derivatives import rollout_derivatives
        return rollout_derivatives(self, q, v, qk, vk_seq, nsteps, params, method)

    def rollout(self, q, v, qk, vk_seq, nsteps, stop_on_failure=True, record_contacts=False, trajectory_rows=False):
        """nsteps steps by the jitted kernels (one call for a short rollout, chunks for a long one).
        vk_seq: (nvk, nkin, 3), step i uses vk_seq[min(i, nvk - 1)].

        Returns a dict of arrays: q, v (nsteps+1, ndyn, 3), qk (nsteps+1, nkin, 3), stats (nsteps, NSTAT),
        status (nsteps,), steps_done, contact arrays when record_contacts, and when trajectory_rows the stats by
        stat and the energy per state, as `simulate`'s Trajectory takes them (engine/rollout.py `Recording`)."""
        nk = self.model.nkin
        vk_seq = np.asarray(vk_seq, dtype=float)
        if nk == 0 or vk_seq.size == 0:
            vk_seq = np.zeros((1, nk, 3))  # nothing to prescribe (reshape(-1, 0, 3) would be ambiguous)
        else:
            vk_seq = vk_seq.reshape(-1, nk, 3)
        rec = self.recording(int(nsteps), record_contacts, trajectory_rows)
        out = rec._asdict()
        out["steps_done"] = self.rollout_into(rec, q, v, qk, np.ascontiguousarray(vk_seq), stop_on_failure)
        return out

    def recording(self, nsteps, record_contacts=False, trajectory_rows=False):
        """The arrays a rollout of nsteps steps writes (engine/rollout.py `Recording`), for `rollout_into`."""
        m = self.model
        return make_recording(nsteps, m.ndyn, m.nkin, m.max_contacts() if record_contacts else 0, trajectory_rows)

    def rollout_into(self, rec, q, v, qk, vk_seq, stop_on_failure=True):
        """`rollout` into the arrays `rec` (from `recording(nsteps)`, reusable: every row a rollout reads it writes
        first), len(rec.status) steps from (q, v, qk). vk_seq: a C-contiguous float (nvk, nkin, 3). For callers
        that make many short rollouts (a planner's propagations): the same kernels, the same results bit for bit,
        without allocating per call. Returns the steps done."""
        self.forget_last_step()  # the rollout starts cold and leaves no state for `step` to continue
        rec.q[0], rec.v[0], rec.qk[0] = q, v, qk
        return self._run_chunks(rec, vk_seq, len(rec.status), bool(stop_on_failure))

    def wait_for_kernel(self):
        """On a cold cache, wait until the background compilation has put the kernel in numba's cache (Ctrl-C stops
        the wait at once; the compilation goes on for the next run); at once when the kernel is compiled or cached,
        or when it compiles in this process at its first call (no background: class docstring). For callers whose
        first kernel call happens where a Ctrl-C cannot stop it (a planner's propagations, called from OMPL)."""
        self._run_as_python(0, python=False)

    def _run_as_python(self, steps_left, python=True):
        """Whether the next kernel call runs as Python: on a cold cache (class docstring), while the background
        compilation runs and the steps left would take Python no longer than the compilation is expected to (with
        python_while_cold; else never). Otherwise this waits, Ctrl-C stopping the wait, until the kernel is in
        numba's cache (the rest of the run is compiled, bit for bit the same steps), or compiles it here if the
        background stopped without it."""
        if self._ready:
            return False
        bg = self._background
        while bg is not None and not compiled(self._kernel):
            if not bg.running():
                break                          # it stopped without the kernel: compile it here
            rate = self._python_rate
            if python and self._python_while_cold and (rate is None or steps_left / rate <= bg.seconds_left()):
                return True
            time.sleep(0.05)
            raise_if_interrupted()
        self._background, self._ready = None, True
        return False

    def _call(self, rec, vk_seq, start, n, stop_on_failure, reset_warm_start, steps_left):
        """One call of the rollout kernel: n steps from state row `start` of `rec` (a view of n + 1 state rows and n
        step rows), compiled or, on a cold cache, as Python (`_run_as_python`). Returns (steps done, steps per
        second of the call, whether it ran as Python)."""
        kernel = self._kernel
        python = self._run_as_python(steps_left)
        if python:           # a cold cache: the kernel's Python, on the namedtuples of the same buffers
            kernel, m, w = python_version(kernel), self.model.arrays, self.work
        else:
            m, w = self.kmodel, self.kwork
        # a first call that compiles in this process: with numba's inliner copying a callee's IR once
        # (planar_lcp.engine), restored after
        compiles = not python and not getattr(kernel, "overloads", True)
        run = RolloutRun(rec.q[0], rec.v[0], rec.qk[0], vk_seq, start, n, stop_on_failure, reset_warm_start)
        t0 = time.perf_counter()
        with copying_inlined_ir_once() if compiles else contextlib.nullcontext():
            done = int(kernel(m, run, self.h, self.kopt, w, rec))
        # a Ctrl-C that numba's dispatcher swallowed during the call (planar_lcp.interrupt) stops the run here
        raise_if_interrupted()
        return done, done / max(time.perf_counter() - t0, 1e-9), python

    #: Wall-clock length a rollout's kernel calls aim at: between two calls Python handles signals, so Ctrl-C stops a
    #: long simulation within about this long. Short rollouts (a planner's propagation) are one call.
    CHUNK_SECONDS = 0.25

    def _run_chunks(self, rec, vk_seq, nsteps, stop_on_failure):
        """The rollout in calls of the rollout kernel of CHUNK_SECONDS each (the kernel is resumable, so the chunks
        together equal one call bit for bit). A step that needs larger dense buffers (STEP_NEEDS_SPACE) is run again
        after they grow. Returns the steps done."""
        start, chunk = 0, self._chunk
        while start < nsteps:
            n = min(chunk, nsteps - start)
            # state rows start .. start + n, per-step rows start .. start + n - 1 (an empty contact array stays empty)
            # the Trajectory's rows go whole: the kernel writes them at the run's step index
            view = rec if n == nsteps else Recording(*(a[start:start + n + 1] if k in ("q", "v", "qk") else
                                                       a if k in RUN_ROWS else a[start:start + n]
                                                       for k, a in zip(Recording._fields, rec)))
            done, rate, python = self._call(view, vk_seq, start, n, stop_on_failure, start == 0, nsteps - start)
            if done:
                chunk = int(min(max(16, self.CHUNK_SECONDS * rate), 1 << 20))
                if python:
                    self._python_rate = rate
                else:
                    self._chunk = chunk
            start += done
            if self.progress is not None:
                self.progress(start, nsteps)
            if done and stop_on_failure and rec.status[start - 1] != STEP_OK:
                return start                  # stopped on a failed step
            if done < n:
                if rec.status[start] != STEP_NEEDS_SPACE:
                    raise RuntimeError(f"the rollout kernel stopped at step {start} with status "
                                       f"{int(rec.status[start])}")
                self._grow_dense()            # and run that step again
        return nsteps


#: Fraction of physical memory a run may plan to use (trajectory plus LCP work buffers); see `check_run_size`.
MEMORY_FRACTION = 0.25


def _physical_memory():
    """Bytes of physical memory, or None where the OS does not say."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def _fmt_bytes(n):
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.3g} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024.0


def estimate_run_bytes(model, nsteps, record_contacts=True):
    """(trajectory bytes, LCP work-buffer bytes) that `simulate` would allocate for `nsteps` steps of `model`.

    Trajectory: per step the rollout's q, v (ndyn x 3), qk (nkin x 3), stats (NSTAT), status, the contact arrays
    (88 bytes per contact slot, 2 slots per shape pair) when recorded, the Trajectory's rows it records (NSTAT stats,
    the integer-valued ones again as integers, energy), and the Trajectory's frame poses and velocities and t.
    Work: what `make_step_work` allocates (engine/layout.py `step_work_bytes`; mostly the Lemke tableau U x (2U + 2)
    and the dense A and LU, U x U each, U = model.max_unknowns())."""
    nd, nk = model.ndyn, model.nkin
    C = model.max_contacts() if record_contacts else 0
    per_step = (8 * (2 * 3 * nd + 3 * nk + NSTAT + 1) + (8 + 88 * C if C else 0) + 8 * (NSTAT + len(INT_STATS) + 1)
                + 8 * (2 * 3 * nd + 1))
    return (nsteps + 1) * per_step, model.work_bytes


def check_run_size(model, nsteps, names=None, record_contacts=True, limit=None):
    """Refuse a run whose estimated memory (`estimate_run_bytes`) exceeds `limit` bytes, by default MEMORY_FRACTION
    of physical memory (4 GiB where unknown). `names`: how the message names the settings h, t_end,
    friction_directions the user can change (default the keywords of `simulate`).
    Raises SceneError naming the estimate, the limit and what to change."""
    traj, work = estimate_run_bytes(model, nsteps, record_contacts)
    phys = _physical_memory()
    if limit is None:
        limit = MEMORY_FRACTION * phys if phys else 4 * 1024 ** 3
    if traj + work <= limit:
        return
    labels = {k: (names or {}).get(k, k) for k in ("h", "t_end", "friction_directions", "limit_surface_twists")}
    where = (f"{MEMORY_FRACTION:g} of this machine's {_fmt_bytes(phys)} of memory" if phys else "a default of 4 GiB")
    if traj >= work:
        advice = f"reduce {labels['t_end']} or increase {labels['h']}"
    elif model.scene.world.plane == "horizontal":
        knob = "friction_directions" if model.arrays.support_model == SUPPORT_POINTS else "limit_surface_twists"
        advice = f"reduce {labels[knob]} or the number of shapes in contact"
    else:
        advice = "reduce the number of shapes that can touch each other"
    raise SceneError(f"{model.scene.source}: the run must fit in {_fmt_bytes(limit)} ({where}), got an estimated "
                     f"{_fmt_bytes(traj + work)}: trajectory {_fmt_bytes(traj)} ({nsteps} steps x {model.ndyn} "
                     f"dynamic bodies, {model.max_contacts()} contact slots), LCP work buffers {_fmt_bytes(work)} "
                     f"(up to {model.max_unknowns()} unknowns); {advice}")


#: How `simulate`'s messages name its keywords (the CLI passes its flags instead, see `option_names`).
_KEYWORD_NAMES = {"on_failure": "on_failure='record'"}


@functools.lru_cache(maxsize=32)
def _compiled_scene(scene, friction_directions, seed_friction_arm, support_model, twists, resolution):
    # no background compilation yet: `run_setup` checks the run's size first, and the Simulator starts it
    return compile_scene(scene, friction_directions=friction_directions, seed_friction_arm=seed_friction_arm,
                         support_model=support_model, limit_surface_twists=twists, limit_surface_resolution=resolution,
                         background=False)


def compiled_scene(scene, friction_directions=None, seed_friction_arm=False, support_model=None, twists=None,
                   resolution=None):
    """`compile_scene` remembered for the last 32 (scene, settings): a Model never changes after compile (its
    arrays are the kernels' read-only data; each Simulator has its own work buffers), so `simulate` calls that
    sweep options over one scene share it instead of compiling it again (0.3 to 1.1 ms for a shipped scene). A
    scene that cannot be hashed is compiled each time."""
    key = (scene, friction_directions, seed_friction_arm, support_model, twists, resolution)
    if not _hashes(key):                                  # unhashable (a user's Scene built with lists)
        return _compiled_scene.__wrapped__(*key)
    return _compiled_scene(*key)


#: (name, integer-valued, its row in a rollout's stat_rows or stat_ints) of every stat a Trajectory keeps, in STATS
#: order (lemke_status is named by a failure's cause instead)
_STAT_SLOTS = [(name, integer, INT_STATS.tolist().index(i) if integer else i)
               for i, (name, integer, _) in enumerate(STATS) if name != "lemke_status"]
#: (Recording field, Trajectory.contacts key) of the recorded contacts
_CONTACT_KEYS = [(k, {"con_n": "normal", "con_p": "point"}.get(k, k[4:]))
                 for k in ("con_count", "con_pair", "con_phi", "con_n", "con_p", "con_cn", "con_ft", "con_vt",
                           "con_mode")]


def _trajectory_stats(out, done):
    """Trajectory.stats' rows of the first `done` steps of a rollout made with trajectory_rows: every stat by its
    name, each a contiguous row, the integer-valued ones as int (the rollout kernel writes them after each call's
    steps, engine/rollout.py `record_rows`: a transposed copy and a conversion here took 15 to 20 us)."""
    rows = (out["stat_rows"], out["stat_ints"])
    return {name: rows[integer][row, :done] for name, integer, row in _STAT_SLOTS}


class _RunSetup:
    """What `simulate` makes of its arguments before the rollout (the validated settings, the run's scene, options and
    compiled model, the run-size check passed, the contacts' shape pairs), kept for the next call with the same
    arguments and the same Scene object: a Scene that hashes is immutable (frozen dataclasses and tuples), so
    the same object with the same arguments validates, compiles and checks the same."""

    __slots__ = ("scene", "run_scene", "nsteps", "options", "model", "shape_pairs")

    def __init__(self, scene, run_scene, nsteps, options, model):
        self.scene, self.run_scene, self.nsteps, self.options, self.model = scene, run_scene, nsteps, options, model
        a = model.arrays
        names = [b.name for b in run_scene.bodies]
        self.shape_pairs = tuple((names[a.shape_body[pa]], names[a.shape_body[pb]])
                                 for pa, pb in zip(a.pair_a, a.pair_b))


#: The last RUN_SETUPS `_RunSetup`s of `simulate`, by (id of the Scene, the other arguments that shape the run): each
#: holds its Scene, so the id stays that Scene's while the entry lives.
_run_setups = OrderedDict()
RUN_SETUPS = 32


#: Scenes `simulate` loaded from a name or a file, by (the file, its modification time and size), the last
#: LOADED_SCENES: a sweep that names its scene reads and validates the file once (about 0.4 ms a call, more than the
#: rest of the set-up), so that its calls are kept by `_run_setups` too. Only a Scene that hashes is kept
#: (immutable: shared safely); an edited file has another key.
_loaded_scenes = OrderedDict()
LOADED_SCENES = 32
#: (scene name, $PLANAR_LCP_SCENES) -> its file's absolute path
_shipped_paths = {}


#: guards simulate's caches (_loaded_scenes, _run_setups, _idle_simulators): simulate may run in threads
_cache_lock = threading.Lock()


def _keep(cache, key, value, bound):
    """cache[key] = value in one of simulate's bounded OrderedDicts, the oldest entries dropped past `bound`."""
    with _cache_lock:
        cache[key] = value
        while len(cache) > bound:
            cache.popitem(last=False)


def _hashes(obj):
    """Whether obj hashes: a Scene that does (frozen dataclasses and tuples) is immutable, one that does not (lists)
    may change between calls and is never kept."""
    try:
        hash(obj)
    except TypeError:
        return False
    return True


def _load_scene_once(name_or_path):
    """`load_scene(name_or_path)`, read once per version of the file (see _loaded_scenes)."""
    try:
        # a name's file is where it was (the shipped scenes, or $PLANAR_LCP_SCENES as it is now); a path is resolved
        # again (the working directory may have changed)
        name = (name_or_path, os.environ.get("PLANAR_LCP_SCENES")) if isinstance(name_or_path, str) else None
        path = _shipped_paths.get(name) if name else None
        if path is None:
            path = os.path.abspath(scene_path(name_or_path))
            if name and os.path.basename(path) == f"{name_or_path}.toml":
                _shipped_paths[name] = path
        st = os.stat(path)
    except (OSError, SceneError, TypeError):
        return load_scene(name_or_path)               # raises its own error
    key = (path, st.st_mtime_ns, st.st_size)
    with _cache_lock:
        scene = _loaded_scenes.get(key)
    if scene is not None:
        return scene
    scene = load_scene(name_or_path)
    if _hashes(scene):
        _keep(_loaded_scenes, key, scene, LOADED_SCENES)
    return scene


#: Idle simulators of `simulate`, by (id of the model, options): a call takes one (or makes one) and gives it back, so
#: that a sweep of short runs does not allocate and wrap the work buffers every call (about 100 µs of the call).
#: A rollout depends on its inputs only (it forgets the warm-start memory and writes every buffer a step reads
#: before reading it), so a kept simulator runs as a new one, bit for bit (tests/simulation/test_sim_scenes.py). Each entry
#: holds its model, so the id stays that model's; at most IDLE_SIMULATORS entries, none whose buffers exceed
#: IDLE_SIMULATOR_BYTES.
_idle_simulators = OrderedDict()
IDLE_SIMULATORS = 16
IDLE_SIMULATOR_BYTES = 1 << 20


def _take_simulator(model, options):
    with _cache_lock:
        sim = _idle_simulators.pop((id(model), options), None)
    # a cold cache: this run goes on as Python while the kernels compile in the background (engine/interpreted.py)
    return sim if sim is not None else Simulator(model, options, python_while_cold=True)


def _give_back(sim):
    if sim.model.work_bytes > IDLE_SIMULATOR_BYTES:
        return
    sim.progress = None
    _keep(_idle_simulators, (id(sim.model), sim.options), sim, IDLE_SIMULATORS)


def run_setup(scene, *, t_end=None, h=None, solver=None, formulation=None, fixed_point_iterations=None,
              friction_directions=None, pgs_iterations=None, support_model=None, limit_surface_twists=None,
              limit_surface_resolution=None, restitution=None, record_contacts=True, seed_friction_arm=False,
              option_names=None, **options):
    """The run `simulate(scene, ...)` makes with these keywords, before it runs (a `_RunSetup`): `run_scene` (the
    scene with the restitution override), `nsteps`, `options` (SimOptions) and the compiled `model`; the run starts
    at the model's initial state with the kinematic velocities `kinematic_velocities(model.scene, model.kin_names, h,
    nsteps)`. Checked as simulate checks them (SceneError naming the setting); kept for the next call with the same
    keywords."""
    if isinstance(scene, dict):
        scene = parse_scene(scene)                       # SceneError (a ValueError) naming the field
    elif isinstance(scene, (str, os.PathLike)):
        scene = _load_scene_once(scene)
    elif not isinstance(scene, Scene):
        raise TypeError(f"simulate: scene must be a Scene, a scene dict, a shipped scene's name or a .toml path, got "
                        f"{type(scene).__name__}")
    names = {**_KEYWORD_NAMES, **(option_names or {})}
    key = (id(scene), t_end, h, solver, formulation, fixed_point_iterations, friction_directions, pgs_iterations,
           support_model, limit_surface_twists, limit_surface_resolution, restitution, bool(record_contacts),
           bool(seed_friction_arm), *options.items())
    try:
        setup = _run_setups.get(key)
    except TypeError:                                     # an unhashable keyword value: nothing is kept
        setup, key = None, None
    if setup is None or setup.scene is not scene:
        sim, nsteps, _ = sim_settings(scene, dict(
            t_end=t_end, h=h, solver=solver, formulation=formulation, fixed_point_iterations=fixed_point_iterations,
            friction_directions=friction_directions, pgs_iterations=pgs_iterations,
            limit_surface_twists=limit_surface_twists, limit_surface_resolution=limit_surface_resolution), names)
        support = support_model_setting(scene, support_model, names.get("support_model", "support_model"))
        run_scene = restitution_setting(scene, restitution, names.get("restitution", "restitution"))
        opts = SimOptions(h=sim.h, solver=sim.solver, formulation=sim.formulation,
                          fixed_point_iterations=sim.fixed_point_iterations, pgs_iterations=sim.pgs_iterations,
                          **options)
        model = compiled_scene(run_scene, sim.friction_directions, seed_friction_arm, support,
                               sim.limit_surface_twists, sim.limit_surface_resolution)
        check_run_size(model, nsteps, names, record_contacts)
        setup = _RunSetup(scene, run_scene, nsteps, opts, model)
        if key is not None and _hashes(scene):
            _keep(_run_setups, key, setup, RUN_SETUPS)
    return setup


def simulate(scene, *, t_end=None, h=None, solver=None, formulation=None, fixed_point_iterations=None,
             friction_directions=None, pgs_iterations=None, support_model=None, limit_surface_twists=None,
             limit_surface_resolution=None, restitution=None, on_failure="raise", record_contacts=True,
             seed_friction_arm=False, option_names=None, progress=None, **options) -> Trajectory:
    """Simulate a scene (a Scene, a scene dict as a TOML file's document, e.g. `planar_lcp.spec.piles`'s, a shipped
    scene name, or a .toml path). Keywords override the scene's [sim], and
    support_model ("limit_surface" or "points") its world.support_model: the horizontal plane's table friction
    (docs/method.md, "Table friction"; limit_surface_twists and limit_surface_resolution are that model's knobs), and
    restitution (in [0, 1]) its world.restitution: the coefficient of every contact pair without a
    world.restitution_pairs entry (docs/method.md, "Restitution").

    on_failure: "raise" (default) raises SimulationError at the first failed step (one where no method gave a
    certified answer); "record" continues (the failed island takes PGS's uncertified answer) and lists every failure
    in Trajectory.failures. seed_friction_arm applies contact
    friction at the shapes' core points, as Stewart & Trinkle's rod does (see compile_scene). option_names: how error
    messages name the keywords, e.g. {"t_end": "--t-end", "on_failure": "--on-failure record"} for a command line
    (default: the keywords themselves). progress: called as progress(steps_done, nsteps) every quarter second or so
    of a long run (`Simulator.progress`). Further keywords go to SimOptions.

    Every override is checked by the rules of the scene file's [sim] table (docs/scene-format.md, "Limits"), and the
    run's memory (`check_run_size`) before anything is allocated: SceneError (a ValueError) names the setting, the
    expected and the actual value.
    """
    if on_failure not in ("raise", "record"):
        raise ValueError(f"on_failure must be 'raise' or 'record', got {on_failure!r}")
    setup = run_setup(scene, t_end=t_end, h=h, solver=solver, formulation=formulation,
                      fixed_point_iterations=fixed_point_iterations, friction_directions=friction_directions,
                      pgs_iterations=pgs_iterations, support_model=support_model,
                      limit_surface_twists=limit_surface_twists, limit_surface_resolution=limit_surface_resolution,
                      restitution=restitution, record_contacts=record_contacts, seed_friction_arm=seed_friction_arm,
                      option_names=option_names, **options)
    names = {**_KEYWORD_NAMES, **(option_names or {})}
    scene, nsteps, opts, model = setup.run_scene, setup.nsteps, setup.options, setup.model
    h = opts.h
    simr = _take_simulator(model, opts)
    simr.progress = progress
    vk_seq = kinematic_velocities(model.scene, model.kin_names, h, nsteps)
    # the rollout copies the initial state into its recording and never writes its inputs
    out = simr.rollout(model.q0, model.v0, model.qk0, vk_seq, nsteps, stop_on_failure=(on_failure == "raise"),
                       record_contacts=record_contacts, trajectory_rows=True)
    done = out["steps_done"]
    status = out["status"][:done]
    try:
        # each failed LCP step examined for a certificate that it has no solution (infeasibility.py): per step,
        # 1 in certified_infeasible or in unclassified
        failures, diagnoses = [], {}
        infeasible, unclassified = np.zeros(done, np.int64), np.zeros(done, np.int64)
        for i in (np.flatnonzero(status != STEP_OK) if done and status.any() else ()):
            diagnosis = None
            if out["status"][i] == STEP_LCP_FAILED:
                diagnosis = diagnoses[i] = diagnose_step(simr, out["q"][i], out["v"][i], out["qk"][i],
                                                             vk_seq[min(i, len(vk_seq) - 1)])
                (infeasible if diagnosis.infeasible else unclassified)[i] = 1
            failures.append((int(i), float((i + 1) * h), _cause(out["status"][i], out["stats"][i],
                                                                on_failure == "raise", diagnosis)))
    finally:
        _give_back(simr)
    if failures and on_failure == "raise":
        i, t, cause = failures[0]
        message = (f"{scene.source}: step {i} (t = {t:.6g} s, h = {h}): {cause}; the run stopped at this step. Pass "
                   f"{names['on_failure']} to continue (a failed island then takes PGS's answer) and list the "
                   "failures.")
        if i in diagnoses and diagnoses[i].infeasible:
            raise NoRigidSolution(message, diagnoses[i])
        raise SimulationError(message)
    T = done + 1
    q_com, v_com = out["q"][:T], out["v"][:T]
    stats = _trajectory_stats(out, done)
    # the kernel's energy per state: planar_lcp.trajectory.energy(model, q_com, v_com) bit for bit
    stats.update(status=status.copy(), energy=out["energy"][:T], certified_infeasible=infeasible,
                 unclassified=unclassified)
    contacts = {name: out[k][:done] for k, name in _CONTACT_KEYS}
    contacts["shape_pairs"] = list(setup.shape_pairs)
    q_frame, v_frame = frame_state(q_com, v_com, model.com_local)
    return Trajectory(t=np.arange(T) * h, q=q_frame, v=v_frame, q_com=q_com, v_com=v_com, qk=out["qk"][:T],
                      body_names=model.dyn_names, kinematic_names=model.kin_names, stats=stats, contacts=contacts,
                      options=opts, scene=scene, failures=failures)
