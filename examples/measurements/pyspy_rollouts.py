"""A target for a sampling profiler: 40 push_t rollouts of 300 steps. Used for docs/performance.md, with py-spy
installed separately (it is not a project dependency):

    py-spy record --native -r 500 -f raw -o pyspy.txt -- python examples/measurements/pyspy_rollouts.py

then count the samples whose stack contains `Simulator.rollout` and, of those, the ones whose leaf frame is an
unsymbolized address (numba's machine code).
"""

from planar_lcp import load_scene
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator

sc = load_scene("push_t")
sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
q, v, qk, vk = sim.initial_state()
for _ in range(40):
    sim.rollout(q, v, qk, vk[None], 300)
