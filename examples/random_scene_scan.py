"""The random-scene set (planar_lcp.random_scenes) under each formulation: aborted runs, non-finite states, final
penetration, the largest per-step energy gain and where it comes from, and how the islands were solved.

    python examples/random_scene_scan.py [N_SCENES]        (default 200, as tests/test_reliability.py)

Energy is measured with the ground (y = 0) as the datum, relative to the run's initial energy E0 (> 0: every body
starts above the ground). A step's gain splits exactly into
  - the contact impulses' change of kinetic energy, KE(v+) - KE(v~) with v~ = v + h g (gravity's own work is
    exchanged with potential energy by the integrator and cancels),
  - the potential energy of any position change beyond q + h v+ (the velocity form's projection),
  - and gravity's exchange, which is zero for q+ = q + h v+ up to the O(h^2) term of symplectic Euler.
Runs are made with on_failure="record" so that a failure is counted, not raised.
"""

import sys

import numpy as np

from planar_lcp import simulate
from planar_lcp.model import compile_scene
from planar_lcp.random_scenes import random_scene
from planar_lcp.scene import parse_scene

FORMULATIONS = ("position", "fixed_point", "velocity")


def energy_split(tr, model, h):
    """Per step, relative to E0: total energy change, contact-impulse KE change, projection PE change."""
    a = model.arrays
    g = -a.gravity[1]
    vc, qc = tr.v_com, tr.q_com

    def ke(v):
        return (0.5 * a.dyn_mass * (v[..., 0] ** 2 + v[..., 1] ** 2) + 0.5 * a.dyn_inertia * v[..., 2] ** 2).sum(-1)

    e = tr.stats["energy"]
    v_free = vc[:-1].copy()
    v_free[..., :2] += h * a.gravity
    impulses = ke(vc[1:]) - ke(v_free)
    projection = (a.dyn_mass * g * (qc[1:, :, 1] - (qc[:-1, :, 1] + h * vc[1:, :, 1]))).sum(-1)
    return np.diff(e) / e[0], impulses / e[0], projection / e[0]


def main(n_scenes=200):
    rows = {f: dict(aborted=0, failed_steps=0, nonfinite=0, pen=0.0, gain=(0.0, None), imp=0.0, proj=0.0,
                    runs_gaining_1e3=0, methods={}) for f in FORMULATIONS}
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
            for k in ("warm_starts", "solved_lemke", "solved_unscaled", "solved_strict", "solved_velocity",
                      "pgs_uncertified"):
                r["methods"][k] = r["methods"].get(k, 0) + int(tr.stats[k].sum())
            if data["world"]["plane"] != "vertical":
                continue
            total, imp, proj = energy_split(tr, model, sc.sim.h)
            if total.max() > r["gain"][0]:
                r["gain"] = (float(total.max()), seed)
            r["imp"] = max(r["imp"], float(imp.max()))
            r["proj"] = max(r["proj"], float(proj.max()))
            r["runs_gaining_1e3"] += bool(total.max() > 1e-3)
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
    print("\nislands solved by each method (summed over steps and runs):")
    for f in FORMULATIONS:
        print(f"  {f}: " + ", ".join(f"{k} {v}" for k, v in rows[f]["methods"].items()))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)
