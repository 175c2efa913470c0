"""Shared pieces of the studies: runs over step sizes, Stewart & Trinkle's Table 1 measures, tables and figures.

Nothing here imports matplotlib at module level (``import planar_lcp.cli`` must stay light).
"""

import csv
import math
import os
import sys

import numpy as np

from planar_lcp.studies.accuracy import table1_errors

#: Stewart & Trinkle's step sizes (their Table 1); the finest is the reference solution.
SEED_STEPS = (0.02, 0.01, 0.005, 0.0025, 0.00125)
#: `--quick`: two step sizes, each compared against a reference run at half the finer one.
QUICK_STEPS = (0.0025, 0.00125)
QUICK_REFERENCE = 0.000625


def step_sizes(quick):
    """(step sizes with an error, reference step size) of a study."""
    if quick:
        return QUICK_STEPS, QUICK_REFERENCE
    return SEED_STEPS[:-1], SEED_STEPS[-1]


def active_contacts(traj, k, min_cn=0.0):
    """The contacts of step k (from t[k] to t[k+1]) with a normal impulse > min_cn.

    Returns
    -------
    list of dict: pair (body A, body B), cn, ft (N s), normal n (2,), tangent t (2,), point (2,) m, phi (m), vt (m/s),
    mode (0 separated, 1 sticking, 2 sliding). The impulse on body A is cn n + ft t, on body B its negative.
    """
    c = traj.contacts
    nrm, pnt = c["normal"], c["point"]
    out = []
    for i in range(int(c["count"][k])):
        cn = float(c["cn"][k, i])
        if cn <= min_cn:
            continue
        n = np.array(nrm[k, i], dtype=float)
        out.append(dict(pair=tuple(c["shape_pairs"][int(c["pair"][k, i])]), cn=cn, ft=float(c["ft"][k, i]),
                        normal=n, tangent=np.array([-n[1], n[0]]), point=np.array(pnt[k, i], dtype=float),
                        phi=float(c["phi"][k, i]), vt=float(c["vt"][k, i]), mode=int(c["mode"][k, i])))
    return out


def all_contacts(traj, k):
    """Every recorded contact of step k, including those with zero impulse (see active_contacts)."""
    return active_contacts(traj, k, min_cn=-np.inf)


def start(out, scene_name, quick, t_end, *, desc, restitution=None):
    """A study's first part: create `out`, load the scene and run it to t_end over the study's step sizes and the
    reference. `restitution` (in [0, 1]), when given, replaces the scene's world.restitution (`--restitution`), so
    every run made from the returned scene uses it. Returns (scene, step sizes with an error, reference step size,
    {h: Trajectory})."""
    from planar_lcp.spec.scene import load_scene, restitution_setting

    scene = restitution_setting(load_scene(scene_name), restitution, "--restitution")
    ensure_dir(out)
    hs, h_ref = step_sizes(quick)
    return scene, hs, h_ref, run_steps(scene, list(hs) + [h_ref], desc=desc, t_end=t_end)


def run_steps(scene, hs, *, desc, **kwargs):
    """simulate(scene, h=h) for each h with a tqdm progress bar on stderr; {h: Trajectory}."""
    from tqdm import tqdm

    from planar_lcp.sim import simulate

    out = {}
    for h in tqdm(list(hs), desc=desc, unit="run", leave=False):
        out[h] = simulate(scene, h=h, on_failure="record", **kwargs)
        for i, t, cause in out[h].failures:
            print(f"warning: h = {h}: step {i} (t = {t:.6g} s): {cause}", file=sys.stderr)
    return out


def convergence(trajs, ref, t_end):
    """Stewart & Trinkle's Table 1 measures for each trajectory against the reference `ref`.

    All norms are the infinity norm over every coordinate of every dynamic body (n = 3 nbody), as in Stewart & Trinkle.
    The comparison is at the common times t_i = i h, i = 0..round(t_end / h), of the coarser step h.

    - vel_err = integral over [0, t_end] of ||v_h(t) - v_ref(t)|| dt, pos_err = max_i ||q_h(t_i) - q_ref(t_i)||
      (`accuracy.table1_errors`)
    - vel_var = total variation of v_h on its own grid, sum_k ||v_h(t_k+1) - v_h(t_k)||
    - order_vel, order_pos = log2(err(2h) / err(h)) against the previous (twice coarser) row, NaN on the first row

    Parameters
    ----------
    trajs : dict {h: Trajectory}, h in s
    ref : Trajectory (its step divides every h)
    t_end : float, s

    Returns
    -------
    list of dict with keys h, vel_err, pos_err, vel_var, order_vel, order_pos, sorted from coarse to fine, then the
    reference's own row (errors NaN).
    """
    h_ref = ref.options.h
    rows = []
    for h in sorted(trajs, reverse=True):
        vel_err, pos_err = table1_errors(trajs[h], ref, t_end)
        rows.append(dict(h=h, vel_err=vel_err, pos_err=pos_err, vel_var=_variation(trajs[h], t_end)))
    rows.append(dict(h=h_ref, vel_err=math.nan, pos_err=math.nan, vel_var=_variation(ref, t_end)))
    for i, row in enumerate(rows):
        for key in ("vel", "pos"):
            prev = rows[i - 1] if i else None
            ok = (prev is not None and abs(prev["h"] - 2 * row["h"]) < 1e-12 and prev[f"{key}_err"] > 0
                  and row[f"{key}_err"] > 0)
            row[f"order_{key}"] = math.log2(prev[f"{key}_err"] / row[f"{key}_err"]) if ok else math.nan
    return rows


