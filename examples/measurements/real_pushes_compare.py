"""The comparison of docs/real_pushes.md: models of the table and the dynamics against recorded real pushes.

    python examples/measurements/real_pushes_compare.py [--data DIR] [--out DIR] [--every K] [--models A,B] [--per-object N]

On the 30 held-out butter pushes, with every model fitted on the 42 pushes of the four training objects only, and by
leave-one-object-out cross-validation on those four (fit on three objects' pushes, predict the fourth's):

- "fitted": our model (limit surface of a uniform pressure) with both friction coefficients fitted;
- "fitted ring": the same with the support pressure's ring (its share and scale, `mit.push_scene`) fitted too;
- "defaults": the same with the reader's defaults (both coefficients 0.25), nothing fitted;
- "points": support_model = "points": Coulomb friction cones (8 directions) at 16 points along the outline
  (`mit.support_ring` at scale 0.95), the fitted coefficients (each convex piece's own default points would make
  butter's 13 pieces a table of about 50 points, minutes per push);
- "rim": all the table's load on a ring along the outline (ring_share 1, ring_scale 0.95), fitted coefficients;
- "quasi-static": the fitted model with inertia scaled by 0.01 (the table's load kept): the quasi-static limit;
- "pymunk": pymunk (Chipmunk2D) through planar_lcp's bridge, the fitted coefficients, its friction at the support
  points (docs/pymunk-comparison.md).

Scores (planar_lcp.studies.pushdata.score): final displacement NMSE (mean over dx, dy in the object's initial frame
and dtheta), median final position and angle errors, and the rms position error along each push (median over pushes).
Writes OUT/compare.csv, OUT/compare.md (the table) and OUT/errors.png (the error along each push, per model).
"""

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np


def scores(rec, pred, along):
    """The table's scores of N pushes from their recorded and predicted final displacements (N, 3) and each push's
    rms position error along it (m): planar_lcp.studies.pushdata.score."""
    from planar_lcp.studies.pushdata import score

    pos, ang = score.final_errors(pred, rec)
    return {"nmse": score.nmse(pred, rec), "median_position_mm": float(np.median(pos)) * 1e3,
            "median_angle_deg": float(np.degrees(np.median(ang))), "max_position_mm": float(pos.max()) * 1e3,
            "median_rms_along_mm": float(np.median(along)) * 1e3, "pushes": len(rec)}


def predict(push, params, simulator="planar_lcp", support_model=None):
    """(recorded poses (T, 3), predicted poses (T, 3), CPU s) of the object at its recorded times."""
    from planar_lcp.studies.pushdata import mit
    from planar_lcp.fitting import predict_run, run_scene

    doc = mit.push_scene(push, params)
    rec = mit.push_recording(push)
    c0 = time.thread_time()
    if simulator == "pymunk":
        from planar_lcp.bridges.pymunk import simulate_pymunk
        from planar_lcp.spec.scene import parse_scene
        traj = simulate_pymunk(parse_scene(run_scene(doc, rec)))
        t = rec.t - rec.t[0]
        pred = np.stack([np.interp(t, traj.t, traj.q[:, 0, c]) for c in range(3)], axis=1)
    else:
        opts = {} if support_model is None else {"support_model": support_model}
        _, p = predict_run(doc, rec, **opts)
        pred = p[:, 0]
    return rec.poses[:, 0], pred, time.thread_time() - c0


#: the parameters each fitted model fits, their starting values and bounds
FITTED = {"fitted": {"support_friction": (0.25, 0.0, 2.0), "pusher_friction": (0.25, 0.0, 2.0)},
          "fitted ring": {"support_friction": (0.25, 0.0, 2.0), "pusher_friction": (0.25, 0.0, 2.0),
                          "ring_share": (0.4, 0.0, 1.0), "ring_scale": (0.4, 0.05, 1.0)}}


def fit_on(pushes, every, kind="fitted"):
    from planar_lcp.studies.pushdata import mit
    from planar_lcp.fitting import fit

    recs = [mit.push_recording(p) for p in pushes]
    spec = FITTED[kind]
    names = list(spec)
    base = dict(mit.DEFAULT_PARAMS)
    res = fit(lambda i, v: mit.push_scene(pushes[i], dict(base, **v)), recs, names,
              x0=[spec[n][0] for n in names], bounds=[spec[n][1:] for n in names], every=every, diff_step=1e-2)
    return dict(base, **res.values), res


