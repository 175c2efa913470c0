"""Why assembling an island's LCP costs more than solving it: times Lemke and the assembly on the falling rod's
8-unknown LCP (at rest, two contacts) in jitted loops, and counts the reference-count operations in the assembly's
LLVM IR. Used for docs/performance.md:

    NUMBA_CACHE_DIR=$(mktemp -d) python examples/measurements/assembly_cost.py
"""

import time

import numpy as np
from numba import njit

import planar_lcp.engine.step as S
from planar_lcp.engine.assemble import assemble_lcp
from planar_lcp.engine.layout import NSTAT, LemkeSettings, lemke_work_struct, make_lemke_work
from planar_lcp.engine.solvers.lemke import lemke_kernel
from planar_lcp.model import compile_scene
from planar_lcp.spec.scene import load_scene
from planar_lcp.sim import SimOptions, Simulator

sc = load_scene("falling_rod")
sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
q, v, qk, vk = sim.initial_state()
out = sim.rollout(q, v, qk, vk[None], 300)
q, v, qk = out["q"][300].copy(), out["v"][300].copy(), out["qk"][300].copy()
m, w, kw, opt, h = sim.kmodel, sim.work, sim.kwork, sim.kopt, sim.h  # kernels take the structs; Python reads w
st = np.zeros(NSTAT)
S.begin_step(m, q, v, qk, vk, h, opt, kw, qk.copy(), st)
ncon, nisl = S.prepare_contacts(m, kw, opt, qk, st)
w.island_con[:ncon] = np.arange(ncon)  # one island: every contact (the rod has no support points)
n = 4 * ncon
A, b = np.zeros((n, n)), np.zeros(n)
args = (m, kw, vk, ncon, 0, h, False, A, b)
assemble_lcp(*args)
work = lemke_work_struct(make_lemke_work(n))
settings = LemkeSettings(500, 1e-9, 1e-12, 1e-9, True)


@njit
def loop_lemke(A, b, settings, work, N):
    for _ in range(N):
        lemke_kernel(A, b, settings, work)


@njit
def loop_assembly(args, N):
    for _ in range(N):
        assemble_lcp(*args)


N = 100000
for label, f, a in (("Lemke", loop_lemke, (A, b, settings, work)), ("assembly", loop_assembly, (args,))):
    f(*a, 2)
    t0 = time.perf_counter()
    f(*a, N)
    print(f"{label} of the {n}-unknown LCP: {(time.perf_counter() - t0) / N * 1e6:.2f} us")
fresh = njit(assemble_lcp.py_func)   # an uncached copy, whose IR can be read
fresh(*args)
ir = fresh.inspect_llvm(fresh.signatures[0])
print(f"assembly IR: {ir.count('NRT_incref')} NRT_incref and {ir.count('NRT_decref')} NRT_decref calls")
