"""The random-scene set (planar_lcp.spec.random_scenes) under each formulation: aborted runs, non-finite states, final
penetration, the largest per-step energy gain and where it comes from, and how the islands were solved.

    python examples/measurements/random_scene_scan.py [N_SCENES]        (default 200, as tests/simulation/test_reliability.py)

Energy is measured with the ground (y = 0) as the datum, relative to the run's initial energy E0 (> 0: every body
starts above the ground), and split by `planar_lcp.trajectory.energy_changes` into what the contact impulses add to the
kinetic energy and what the velocity form's projection adds to the potential energy.
Runs are made with on_failure="record" so that a failure is counted, not raised.
"""

import sys

import numpy as np

from planar_lcp import simulate
from planar_lcp.model import compile_scene
from planar_lcp.spec.random_scenes import random_scene
from planar_lcp.spec.scene import FORMULATIONS, parse_scene
from planar_lcp.trajectory import energy_changes


def body_sizes(scene):
    """(ndyn,) m: each dynamic body's extent, the largest distance of its shapes' points from the body origin."""
    return np.array([max(float(np.max(np.linalg.norm(sh.core_vertices_body(), axis=1))) + sh.radius
                         for sh in b.shapes) for b in scene.bodies if b.type == "dynamic"])


def main(n_scenes=200):
    rows = {f: dict(aborted=0, failed_steps=0, nonfinite=0, pen=0.0, gain=(0.0, None), imp=0.0, proj=0.0,
                    runs_gaining_1e3=0, methods={}, big_steps=0, big_fast=0, big_fallback=0) for f in FORMULATIONS}
    for seed in range(n_scenes):
        data = random_scene(seed)
        sc = parse_scene(data, f"<random {seed}>")
        model = compile_scene(sc)
        for f in FORMULATIONS:
            r = rows[f]
            tr = simulate(sc, formulation=f, on_failure="record")
            r["aborted"] += bool(tr.failures)
            r["failed_steps"] += len(tr.failures)
            r["nonfinite"] += not (np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v)))
            r["pen"] = max(r["pen"], float(tr.stats["penetration"][-1]))
            for k in ("warm_starts", "solved_lemke", "solved_equilibrated", "solved_strict", "solved_velocity",
                      "pgs_uncertified"):
                r["methods"][k] = r["methods"].get(k, 0) + int(tr.stats[k].sum())
            if data["world"]["plane"] != "vertical":
                continue
            total, imp, proj = (x / tr.stats["energy"][0] for x in energy_changes(model, tr.q_com, tr.v_com,
                                                                                     sc.sim.h))
            if total.max() > r["gain"][0]:
                r["gain"] = (float(total.max()), seed)
            r["imp"] = max(r["imp"], float(imp.max()))
            r["proj"] = max(r["proj"], float(proj.max()))
            r["runs_gaining_1e3"] += bool(total.max() > 1e-3)
            # the steps whose contact impulses add more than 1e-3 E0: does a body travel more than half its size?
            big = np.flatnonzero(imp > 1e-3)
            travel = sc.sim.h * np.hypot(tr.v_com[:-1, :, 0], tr.v_com[:-1, :, 1]) / body_sizes(sc)
            r["big_steps"] += len(big)
            r["big_fast"] += int((travel[big].max(axis=1) > 0.5).sum()) if len(big) else 0
            r["big_fallback"] += int((tr.stats["solved_velocity"][big] > 0).sum())
    n_vert = sum(random_scene(s)["world"]["plane"] == "vertical" for s in range(n_scenes))
    print(f"{n_scenes} random scenes ({n_vert} vertical, {n_scenes - n_vert} horizontal), defaults")
    print("| formulation | runs with a failed step | failed steps | non-finite | max final penetration (m) "
          "| max per-step gain / E0 (seed) | by impulses | by projection | vertical runs gaining > 1e-3 E0 |")
    print("|---|---|---|---|---|---|---|---|---|")
    for f in FORMULATIONS:
        r = rows[f]
        print(f"| {f} | {r['aborted']} | {r['failed_steps']} | {r['nonfinite']} | {r['pen']:.2e} "
              f"| {r['gain'][0]:.2e} ({r['gain'][1]}) | {r['imp']:.2e} | {r['proj']:.2e} "
              f"| {r['runs_gaining_1e3']} of {n_vert} |")
    print("\nsteps whose contact impulses add more than 1e-3 E0 (vertical plane): how many have a body moving more "
          "than half its size in the step (h |v| > size / 2), how many used the velocity-form fallback")
    for f in FORMULATIONS:
        r = rows[f]
        print(f"  {f}: {r['big_steps']} steps, {r['big_fast']} with h |v| > size / 2, {r['big_fallback']} with the "
              "fallback")
    print("\nislands solved by each method (summed over steps and runs):")
    for f in FORMULATIONS:
        print(f"  {f}: " + ", ".join(f"{k} {v}" for k, v in rows[f]["methods"].items()))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)
