"""The MIT pushing data set as this package reads it: each object's outline registration, then one line per push
(docs/real_pushes.md cites what this prints).

    python examples/measurements/pushdata_summary.py [DATA_ROOT]

DATA_ROOT defaults to $PLANAR_LCP_MIT_PUSH, else ../shared/data/mit-push (planar_lcp.studies.pushdata.mit.
find_data_root). Needs the extra 'pushdata' (h5py, scipy). About 10 s.
"""

import math
import sys

import numpy as np

from planar_lcp.cli_support import require


def main(argv):
    require("h5py", "scipy")
    from planar_lcp.studies.pushdata import mit
    from planar_lcp.studies.pushdata.outline import clean, signed_distance

    root = mit.data_root(argv[0] if argv else None)
    print(f"data: {root}")
    print(f"pusher radius {mit.PUSHER_RADIUS * 1000:g} mm; registration prior: centroid shift sd "
          f"{mit.REGISTRATION_SHIFT_SD * 1000:g} mm against contact noise {mit.REGISTRATION_NOISE * 1000:g} mm")
    print()
    print("registration of each outline file into its pose frame (p_pose = R(dtheta) p_file + (dx, dy))")
    print(f"{'object':7} {'pushes':>7} {'cue':>7} {'dx mm':>7} {'dy mm':>7} {'dtheta deg':>10} {'sym':>4} "
          f"{'sd x,y mm / deg':>17} {'rms mm':>7} {'as filed':>8} {'moved':>6} {'pieces':>6}  unidentified")
    shapes = sorted({mit.parse_push_name(f).shape for f in mit.push_files(root)})
    for shape in shapes:
        model = mit.object_model(shape, root)
        reg = model.registration
        used = [(f, o) for f, o in zip(model.files, model.onsets) if o is not None]
        cues = sorted({o.cue for _, o in used})
        # the contact points' residual against the outline as filed (no registration), for comparison
        pts = np.array([mit.contact_point(mit.read_push(f, root), o.t) for f, o in used])
        raw = signed_distance(pts, clean(mit.read_outline(shape, root)))[0] - mit.PUSHER_RADIUS
        # how far registration moved the outline where the pusher touched it (along the normal)
        moved = np.max(np.abs(signed_distance(pts, model.outline)[0] - mit.PUSHER_RADIUS - raw))
        sd = reg.std
        sd_text = (f"{sd[0] * 1000:.1f},{sd[1] * 1000:.1f} / "
                   + ("-" if math.isnan(sd[2]) else f"{math.degrees(sd[2]):.1f}"))
        print(f"{shape:7} {len(used):>3}/{len(model.files):<3} {'+'.join(cues):>7} {reg.dx * 1000:7.2f} "
              f"{reg.dy * 1000:7.2f} {math.degrees(reg.dtheta):10.2f} {reg.symmetry:4d} {sd_text:>17} "
              f"{reg.rms * 1000:7.2f} {math.sqrt(np.mean(raw ** 2)) * 1000:8.2f} {moved * 1000:6.2f} "
              f"{len(model.pieces):6d}  "
              f"{', '.join(reg.unidentified) or '-'}")
    print("(sym: the order of rotational symmetry, 0 continuous; dtheta is given modulo 360/sym degrees; 'as filed': "
          "the contacts' rms with no registration; moved: the largest distance, mm, the registration moved the outline "
          "at a contact, along its normal)")
    print()
    rows = mit.summary(root)
    print(f"{'push':58} {'v':>4} {'v meas':>6} {'dur s':>5} {'disp mm':>7} {'rot deg':>7} {'onset':>6} "
          f"{'res mm':>6} {'gap mm':>6} {'shift':>5} {'after':>5}")
    for r in rows:
        name = r["file"].removeprefix("motion_surface=").removesuffix(".h5")
        onset = f"{r['onset']:.3f}" if r["onset"] is not None else "-"
        res = f"{r['residual']:.2f}" if r["residual"] is not None else "-"
        print(f"{name:58} {r['v']:4.0f} {r['v_measured']:6.1f} {r['duration']:5.2f} {r['displacement']:7.1f} "
              f"{r['rotation']:7.1f} {onset:>6} {res:>6} {r['gap']:6.2f} {r['shift']:5.2f} "
              f"{round(r['gap_after'], 2) + 0.0:5.2f}")
    shifts = [r["shift"] for r in rows if r["shift"] > 0.0]
    clear = [r for r in rows if r["gap_after"] > 1.0]
    print()
    print(f"{len(rows)} pushes; overlap at t = 0 reconciled in {len(shifts)} (shift median {np.median(shifts):.2f} mm, "
          f"max {max(shifts):.2f} mm); gap after reconciliation "
          f"{round(min(r['gap_after'] for r in rows), 2) + 0.0:.2f} to "
          f"{max(r['gap_after'] for r in rows):.2f} mm, above 1 mm in {len(clear)}: "
          + (", ".join(r["file"] for r in clear) or "none"))
    moved = [r["reordered"] for r in rows]
    print(f"samples out of time order or repeating a time (sorted, repeats dropped): {sum(moved)} in "
          f"{sum(m > 0 for m in moved)} files, at most {max(moved)} in one")
    for v in sorted({r["v"] for r in rows}):
        meas = [r["v_measured"] for r in rows if r["v"] == v]
        print(f"v = {v:g} mm/s: measured {min(meas):.1f} to {max(meas):.1f} mm/s over {len(meas)} pushes")
    disp = np.array([r["displacement"] for r in rows])
    rot = np.array([abs(r["rotation"]) for r in rows])
    print(f"object displacement {disp.min():.1f} to {disp.max():.1f} mm (median {np.median(disp):.1f}), "
          f"|rotation| {rot.min():.1f} to {rot.max():.1f} deg (median {np.median(rot):.1f})")


if __name__ == "__main__":
    main(sys.argv[1:])
