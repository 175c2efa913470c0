"""The jam set (planar_lcp.spec.random_scenes.jam_scene) under the three formulations: how many runs are solved,
how many stop at a step certified to have no rigid solution, how many fail without a certificate, and what the
certificates took (branches of the search, the impulse bound). Used for docs/method.md ("No rigid solution"):

    python examples/measurements/jam_scan.py [--seeds 60]
"""

import argparse
import statistics

from planar_lcp import simulate
from planar_lcp.sim import NoRigidSolution, SimulationError
from planar_lcp.spec.random_scenes import jam_scene
from planar_lcp.spec.scene import FORMULATIONS, parse_scene


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=60)
    a = ap.parse_args()
    print("| formulation | runs | solved | certified: no rigid solution | failed without a certificate | "
          "branches per certificate, median [max] | least impulse bound (N s) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for formulation in FORMULATIONS:
        solved, certified, unclassified, branches, bounds = 0, 0, 0, [], []
        for seed in range(a.seeds):
            sc = parse_scene(jam_scene(seed), f"<jam scene {seed}>")
            try:
                simulate(sc, formulation=formulation)
                solved += 1
            except NoRigidSolution as e:
                certified += 1
                branches.append(e.diagnosis.branches)
                bounds.append(e.diagnosis.impulse_bound)
            except SimulationError:
                unclassified += 1
        med = f"{statistics.median(branches):.0f} [{max(branches)}]" if branches else "-"
        least = f"{min(bounds):.2g}" if bounds else "-"
        print(f"| {formulation} | {a.seeds} | {solved} | {certified} | {unclassified} | {med} | {least} |")


if __name__ == "__main__":
    main()
