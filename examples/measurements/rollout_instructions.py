"""N warm rollouts of SCENE (Simulator.rollout over the scene's own run, contacts recorded), for counting
instructions with valgrind, which counts the same whatever else the machine is doing. The step's cost is the count of
N runs less the count of 0 (imports, compilation or cache loads, the warm-up run), divided by N. numba's code for this
machine may use instructions valgrind cannot run (AVX-512), so the counts use code for a generic CPU in a cache of its
own. Used for docs/performance.md ("Reference counts" and "Compile time"), in each source tree (PYTHONPATH=TREE):

    for n in 0 100; do NUMBA_CACHE_DIR=/tmp/cg_cache NUMBA_CPU_NAME=haswell NUMBA_CPU_FEATURES="" \\
        valgrind --tool=callgrind --callgrind-out-file=/tmp/cg.$n python examples/measurements/rollout_instructions.py box_tip $n; done
    grep totals: /tmp/cg.0 /tmp/cg.100        (instructions per rollout: the difference / 100)
"""

import sys

from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec.scene import load_scene

name, runs = sys.argv[1], int(sys.argv[2])
sc = load_scene(name)
nsteps = int(round(sc.sim.t_end / sc.sim.h))
sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, solver=sc.sim.solver, formulation=sc.sim.formulation))
q, v, qk, vk = sim.initial_state()
sim.rollout(q, v, qk, vk[None], nsteps, record_contacts=True)      # warm-up: compiles or loads the kernels
for _ in range(runs):
    sim.rollout(q, v, qk, vk[None], nsteps, record_contacts=True)
