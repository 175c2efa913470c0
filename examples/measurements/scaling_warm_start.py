"""The tower of `planar-lcp bench scaling` with the warm start on: cost and pivots per step for 1 to 32 boxes.
Used for docs/performance.md ("Scaling"):

    python examples/measurements/scaling_warm_start.py
"""

import statistics
import time

from planar_lcp.benchmarks.bench import scaling_scene
from planar_lcp.engine.layout import Stat
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator

print("| bodies | µs / step | pivots / step | warm-started LCPs per step |\n|---:|---:|---:|---:|")
for n in (1, 2, 4, 8, 16, 32):
    # the dense path, as when it was measured (docs/performance.md): the warm start of dense Lemke's bases
    sim = Simulator(compile_scene(scaling_scene(n, "pile")),
                    SimOptions(h=0.005, warm_start=True, sparse_min_unknowns=0))
    q, v, qk, vk = sim.initial_state()
    sim.rollout(q, v, qk, vk[None], 2)
    steps, reps, times = 20, max(1, 200 // n), []
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(reps):
            out = sim.rollout(q, v, qk, vk[None], steps)
        times.append((time.perf_counter() - t0) / (reps * steps))
    st = out["stats"]
    print(f"| {n} | {statistics.median(times) * 1e6:.1f} | {st[:, Stat.PIVOTS].mean():.1f} | "
          f"{st[:, Stat.WARM_STARTS].mean():.2f} |")
