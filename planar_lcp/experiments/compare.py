"""`planar-lcp compare SCENE --out DIR`: the same scene and time step in planar_lcp and in pymunk, side by side.

Writes to DIR:
- trajectories.png: x, y, theta of every dynamic body against time, ours (solid) and pymunk (dashed);
- frames.png: the scene drawn at four times, ours (top row) and pymunk (bottom row);
- side_by_side.gif (unless --no-gif): an animation, ours left, pymunk right;
- report.csv: one row per (simulator, dynamic body), columns `REPORT_COLUMNS`;
- report.md: the same numbers as tables, with the settings and the command line.

Both runs are measured on the same geometry: gaps come from our collision code (`planar_lcp.engine.contacts`)
evaluated at each simulator's recorded poses, so "first contact" and "penetration" mean the same for both.
matplotlib and pymunk are imported inside the functions only.
"""

import csv
import math
import sys
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
    from planar_lcp.engine.contacts import body_poses, find_contacts, world_vertices
    from planar_lcp.engine.layout import model_struct

    a = model.arrays
    km = model_struct(a)
    T = q_com.shape[0]
    npair = a.pair_a.shape[0]
    out = np.full(T, np.inf)
    if npair == 0:
        return out
    poses = np.zeros((a.body_kind.shape[0], 3))
    vw = np.zeros((max(1, a.vert_local.shape[0]), 2))
    C = 2 * npair
    con_pair, con_phi = np.zeros(C, np.int64), np.zeros(C)
    con_n, con_p = np.zeros((C, 2)), np.zeros((C, 2))
    force = np.ones(npair, np.bool_)
    tmp = (np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2)))
    for i in range(T):
        body_poses(km, np.ascontiguousarray(q_com[i]), np.ascontiguousarray(qk[i]), poses)
        world_vertices(km, poses, vw)
        n = find_contacts(km, vw, np.inf, force, con_pair, con_phi, con_n, con_p, *tmp)
        if n:
            out[i] = float(np.min(con_phi[:n]))
    return out


def _time_ours(model, options, nsteps, repeats=3):
    """Microseconds per step of Simulator.rollout over nsteps steps, best of `repeats`, after a warm-up."""
    from planar_lcp.sim import Simulator

    simr = Simulator(model, options)
    q0, v0, qk0, vk0 = simr.initial_state()
    simr.rollout(q0, v0, qk0, vk0[None], nsteps, stop_on_failure=False)  # warm-up: JIT compile / cache load
    best = np.inf
    for _ in range(max(1, int(repeats))):
        t0 = time.perf_counter()
        simr.rollout(q0, v0, qk0, vk0[None], nsteps, stop_on_failure=False)
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


def _view(scene, qs, qks):
    """Axis limits (x0, x1, y0, y1) covering the moving bodies over both runs, and the ground under them."""
    pts = []
    for kind, seqs in (("dynamic", qs), ("kinematic", qks)):
        bodies = [b for b in scene.bodies if b.type == kind]
        for seq in seqs:
            for j, b in enumerate(bodies):
                for s in b.shapes:
                    core = np.asarray(s.core_vertices_body(), float).reshape(-1, 2)
                    th = seq[:, j, 2]
                    c, sn = np.cos(th)[:, None], np.sin(th)[:, None]
                    x = seq[:, j, 0:1] + c * core[:, 0] - sn * core[:, 1]
                    y = seq[:, j, 1:2] + sn * core[:, 0] + c * core[:, 1]
                    r = float(s.radius)
                    pts.append(np.column_stack([x.min() - r, y.min() - r]))
                    pts.append(np.column_stack([x.max() + r, y.max() + r]))
    for b in scene.bodies:
        if b.type == "static":
            for s in b.shapes:
                if s.type != "halfplane":
                    core = np.asarray(s.core_vertices_body(), float).reshape(-1, 2) + np.asarray(b.position)
                    pts.append(core.min(0) - s.radius)
                    pts.append(core.max(0) + s.radius)
    P = np.vstack([np.atleast_2d(p) for p in pts])
    x0, y0 = P.min(0)
    x1, y1 = P.max(0)
    if scene.world.plane == "vertical" and any(s.type == "halfplane" for b in scene.bodies for s in b.shapes):
        y0 = min(y0, -0.05 * max(y1 - y0, 0.1))   # show some ground
    span = max(x1 - x0, y1 - y0, 0.05)
    m = 0.08 * span
    return x0 - m, x1 + m, y0 - m, y1 + m


