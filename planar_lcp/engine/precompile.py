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

`simulate` on a cold cache starts instead a background compilation of the whole run (planar_lcp/background.py),
which starts this helper in turn, while the run goes on as Python (engine/interpreted.py).
"""

import atexit
import os
import subprocess
import sys

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


def may_start():
    """Whether a second process may compile: not switched off, the JIT on, two CPUs or more."""
    return os.environ.get(ENV_SWITCH, "1") != "0" and not numba.config.DISABLE_JIT and _cpus() >= 2


def start_if_cold(model, single_kernel=False):
    """Start the helper (module docstring) for `model`'s kernels if the cache is cold; at most once per process.
    single_kernel: the run starts with the single kernel (compile_scene's hint). Returns the helper's Popen, or
    None."""
    global _helper
    if _helper is not None or not may_start():
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


if __name__ == "__main__":
    compile_kinds(sys.argv[1:])
