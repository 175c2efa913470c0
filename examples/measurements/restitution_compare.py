"""Restitution in planar_lcp and in pymunk, impact by impact: the tables of docs/pymunk-comparison.md, "Restitution:
a bouncing disk and the falling rod at e = 0.5".

    python examples/measurements/restitution_compare.py

Runs scenes/bouncing_disk.toml (e = 0.5) and scenes/falling_rod.toml with world.restitution replaced by 0.5 (what
`planar-lcp compare falling_rod --restitution 0.5` does) in both simulators at the scene's own h, pymunk with the
bridge's defaults (10 iterations, slop 1e-4 m), and prints for each:

- impacts: the steps whose velocity change is not free flight's (|v+ - v - h g| > IMPULSE_TOL on any COM velocity
  component: a contact impulse acted), consecutive such steps counted as one impact; per impact its step's end time,
  the number of steps, the vertical COM velocity before (the step before it) and after (its last step), the
  kinetic energy before and after and their ratio, the total energy after (potential m g y, y = 0 the table) and
  the smallest gap between the shapes over the recorded states from the one before the impact to its last
  (`planar_lcp.studies.compare._pose_gaps`, our collision code at each simulator's poses, as `planar-lcp compare` measures:
  positive = the impact acted at a distance, negative = an overlap);
- apexes: the highest COM point between an impact and the next, the height of the disk's bottom (COM y - r) or of
  the rod's COM above the table, and the ratio to the previous apex (the first to the drop height);
- time to rest: the first time from which every later state has COM speed < REST_SPEED and |omega| < REST_OMEGA.

The ideal bounce (a point mass, instantaneous impacts, no friction): apex_n = e^(2n) H and impacts at
t0 (1 + 2e + ... + 2e^(n-1)), t0 = sqrt(2 H / g), ending at t0 (1 + e) / (1 - e); printed for the disk.
"""

import math

import numpy as np

from planar_lcp.studies.compare import _pose_gaps
from planar_lcp.bridges.pymunk import simulate_pymunk
from planar_lcp.model import compile_scene
from planar_lcp.sim import simulate
from planar_lcp.spec.scene import load_scene, restitution_setting

IMPULSE_TOL = 1e-6     # m/s (rad/s): a velocity change this far from free flight's is a contact impulse
REST_SPEED = 1e-3      # m/s
REST_OMEGA = 1e-2      # rad/s
SHOWN = 6              # impacts listed per run


def impacts(tr):
    """[(first step k, last step k)] of the runs of steps with a contact impulse (step k: state k-1 -> k)."""
    g = np.asarray(tr.scene.world.gravity, float)
    h = tr.options.h
    dv = np.diff(tr.v_com[:, 0, :], axis=0)
    dv[:, :2] -= h * g
    hit = np.flatnonzero(np.max(np.abs(dv), axis=1) > IMPULSE_TOL) + 1
    runs = []
    for k in hit:
        if runs and k == runs[-1][1] + 1:
            runs[-1][1] = k
        else:
            runs.append([k, k])
    return [tuple(r) for r in runs]


def rest_time(tr):
    moving = (np.hypot(tr.v_com[:, 0, 0], tr.v_com[:, 0, 1]) >= REST_SPEED) | (np.abs(tr.v_com[:, 0, 2]) >= REST_OMEGA)
    idx = np.flatnonzero(moving)
    if idx.size == 0:
        return 0.0
    return math.nan if idx[-1] == len(tr.t) - 1 else float(tr.t[idx[-1] + 1])


def kinetic(tr, k):
    b = tr.scene.body(tr.body_names[0])
    from planar_lcp.spec.massprops import body_mass_properties
    inertia = body_mass_properties(b)[1]
    v = tr.v_com[k, 0]
    return 0.5 * b.mass * (v[0] ** 2 + v[1] ** 2) + 0.5 * inertia * v[2] ** 2


def table(label, tr, height_offset, drop):
    """Print the impacts, apexes and rest time of one run (height = COM y - height_offset)."""
    runs = impacts(tr)
    y = tr.q_com[:, 0, 1] - height_offset
    E = tr.stats["energy"]
    gaps = _pose_gaps(compile_scene(tr.scene), tr.q_com, tr.qk)
    print(f"\n{label}: {len(runs)} impacts (runs of impulse steps), time to rest {rest_time(tr):.4f} s, "
          f"final COM y {tr.q_com[-1, 0, 1]:.6f} m")
    print("| impact | t [s] | steps | v_y before [m/s] | v_y after [m/s] | -after/before | KE before [J] "
          "| KE after [J] "
          "| KE ratio | E after [J] | gap at impact [m] | next apex [m] | apex ratio |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    prev = drop
    for i, (k0, k1) in enumerate(runs[:SHOWN]):
        vb, va = tr.v_com[k0 - 1, 0, 1], tr.v_com[k1, 0, 1]
        kb, ka = kinetic(tr, k0 - 1), kinetic(tr, k1)
        gap = np.min(gaps[k0 - 1:k1 + 1])
        end = runs[i + 1][0] if i + 1 < len(runs) else len(tr.t) - 1
        apex = float(np.max(y[k1:end + 1]))
        ratio = apex / prev if prev > 0 else math.nan
        print(f"| {i + 1} | {tr.t[k0]:.4f} | {k1 - k0 + 1} | {vb:.4f} | {va:.4f} | {-va / vb:.4f} | {kb:.4g} | "
              f"{ka:.4g} | {ka / kb:.4f} | {E[k1]:.4f} | {gap:.2e} | {apex:.4g} | {ratio:.4f} |")
        prev = apex


def ideal(e, H, g, n=SHOWN):
    t0 = math.sqrt(2 * H / g)
    times = [t0 * (1 + 2 * sum(e ** j for j in range(1, i + 1))) for i in range(n)]
    print(f"\nideal bounce (point mass, e = {e:g}, H = {H:g} m, g = {g:g}): t0 = {t0:.4f} s, rest at "
          f"t0 (1 + e) / (1 - e) = {t0 * (1 + e) / (1 - e):.4f} s")
    print("| impact | t [s] | next apex [m] | apex ratio |")
    print("|---:|---:|---:|---:|")
    for i in range(n):
        print(f"| {i + 1} | {times[i]:.4f} | {H * e ** (2 * (i + 1)):.4g} | {e ** 2:.4f} |")


def main():
    disk = load_scene("bouncing_disk")
    r = disk.body("disk").shapes[0].radius
    H = disk.body("disk").position[1] - r
    g = -disk.world.gravity[1]
    print(f"# bouncing_disk: e = {disk.world.restitution:g}, h = {disk.sim.h:g} s, t_end = {disk.sim.t_end:g} s")
    ideal(disk.world.restitution, H, g)
    table("planar_lcp", simulate(disk), r, H)
    table("pymunk", simulate_pymunk(disk), r, H)

    rod = restitution_setting(load_scene("falling_rod"), 0.5)
    y0 = rod.body("rod").position[1]
    print(f"\n# falling_rod with restitution 0.5: h = {rod.sim.h:g} s, t_end = {rod.sim.t_end:g} s "
          "(heights: the rod's COM above the table)")
    table("planar_lcp", simulate(rod), 0.0, y0)
    table("pymunk", simulate_pymunk(rod), 0.0, y0)


if __name__ == "__main__":
    main()