def _set_limits(ax, view):
    ax.set_autoscale_on(False)
    ax.set_xlim(view[0], view[1])
    ax.set_ylim(view[2], view[3])
    ax.set_aspect("equal", adjustable="box")


def plot_overlay(path, scene, t, q_ours, q_pm, names, h, iterations):
    """x, y, theta of each dynamic body against time: ours solid, pymunk dashed."""
    from planar_lcp.viz import _new_figure

    nd = len(names)
    fig = _new_figure((max(7.0, 4.2 * nd + 1.0), 6.4), dpi=90)
    fig.suptitle(f"{scene.name}: planar_lcp (solid) vs pymunk (dashed)\nh = {h:g} s, pymunk iterations "
                 f"{iterations}", fontsize=10)
    labels = ("x [m]", "y [m]", "theta [rad]")
    for j, name in enumerate(names):
        for r in range(3):
            ax = fig.add_subplot(3, max(1, nd), r * max(1, nd) + j + 1)
            ax.plot(t, q_ours[:, j, r], color="tab:blue", lw=1.4, label="planar_lcp")
            ax.plot(t, q_pm[:, j, r], color="tab:orange", lw=1.4, ls="--", label="pymunk")
            lo = min(q_ours[:, j, r].min(), q_pm[:, j, r].min())
            hi = max(q_ours[:, j, r].max(), q_pm[:, j, r].max())
            if hi - lo < 1e-3:
                c = 0.5 * (hi + lo)
                ax.set_ylim(c - 5e-4, c + 5e-4)
            ax.set_ylabel(labels[r], fontsize=9)
            ax.tick_params(labelsize=8)
            ax.grid(True, color="0.9", lw=0.6)
            if r == 0:
                ax.set_title(name, fontsize=10)
                if j == 0:
                    ax.legend(fontsize=8, loc="best")
            if r == 2:
                ax.set_xlabel("t [s]", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    fig.savefig(path, format="png")
    return path


def plot_frames(path, scene, t, runs, nframes=4):
    """The scene at `nframes` evenly spaced times, one row per run: runs = [(label, q, qk), ...]."""
    from planar_lcp.viz import _new_figure, draw_scene

    view = _view(scene, [r[1] for r in runs], [r[2] for r in runs])
    idx = np.unique(np.round(np.linspace(0, len(t) - 1, nframes)).astype(int))
    aspect = (view[3] - view[2]) / (view[1] - view[0])
    w = 2.6
    fig = _new_figure((w * len(idx) + 0.6, w * aspect * len(runs) + 0.9), dpi=80)
    for r, (label, q, qk) in enumerate(runs):
        for c, i in enumerate(idx):
            ax = fig.add_subplot(len(runs), len(idx), r * len(idx) + c + 1)
            _set_limits(ax, view)
            draw_scene(ax, scene, q[i], qk[i])
            ax.set_title(f"{label}, t = {t[i]:.3g} s", fontsize=8)
            ax.tick_params(labelsize=6)
    fig.tight_layout()
    fig.savefig(path, format="png")
    return path


def animate_side_by_side(path, scene, t, runs, fps=20, max_frames=60):
    """A GIF, one panel per run (runs = [(label, q, qk), ...]), redrawn per frame with our draw_scene."""
    from matplotlib.animation import PillowWriter

    from planar_lcp.viz import _new_figure, draw_scene

    view = _view(scene, [r[1] for r in runs], [r[2] for r in runs])
    frames = np.unique(np.round(np.linspace(0, len(t) - 1, min(len(t), max_frames))).astype(int))
    aspect = (view[3] - view[2]) / (view[1] - view[0])
    fig = _new_figure((3.2 * len(runs), 3.2 * aspect + 0.6), dpi=60)
    axes = [fig.add_subplot(1, len(runs), k + 1) for k in range(len(runs))]
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(path), dpi=fig.dpi):
        for i in frames:
            for ax, (label, q, qk) in zip(axes, runs):
                ax.clear()
                _set_limits(ax, view)
                draw_scene(ax, scene, q[i], qk[i])
                ax.set_title(f"{label}  t = {t[i]:.2f} s", fontsize=9)
                ax.tick_params(labelsize=6)
            writer.grab_frame()
    return path


