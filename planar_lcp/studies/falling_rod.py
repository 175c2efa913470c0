"""Stewart & Trinkle's falling rod (their section 4.1, Figures 2-5), over their step sizes.

`planar-lcp study falling-rod --out DIR [--quick] [--restitution E]` writes strobe.png, vy.png, omega.png, vx.png,
seed_arm.png, events.csv/.md and convergence.csv/.md (see docs/falling-rod.md). --restitution E replaces the scene's
world.restitution (0: Stewart & Trinkle's inelastic contact) in every run; events.md and convergence.md then state E, and the
figures' titles too when E > 0.
"""

import math
import os

import numpy as np

from planar_lcp.studies import common
from planar_lcp.viz import new_figure

TITLE = "falling rod (seed 4.1)"
SCENE = "falling_rod"
STROBE_H = 0.0025          # Stewart & Trinkle's Figure 2
REST_TOL = 1e-6            # m/s and rad/s: "at rest"
T_END = 1.0
ZOOM = (0.36, 0.62)         # the velocity figures' zoom on impact, slap-down and rest (e = 0)


def restitution_note(e):
    """The line events.md and convergence.md state E with (only when --restitution was given)."""
    return f"Coefficient of restitution (`--restitution`): e = {e:g} in every run.\n\n"


def title_suffix(scene):
    """', e = E' for figure titles when the scene's world.restitution E > 0, else ''."""
    e = scene.world.restitution
    return f", e = {e:g}" if e > 0 else ""


def zoom_window(trajs):
    """ZOOM with e = 0; with e > 0 the bounces last longer: from ZOOM's start to 0.1 s after the run with the
    finest step rests (the end of the run if it does not)."""
    finest = min(trajs.values(), key=lambda tr: tr.options.h)
    if finest.scene.world.restitution == 0:
        return ZOOM
    t_rest = events(finest)["t_rest"]
    return ZOOM[0], min(T_END, t_rest + 0.1) if math.isfinite(t_rest) else T_END

EVENT_COLUMNS = ("h", "friction_arm", "t_impact", "t_tip_stops_right", "t_slap_down", "t_rest", "slide_left_s",
                 "contact_losses", "x_final", "theta_final")


def rod_geometry(scene):
    """(half length l/2 of the core, cap radius r) of the scene's rod (its first dynamic body, one capsule)."""
    body = next(b for b in scene.bodies if b.type == "dynamic")
    cap = body.shapes[0]
    if cap.type != "capsule":
        raise ValueError(f"{scene.source}: the rod study needs a capsule, got {cap.type}")
    return 0.5 * cap.length, cap.radius


def exact_impact_time(scene):
    """Free-flight time at which the lower cap first touches y = 0 (brentq on the exact parabola and rotation).

    The body frame is the rod's centre: y(t) = y0 + vy0 t - g t^2 / 2, theta(t) = theta0 + omega0 t, and the lowest
    point of the caps is y - (l/2) |sin theta| - r.
    """
    from scipy.optimize import brentq

    body = next(b for b in scene.bodies if b.type == "dynamic")
    half, r = rod_geometry(scene)
    g = -scene.world.gravity[1]
    y0, vy0, th0, w0 = body.position[1], body.velocity[1], body.angle, body.angular_velocity

    def gap(t):
        return y0 + vy0 * t - 0.5 * g * t * t - half * abs(math.sin(th0 + w0 * t)) - r

    ts = np.linspace(0.0, 5.0, 5001)
    i = int(np.argmax([gap(t) <= 0 for t in ts]))
    return brentq(gap, ts[i - 1], ts[i], xtol=1e-14)