def _variation(tr, t_end):
    n = int(round(t_end / tr.options.h))
    v = tr.v[:n + 1].reshape(n + 1, -1)
    return float(np.abs(np.diff(v, axis=0)).max(axis=1).sum())


CONVERGENCE_COLUMNS = ("h", "vel_err", "pos_err", "vel_var", "order_vel", "order_pos")


def fmt(x, spec=".4g"):
    """A number for a table: '' for NaN/None."""
    if x is None:
        return ""
    if isinstance(x, (float, np.floating)) and not math.isfinite(x):
        return ""
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        return format(float(x), spec)
    return str(x)


def write_csv(path, columns, rows):
    """Rows (dicts) as CSV with the given header; floats at full precision, NaN as empty."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for r in rows:
            w.writerow(["" if (isinstance(r[c], float) and not math.isfinite(r[c])) else
                        (repr(float(r[c])) if isinstance(r[c], (float, np.floating)) else r[c]) for c in columns])


def md_table(columns, rows, headers=None, spec=None):
    """A Markdown table; `spec` maps a column to a format spec."""
    spec = spec or {}
    headers = headers or columns
    lines = ["| " + " | ".join(headers) + " |",
             "|" + "|".join("---:" for _ in headers) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(fmt(r[c], spec.get(c, ".4g")) for c in columns) + " |")
    return "\n".join(lines)


def convergence_md(rows, title, note=""):
    head = ["h (s)", "vel. error", "pos. error", "vel. variation", "order (vel.)", "order (pos.)"]
    text = f"# {title}\n\n"
    if note:
        text += note.strip() + "\n\n"
    return text + md_table(CONVERGENCE_COLUMNS, rows, head,
                           spec=dict(h="g", vel_err=".4f", pos_err=".4f", vel_var=".4f", order_vel=".2f",
                                     order_pos=".2f")) + "\n"


CONVERGENCE_NOTE = """
vel. error = integral over [0, {t_end:g}] s of ||v_h(t) - v_ref(t)||_inf dt (v_h(t) = v_h(t_k+1) over each step
(t_k, t_k+1], as the time stepping's velocity; v_ref sampled at the same t_k+1);
pos. error = max over t = multiples of h of ||q_h(t) - q_ref(t)||_inf; vel. variation = sum over the steps of
||v_h(t_k+1) - v_h(t_k)||_inf; order = log2(err(2h) / err(h)). Reference: h = {h_ref:g} s (its row has no error).
q = (x, y, theta) and v = (vx, vy, omega) of {bodies}, in m, rad, m/s, rad/s.
"""


def save_png(fig, path, limit=300_000):
    """Save a PNG below `limit` bytes, lowering the resolution if needed."""
    dpi = fig.dpi
    for _ in range(6):
        fig.savefig(path, format="png", dpi=dpi)
        if os.path.getsize(path) < limit:
            return path
        dpi *= 0.8
    return path


def h_colors(hs):
    """A colour per step size, coarse = light, fine = dark."""
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    hs = sorted(hs, reverse=True)
    n = max(len(hs) - 1, 1)
    return {h: cmap(0.85 * (1 - i / n)) for i, h in enumerate(hs)}


def ensure_dir(path):
    os.makedirs(path, exist_ok=True)
    return path


# ------------------------------------------------------------------------------------ grid-phase averaged errors

PHASES = 16
PHASE_COLUMNS = ("h", "phases", "vel_err_mean", "vel_err_max", "pos_err_mean", "pos_err_max", "order_vel",
                 "order_pos", "failed_steps")


def shift_scene(scene, tau):
    """The same physical problem started at t = tau instead of 0: every dynamic body that moves at t = 0 is advanced
    along its exact free-flight solution (x + vx tau, y + vy tau + g tau^2 / 2, theta + omega tau); bodies at rest stay
    (in the shipped scenes they rest on a support). Valid only while no moving body has touched anything."""
    import dataclasses

    gx, gy = scene.world.gravity
    bodies = []
    for b in scene.bodies:
        if b.type == "dynamic" and (any(b.velocity) or b.angular_velocity):
            (x, y), (vx, vy) = b.position, b.velocity
            b = dataclasses.replace(
                b, position=(x + vx * tau + 0.5 * gx * tau * tau, y + vy * tau + 0.5 * gy * tau * tau),
                velocity=(vx + gx * tau, vy + gy * tau), angle=b.angle + b.angular_velocity * tau)
        bodies.append(b)
    return dataclasses.replace(scene, bodies=tuple(bodies))


def phase_averaged(scene, hs, t_end, *, phases=PHASES, refine=8, seed=0, desc="phases"):
    """Table 1's errors averaged over the phase of the time grid relative to the impacts.

    One run's error at step h depends on where the impacts fall between grid points (an O(h) error with a
    phase-dependent constant), so log2(err(2h)/err(h)) of a single run scatters. Here the start is shifted by
    `phases` times tau_j drawn uniformly in [0, max(hs)) (numpy seed `seed`), each along the exact free flight
    (shift_scene); each shifted problem is solved at every h and at h_ref = min(hs)/refine, and the errors of
    `convergence` are averaged over the phases. Runs record failed steps (a Lemke failure: that island is solved by
    PGS) instead of stopping; failed_steps counts them (in the run at h and its reference).

    Returns
    -------
    list of dict with PHASE_COLUMNS (coarse to fine), h_ref
    """
    from tqdm import tqdm

    from planar_lcp.sim import simulate

    hs = sorted(hs, reverse=True)
    h_ref = min(hs) / refine
    taus = np.random.default_rng(seed).uniform(0.0, max(hs), phases)
    errs = {h: [] for h in hs}
    for tau in tqdm(taus, desc=desc, unit="phase", leave=False):
        sc = shift_scene(scene, float(tau))
        ref = simulate(sc, h=h_ref, t_end=t_end, on_failure="record")
        runs = {h: simulate(sc, h=h, t_end=t_end, on_failure="record") for h in hs}
        rows = convergence(runs, ref, t_end)
        for r in rows[:-1]:
            errs[r["h"]].append((r["vel_err"], r["pos_err"], len(runs[r["h"]].failures) + len(ref.failures)))
    out = []
    for h in hs:
        e = np.array(errs[h])
        out.append(dict(h=h, phases=int(phases), vel_err_mean=float(e[:, 0].mean()), vel_err_max=float(e[:, 0].max()),
                        pos_err_mean=float(e[:, 1].mean()), pos_err_max=float(e[:, 1].max()),
                        failed_steps=int(e[:, 2].sum())))
    for i, row in enumerate(out):
        for key in ("vel", "pos"):
            row[f"order_{key}"] = (math.log2(out[i - 1][f"{key}_err_mean"] / row[f"{key}_err_mean"]) if i else math.nan)
    return out, h_ref


def phase_md(rows, h_ref, t_end):
    head = ["h (s)", "phases", "vel. error (mean)", "vel. error (max)", "pos. error (mean)", "pos. error (max)",
            "order (vel.)", "order (pos.)", "failed steps"]
    text = (f"Averaged over the grid phase: {rows[0]['phases']} starts shifted by tau uniform in [0, {rows[0]['h']:g}) "
            f"s along the exact free flight, each against its own reference at h = {h_ref:g} s, over "
            f"[tau, tau + {t_end:g}] s; order = log2 of the ratio of the means.\n\n")
    return text + md_table(PHASE_COLUMNS, rows, head,
                           spec=dict(h="g", vel_err_mean=".4f", vel_err_max=".4f", pos_err_mean=".4f",
                                     pos_err_max=".4f", order_vel=".2f", order_pos=".2f")) + "\n"


def write_convergence(out, scene, trajs, hs, h_ref, t_end, *, title, bodies, desc, note=""):
    """convergence.csv, convergence_phase.csv and convergence.md (both tables) of a study in `out`: the Table 1
    measures of the runs trajs[h], h in hs, against trajs[h_ref], and their grid-phase averages; `note`, if any,
    right under convergence.md's title. Returns (rows, phase rows)."""
    rows = convergence({h: trajs[h] for h in hs}, trajs[h_ref], t_end)
    write_csv(os.path.join(out, "convergence.csv"), CONVERGENCE_COLUMNS, rows)
    phase_rows, phase_ref = phase_averaged(scene, hs, t_end, desc=desc)
    write_csv(os.path.join(out, "convergence_phase.csv"), PHASE_COLUMNS, phase_rows)
    with open(os.path.join(out, "convergence.md"), "w") as f:
        f.write(convergence_md(rows, f"{title}: errors and variations (analogue of Stewart & Trinkle's Table 1)",
                               note + CONVERGENCE_NOTE.format(t_end=t_end, h_ref=h_ref, bodies=bodies)))
        f.write("\n## The same errors averaged over the phase of the time grid\n\n")
        f.write(phase_md(phase_rows, phase_ref, t_end))
    return rows, phase_rows


def print_phase_table_and_files(res, out):
    """The summary lines both studies end with: the phase-averaged convergence rows and the files written."""
    for r in res["phase"]:
        print(f"  h = {r['h']:<8g} phase-averaged vel. error {r['vel_err_mean']:.4f}  pos. error "
              f"{r['pos_err_mean']:.4f}  order {fmt(r['order_vel'], '.2f')}")
    print(f"wrote {len(res['files'])} files in {out}: {', '.join(res['files'])}")
