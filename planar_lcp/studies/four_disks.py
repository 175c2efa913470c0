"""Stewart & Trinkle's colliding balls (their section 4.2, Figures 6-8, Table 1), in a vertical plane (elevation view).

`planar-lcp study four-disks --out DIR [--quick]` writes trajectories.png, impulses.png, velocity.png,
events.csv/.md, cascade.csv/.md and convergence.csv/.md (see docs/four-disks.md).
"""

import math
import os

import numpy as np

from planar_lcp.studies import common
from planar_lcp.viz import new_figure

TITLE = "four disks (seed 4.2, elevation)"
SCENE = "four_disks"
FIGURE_H = 0.0025
T_END = 1.0

EVENT_COLUMNS = ("h", "t_ground", "t_first_disk_contact", "cascade_step", "active_contacts", "active_disk_disk",
                 "active_table")
CASCADE_COLUMNS = ("h", "step", "t_start", "t_end", "body_a", "body_b", "cn", "ft", "mode", "point_x", "point_y",
                   "normal_x", "normal_y")


def _is_table(pair):
    return "table" in pair


def cascade_step(traj):
    """Index k of the first step (from t[k] to t[k+1]) with a normal impulse > 0 between two disks, or None."""
    for k in range(len(traj.t) - 1):
        if any(not _is_table(a["pair"]) for a in common.active_contacts(traj, k)):
            return k
    return None


def events(traj):
    """t_ground: end of the first step with c_n > 0 between the thrown disk and the table; t_first_disk_contact: end
    of the first step with c_n > 0 between two disks (the cascade step); the counts of active contacts (c_n > 0)
    in that step."""
    t = traj.t
    ev = dict(h=traj.options.h, t_ground=math.nan, t_first_disk_contact=math.nan, cascade_step=-1,
              active_contacts=0, active_disk_disk=0, active_table=0)
    for k in range(len(t) - 1):
        if any(a["pair"] == ("thrown", "table") for a in common.active_contacts(traj, k)):
            ev["t_ground"] = float(t[k + 1])
            break
    k = cascade_step(traj)
    if k is not None:
        act = common.active_contacts(traj, k)
        ev.update(t_first_disk_contact=float(t[k + 1]), cascade_step=k, active_contacts=len(act),
                  active_disk_disk=sum(not _is_table(a["pair"]) for a in act),
                  active_table=sum(_is_table(a["pair"]) for a in act))
    return ev


def cascade_rows(traj):
    """Every contact recorded in the cascade step (zero impulses included), as rows of CASCADE_COLUMNS."""
    k = cascade_step(traj)
    if k is None:
        return []
    rows = []
    for a in common.all_contacts(traj, k):
        rows.append(dict(h=traj.options.h, step=k, t_start=float(traj.t[k]), t_end=float(traj.t[k + 1]),
                         body_a=a["pair"][0], body_b=a["pair"][1], cn=a["cn"], ft=a["ft"], mode=a["mode"],
                         point_x=float(a["point"][0]), point_y=float(a["point"][1]),
                         normal_x=float(a["normal"][0]), normal_y=float(a["normal"][1])))
    return rows


def analytic_times(scene):
    """2D rigid-body estimates: landing (free fall of the centre to y = r), the inelastic frictional landing impulse
    leaving the disk rolling at v0 / (1 + J / (m r^2)) (if mu allows), and the time the centres are 2 r apart."""
    thrown, d1 = scene.bodies[0], scene.bodies[1]
    r = thrown.shapes[0].radius
    g = -scene.world.gravity[1]
    t_land = math.sqrt(2 * (thrown.position[1] - r) / g)
    k = thrown.inertia / (thrown.mass * r * r)
    v_roll = thrown.velocity[0] / (1 + k)
    x_land = thrown.position[0] + thrown.velocity[0] * t_land
    t_hit = t_land + (d1.position[0] - 2 * r - x_land) / v_roll
    return t_land, t_hit, v_roll


# ---------------------------------------------------------------------------------------------------------- figures