def events(traj):
    """Stewart & Trinkle's events, read from the contact impulses and the velocities of one run.

    Every time is the END t[k+1] of the step k (from t[k] to t[k+1]) in which the event happens: the first time at
    which the state shows it.

    - t_impact: end of the first step with a contact normal impulse c_n > 0.
    - t_tip_stops_right: the "tip" is the end cap that made that first contact; its lowest point p = e - (0, r),
      e the cap centre, moves with u = vx - omega (p_y - y_c). The first time at or after t_impact with u <= 0.
    - t_slap_down: end of the first step with c_n > 0 at both ends (two active contacts more than l/2 apart).
    - t_rest: the first time after which every |v| component stays below 1e-6 (m/s, rad/s) to the end of the run.
    - slide_left_s = t_rest - t_slap_down; contact_losses: how often, between t_impact and t_rest, a step with an
      active contact is followed by one without (a bounce; 0 means no chattering).
    - x_final, theta_final: the rod's centre x (m) and angle (rad, in [0, 2 pi)) at the end.
    """
    half, r = rod_geometry(traj.scene)
    t, q, v = traj.t, traj.q[:, 0], traj.v[:, 0]
    nsteps = len(t) - 1
    active = [common.active_contacts(traj, k) for k in range(nsteps)]
    nan = math.nan
    ev = dict(h=traj.options.h, t_impact=nan, t_tip_stops_right=nan, t_slap_down=nan, t_rest=nan,
              slide_left_s=nan, contact_losses=0, x_final=float(q[-1, 0]),
              theta_final=float(q[-1, 2] % (2 * math.pi)))
    hit = [k for k in range(nsteps) if active[k]]
    if not hit:
        return ev
    k0 = hit[0]
    ev["t_impact"] = float(t[k0 + 1])
    ev["impact_step"] = k0
    # which end touched: the cap centre nearest to the first contact point
    p0 = active[k0][0]["point"]
    x, y, th = q[k0 + 1]
    ends = [np.array([x, y]) + s * half * np.array([math.cos(th), math.sin(th)]) for s in (1.0, -1.0)]
    s = (1.0, -1.0)[int(np.argmin([np.linalg.norm(e - p0) for e in ends]))]
    py_rel = s * half * np.sin(q[:, 2]) - r
    u = v[:, 0] - v[:, 2] * py_rel
    for j in range(k0 + 1, len(t)):
        if u[j] <= 0.0:
            ev["t_tip_stops_right"] = float(t[j])
            break
    for k in range(k0, nsteps):
        xs = [a["point"][0] for a in active[k]]
        if len(xs) >= 2 and max(xs) - min(xs) > half:
            ev["t_slap_down"] = float(t[k + 1])
            ev["slap_step"] = k
            break
    moving = np.abs(v.reshape(len(t), -1)).max(axis=1) >= REST_TOL
    if not moving[-1]:
        j = int(np.flatnonzero(moving)[-1]) + 1 if moving.any() else 0
        ev["t_rest"] = float(t[j])
        ev["slide_left_s"] = ev["t_rest"] - ev["t_slap_down"]
    k_end = nsteps if math.isnan(ev["t_rest"]) else int(round(ev["t_rest"] / traj.options.h))
    ev["contact_losses"] = int(sum(1 for k in range(k0, min(k_end, nsteps) - 1) if active[k] and not active[k + 1]))
    ev["tip_u"] = u
    return ev


# ---------------------------------------------------------------------------------------------------------- figures

def plot_strobe(traj, path, every=8):
    """Stewart & Trinkle's Figure 2: the rod every `every` steps until it rests (and at the end), time at the + end."""
    from planar_lcp.viz import draw_scene

    half, r = rod_geometry(traj.scene)
    ev = events(traj)
    t_stop = ev["t_rest"] if math.isfinite(ev["t_rest"]) else traj.t[-1]
    idx = [i for i in range(0, len(traj.t), every) if traj.t[i] <= t_stop + 1e-12]
    if idx[-1] != len(traj.t) - 1:
        idx.append(len(traj.t) - 1)
    fig = new_figure((7.5, 9.0))
    ax = fig.add_subplot(1, 1, 1)
    xs, ys = traj.q[idx, 0, 0], traj.q[idx, 0, 1]
    ax.set_xlim(float(xs.min()) - half - 0.12, float(xs.max()) + half + 0.12)
    ax.set_ylim(-0.05, float(ys.max()) + half + 0.1)
    ax.set_autoscale_on(False)
    for n, i in enumerate(idx):
        a = 0.25 + 0.75 * n / max(len(idx) - 1, 1)
        draw_scene(ax, traj.scene, traj.q[i], np.zeros((0, 3)), alpha=a)
        x, y, th = traj.q[i, 0]
        d = np.array([math.cos(th), math.sin(th)])
        tip = np.array([x, y]) + (half + r + 0.015) * d
        ax.text(tip[0], tip[1], f"{traj.t[i]:.2f}", fontsize=6, ha="center", va="center", color="0.15")
    ax.plot(traj.q[:, 0, 0], traj.q[:, 0, 1], color="tab:red", lw=0.6, ls="--", alpha=0.6)
    ax.set_title(f"Falling rod{title_suffix(traj.scene)}, h = {traj.options.h:g} s: every {every} steps "
                 f"({every * traj.options.h:g} s) until rest at t = {t_stop:.4f} s\n(simulated time in seconds at "
                 f"the end the rod's angle points to; dashed: path of the centre)", fontsize=9)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    common.save_png(fig, path)


