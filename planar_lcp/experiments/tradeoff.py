"""`planar-lcp tradeoff`: measure the speed/accuracy trade of the knobs users turn.

For each scene, every setting (step size h, solver and its iteration count, formulation, and in the horizontal plane
the number of support-friction directions) is run and compared with a reference solution: the finest run of Lemke
with the fixed-point formulation (h_ref = the smallest swept h / 2, 16 friction directions in the horizontal plane).
Per setting: the velocity error integral over [0, t_end] of ||v_h - v_ref|| dt and the sup-norm position error (the
seed paper's Table 1 measures, `accuracy.table1_errors`), the deepest penetration, the energy drift (largest rise of
the energy above its starting value, J; 0 when the energy only decreases, as it must without external work), and
the CPU cost per simulated second (wall time of a warm run / t_end).
"""

import csv
import itertools
import math
import time
from pathlib import Path

from planar_lcp.experiments.accuracy import table1_errors
from planar_lcp.spec.scene import FORMULATIONS, SOLVERS

DEFAULT_SCENES = ("falling_rod", "four_disks", "box_push")
SOLVER_SETTINGS = (("lemke", None), ("pgs", 5), ("pgs", 20), ("pgs", 100), ("osqp", None))
FRICTION_DIRECTIONS = (4, 8, 16, 32)
H_FACTORS = (4.0, 2.0, 1.0, 0.5, 0.25)

COLUMNS = ["scene", "h", "solver", "pgs_iterations", "formulation", "friction_directions", "velocity_error",
           "position_error", "max_penetration", "energy_drift", "cpu_s_per_sim_s", "failed_steps", "reference"]


def _settings(scene, quick):
    from planar_lcp.spec.scene import load_scene
    sc = load_scene(scene)
    h0 = sc.sim.h
    horizontal = sc.world.plane == "horizontal"
    if quick:
        hs = (2.0 * h0, h0)
        solvers = (("lemke", None), ("pgs", 20))
        forms = ("position",)
        ks = (8,) if horizontal else (None,)
    else:
        hs = tuple(h0 * f for f in H_FACTORS)
        solvers, forms = SOLVER_SETTINGS, FORMULATIONS
        ks = FRICTION_DIRECTIONS if horizontal else (None,)
    out = []
    for h, (solver, iters), form in itertools.product(hs, solvers, forms):
        out.append(dict(h=h, solver=solver, pgs_iterations=iters, formulation=form,
                        friction_directions=8 if horizontal else None))
    if horizontal:
        # the friction polygon: swept with the default solver and formulation at every h
        for h, k in itertools.product(hs, ks):
            if k != 8:
                out.append(dict(h=h, solver="lemke", pgs_iterations=None, formulation="position",
                                friction_directions=k))
    h_ref = min(hs) / 2.0
    ref = dict(h=h_ref, solver="lemke", pgs_iterations=None, formulation="fixed_point",
               friction_directions=16 if horizontal else None)
    return sc, out, ref


def _run(sc, s, t_end):
    from planar_lcp.sim import simulate
    kw = dict(h=s["h"], t_end=t_end, solver=s["solver"], formulation=s["formulation"], on_failure="record",
              record_contacts=False)
    if s["pgs_iterations"]:
        kw["pgs_iterations"] = s["pgs_iterations"]
    if s["friction_directions"]:
        kw["friction_directions"] = s["friction_directions"]
    simulate(sc, **dict(kw, t_end=min(t_end, 5 * s["h"])))  # warm the JIT for this setting
    t0 = time.perf_counter()
    tr = simulate(sc, **kw)
    return tr, time.perf_counter() - t0


