"""`planar-lcp compare SCENE --out DIR`: the same scene and time step in planar_lcp and in pymunk, side by side.

Writes to DIR:
- trajectories.png: x, y, theta of every dynamic body against time, ours (solid) and pymunk (dashed);
- frames.png: the scene drawn at four times, ours (top row) and pymunk (bottom row);
- side_by_side.gif (unless --no-gif): an animation, ours left, pymunk right;
- report.csv: one row per (simulator, dynamic body), columns `REPORT_COLUMNS`;
- report.md: the same numbers as tables, with the settings and the command line.

This module measures and reports; `compare_plots` draws the figures, `compare_cli` is the command.

Both runs are measured on the same geometry: gaps come from our collision code (`planar_lcp.engine.contacts`)
evaluated at each simulator's recorded poses, so "first contact" and "penetration" mean the same for both.
matplotlib and pymunk are imported inside the functions only.
"""

import csv
import math
import time
from pathlib import Path

import numpy as np

from planar_lcp.spec.scene import display_source

#: Columns of report.csv, in order.
REPORT_COLUMNS = ("scene", "simulator", "body", "h_s", "steps", "first_contact_t_s", "max_penetration_m",
                  "max_penetration_geom_m", "drift_xy_m", "drift_theta_rad", "final_speed_m_s", "final_x_m",
                  "final_y_m", "final_theta_rad", "max_dev_xy_m", "max_dev_theta_rad", "us_per_step")

CONTACT_DISTANCE = 1e-3     # m: "first contact" is the first step at which any two shapes are closer than this
DRIFT_FRACTION = 0.1        # drift at rest: the motion over the last 10 % of the run


def _pose_gaps(model, q_com, qk):
    """Smallest gap (m, negative = overlap) over all shape pairs at each recorded pose, with our collision code.

    q_com (T, ndyn, 3) centre-of-mass poses, qk (T, nkin, 3). Returns (T,); +inf when the scene has no pairs.
    """
    from planar_lcp.engine.contacts import contacts_at
    from planar_lcp.engine.layout import model_struct

    a = model.arrays
    out = np.full(q_com.shape[0], np.inf)
    if a.pair_a.shape[0] == 0:
        return out
    km = model_struct(a)  # once for every pose
    for i in range(q_com.shape[0]):
        phi = contacts_at(a, q_com[i], qk[i], np.inf, all_pairs=True, m=km)[1]
        if len(phi):
            out[i] = float(np.min(phi))
    return out


def _time_ours(model, options, nsteps, repeats=3):
    """Microseconds per step of Simulator.rollout over nsteps steps, best of `repeats`, after a warm-up."""
    from planar_lcp.sim import Simulator

    from planar_lcp.spec.path import kinematic_velocities

    simr = Simulator(model, options)
    q0, v0, qk0, _ = simr.initial_state()
    # the run's own kinematic velocities (a `path` body's change step by step), as simulate() takes them
    vk_seq = kinematic_velocities(model.scene, model.kin_names, simr.h, nsteps)
    simr.rollout(q0, v0, qk0, vk_seq, nsteps, stop_on_failure=False)  # warm-up: JIT compile / cache load
    best = np.inf
    for _ in range(max(1, int(repeats))):
        t0 = time.perf_counter()
        simr.rollout(q0, v0, qk0, vk_seq, nsteps, stop_on_failure=False)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / max(1, nsteps)


