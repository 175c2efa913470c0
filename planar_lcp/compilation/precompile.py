"""On a cold numba cache, compile half of the step's kernels in a second process while the compiling one does the rest.

numba compiles one function at a time in one thread, while the machine has a second core. The step's kernels split
in two independent halves: the contacts and the rollout loop (the compiling process's) and the island solvers
(assembly, Lemke and its certification, PGS, the large-island solvers, the impulses: this helper's).
`start_helper()`, called by the background compilation (planar_lcp/compilation/background.py `compile_kernels`) before its
first stage, starts `python -m planar_lcp.compilation.precompile KIND ...` when the cache has not got the rollout
kernel: that process compiles the island solvers' kernels into numba's on-disk cache, with exactly the argument
types the step's pipeline gives them (the drivers below call them as `step_pipeline` does), and exits. When the
compiling process's own compilation of the step reaches those kernels, numba's dispatcher finds them in the cache
(it tries the cache before compiling) and loads them instead. The results are the same machine code, bit for bit
the same steps; if the helper is late or fails, the compiling process compiles what it needs itself.

Nothing starts when the JIT is disabled, numba cannot cache, fewer than two CPUs are available, the kernel is
already in the cache or compiled in this process, or PLANAR_LCP_PRECOMPILE=0. The helper is stopped when the process
that started it exits.
"""

import atexit
import os
import subprocess
import sys

import numba
from numba import njit, types
from numba.core.compiler import CompilerBase, DefaultPassBuilder
from numba.core.compiler_machinery import FunctionPass, PassManager, register_pass
from numba.core.typed_passes import NopythonTypeInference

from planar_lcp.engine.assemble import (assemble_lcp, assemble_servo, island_is_elastic, recentre_limit_surfaces,
                                        record_servo_lag, servo_within_limits)
from planar_lcp.engine.interpreted import compiled
from planar_lcp.engine.islands import contact_island, find_islands
from planar_lcp.engine.layout import (MODEL_STRUCT, OPTIONS_LAYOUT, WORK_LAYOUT, WORK_STRUCT, StepOptions, StepWork,
                                      numba_type)
from planar_lcp.engine.solvers.lemke import (LEMKE_CHAIN, block_lemke_equilibrated, block_lemke_in_work,
                                             lemke_from_basis, lemke_in_work, record_failed_island, solve_island_lemke)
from planar_lcp.engine.solvers.pgs import solve_island_pgs
from planar_lcp.engine.step import project_positions

#: environment variable: "0" turns the helper off
ENV_SWITCH = "PLANAR_LCP_PRECOMPILE"

_F2 = types.Array(types.float64, 2, "C")
_F1 = types.Array(types.float64, 1, "C")


class _Typed(Exception):
    """A driver's compilation stops here: typing it compiled (and cached) its callees, which is all it is for."""


@register_pass(mutates_CFG=False, analysis_only=True)
class _StopAfterTyping(FunctionPass):
    _name = "planar_lcp_stop_after_typing"

    def __init__(self):
        FunctionPass.__init__(self)

    def run_pass(self, state):
        raise _Typed()


class _TypeOnly(CompilerBase):
    """numba's pipeline up to type inference, then stop: a driver's own lowering and machine code (2 to 3 s of the
    helper's CPU per driver, never run) are not made; the kernels it calls were compiled while it was typed."""

    def define_pipelines(self):
        pm = PassManager("planar_lcp_type_only")
        pm.passes.extend(DefaultPassBuilder.define_untyped_pipeline(self.state).passes)
        pm.add_pass(NopythonTypeInference, "nopython frontend")
        pm.add_pass(_StopAfterTyping, "stop after typing")
        pm.finalize()
        return [pm]


def _driver(func):
    return njit(pipeline_class=_TypeOnly)(func)


@_driver
def _drive_islands(m, w, ncon, j):
    """The contact stage's kernels after the collision: the limit surfaces' re-centring and the islands
    (`prepare_contacts`, `island_members`; ncon, j: int64 counters)."""
    recentre_limit_surfaces(m, w)
    nisl = find_islands(m, ncon, w.con_pair, w.island_parent, w.body_island, w.servo_root)
    return nisl + contact_island(m, w.body_island, w.con_pair, j)


