"""On a cold numba cache, compile half of the step's kernels in a second process while this one compiles the rest.

numba compiles one function at a time in one thread, and a cold `simulate()` spends 30 to 45 s in it (issue M,
docs/performance.md "Compile time"), while the machine has a second core. The step's kernels split in two
independent halves: the contacts (compiled first: the model's start-overlap check needs them) and the island
solvers (assembly, Lemke and its certification, the impulses). `start_if_cold(model)`, called by `compile_scene`
before its first kernel call, starts `python -m planar_lcp.engine.precompile KIND ...` when the cache has not got
this model's rollout kernel: that process compiles the island solvers' kernels into numba's on-disk cache, with
exactly the argument types the step's pipeline gives them (the drivers below call them as `step_pipeline` does),
and exits. When this process's own compilation of the step reaches those kernels, numba's dispatcher finds them in
the cache (it tries the cache before compiling) and loads them instead. The results are the same machine code, bit
for bit the same steps; if the helper is late or fails, this process compiles what it needs itself, as before.

Nothing starts when the JIT is disabled, numba cannot cache, fewer than two CPUs are available, the kernel is
already in the cache or compiled in this process, or PLANAR_LCP_PRECOMPILE=0. The helper is stopped when this
process exits.

`start_background(model, options)` (what `simulate` calls on a cold cache, through `Simulator(...,
python_while_cold=True)`) starts instead a process that compiles everything a run of (model, options) compiles, as
such a run in the foreground would (the helper above included), while the run goes on as Python
(engine/interpreted.py); it outlives the run if it must, so that the next run finds the kernels cached.
"""

import atexit
import os
import pickle
import subprocess
import sys
import tempfile
import time

import numba
from numba import njit, types

from planar_lcp.engine.assemble import recentre_limit_surfaces
from planar_lcp.engine.interpreted import compiled
from planar_lcp.engine.islands import contact_island, find_islands
from planar_lcp.engine.constants import SPARSE_MIN_UNKNOWNS
from planar_lcp.engine.layout import (MODEL_STRUCT, OPTIONS_LAYOUT, WORK_LAYOUT, WORK_STRUCT, StepOptions, StepWork,
                                      numba_type)
from planar_lcp.engine.solvers.lemke import (solve_island_lemke, solve_island_lemke_cold, solve_island_lemke_small,
                                             solve_island_lemke_small_cold)
from planar_lcp.engine.solvers.pgs import solve_island_pgs
from planar_lcp.engine.step import project_positions

#: environment variable: "0" turns the helper off
ENV_SWITCH = "PLANAR_LCP_PRECOMPILE"

_F2 = types.Array(types.float64, 2, "C")
_F1 = types.Array(types.float64, 1, "C")


@njit
def _drive_islands(m, w, ncon, j):
    """The contact stage's kernels after the collision: the limit surfaces' re-centring and the islands
    (`prepare_contacts`, `island_members`; ncon, j: int64 counters)."""
    recentre_limit_surfaces(m, w)
    nisl = find_islands(m, ncon, w.con_pair, w.island_parent, w.body_island, w.servo_root)
    return nisl + contact_island(m, w.body_island, w.con_pair, j)


# The drivers: each calls island solvers with the argument types of `step_pipeline`'s call (engine/step.py:
# vk a row of the rollout's (nvk, nkin, 3) controls, stats a row of its stats, isl / nci / nsi int64 counters).
# Compiling a driver compiles (and caches) every kernel the solvers call; the driver itself is never cached or run.