def _metrics(name, t, q, v, gaps, pen_reported, us, q_other):
    """Per-body rows for one simulator. q, v (T, ndyn, 3) body-frame; q_other the other simulator's q."""
    T = len(t)
    close = np.flatnonzero(gaps < CONTACT_DISTANCE)
    first = float(t[close[0]]) if close.size else math.nan
    pen_geom = float(max(0.0, -np.min(gaps))) if np.isfinite(gaps).any() else 0.0
    k0 = max(0, int(round((T - 1) * (1.0 - DRIFT_FRACTION))))
    rows = []
    for j in range(q.shape[1]):
        dxy = float(np.hypot(*(q[-1, j, :2] - q[k0, j, :2])))
        dth = float(abs(q[-1, j, 2] - q[k0, j, 2]))
        dev = q[:, j] - q_other[:, j]
        rows.append(dict(simulator=name, j=j, first_contact_t_s=first, max_penetration_m=pen_reported,
                         max_penetration_geom_m=pen_geom, drift_xy_m=dxy, drift_theta_rad=dth,
                         final_speed_m_s=float(np.hypot(*v[-1, j, :2])), final_x_m=float(q[-1, j, 0]),
                         final_y_m=float(q[-1, j, 1]), final_theta_rad=float(q[-1, j, 2]),
                         max_dev_xy_m=float(np.max(np.hypot(dev[:, 0], dev[:, 1]))),
                         max_dev_theta_rad=float(np.max(np.abs(dev[:, 2]))), us_per_step=us))
    return rows


def fmt(x):
    """A report number: 4 significant digits, "n/a" for NaN."""
    if isinstance(x, float):
        if math.isnan(x):
            return "n/a"
        return f"{x:.4g}" if abs(x) >= 1e-3 or x == 0 else f"{x:.2e}"
    return str(x)


def measure(scene, *, h, t_end, settings, repeats=3):
    """Both runs of `scene` and their REPORT_COLUMNS rows (one per simulator and dynamic body).

    settings: pymunk's (`planar_lcp.bridges.pymunk.build_space`). Returns (ours, pymunk, rows): two Trajectory and the rows.
    """
    from planar_lcp.bridges import pymunk as pb
    from planar_lcp.model import compile_scene
    from planar_lcp.sim import simulate

    ours = simulate(scene, t_end=t_end, h=h)
    pm = pb.simulate_pymunk(scene, t_end=t_end, h=h, **settings)
    nsteps = len(ours.t) - 1
    if len(pm.t) != len(ours.t):
        raise RuntimeError(f"step counts differ: ours {len(ours.t) - 1}, pymunk {len(pm.t) - 1}")

    model = compile_scene(scene)
    us_ours = _time_ours(model, ours.options, nsteps, repeats=repeats)
    us_pm = pb.time_pymunk(scene, nsteps, h=h, repeats=repeats, **settings)

    gaps_ours = _pose_gaps(model, ours.q_com, ours.qk)
    gaps_pm = _pose_gaps(model, pm.q_com, pm.qk)
    pen_ours = float(np.max(ours.stats["penetration"])) if nsteps else 0.0
    pen_pm = float(max(0.0, -np.min(gaps_pm))) if np.isfinite(gaps_pm).any() else 0.0

    rows = []
    for sim_name, t, q, v, gaps, pen, us, other in (
            ("planar_lcp", ours.t, ours.q, ours.v, gaps_ours, pen_ours, us_ours, pm.q),
            ("pymunk", pm.t, pm.q, pm.v, gaps_pm, pen_pm, us_pm, ours.q)):
        for r in _metrics(sim_name, t, q, v, gaps, pen, us, other):
            r.update(scene=scene.name, body=ours.body_names[r.pop("j")], h_s=h, steps=nsteps)
            rows.append({k: r[k] for k in REPORT_COLUMNS})
    return ours, pm, rows


