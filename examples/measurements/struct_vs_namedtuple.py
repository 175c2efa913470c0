"""Why the kernels take structrefs (planar_lcp/engine/layout.py): compile time and cost per step of the same
rollout kernel called with the ModelArrays / StepWork namedtuples and with their structs.

Each variant runs in its own process with a fresh numba cache, so the compile times are cold:

    python examples/measurements/struct_vs_namedtuple.py [SCENE ...]      (default: falling_rod box_push)
"""

import os
import subprocess
import sys
import tempfile

CHILD = r"""
import sys, time
import numpy as np
from planar_lcp import load_scene
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.engine.rollout import RolloutRun, make_recording, rollout_lemke

kind, name = sys.argv[1], sys.argv[2]
sc = load_scene(name)
sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
m, w = (sim.kmodel, sim.kwork) if kind == "struct" else (sim.model.arrays, sim.work)
q, v, qk, vk = sim.initial_state()
n = 400
rec = make_recording(n, q.shape[0], qk.shape[0])
args = (m, RolloutRun(q, v, qk, vk.reshape(1, -1, 3).copy(), 0, n, False, True), sim.h, sim.kopt, w, rec)
t0 = time.perf_counter()
rollout_lemke(*args)
t1 = time.perf_counter()
best = np.inf
for _ in range(10):
    t = time.perf_counter()
    rollout_lemke(*args)
    best = min(best, time.perf_counter() - t)
print(f"{t1 - t0:.1f} {best / n * 1e6:.2f}")
"""


def main(scenes):
    print("| scene | kernel arguments | first call incl. compile (s) | us / step (best of 10 rollouts of 400 steps) |")
    print("|---|---|---:|---:|")
    for name in scenes:
        for kind in ("namedtuple", "struct"):
            with tempfile.TemporaryDirectory() as cache:
                env = dict(os.environ, NUMBA_CACHE_DIR=cache)
                out = subprocess.run([sys.executable, "-c", CHILD, kind, name], env=env, capture_output=True,
                                     text=True, check=True).stdout.split()
            print(f"| {name} | {kind} | {out[0]} | {out[1]} |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or ["falling_rod", "box_push"])