@njit
def _drive_lemke_small_cold(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    return solve_island_lemke_small_cold(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats)


@njit
def _drive_lemke_cold(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    return solve_island_lemke_cold(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats)


@njit
def _drive_lemke_small(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    return solve_island_lemke_small(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats)


@njit
def _drive_lemke(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    return solve_island_lemke(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats)


@njit
def _drive_pgs(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    return solve_island_pgs(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats)


@njit
def _drive_projection(m, w, opt, qk_out, stats):
    return project_positions(m, w, opt, qk_out, stats)


_DRIVERS = {"lemke_small_cold": _drive_lemke_small_cold, "lemke_cold": _drive_lemke_cold,
            "lemke_small": _drive_lemke_small, "lemke": _drive_lemke, "pgs": _drive_pgs,
            "projection": _drive_projection}


def _options_type():
    """The numba type of the step options (`SimOptions.kernel_options`: Python int, float and bool fields)."""
    sample = {"int": 0, "float": 0.0, "bool": False}
    return numba.typeof(StepOptions(*(sample[f.dtype] for f in OPTIONS_LAYOUT)))


def _solver_signature():
    return (MODEL_STRUCT, WORK_STRUCT, _options_type(), _F2, types.int64, types.int64, types.int64, types.float64,
            types.boolean, _F1)


def compile_kinds(kinds):
    """Compile (into numba's cache) what a step needs after its collision, in the order the step needs it: the
    work struct's constructor, the islands' kernels, then the kernels of each island solver in `kinds`
    (keys of _DRIVERS). The helper process's work; also callable in-process."""
    from planar_lcp.engine.layout import _new_struct
    _new_struct.compile((numba.typeof(WORK_STRUCT), types.NamedTuple([numba_type(f) for f in WORK_LAYOUT],
                                                                     StepWork)))
    _drive_islands.compile((MODEL_STRUCT, WORK_STRUCT, types.int64, types.int64))
    sig = _solver_signature()
    for kind in kinds:
        _DRIVERS[kind].compile((MODEL_STRUCT, WORK_STRUCT, sig[2], _F2, _F1) if kind == "projection" else sig)


_helper = None


def _rollout_kernel(model, single_kernel):
    """The rollout kernel a run of `model` starts with (`simulate`'s defaults, or the single kernel with the warm
    start's code, as the planners run it: sim.py `_kernels`), and the island solvers' kinds (keys of _DRIVERS) to
    compile for it, in order: the first kernel's, then what the fallback kernel adds (PGS, the warm start, the
    velocity form's projection), which shares the rest. A single-kernel run (a planner's) needs no cold variant:
    compiling it first cost the first `plan` about 7 s of the helper's CPU time (docs/performance.md)."""
    from planar_lcp.engine import rollout
    small = model.max_unknowns() < SPARSE_MIN_UNKNOWNS
    kind = "lemke_small" if small else "lemke"
    if single_kernel:
        return (rollout.rollout_lemke_full_small if small else rollout.rollout_lemke_full), [kind, "pgs", "projection"]
    return (rollout.rollout_lemke_small if small else rollout.rollout_lemke), [kind + "_cold", "pgs", kind,
                                                                                "projection"]


def _cpus():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def _may_start():
    """Whether a second process may compile: not switched off, the JIT on, two CPUs or more."""
    return os.environ.get(ENV_SWITCH, "1") != "0" and not numba.config.DISABLE_JIT and _cpus() >= 2


def start_if_cold(model, single_kernel=False):
    """Start the helper (module docstring) for `model`'s kernels if the cache is cold; at most once per process.
    single_kernel: the run starts with the single kernel (compile_scene's hint). Returns the helper's Popen, or
    None."""
    global _helper
    if _helper is not None or not _may_start():
        return None
    kernel, kinds = _rollout_kernel(model, single_kernel)
    if compiled(kernel):
        return None
    env = dict(os.environ, **{ENV_SWITCH: "0"})
    if numba.config.CACHE_DIR:
        env["NUMBA_CACHE_DIR"] = numba.config.CACHE_DIR
    try:
        _helper = subprocess.Popen([sys.executable, "-m", __name__, *kinds], env=env, stdin=subprocess.DEVNULL,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None
    atexit.register(stop)
    return _helper


def stop():
    """Stop the helper if it still runs (what it cached stays cached: numba writes each entry whole)."""
    if _helper is not None and _helper.poll() is None:
        _helper.terminate()
        try:
            _helper.wait(5)
        except subprocess.TimeoutExpired:
            _helper.kill()


# The background compilation (`Simulator(..., python_while_cold=True)`, what `simulate` runs): on a cold cache the
# first run goes on as Python (engine/interpreted.py) while a process of its own compiles the run's kernels into
# numba's cache, exactly as a cold run in the foreground would (with its own helper above), and outlives the run if
# it must: the next run finds the kernels cached. One such process per cache directory at a time, by a lock file
# holding its pid.

#: the lock file's name in numba's cache directory
BACKGROUND_LOCK = "planar_lcp_compiling.pid"


class Background:
    """A background compilation: this process's child (`popen`), or another process's (its lock file only)."""

    def __init__(self, popen, lock, started):
        self.popen, self.lock, self.started = popen, lock, started

    def running(self):
        if self.popen is not None:
            return self.popen.poll() is None
        return _lock_holder(self.lock) is not None

    def seconds_left(self):
        """The compilation's expected time left (compile_notice.COLD_START_SECONDS from its start)."""
        from planar_lcp.engine.compile_notice import COLD_START_SECONDS
        return max(0.0, COLD_START_SECONDS - (time.time() - self.started))

    def wait(self, timeout=None):
        """Wait until it ends (for tests and scripts that measure the cache it leaves); True if it did."""
        end = None if timeout is None else time.monotonic() + timeout
        while self.running():
            if end is not None and time.monotonic() > end:
                return False
            time.sleep(0.05)
        return True


_background = None


def _lock_holder(lock):
    """The pid in the lock file if that process is alive, else None."""
    try:
        with open(lock) as f:
            pid = int(f.read().strip() or 0)
        os.kill(pid, 0)
    except (OSError, ValueError):
        return None
    return pid


def start_background(model, options):
    """Compile the kernels that `Simulator(model, options)` runs in a background process, if the cache is cold and a
    second process may compile (`_may_start`, a cache directory set); at most one per cache directory (a running one
    is returned instead of a new one). Returns a `Background`, or None: the caller then compiles in-process."""
    global _background
    cache_dir = numba.config.CACHE_DIR
    if not _may_start() or not cache_dir:
        return None
    if _background is not None and _background.running():
        return _background
    lock = os.path.join(cache_dir, BACKGROUND_LOCK)
    if _lock_holder(lock) is not None:         # another process's: this run waits for it as for its own
        try:
            started = os.path.getmtime(lock)
        except OSError:
            started = time.time()
        return Background(None, lock, started)
    try:
        os.makedirs(cache_dir, exist_ok=True)
        fd, payload = tempfile.mkstemp(prefix="planar_lcp_run_", suffix=".pickle", dir=cache_dir)
        with os.fdopen(fd, "wb") as f:
            pickle.dump((model, options), f)
        env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
        popen = subprocess.Popen([sys.executable, "-m", __name__, "--background", payload], env=env,
                                 stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                 start_new_session=True)
    except (OSError, pickle.PicklingError, TypeError, AttributeError):
        return None
    _take_lock(lock, popen.pid)  # for it, now: it takes the lock as its own once it has imported numba
    _background = Background(popen, lock, time.time())
    from planar_lcp.engine.compile_notice import announce_background
    announce_background()
    return _background


def _take_lock(lock, pid):
    """Create the lock file holding `pid`; a stale one (its process gone) is replaced. False if another process
    holds it."""
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            holder = _lock_holder(lock)
            if holder == pid:
                return True
            if holder is not None:
                return False
            try:
                os.unlink(lock)
            except OSError:
                pass
            continue
        with os.fdopen(fd, "w") as f:
            f.write(str(pid))
        return True
    return False


def _compile_in_background(payload):
    """The background process: the kernels of a run of (model, options) from `payload`, compiled into the cache as a
    cold run in the foreground compiles them: the model's (the start-overlap check's contacts, the limit surfaces'
    fixed columns), the structs' constructors, the first rollout kernel (one step of the run)."""
    lock = os.path.join(numba.config.CACHE_DIR, BACKGROUND_LOCK)
    try:
        with open(payload, "rb") as f:
            model, options = pickle.load(f)
    finally:
        os.unlink(payload)
    if not _take_lock(lock, os.getpid()):
        return
    try:
        import numpy as np
        from planar_lcp.engine.contacts import contacts_at
        from planar_lcp.engine.limit_surface import unit_load_wrench
        from planar_lcp.sim import Simulator
        start_if_cold(model, options.single_kernel or options.warm_start)
        contacts_at(model.arrays, model.q0, model.qk0, 0.0, m=model.struct)
        if model.arrays.ls_wrench.shape[0] and model.arrays.ls_wrench.shape[1]:
            unit_load_wrench(model.struct, 0, 1.0, 0.0, 0.0, np.zeros(3))
        Simulator(model, options).rollout(model.q0, model.v0, model.qk0, model.vk0[None], 1, record_contacts=True)
    finally:
        os.unlink(lock)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--background"]:
        _compile_in_background(sys.argv[2])
    else:
        compile_kinds(sys.argv[1:])
