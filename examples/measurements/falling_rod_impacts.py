"""The falling rod's impacts with and without restitution: every contact episode, its end and its energy.

    python examples/measurements/falling_rod_impacts.py                    # e = 0 and e = 0.5 at h = 0.0025 (the strobe's step)
    python examples/measurements/falling_rod_impacts.py --h 0.00125 --e 0 0.5 1
    python examples/measurements/falling_rod_impacts.py --seed-arm          # friction at the end-cap centre, as Stewart & Trinkle's d
    python examples/measurements/falling_rod_impacts.py --e 1 --friction 0  # the scene's mu = 0.6 replaced

A contact episode is a maximal run of steps with a normal impulse c_n > 0 (common.active_contacts); a bounce ends
one (the study's "contact losses" count them). For each episode: the steps it spans (t[k0] to t[k1], k1 the first
step without contact, or the end of the run), which end of the rod touched ("tip": the end cap that touched first;
"other": the opposite end; "both"), the rod's (vy, omega) and kinetic energy KE = m |v|^2 / 2 + J omega^2 / 2 at
t[k0] and t[k1], and dKE_imp, the kinetic energy the contact impulses added over the episode
(trajectory.energy_changes: KE(v+) - KE(v + h g) summed over the episode's steps; < 0: dissipated). The first
episode is the impact on the tip; with e = 0 it lasts to the end of the run (the rod never leaves the table), so
the first rows also list the first steps of that episode one by one.

Then: the events of the study (falling_rod.events: slap-down, rest, contact losses, final x), the episodes before
slap-down, and every step of the run in which the impulses added kinetic energy (dKE_imp > 1e-9 J), if any.
"""

import argparse
import dataclasses
import math

import numpy as np

from planar_lcp.studies import common
from planar_lcp.studies import falling_rod as fr
from planar_lcp.model import compile_scene
from planar_lcp.sim import simulate
from planar_lcp.spec.scene import load_scene
from planar_lcp.trajectory import energy_changes

GAIN_TOL = 1e-9      # J


def kinetic(tr, i):
    b = next(b for b in tr.scene.bodies if b.type == "dynamic")
    vx, vy, w = tr.v_com[i, 0]
    return 0.5 * b.mass * (vx * vx + vy * vy) + 0.5 * b.inertia * w * w


def ends_touching(tr, k, half):
    """The set of rod ends (+1: the +x end of the body frame, -1: the other) with c_n > 0 in step k."""
    x, y, th = tr.q[k + 1, 0]
    d = np.array([math.cos(th), math.sin(th)])
    return {1 if float(np.dot(a["point"] - np.array([x, y]), d)) > 0 else -1 for a in common.active_contacts(tr, k)}


def episodes(tr):
    n = len(tr.t) - 1
    act = [bool(common.active_contacts(tr, k)) for k in range(n)]
    out, k = [], 0
    while k < n:
        if act[k]:
            j = k
            while j < n and act[j]:
                j += 1
            out.append((k, j))
            k = j
        else:
            k += 1
    return out


def report(e, h, t_end, seed_arm=False, friction=None):
    scene = load_scene("falling_rod")
    if friction is not None:
        scene = dataclasses.replace(scene, world=dataclasses.replace(scene.world, friction=friction))
    tr = simulate(scene, h=h, t_end=t_end, restitution=e, on_failure="record", seed_friction_arm=seed_arm)
    half, _ = fr.rod_geometry(tr.scene)
    _, imp, _ = energy_changes(compile_scene(tr.scene), tr.q_com, tr.v_com, h)
    eps = episodes(tr)
    ev = fr.events(tr)
    tip = next(iter(ends_touching(tr, eps[0][0], half))) if eps else 1
    arm = "end-cap centre (seed)" if seed_arm else "contact point"
    print(f"\n## e = {e:g}, h = {h:g} s, mu = {tr.scene.world.friction:g}, friction arm: {arm}, t = 0 to {t_end:g} s "
          f"({len(tr.failures)} failed steps)\n")
    print("| # | from t (s) | to t (s) | steps | end | vy before | vy after | omega before | omega after "
          "| KE before (J) | KE after (J) | dKE_imp (J) |")
    print("|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for n, (k0, k1) in enumerate(eps, 1):
        ends = set().union(*(ends_touching(tr, k, half) for k in range(k0, k1)))
        name = "both" if len(ends) == 2 else ("tip" if ends == {tip} else "other")
        print(f"| {n} | {tr.t[k0]:.4f} | {tr.t[k1]:.4f} | {k1 - k0} | {name} | {tr.v_com[k0, 0, 1]:.4f} | "
              f"{tr.v_com[k1, 0, 1]:.4f} | {tr.v_com[k0, 0, 2]:.4f} | {tr.v_com[k1, 0, 2]:.4f} | "
              f"{kinetic(tr, k0):.4f} | {kinetic(tr, k1):.4f} | {imp[k0:k1].sum():.4f} |")
    if eps:
        k0 = eps[0][0]
        print("\nFirst steps of the first episode (step from t to t + h):\n")
        print("| t (s) | c_n (N s) | vx after | vy after | omega after | KE before (J) | KE after (J) | dKE_imp (J) |")
        print("|---:|---:|---:|---:|---:|---:|---:|---:|")
        for k in range(k0, min(k0 + 3, len(tr.t) - 1)):
            cn = sum(a["cn"] for a in common.active_contacts(tr, k))
            vx, vy, w = tr.v_com[k + 1, 0]
            print(f"| {tr.t[k]:.4f} | {cn:.4f} | {vx:.4f} | {vy:.4f} | {w:.4f} | {kinetic(tr, k):.4f} | "
                  f"{kinetic(tr, k + 1):.4f} | {imp[k]:.4f} |")
    before = [p for p in eps if math.isnan(ev["t_slap_down"]) or tr.t[p[1]] < ev["t_slap_down"] - 1e-12]
    print(f"\nimpact {ev['t_impact']:.4f}  slap-down {ev['t_slap_down']:.4f}  rest {ev['t_rest']:.4f}  "
          f"contact losses {ev['contact_losses']}  final x {ev['x_final']:.4f} m")
    print(f"contact episodes ended before the slap-down step: {len(before)} (the first impact included)")
    if eps:
        up = next((i for i in range(eps[0][0] + 1, len(tr.t)) if tr.v_com[i, 0, 1] > 0), None)
        print("COM vy > 0 after the first contact: " + ("never" if up is None else f"first at t = {tr.t[up]:.4f}"))
    gains = np.flatnonzero(imp > GAIN_TOL)
    print(f"steps in which the impulses added kinetic energy (> {GAIN_TOL:g} J): {len(gains)}")
    for k in gains:
        print(f"  step t = {tr.t[k]:.4f} to {tr.t[k + 1]:.4f}: dKE_imp = {imp[k]:+.6f} J, KE {kinetic(tr, k):.4f} -> "
              f"{kinetic(tr, k + 1):.4f} J")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--h", type=float, default=fr.STROBE_H)
    p.add_argument("--e", type=float, nargs="+", default=[0.0, 0.5])
    p.add_argument("--t-end", type=float, default=fr.T_END)
    p.add_argument("--seed-arm", action="store_true", help="friction at the end-cap centre (Stewart & Trinkle's d)")
    p.add_argument("--friction", type=float, help="the rod-table friction coefficient (default: the scene's 0.6)")
    a = p.parse_args()
    for e in a.e:
        report(e, a.h, a.t_end, a.seed_arm, a.friction)


if __name__ == "__main__":
    main()