def _fmt(x):
    if isinstance(x, float):
        if math.isnan(x):
            return "n/a"
        return f"{x:.4g}" if abs(x) >= 1e-3 or x == 0 else f"{x:.2e}"
    return str(x)


def run_compare(scene, out, *, h=None, t_end=None, iterations=None, collision_slop=None, gif=True, repeats=3,
                command=None):
    """Run both simulators on `scene` and write the files listed in the module docstring into `out`.

    Returns a dict: rows (list of dicts, the CSV), files (paths written), ours (Trajectory), pymunk
    (PymunkTrajectory).
    """
    from planar_lcp.experiments import pymunk_bridge as pb
    from planar_lcp.model import compile_scene
    from planar_lcp.spec.scene import Scene, load_scene
    from planar_lcp.sim import simulate

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

    files = []
    csv_path = out / "report.csv"
    with open(csv_path, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(REPORT_COLUMNS)
        for r in rows:
            wr.writerow([repr(r[k]) if isinstance(r[k], float) else r[k] for k in REPORT_COLUMNS])
    files.append(csv_path)

    its = pm.settings["iterations"]
    runs = [("planar_lcp", ours.q, ours.qk), ("pymunk", pm.q, pm.qk)]
    files.append(plot_overlay(out / "trajectories.png", scene, ours.t, ours.q, pm.q, ours.body_names, h, its))
    files.append(plot_frames(out / "frames.png", scene, ours.t, runs))
    if gif:
        files.append(animate_side_by_side(out / "side_by_side.gif", scene, ours.t, runs))

    o = ours.options
    lines = [f"# planar_lcp vs pymunk: {scene.name}", ""]
    if command:
        lines += [f"Command: `{command}`", ""]
    lines += [f"Scene `{scene.name}` ({display_source(scene)}): {scene.description}", "",
              f"- time step h = {h:g} s, {nsteps} steps, t = 0 to {ours.t[-1]:.6g} s (same for both)",
              f"- planar_lcp: solver {o.solver}, formulation {o.formulation}, contact margin {o.contact_margin:g} m",
              f"- pymunk: iterations {its}, collision_slop {pm.settings['collision_slop']:g} m, collision_bias "
              f"{pm.settings['collision_bias']:.3g}, elasticity 0, friction by the {pm.friction_mode} rule"
              + (", table friction by PivotJoint + GearJoint (max_bias 0)" if scene.world.plane == "horizontal"
                 else ""),
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
        lines.append("| " + " | ".join(_fmt(r[k]) for k in (
            "simulator", "body", "first_contact_t_s", "max_penetration_m", "max_penetration_geom_m", "drift_xy_m",
            "drift_theta_rad", "final_speed_m_s", "final_x_m", "final_y_m", "final_theta_rad", "max_dev_xy_m",
            "max_dev_theta_rad")) + f" | {r['us_per_step']:.1f} |")
    lines += ["", "Files: " + ", ".join(f"`{p.name}`" for p in files + [out / "report.md"]), ""]
    md_path = out / "report.md"
    md_path.write_text("\n".join(lines))
    files.append(md_path)
    return dict(rows=rows, files=files, ours=ours, pymunk=pm)


# ---------------------------------------------------------------------------------------------------------------
# CLI


def _cmd_compare(args):
    from planar_lcp.spec.scene import SceneError, load_scene
    from planar_lcp.sim import SimulationError

    prog = "planar-lcp compare"
    try:
        import pymunk  # noqa: F401
    except ImportError:
        print(f"{prog}: error: pymunk is not installed (pip install pymunk)", file=sys.stderr)
        return 2
    try:
        scene = load_scene(args.scene)
    except SceneError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    from planar_lcp.cli import SIMULATE_FLAGS, _InputError, prepare_output_dir
    from planar_lcp.spec.scene import sim_settings
    out = Path(args.out)
    try:
        sim_settings(scene, {"h": args.h, "t_end": args.t_end}, SIMULATE_FLAGS)  # before any work, named by flag
        prepare_output_dir(args.out, "--out")
    except (_InputError, SceneError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    parts = [f"planar-lcp compare {args.scene} --out {args.out}"]
    for opt, val in (("--h", args.h), ("--t-end", args.t_end), ("--iterations", args.iterations),
                     ("--collision-slop", args.collision_slop)):
        if val is not None:
            parts.append(f"{opt} {val}")
    if args.no_gif:
        parts.append("--no-gif")
    cmd = " ".join(parts)
    try:
        res = run_compare(scene, out, h=args.h, t_end=args.t_end, iterations=args.iterations,
                          collision_slop=args.collision_slop, gif=not args.no_gif, command=cmd)
    except SimulationError as e:
        print(f"{prog}: planar_lcp simulation failed: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"{prog}: error: cannot write {e.filename or ''}: {e.strerror or e}", file=sys.stderr)
        return 1
    except SceneError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except ValueError as e:
        print(f"{prog}: error: {scene.source}: {e}", file=sys.stderr)
        return 2
    for r in res["rows"]:
        print(f"{r['simulator']:<10s} {r['body']:<8s} first contact {_fmt(r['first_contact_t_s'])} s  "
              f"max pen {_fmt(r['max_penetration_m'])} m  drift {_fmt(r['drift_xy_m'])} m  "
              f"final ({r['final_x_m']:.4f}, {r['final_y_m']:.4f}, {r['final_theta_rad']:.4f})  "
              f"{r['us_per_step']:.1f} us/step")
    for p in res["files"]:
        print(f"wrote {p}")
    return 0


def register(subparsers):
    from planar_lcp.cli import finite_number, one_line_errors

    c = one_line_errors(subparsers.add_parser(
        "compare", help="run a scene in planar_lcp and in pymunk with the same time step; plots, GIF, report",
        description="Run a scene (a shipped name or a .toml path) in planar_lcp and in pymunk (Chipmunk2D) with the "
                    "same time step; write overlaid trajectories, frames, a side-by-side GIF and report.md/.csv."))
    c.add_argument("scene", metavar="SCENE", help="a shipped scene name or a path to a .toml scene file")
    c.add_argument("--out", required=True, metavar="DIR", help="directory for the files (created if missing)")
    c.add_argument("--h", type=finite_number(float, 0, True), metavar="H", help="time step [s] (default: the scene's)")
    c.add_argument("--t-end", type=finite_number(float, 0, True), metavar="T", help="duration [s] (default: the scene's)")
    c.add_argument("--iterations", type=finite_number(int, 1, False), metavar="N",
                   help="pymunk solver iterations per step (default 10, pymunk's)")
    c.add_argument("--collision-slop", type=finite_number(float, 0, False), metavar="M",
                   help="pymunk allowed overlap [m] (default 1e-4)")
    c.add_argument("--no-gif", action="store_true", help="skip the side-by-side GIF")
    c.set_defaults(func=_cmd_compare)
    return c
