"""Towers and pyramids with the sparse island solver (the default) and without it (sparse_min_unknowns=0: dense
Lemke on every island): thread CPU time per step of a whole run, and how far apart the two trajectories end.

Used for docs/performance.md ("Piles"):   python examples/measurements/sparse_vs_dense.py
"""

import time

import numpy as np

from planar_lcp.engine.layout import Stat
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec import piles
from planar_lcp.spec.scene import parse_scene

print("| scene | LCP unknowns | dense µs/step | sparse µs/step | speed-up | sparse solves / fallbacks | "
      "max |q| difference (m, rad) |")
print("|---|---:|---:|---:|---:|---|---:|")
for make, steps in ((lambda: piles.tower(16), 120), (lambda: piles.tower(64), 30), (lambda: piles.pyramid(6), 60)):
    scene = parse_scene(make())
    model = compile_scene(scene)
    res = {}
    for smin in (0, 128):
        sim = Simulator(model, SimOptions(h=scene.sim.h, sparse_min_unknowns=smin))
        q, v, qk, vk = sim.initial_state()
        sim.rollout(q, v, qk, vk[None], 2)                  # compile
        t = time.thread_time()
        out = sim.rollout(q, v, qk, vk[None], steps)
        res[smin] = (time.thread_time() - t) / steps * 1e6, out
    (dense_us, dense), (sparse_us, sparse) = res[0], res[128]
    st = sparse["stats"]
    print(f"| {scene.name} | {int(st[:, Stat.LCP_MAX].max())} | {dense_us:.0f} | {sparse_us:.0f} | "
          f"{dense_us / sparse_us:.1f} | {int(st[:, Stat.SOLVED_SPARSE].sum())} / "
          f"{int(st[:, Stat.SPARSE_FALLBACKS].sum())} | {np.abs(dense['q'] - sparse['q']).max():.1e} |")