# The drivers: each calls island solvers with the argument types of `step_pipeline`'s call (engine/step.py:
# vk a row of the rollout's (nvk, nkin, 3) controls, stats a row of its stats, isl / nci / nsi int64 counters).
# Typing a driver compiles (and caches) every kernel the solvers call; the driver itself is only typed (`_TypeOnly`),
# never lowered, cached or run.

@_driver
def _drive_lemke(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    return solve_island_lemke(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats)


@_driver
def _drive_lemke_reversed(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    """The kernels `lemke_island` calls (engine/solvers/lemke.py), typed as it calls them, in the reverse of the order
    in which the step's typing reaches them: the first process, whose step reaches them from the first, meets this
    one's work instead of compiling the same kernels at the same time (an earlier design of the helper compiled most
    of them in both). A kernel whose callees the step reaches earlier (record_failed_island: the assembly) comes after
    them. PGS's driver, run before this one, has compiled the impulses' kernels (apply_impulses,
    record_impulses, contact_velocities, typed alike) and island_problem_size and island_servo. The values are never
    computed: only the types count (n, nf, nsb, ns int64 as island_problem_size's and island_servo's; piv_tol,
    equilibrate and elastic as LEMKE_CHAIN's items)."""
    n = nci + nsi
    nf = nci
    nsb = nsi
    ns = nsi
    record_servo_lag(m, w, vk, n, nsb, w.lemke_z)
    A = w.lcp_matrix[:n * n].reshape((n, n))
    b = w.lcp_vector[:n]
    _, _, _, _, elastic = LEMKE_CHAIN[isl]
    island_is_elastic(m, w.island_con, nci, w.con_pair)
    lemke_from_basis(A, b, w.warm_basic_z[isl], opt.res_tol, w)
    assemble_servo(m, w, nci, nf, n, nsb, h, A, w.lcp_vector)
    assemble_lcp(m, w, vk, nci, nsi, h, velocity_form, A, w.lcp_vector, elastic)
    record_failed_island(m, w, vk, nci, nsi, h, velocity_form, (n, nf, nsb, ns))
    return servo_within_limits(m, w, nci, nf, nsb, h, w.lemke_z)


@_driver
def _drive_block(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    """Block Lemke's kernels (large islands), typed as `solve_island_lemke` calls them; before the sparse solver,
    which the step reaches first (see _drive_lemke_reversed)."""
    n = nci + nsi
    A = w.lcp_matrix[:n * n].reshape((n, n))
    b = w.lcp_vector[:n]
    block_lemke_equilibrated(m, w, opt, vk, nci, nsi, h, velocity_form, n)
    return block_lemke_in_work(w, A, b, n, opt)


@_driver
def _drive_lemke_kernel(w, opt, isl, n, velocity_form):
    """`lemke_kernel` and its callees, typed as `lemke_chain` calls them (n int64; piv_tol and equilibrate as
    LEMKE_CHAIN's items): the largest of Lemke's kernels, compiled first (see _drive_lemke_reversed)."""
    A = w.lcp_matrix[:n * n].reshape((n, n))
    b = w.lcp_vector[:n]
    _, piv_tol, equilibrate, _, _ = LEMKE_CHAIN[isl]
    return lemke_in_work(w, A, b, n, opt, piv_tol, equilibrate, -1 if velocity_form else n)


@_driver
def _drive_pgs(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats):
    return solve_island_pgs(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats)


@_driver
def _drive_projection(m, w, opt, qk_out, stats):
    return project_positions(m, w, opt, qk_out, stats)


_DRIVERS = {"lemke": _drive_lemke, "pgs": _drive_pgs, "projection": _drive_projection, "block": _drive_block,
            "lemke_reversed": _drive_lemke_reversed, "lemke_kernel": _drive_lemke_kernel}


def _options_type():
    """The numba type of the step options (`SimOptions.kernel_options`: Python int, float and bool fields)."""
    sample = {"int": 0, "float": 0.0, "bool": False}
    return numba.typeof(StepOptions(*(sample[f.dtype] for f in OPTIONS_LAYOUT)))


def _solver_signature():
    return (MODEL_STRUCT, WORK_STRUCT, _options_type(), _F2, types.int64, types.int64, types.int64, types.float64,
            types.boolean, _F1)


def _compile_lcp():
    """`planar_lcp.lemke`'s kernel and `lcp_scale` (a failed step's checks), by calls with the argument types their
    callers give them (planar_lcp/lcp.py: float64 arrays, then int, float, float, float, bool): they share
    `lemke_kernel`, which the helper has compiled by then."""
    import numpy as np

    from planar_lcp.engine.solvers.certificate import lcp_scale
    from planar_lcp.engine.solvers.lemke import lemke_solve
    A, b = np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0])
    lcp_scale(A, b)
    lemke_solve(A, b, 100, 1e-9, 1e-12, 1e-9, False)


#: kinds compiled by a call rather than by typing a driver
_CALLS = {"lcp": _compile_lcp}


def compile_kinds(kinds):
    """Compile (into numba's cache) what a step needs after its collision, in the order the step needs it: the
    islands' kernels, then the kernels of each island solver in `kinds` (keys of _DRIVERS, or of _CALLS), then the
    work struct's constructor. Each driver is typed only (`_TypeOnly`). The helper process's work; also callable
    in-process."""
    from planar_lcp.engine.layout import _new_struct
    sig = _solver_signature()
    special = {"projection": (MODEL_STRUCT, WORK_STRUCT, sig[2], _F2, _F1),
               "lemke_kernel": (WORK_STRUCT, sig[2], types.int64, types.int64, types.boolean)}
    stages = [(_drive_islands, (MODEL_STRUCT, WORK_STRUCT, types.int64, types.int64))]
    stages += [(_CALLS[kind], None) if kind in _CALLS else (_DRIVERS[kind], special.get(kind, sig)) for kind in kinds]
    from planar_lcp.engine import copying_inlined_ir_once
    with copying_inlined_ir_once():
        for driver, driver_sig in stages:
            if driver_sig is None:
                driver()
                continue
            try:
                driver.compile(driver_sig)
            except _Typed:
                pass
        _new_struct.compile((numba.typeof(WORK_STRUCT), types.NamedTuple([numba_type(f) for f in WORK_LAYOUT],
                                                                         StepWork)))


_helper = None


#: The kinds (keys of _DRIVERS and _CALLS) the helper compiles for `rollout_lemke`, in order: the reverse of the order
#: in which the compiling process's typing of the step reaches them (its contacts, then the island solver: the sparse
#: solver, the assembly and the warm start, block Lemke, lemke_kernel, PGS, the velocity form's projection), so that
#: the two meet in the middle instead of compiling the same kernels side by side; `planar_lcp.lemke`'s kernel right
#: after lemke_kernel, on which it builds (a first run may want it early: the demo does); the solver's own driver
#: last, by when it finds its callees cached.
HELPER_KINDS = ("block", "lemke_kernel", "lcp", "pgs", "lemke_reversed", "lemke", "projection")


def _cpus():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def may_start():
    """Whether a second process may compile: not switched off, the JIT on, two CPUs or more."""
    return os.environ.get(ENV_SWITCH, "1") != "0" and not numba.config.DISABLE_JIT and _cpus() >= 2


def start_helper():
    """Start the helper (module docstring) if the rollout kernel is not compiled or cached; at most once per
    process. Returns its Popen, or None."""
    global _helper
    from planar_lcp.engine.rollout import rollout_lemke
    if _helper is not None or not may_start() or compiled(rollout_lemke):
        return None
    env = dict(os.environ, **{ENV_SWITCH: "0"})
    from planar_lcp.engine import cache_dir
    if cache_dir():
        env["NUMBA_CACHE_DIR"] = cache_dir()
    try:
        _helper = subprocess.Popen([sys.executable, "-m", __name__, *HELPER_KINDS], env=env,
                                   stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
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