def run_tradeoff(scenes=DEFAULT_SCENES, quick=False, out_dir="tradeoff", progress=True):
    """Run the sweep; write tradeoff.csv and one Pareto plot per scene into out_dir. Returns the rows."""
    from tqdm import tqdm
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plans = [(name, *_settings(name, quick)) for name in scenes]
    total = sum(len(s) + 1 for _, _, s, _ in plans)
    rows = []
    with tqdm(total=total, disable=not progress, desc="tradeoff", unit="run") as bar:
        for name, sc, settings, ref_setting in plans:
            t_end = sc.sim.t_end
            ref, _ = _run(sc, ref_setting, t_end)
            bar.update(1)
            ref_label = (f"lemke/fixed_point h={ref_setting['h']:g}"
                         + (f" k={ref_setting['friction_directions']}" if ref_setting["friction_directions"] else ""))
            for s in settings:
                bar.set_postfix_str(f"{name} {s['solver']} {s['formulation']} h={s['h']:g}")
                tr, wall = _run(sc, s, t_end)
                verr, qerr = table1_errors(tr, ref, t_end)
                e = tr.stats["energy"]
                rows.append(dict(scene=name, h=s["h"], solver=s["solver"], pgs_iterations=s["pgs_iterations"] or "",
                                 formulation=s["formulation"], friction_directions=s["friction_directions"] or "",
                                 velocity_error=verr, position_error=qerr,
                                 max_penetration=float(tr.stats["penetration"].max()),
                                 energy_drift=float(max(0.0, (e - e[0]).max())), cpu_s_per_sim_s=wall / t_end,
                                 failed_steps=len(tr.failures), reference=ref_label))
                bar.update(1)
    with open(out / "tradeoff.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(rows)
    for name in scenes:
        plot_pareto([r for r in rows if r["scene"] == name], out / f"pareto_{name}.png", name)
    return rows


def pareto_front(points):
    """Indices of the non-dominated (cost, error) points, sorted by cost: no other point is cheaper AND better."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def _label(r):
    s = r["solver"] + (f"({r['pgs_iterations']})" if r["pgs_iterations"] else "")
    k = f" k={r['friction_directions']}" if r["friction_directions"] not in ("", 8) else ""
    return f"{s} {r['formulation']} h={r['h']:g}{k}"


def plot_pareto(rows, path, title):
    from matplotlib.lines import Line2D

    from planar_lcp.viz import new_figure
    fig = new_figure((9, 6))
    ax = fig.add_subplot(1, 1, 1)
    markers = dict(zip(SOLVERS, ("o", "s", "^")))
    colors = dict(zip(FORMULATIONS, ("C0", "C1", "C2")))
    floor = 1e-12
    pts = [(r["cpu_s_per_sim_s"], max(r["velocity_error"], floor)) for r in rows]
    for r, (c, e) in zip(rows, pts):
        ax.scatter(c, e, marker=markers[r["solver"]], color=colors[r["formulation"]], alpha=0.6, s=30)
    front = pareto_front(pts)
    ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "k-", lw=1)
    for i in front:
        ax.annotate(_label(rows[i]), pts[i], fontsize=7, xytext=(4, 2), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("CPU seconds per simulated second")
    ax.set_ylabel("velocity error  integral ||v_h - v_ref|| dt")
    ax.set_title(f"{title}: speed/accuracy (marker = solver, colour = formulation; line = Pareto front)")
    handles = [Line2D([], [], marker=m, ls="", color="gray", label=k) for k, m in markers.items()]
    handles += [Line2D([], [], marker="o", ls="", color=c, label=k) for k, c in colors.items()]
    ax.legend(handles=handles, fontsize=8, loc="upper right")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _cmd(args):
    import sys

    from planar_lcp.cli import InputError, prepare_output_dir
    from planar_lcp.spec.scene import list_scenes
    known = [n for n, _ in list_scenes()]
    bad = [n for n in args.scenes if n not in known]
    if bad:
        print(f"planar-lcp tradeoff: error: unknown scene {bad[0]!r} (shipped: {', '.join(known)})", file=sys.stderr)
        return 2
    try:
        prepare_output_dir(args.out, "--out")
    except InputError as e:
        print(f"planar-lcp tradeoff: error: {e}", file=sys.stderr)
        return 2
    rows = run_tradeoff(scenes=tuple(args.scenes), quick=args.quick, out_dir=args.out, progress=not args.no_progress)
    print(f"{len(rows)} settings; wrote {Path(args.out) / 'tradeoff.csv'} and the Pareto plots")
    for name in args.scenes:
        sub = [r for r in rows if r["scene"] == name]
        front = pareto_front([(r["cpu_s_per_sim_s"], r["velocity_error"]) for r in sub])
        print(f"{name}: Pareto front (cheapest first)")
        for i in front:
            r = sub[i]
            print(f"  {_label(r):45s} cost {r['cpu_s_per_sim_s']:.3g} s/s  velocity error {r['velocity_error']:.3g}  "
                  f"penetration {r['max_penetration']:.2g} m")
    return 0


def register(sub):
    p = sub.add_parser("tradeoff", help="measure the speed/accuracy trade of h, solver, formulation, friction "
                                        "directions")
    p.add_argument("--scenes", nargs="+", default=list(DEFAULT_SCENES), metavar="SCENE",
                   help=f"scenes to sweep (default: {' '.join(DEFAULT_SCENES)})")
    p.add_argument("--quick", action="store_true", help="two step sizes, lemke and pgs(20), position form only")
    p.add_argument("--out", default="tradeoff", metavar="DIR", help="output directory (default ./tradeoff)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd)
