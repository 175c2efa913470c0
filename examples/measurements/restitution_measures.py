"""The numbers docs/method.md ("Restitution") quotes, measured: python examples/measurements/restitution_measures.py

1. A 1 kg disk (r = 0.1 m) dropped from 1 m onto the table, mu = 0.5, h = 1e-3, each formulation: the apex ratios
   H_{k+1} / H_k of the first bounces against e^2, the kinetic energy kept at each impact (v+^2 / v-^2 against e^2),
   and the time the disk comes to rest against t_inf = t_0 (1 + e) / (1 - e), at h = 2e-3, 1e-3 and 5e-4.
2. Stewart & Trinkle's row of four disks (gaps 1e-5 m, striker at 1 m/s, e = 1, no friction or gravity): velocities after one
   step at h = 0.0025, and after the cascade at h = 1e-6.
3. One step of 30 random rods landing (no gravity), e in {0.5, 1}, mu in {0, 0.3, 1}: the largest kinetic-energy
   change of a rod relative to its kinetic energy before the step (tests/simulation/test_restitution.py draws the same kind).
4. The shipped falling rod at e = 0.9 (an open contact that the step's impacts drive in may end the step inside):
   the deepest penetration at the end of a step, per h.
5. The 200 seeded random scenes (tests/simulation/test_reliability.py) at e = 0.5, each formulation: failed runs, island solves
   that fell back to e = 0 (solved_inelastic), the largest one-step energy gain / E0 (vertical plane; energy with the
   ground as datum) and the largest rise of the energy above E0.
"""

import numpy as np

from planar_lcp.model import compile_scene
from planar_lcp.sim import simulate
from planar_lcp.spec.scene import parse_scene

G = 9.81
TABLE = {"name": "table", "type": "static", "shapes": [{"type": "halfplane", "point": [0, 0], "normal": [0, 1]}]}


def drop(e, h, t_end, formulation="position"):
    scene = parse_scene({
        "name": "drop", "world": {"plane": "vertical", "friction": 0.5, "restitution": e},
        "sim": {"h": h, "t_end": t_end, "formulation": formulation},
        "bodies": [{"name": "ball", "type": "dynamic", "mass": 1.0, "position": [0.0, 1.1],
                    "shapes": [{"type": "disk", "radius": 0.1}]}, TABLE]})
    tr = simulate(scene)
    y, vy = tr.q[:, 0, 1] - 0.1, tr.v[:, 0, 1]
    impacts = [k for k in range(len(vy) - 1) if vy[k] < 0.0 and vy[k + 1] > 1e-9]
    ends = [0] + impacts + [len(y) - 1]
    apex = [float(y[a:b + 1].max()) for a, b in zip(ends[:-1], ends[1:])]
    moving = np.flatnonzero(np.abs(vy) > 1e-9)
    at_rest = tr.t[moving[-1] + 1] if moving[-1] + 1 < len(tr.t) else None
    return tr, impacts, apex, at_rest


def bounces():
    print("1. disk dropped from 1 m, h = 1e-3: apex ratios H_k+1 / H_k (first six) and KE kept per impact")
    for e in (0.5, 0.8):
        for form in ("position", "fixed_point", "velocity"):
            tr, impacts, apex, _ = drop(e, 1e-3, 3.0, form)
            ratios = [apex[k + 1] / apex[k] for k in range(min(6, len(impacts)))]
            vy = tr.v[:, 0, 1]
            dev = [abs(vy[k + 1] ** 2 / vy[k] ** 2 - e * e) for k in impacts]
            print(f"  e = {e} (e^2 = {e * e:.4f}) {form:<11} ratios {' '.join(f'{r:.4f}' for r in ratios)}; "
                  f"KE kept / e^2 - 1 at most {max(dev[:6]) / e ** 2:.1e} (first six impacts), "
                  f"{max(dev) / e ** 2:.1e} (all {len(dev)}, down to |v-| = {-vy[impacts[-1]]:.1e} m/s)")
    print("   time to rest (|v_y| <= 1e-9 from then on) against t_inf:")
    for e in (0.5, 0.8):
        t_inf = np.sqrt(2.0 / G) * (1 + e) / (1 - e)
        for h in (2e-3, 1e-3, 5e-4):
            _, impacts, _, t_rest = drop(e, h, t_inf + 0.8)
            print(f"  e = {e} h = {h:g}: t_inf {t_inf:.4f} s, at rest from {t_rest:.4f} s (+{t_rest - t_inf:.4f} s = "
                  f"{(t_rest - t_inf) / h:.0f} h), {len(impacts)} impacts")