def plot_trajectories(traj, path):
    """Elevation view (Stewart & Trinkle's Figure 7): the centres' paths and the disks at a few times."""
    from planar_lcp.viz import draw_scene

    ev = events(traj)
    times = [0.0, 0.2, ev["t_ground"], ev["t_first_disk_contact"], traj.t[-1]]
    fig = new_figure((11, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    ax.set_xlim(-0.15, float(traj.q[:, :, 0].max()) + 0.2)
    ax.set_ylim(-0.05, 1.15)
    ax.set_autoscale_on(False)
    for n, tt in enumerate(times):
        if not math.isfinite(tt):
            continue
        i = int(round(tt / traj.options.h))
        draw_scene(ax, traj.scene, traj.q[i], np.zeros((0, 3)), alpha=0.2 + 0.8 * n / (len(times) - 1))
        ax.text(traj.q[i, 0, 0], traj.q[i, 0, 1] + 0.13, f"{traj.t[i]:.3f}", fontsize=7, ha="center")
    for j, name in enumerate(traj.body_names):
        ax.plot(traj.q[:, j, 0], traj.q[:, j, 1], lw=1.0, ls="--", label=f"{name} (centre)")
    ax.legend(fontsize=8, loc="upper right")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"Four disks, elevation view, h = {traj.options.h:g} s (thrown disk drawn at the times printed "
                 f"above it; final poses darkest)", fontsize=10)
    common.save_png(fig, path)


def plot_impulses(traj, path):
    """Stewart & Trinkle's Figure 6: every contact impulse of the cascade step, normal and friction parts as arrows.

    Arrows start at the contact point, just inside the body they act on: cn n (red) and ft t (blue) on body A, their
    negatives on body B (none on the static table). Poses are those at the start of the step.
    """
    from planar_lcp.viz import draw_scene

    k = cascade_step(traj)
    act = common.all_contacts(traj, k)
    fig = new_figure((12, 5.2))
    ax = fig.add_subplot(1, 1, 1)
    ax.set_xlim(0.62, 1.58)
    ax.set_ylim(-0.09, 0.3)
    ax.set_autoscale_on(False)
    draw_scene(ax, traj.scene, traj.q[k], np.zeros((0, 3)), alpha=0.35)
    big = max([max(abs(a["cn"]), abs(a["ft"])) for a in act] + [1e-12])
    scale = 0.07 / big            # m per N s

    def arrow(p, d, color):
        if np.linalg.norm(d) * scale < 1e-4:
            return
        ax.annotate("", xy=p + d * scale, xytext=p,
                    arrowprops=dict(arrowstyle="-|>", color=color, lw=1.6, mutation_scale=10))

    centres = {n: traj.q[k, j, :2] for j, n in enumerate(traj.body_names)}
    for a in act:
        p = a["point"]
        for sign, body in ((1.0, a["pair"][0]), (-1.0, a["pair"][1])):
            if body not in centres:
                continue
            # draw each body's arrows slightly inside that body, so the two sides of a contact do not overlap
            off = 0.006 * (centres[body] - p) / max(np.linalg.norm(centres[body] - p), 1e-12)
            arrow(p + off, sign * a["cn"] * a["normal"], "tab:red")
            arrow(p + off, sign * a["ft"] * a["tangent"], "tab:blue")
        label = f"{a['pair'][0]}-{a['pair'][1]}\ncn {a['cn']:.4f}\nft {a['ft']:+.4f}"
        dy = -0.075 if _is_table(a["pair"]) else 0.13
        ax.text(p[0], p[1] + dy, label, fontsize=7, ha="center", va="center", color="0.1")
    ax.plot([], [], color="tab:red", label="normal impulse c_n n")
    ax.plot([], [], color="tab:blue", label="friction impulse f_t t")
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(f"Impulses in the step of the first disk-disk contact, t = {traj.t[k]:.4f} to {traj.t[k + 1]:.4f} s "
                 f"(h = {traj.options.h:g} s); arrows: {0.07:g} m = {big:.3g} N s; poses at the start of the step",
                 fontsize=9)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    common.save_png(fig, path)


def plot_velocity(trajs, path):
    """vx, vy, omega of each disk against time at the figure's h, with the other step sizes' thrown disk dashed."""
    h0 = FIGURE_H if FIGURE_H in trajs else min(trajs)
    tr = trajs[h0]
    fig = new_figure((12, 7.5))
    labels = ("vx [m/s]", "vy [m/s]", "omega [rad/s]")
    colors = common.h_colors(trajs)
    for c in range(3):
        ax = fig.add_subplot(3, 1, c + 1)
        for h in sorted(trajs, reverse=True):
            if h != h0:
                ax.plot(trajs[h].t, trajs[h].v[:, 0, c], color=colors[h], lw=0.8, ls=":",
                        label=f"thrown, h = {h:g}" if c == 0 else None)
        for j, name in enumerate(tr.body_names):
            ax.plot(tr.t, tr.v[:, j, c], lw=1.2, label=f"{name}, h = {h0:g}" if c == 0 else None)
        ax.set_ylabel(labels[c])
        ax.grid(True, color="0.9", lw=0.6)
        ax.set_xlim(0, tr.t[-1])
        if c == 0:
            ax.legend(fontsize=7, ncol=3, loc="upper right")
    ax.set_xlabel("t [s]")
    fig.suptitle("Four disks: velocities of the centres", fontsize=10)
    fig.tight_layout()
    common.save_png(fig, path)


# ---------------------------------------------------------------------------------------------------------- study

def run(out, quick=False):
    """Run the study and write its files into `out`; returns the runs, events, cascade and convergence rows."""
    scene, hs, h_ref, trajs = common.start(out, SCENE, quick, T_END, desc="four disks")
    ref = trajs[h_ref]
    t_land, t_hit, v_roll = analytic_times(scene)

    ev_rows = [events(trajs[h]) for h in sorted(trajs, reverse=True)]
    common.write_csv(os.path.join(out, "events.csv"), EVENT_COLUMNS, ev_rows)
    with open(os.path.join(out, "events.md"), "w") as f:
        f.write("# Four disks: events per step size\n\n")
        f.write(EVENTS_NOTE.format(t_land=t_land, t_hit=t_hit, v_roll=v_roll))
        f.write(common.md_table(EVENT_COLUMNS, ev_rows,
                                ["h (s)", "ground hit", "first disk-disk contact", "that step k",
                                 "active contacts", "disk-disk", "table"],
                                spec=dict(h="g", t_ground=".4f", t_first_disk_contact=".4f")))
        f.write("\n")

    casc = [r for h in sorted(trajs, reverse=True) for r in cascade_rows(trajs[h])]
    common.write_csv(os.path.join(out, "cascade.csv"), CASCADE_COLUMNS, casc)
    with open(os.path.join(out, "cascade.md"), "w") as f:
        f.write("# Four disks: every contact in the step of the first disk-disk contact\n\n")
        f.write("cn: normal impulse (N s) along n (from body B to body A), ft: friction impulse (N s) along "
                "t = (-n_y, n_x), both acting on body A (body B gets the negative); mode 0 separated, 1 sticking, "
                "2 sliding; a contact with cn = 0 is in the LCP but inactive.\n\n")
        f.write(common.md_table(("h", "step", "t_start", "t_end", "body_a", "body_b", "cn", "ft", "mode"), casc,
                                ["h (s)", "step", "from t", "to t", "body A", "body B", "cn (N s)", "ft (N s)",
                                 "mode"], spec=dict(h="g", t_start=".5f", t_end=".5f", cn=".5f", ft="+.5f")))
        f.write("\n")

    rows, phase_rows = common.write_convergence(out, scene, trajs, hs, h_ref, T_END, title="Four disks",
                                                bodies="the four disks (n = 12)", desc="four disks, grid phases")

    fig_h = FIGURE_H if FIGURE_H in trajs else min(trajs)
    plot_trajectories(trajs[fig_h], os.path.join(out, "trajectories.png"))
    plot_impulses(trajs[fig_h], os.path.join(out, "impulses.png"))
    plot_velocity(trajs, os.path.join(out, "velocity.png"))
    return dict(trajs=trajs, ref=ref, events=ev_rows, cascade=casc, convergence=rows, phase=phase_rows,
                analytic=dict(t_land=t_land, t_hit=t_hit, v_roll=v_roll), files=sorted(os.listdir(out)))


EVENTS_NOTE = """\
Each time is the end t[k+1] of the step k in which the event happens. ground hit: the first step with c_n > 0
between the thrown disk and the table; first disk-disk contact: the first step k with c_n > 0 between two disks;
active = c_n > 0 in that step. 2D rigid-body estimates: landing at {t_land:.4f} s, after which the inelastic
frictional landing leaves the disk rolling at {v_roll:.4f} m/s, reaching d1 at {t_hit:.4f} s.

"""


def print_summary(res):
    """The study's own summary lines (the runner adds the phase table and the files)."""
    a = res["analytic"]
    print(f"  analytic (2D rigid): landing {a['t_land']:.4f} s, first disk contact {a['t_hit']:.4f} s")
    for e in res["events"]:
        print(f"  h = {e['h']:<8g} ground {e['t_ground']:.4f}  first disk contact {e['t_first_disk_contact']:.4f}  "
              f"active: {e['active_disk_disk']} disk-disk + {e['active_table']} table")