def write_report_csv(path, rows):
    """report.csv: REPORT_COLUMNS, floats at full precision."""
    with open(path, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(REPORT_COLUMNS)
        for r in rows:
            wr.writerow([repr(r[k]) if isinstance(r[k], float) else r[k] for k in REPORT_COLUMNS])
    return path


def report_markdown(scene, ours, pm, rows, files, *, repeats, command=None):
    """report.md's text: the settings of both runs, what each column means, the rows as a table, the files."""
    o, po = ours.options, pm.options
    nsteps = len(ours.t) - 1
    lines = [f"# planar_lcp vs pymunk: {scene.name}", ""]
    if command:
        lines += [f"Command: `{command}`", ""]
    lines += [f"Scene `{scene.name}` ({display_source(scene)}): {scene.description}", "",
              f"- time step h = {o.h:g} s, {nsteps} steps, t = 0 to {ours.t[-1]:.6g} s (same for both)",
              f"- restitution (both simulators): e = {scene.world.restitution:g}"
              + "".join(f", {a}-{b} {e:g}" for a, b, e in scene.world.restitution_pairs)
              + " (Newton's coefficient; 0 is perfectly inelastic)",
              f"- planar_lcp: solver {o.solver}, formulation {o.formulation}, contact margin {o.contact_margin:g} m",
              f"- pymunk: iterations {po.iterations}, collision_slop {po.collision_slop:g} m, collision_bias "
              f"{po.collision_bias:.3g}, "
              + ("elasticity 0" if po.restitution_mode == "zero" else "each arbiter's restitution the scene's e "
                 "for its pair (pre_solve)")
              + f", friction by the {po.friction_mode} rule"
              + (", table friction by one PivotJoint per support point (max_bias 0)"
                 if scene.world.plane == "horizontal" else ""),
              f"- first contact: the first recorded step with any two shapes closer than {CONTACT_DISTANCE:g} m "
              "(gaps from our collision code at each simulator's poses)",
              "- max_penetration_m: ours `Trajectory.stats['penetration']`, pymunk the deepest overlap of its poses; "
              "max_penetration_geom_m: the deepest overlap of the recorded poses, same code for both",
              f"- drift: motion of the body-frame origin (and angle) over the last {DRIFT_FRACTION:.0%} of the run "
              "(meaningful where the body should be at rest)",
              "- max_dev: the largest difference from the other simulator's pose over the run",
              f"- us_per_step: ours `Simulator.rollout` (after a warm-up), pymunk a `space.step(h)` loop; best of "
              f"{repeats}, same process", "",
              "| simulator | body | first contact [s] | max pen. [m] | max pen. geom [m] | drift xy [m] | "
              "drift theta [rad] | final speed [m/s] | final x [m] | final y [m] | final theta [rad] | "
              "max dev xy [m] | max dev theta [rad] | us/step |",
              "|---|---|" + "---:|" * 12]
    for r in rows:
        lines.append("| " + " | ".join(fmt(r[k]) for k in (
            "simulator", "body", "first_contact_t_s", "max_penetration_m", "max_penetration_geom_m", "drift_xy_m",
            "drift_theta_rad", "final_speed_m_s", "final_x_m", "final_y_m", "final_theta_rad", "max_dev_xy_m",
            "max_dev_theta_rad")) + f" | {r['us_per_step']:.1f} |")
    lines += ["", "Files: " + ", ".join(f"`{Path(p).name}`" for p in files), ""]
    return "\n".join(lines)


def run_compare(scene, out, *, h=None, t_end=None, iterations=None, collision_slop=None, gif=True, repeats=3,
                command=None):
    """Run both simulators on `scene` and write the files listed in the module docstring into `out`.

    Returns a dict: rows (list of dicts, the CSV), files (paths written), ours and pymunk (each a Trajectory).
    """
    from planar_lcp.studies.compare_plots import animate_side_by_side, plot_frames, plot_overlay
    from planar_lcp.spec.scene import Scene, load_scene

    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    h = float(scene.sim.h if h is None else h)
    t_end = float(scene.sim.t_end if t_end is None else t_end)
    settings = {}
    if iterations is not None:
        settings["iterations"] = int(iterations)
    if collision_slop is not None:
        settings["collision_slop"] = float(collision_slop)
    ours, pm, rows = measure(scene, h=h, t_end=t_end, settings=settings, repeats=repeats)

    files = [write_report_csv(out / "report.csv", rows)]
    runs = [("planar_lcp", ours.q, ours.qk), ("pymunk", pm.q, pm.qk)]
    files.append(plot_overlay(out / "trajectories.png", ours, pm))
    files.append(plot_frames(out / "frames.png", scene, ours.t, runs))
    if gif:
        files.append(animate_side_by_side(out / "side_by_side.gif", scene, ours.t, runs))
    md_path = out / "report.md"
    md_path.write_text(report_markdown(scene, ours, pm, rows, files + [md_path], repeats=repeats, command=command))
    files.append(md_path)
    return dict(rows=rows, files=files, ours=ours, pymunk=pm)