def plot_velocity(trajs, comp, path, label, seed_fig):
    """One velocity component against time, a curve per h: full run and a zoom on the contact phase."""
    colors = common.h_colors(trajs)
    fig = new_figure((11, 4.2))
    axes = [fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)]
    for ax, (t0, t1) in zip(axes, ((0.0, T_END), zoom_window(trajs))):
        for h in sorted(trajs, reverse=True):
            tr = trajs[h]
            ax.plot(tr.t, tr.v[:, 0, comp], color=colors[h], lw=1.1, label=f"h = {h:g}")
        ax.set_xlim(t0, t1)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(label)
        ax.grid(True, color="0.9", lw=0.6)
    axes[0].legend(fontsize=8, loc="best")
    sfx = title_suffix(next(iter(trajs.values())).scene)
    axes[0].set_title(f"{label} of the rod{sfx} (cf. Stewart & Trinkle's {seed_fig})", fontsize=10)
    axes[1].set_title("zoom on impact, slap-down and rest", fontsize=10)
    fig.tight_layout()
    common.save_png(fig, path)


def plot_seed_arm(ours, seed, path):
    """vy, omega, vx at one h: friction at the contact point (ours) vs at the end-cap centre (Stewart & Trinkle's d)."""
    fig = new_figure((12, 3.8))
    for j, (comp, label) in enumerate(((1, "vy [m/s]"), (2, "omega [rad/s]"), (0, "vx [m/s]"))):
        ax = fig.add_subplot(1, 3, j + 1)
        ax.plot(ours.t, ours.v[:, 0, comp], color="tab:blue", lw=1.2, label="contact point (ours)")
        ax.plot(seed.t, seed.v[:, 0, comp], color="tab:orange", lw=1.2, ls="--", label="end-cap centre (Stewart & Trinkle's d)")
        ax.set_xlim(0.3, 0.7 if ours.scene.world.restitution == 0 else zoom_window({0: ours})[1])
        ax.set_xlabel("t [s]")
        ax.set_ylabel(label)
        ax.grid(True, color="0.9", lw=0.6)
        if j == 0:
            ax.legend(fontsize=8, loc="best")
    fig.suptitle(f"Friction moment arm{title_suffix(ours.scene)}, h = {ours.options.h:g} s", fontsize=10)
    fig.tight_layout()
    common.save_png(fig, path)


# ---------------------------------------------------------------------------------------------------------- study

