"""Where the sparse island solver starts to pay: towers, pyramids and walls of growing size run with every large
island sent to the sparse solver first (sparse_min_unknowns=1) and with dense Lemke only (sparse_min_unknowns=0),
in alternating rounds of thread CPU time (`bench.alternate_rounds`). The ratio dense / sparse above 1 means the
sparse path is faster; `SimOptions.sparse_min_unknowns` (default 128) is set from this table. The bins' islands
mostly fall back to dense Lemke (docs/method.md, "Large islands"): their rows measure what a failed sparse attempt
costs.

Used for docs/performance.md ("Piles", the threshold):   python examples/measurements/sparse_threshold.py [--rounds 7]
"""

import argparse

import numpy as np

from planar_lcp.engine.layout import Stat
from planar_lcp.benchmarks.bench import _spread, alternate_rounds
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec import piles
from planar_lcp.spec.scene import parse_scene

#: (label, scene dict): sizes around the default threshold (a tower of n boxes has an LCP of 8 n unknowns)
CASES = [(f"tower {n}", lambda n=n: piles.tower(n)) for n in (4, 6, 8, 10, 12, 16, 24)] + \
        [(f"pyramid {r} rows", lambda r=r: piles.pyramid(r)) for r in (2, 3, 4, 5)] + \
        [(f"wall 2x{c}", lambda c=c: piles.wall(2, c)) for c in (2, 3, 4, 6)] + \
        [(f"bin {n}", lambda n=n: piles.bin_scene(n)) for n in (8, 16, 24)]
STEPS = 30
#: the bins are dropped from above: their runs start after the pile has formed
BIN_SETTLE = 45


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=7)
    args = ap.parse_args()
    print("| scene | LCP unknowns | dense µs/step | sparse-first µs/step | dense / sparse-first [min-max] | "
          "sparse solves / fallbacks |")
    print("|---|---:|---:|---:|---:|---|")
    for label, make in CASES:
        scene = parse_scene(make())
        model = compile_scene(scene)
        runners, outs = {}, {}
        for key, smin in (("dense", 0), ("sparse", 1)):
            sim = Simulator(model, SimOptions(h=scene.sim.h, sparse_min_unknowns=smin))
            q, v, qk, vk = sim.initial_state()
            if label.startswith("bin"):
                run = sim.rollout(q, v, qk, vk[None], BIN_SETTLE)
                q, v, qk = (np.ascontiguousarray(run[k][-1]) for k in ("q", "v", "qk"))
            outs[key] = sim.rollout(q, v, qk, vk[None], STEPS)
            runners[key] = lambda sim=sim, q=q, v=v, qk=qk, vk=vk: sim.rollout(q, v, qk, vk[None], STEPS)
        m = alternate_rounds(runners, rounds=args.rounds)
        dense, sparse = m["per_unit"]["dense"] / STEPS * 1e6, m["per_unit"]["sparse"] / STEPS * 1e6
        r = _spread(dense / sparse)
        st = outs["sparse"]["stats"]
        print(f"| {label} | {int(st[:, Stat.LCP_MAX].max())} | {np.median(dense):.0f} | {np.median(sparse):.0f} | "
              f"{r['median']:.2f} [{r['min']:.2f}-{r['max']:.2f}] | {int(st[:, Stat.SOLVED_SPARSE].sum())} / "
              f"{int(st[:, Stat.SPARSE_FALLBACKS].sum())} |")
    print(f"\n{STEPS} steps from rest (bins: from step {BIN_SETTLE}, the pile formed; h = 1/60 s) per run, "
          f"{args.rounds} alternating rounds in one process; thread CPU time per step, median; the ratio is the "
          "median of the per-round ratios [min-max]")


if __name__ == "__main__":
    main()