def evaluate(pushes, fitted, models, ring=None):
    from planar_lcp.studies.pushdata import mit, score

    out = {}
    for name in models:
        params, kw = {"defaults": (dict(mit.DEFAULT_PARAMS), {}), "fitted": (fitted, {}), "fitted ring": (ring, {}),
                      "points": (dict(fitted, ring_share=1.0, ring_scale=0.95), {"support_model": "points"}),
                      "rim": (dict(fitted, ring_share=1.0, ring_scale=0.95), {}),
                      "quasi-static": (dict(fitted, inertia_scale=0.01), {}),
                      "pymunk": (fitted, {"simulator": "pymunk"})}[name]
        rec_d, pred_d, along, cpu, curves = [], [], [], [], []
        for p in pushes:
            rec, pred, c = predict(p, params, **kw)
            rec_d.append(score.final_displacement(rec))
            pred_d.append(score.final_displacement(pred))
            err = np.hypot(*(pred - rec)[:, :2].T)
            along.append(float(np.sqrt(np.mean(err ** 2))))
            curves.append(err)
            cpu.append(c)
        out[name] = dict(scores(rec_d, pred_d, along), cpu_median_s=float(np.median(cpu)),
                         cpu_max_s=float(np.max(cpu)), curves=curves, rec_d=np.array(rec_d), pred_d=np.array(pred_d),
                         along=np.array(along), cpu=np.array(cpu))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=None, help="the data set's root (default: $PLANAR_LCP_MIT_PUSH or "
                                                 "../shared/data/mit-push)")
    ap.add_argument("--out", default="docs/figures/real_pushes", help="output folder")
    ap.add_argument("--every", type=int, default=5, help="fit on every K-th sample of each push (default 5)")
    ap.add_argument("--models", default="fitted,fitted ring,defaults,points,rim,quasi-static,pymunk")
    ap.add_argument("--per-object", type=int, default=None, metavar="N",
                    help="only the first N pushes of each object, by file name (a quick check; default all)")
    args = ap.parse_args(argv)
    from planar_lcp.studies.pushdata import mit

    models = args.models.split(",")
    files = mit.push_files(args.data)
    if args.per_object is not None:
        seen = {}
        for f in files:
            seen.setdefault(mit.parse_push_name(f).shape, []).append(f)
        files = sorted(f for group in seen.values() for f in group[:args.per_object])
    pushes = [mit.read_push(f, args.data) for f in files]
    train = [p for p in pushes if "/train/" in p.path]
    butter = [p for p in pushes if p.shape == "butter"]
    if any(p.shape == "butter" for p in train):
        sys.exit("a butter push among the training pushes")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    fitted, res = fit_on(train, args.every)
    print(f"fitted on {len(train)} pushes of {', '.join(sorted({p.shape for p in train}))}: "
          + ", ".join(f"{k} {res.values[k]:.4f} +- {res.stderr[k]:.4f} (by push {res.stderr_by_run[k]:.4f})"
                      for k in res.values), flush=True)
    (out / "fit_train.json").write_text(json.dumps({"values": res.values, "stderr": res.stderr,
                                                    "stderr_by_run": res.stderr_by_run, "cost": res.cost,
                                                    "nfev": res.nfev}, indent=1))
    ring = fit_on(train, args.every, "fitted ring")[0] if "fitted ring" in models else None
    if ring is not None:
        print("fitted ring on the training pushes: " + json.dumps(ring), flush=True)
    held = evaluate(butter, fitted, models, ring)
    for m in models:
        rows.append(dict(evaluation="butter (held out)", model=m, **{k: v for k, v in held[m].items()
                                                                      if k in ROW_KEYS}))
    cv = {m: [] for m in models}
    for shape in sorted({p.shape for p in train}):
        fit_shapes = [p for p in train if p.shape != shape]
        test = [p for p in train if p.shape == shape]
        f_cv, r_cv = fit_on(fit_shapes, args.every)
        ring_cv = fit_on(fit_shapes, args.every, "fitted ring")[0] if "fitted ring" in models else None
        print(f"leave out {shape}: " + ", ".join(f"{k} {v:.4f}" for k, v in r_cv.values.items()), flush=True)
        ev = evaluate(test, f_cv, models, ring_cv)
        for m in models:
            cv[m].append(ev[m])
    for m in models:
        # the four held-out objects' pushes pooled: the scores over all of them
        rows.append(dict(evaluation="leave one object out", model=m, **pooled(cv[m])))
    with open(out / "compare.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = ["| evaluation | model | NMSE | median position error (mm) | median angle error (deg) | median rms error "
             "along the push (mm) | pushes | CPU per push, median / max (s) |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['evaluation']} | {r['model']} | {r['nmse']:.3f} | {r['median_position_mm']:.2f} | "
                     f"{r['median_angle_deg']:.2f} | {r['median_rms_along_mm']:.2f} | {r['pushes']} | "
                     f"{r['cpu_median_s']:.3f} / {r['cpu_max_s']:.3f} |")
    (out / "compare.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    plot_errors(held, butter, out / "errors.png")
    print(f"wrote {out / 'compare.csv'}, {out / 'compare.md'}, {out / 'errors.png'}")


ROW_KEYS = ("nmse", "median_position_mm", "median_angle_deg", "max_position_mm", "median_rms_along_mm", "pushes",
            "cpu_median_s", "cpu_max_s")


def pooled(evs):
    """The scores of several evaluations' pushes together (the cross-validation's four held-out objects)."""
    rec = np.concatenate([e["rec_d"] for e in evs])
    pred = np.concatenate([e["pred_d"] for e in evs])
    along = np.concatenate([e["along"] for e in evs])
    cpu = np.concatenate([e["cpu"] for e in evs])
    return dict(scores(rec, pred, along), cpu_median_s=float(np.median(cpu)), cpu_max_s=float(np.max(cpu)))


def plot_errors(held, pushes, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for k, (name, ev) in enumerate(held.items()):
        # each push's position error against the fraction of the push done, the median over pushes
        grid = np.linspace(0.0, 1.0, 101)
        curves = np.array([np.interp(grid, np.linspace(0.0, 1.0, len(c)), c) for c in ev["curves"]]) * 1e3
        ax.plot(grid, np.median(curves, axis=0), label=name, color=f"C{k}")
        ax.fill_between(grid, np.percentile(curves, 25, axis=0), np.percentile(curves, 75, axis=0), color=f"C{k}",
                        alpha=0.12)
    ax.set_xlabel("fraction of the push")
    ax.set_ylabel("position error of the object (mm)")
    ax.set_title(f"{len(pushes)} held-out butter pushes: median and quartiles of the error along the push")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