def run(out, quick=False, restitution=None):
    """Run the study and write its files into `out`; returns a dict with the runs, events and convergence rows.
    restitution: Newton's coefficient in [0, 1] of the rod-table contact in every run (None: the scene's, 0)."""
    scene, hs, h_ref, trajs = common.start(out, SCENE, quick, T_END, desc="falling rod", restitution=restitution)
    note = "" if restitution is None else restitution_note(scene.world.restitution)
    seed_arm = common.run_steps(scene, [STROBE_H], desc="falling rod, seed arm", t_end=T_END,
                                seed_friction_arm=True)[STROBE_H]
    ref = trajs[h_ref]

    ev_rows = []
    for h in sorted(trajs, reverse=True):
        ev_rows.append(dict(events(trajs[h]), friction_arm="contact point"))
    ev_seed = dict(events(seed_arm), friction_arm="end-cap centre (seed)")
    ev_rows.append(ev_seed)
    common.write_csv(os.path.join(out, "events.csv"), EVENT_COLUMNS, ev_rows)
    t_exact = exact_impact_time(scene)
    spec = dict(h="g", t_impact=".4f", t_tip_stops_right=".4f", t_slap_down=".4f", t_rest=".4f",
                slide_left_s=".4f", x_final=".4f", theta_final=".6f")
    with open(os.path.join(out, "events.md"), "w") as f:
        f.write("# Falling rod: events per step size\n\n")
        f.write(note)
        f.write(EVENTS_NOTE.format(t_exact=t_exact))
        f.write(common.md_table(EVENT_COLUMNS, ev_rows,
                                ["h (s)", "friction arm", "impact", "tip stops sliding right", "slap-down", "rest",
                                 "slides left (s)", "contact losses", "final x (m)", "final theta (rad)"],
                                spec=spec))
        f.write("\n\n" + ("" if scene.world.restitution == 0 else "With e = 0: ")
                + "Stewart & Trinkle (h not stated for these times; their Figure 2 uses h = 0.0025): impact t = 0.383, "
                "the tip slides right, stops, slides left; slap-down t = 0.548; slides left for 0.02 s; then rest.\n")

    rows, phase_rows = common.write_convergence(out, scene, trajs, hs, h_ref, T_END, title="Falling rod",
                                                bodies="the rod", desc="falling rod, grid phases", note=note)

    strobe_h = STROBE_H if STROBE_H in trajs else min(trajs)
    plot_strobe(trajs[strobe_h], os.path.join(out, "strobe.png"))
    for comp, name, label, fig_name in ((1, "vy.png", "vy [m/s]", "Figure 3"),
                                        (2, "omega.png", "omega [rad/s]", "Figure 4"),
                                        (0, "vx.png", "vx [m/s]", "Figure 5")):
        plot_velocity(trajs, comp, os.path.join(out, name), label, fig_name)
    plot_seed_arm(trajs[STROBE_H], seed_arm, os.path.join(out, "seed_arm.png"))
    return dict(trajs=trajs, ref=ref, seed_arm=seed_arm, events=ev_rows, convergence=rows, phase=phase_rows,
                t_exact=t_exact, restitution=scene.world.restitution, files=sorted(os.listdir(out)))


EVENTS_NOTE = """\
Each time is the end t[k+1] of the step k (from t[k] to t[k+1]) in which the event happens; the step itself
started h earlier. Exact free-flight impact time (brentq on the parabola): {t_exact:.6f} s.

- impact: the first step with a normal impulse c_n > 0;
- tip stops sliding right: the first time at or after the impact at which the lowest point of the end cap that hit
  first has a horizontal velocity u = vx - omega (p_y - y) <= 0;
- slap-down: the first step with c_n > 0 at both ends (two active contacts more than l/2 apart);
- rest: the first time after which every velocity component stays below 1e-6 m/s (rad/s) to t = 1 s;
- slides left = rest - slap-down; contact losses = how often a step with an active contact is followed by one
  without, between impact and rest (bounces; 0 = no chattering).

"""


def print_summary(res):
    """The study's own summary lines (the runner adds the phase table and the files)."""
    for e in res["events"]:
        print(f"  h = {e['h']:<8g} {e['friction_arm']:<22s} impact {e['t_impact']:.4f}  slap-down "
              f"{e['t_slap_down']:.4f}  rest {e['t_rest']:.4f}  x_final {e['x_final']:.4f}")
    for r in res["convergence"]:
        if math.isfinite(r["vel_err"]):
            print(f"  h = {r['h']:<8g} vel. error {r['vel_err']:.4f}  pos. error {r['pos_err']:.4f}  "
                  f"order {common.fmt(r['order_vel'], '.2f')}")