def row():
    print("2. row of four disks, gaps 1e-5 m, striker 1 m/s, e = 1 (velocities along the row)")
    for h, t_end in ((0.0025, 0.005), (1e-6, 1e-4)):
        x0 = 0.2 + 0.5 * h
        bodies = [{"name": "striker", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.0], "velocity": [1.0, 0.0],
                   "shapes": [{"type": "disk", "radius": 0.1}]}]
        bodies += [{"name": f"d{i + 1}", "type": "dynamic", "mass": 1.0, "position": [x0 + i * (0.2 + 1e-5), 0.0],
                    "shapes": [{"type": "disk", "radius": 0.1}]} for i in range(3)]
        tr = simulate(parse_scene({"name": "row", "world": {"plane": "vertical", "gravity": [0.0, 0.0],
                                                            "friction": 0.0, "restitution": 1.0},
                                   "sim": {"h": h, "t_end": t_end}, "bodies": bodies}))
        k = 1 if h > 1e-5 else len(tr.t) - 1
        v = tr.v[k, :, 0]
        print(f"  h = {h:g}, after {k} step(s): v = {np.array2string(v, precision=5)}, momentum {v.sum():.15f}, "
              f"KE {0.5 * (v ** 2).sum():.6f} (before 0.5)")


def rods():
    print("3. 30 random rods landing, one step, no gravity: largest dKE / KE of a rod")
    rng = np.random.default_rng(11)
    h = 1e-3
    for e in (0.5, 1.0):
        for mu in (0.0, 0.3, 1.0):
            bodies = []
            for i in range(30):
                th = rng.uniform(-np.pi / 2, np.pi / 2)
                vy = -rng.uniform(0.5, 3.0)
                low = abs(0.25 * np.sin(th)) + 0.02
                bodies.append({"name": f"rod{i}", "type": "dynamic", "mass": 1.0,
                               "position": [3.0 * i, low + 0.3 * h * -vy], "angle": th,
                               "velocity": [rng.uniform(-2, 2), vy], "angular_velocity": rng.uniform(-10, 10),
                               "shapes": [{"type": "capsule", "length": 0.5, "radius": 0.02}]})
            scene = parse_scene({"name": "rods", "world": {"plane": "vertical", "gravity": [0.0, 0.0], "friction": mu,
                                                           "restitution": e},
                                 "sim": {"h": h, "t_end": 2 * h}, "bodies": bodies + [TABLE]})
            tr = simulate(scene)
            a = compile_scene(scene).arrays
            ke = 0.5 * (a.dyn_mass * (tr.v_com[:2, :, 0] ** 2 + tr.v_com[:2, :, 1] ** 2)
                        + a.dyn_inertia * tr.v_com[:2, :, 2] ** 2)
            rel = (ke[1] - ke[0]) / ke[0]
            print(f"  e = {e} mu = {mu}: largest dKE / KE {rel.max():+.3e}, rods gaining more than 1e-12: "
                  f"{int((rel > 1e-12).sum())} of 30")


def rod_penetration():
    print("4. falling_rod at e = 0.9: deepest penetration at the end of a step")
    for h in (0.005, 0.0025, 0.00125):
        tr = simulate("falling_rod", restitution=0.9, h=h, t_end=3.0)
        print(f"  h = {h:g}: {tr.stats['penetration'].max():.2e} m")


def random_set():
    from planar_lcp.spec.random_scenes import random_scene
    from planar_lcp.spec.scene import FORMULATIONS
    from planar_lcp.trajectory import energy_changes

    print("5. the 200 random scenes at e = 0.5")
    for form in FORMULATIONS:
        failed = inelastic = solves = runs_inelastic = 0
        gain, rise = (0.0, -1), (0.0, -1)
        for seed in range(200):
            data = random_scene(seed)
            scene = parse_scene(data, f"<random scene {seed}>")
            tr = simulate(scene, formulation=form, restitution=0.5, on_failure="record")
            failed += bool(tr.failures)
            n = int(tr.stats["solved_inelastic"].sum())
            inelastic += n
            runs_inelastic += n > 0
            solves += int(sum(tr.stats[k].sum() for k in ("warm_starts", "solved_lemke", "solved_equilibrated",
                                                             "solved_strict", "solved_velocity", "solved_inelastic")))
            if data["world"]["plane"] == "vertical":
                e0 = tr.stats["energy"][0]
                total = energy_changes(compile_scene(scene), tr.q_com, tr.v_com, scene.sim.h)[0] / e0
                gain = max(gain, (float(total.max()), seed))
                rise = max(rise, (float(tr.stats["energy"].max() / e0 - 1), seed))
        print(f"  {form:<11}: {failed} failed runs; inelastic fallbacks {inelastic} of {solves} island solves, in "
              f"{runs_inelastic} runs; largest one-step gain / E0 {gain[0]:.3g} (seed {gain[1]}), largest rise "
              f"above E0 {rise[0]:.3g} (seed {rise[1]})")


if __name__ == "__main__":
    bounces()
    row()
    rods()
    rod_penetration()
    random_set()
