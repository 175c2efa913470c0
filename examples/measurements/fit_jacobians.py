"""planar_lcp.fit with its Jacobian by forward differences against the step's derivatives (docs/real_pushes.md,
"Fitting"): both fit a box's table friction and the pusher's friction to synthetic recordings of pushes made with
known values (0.35 and 0.3) from a start 15 % off; printed: the values, the evaluations and the thread CPU time of
each fit, alternating the two in one process, and the ratio derivatives / differences per round (median [min-max]).

    python examples/measurements/fit_jacobians.py [--pushes N] [--seconds S] [--rounds R]
"""

import argparse
import statistics
import sys
import time
from collections import namedtuple

import numpy as np

import planar_lcp
from planar_lcp.fitting import fit

TRUE = {"bodies.box.support_friction": 0.35, "friction_pairs.box.pusher": 0.3}
START = (0.3, 0.25)
#: (offset of the push from the box's centre line, m; its direction, rad from +x)
PUSHES = [(0.035, -0.3), (-0.03, 0.2), (0.01, 0.4), (-0.015, -0.1)]
Run = namedtuple("Run", "t names poses source")


def scene_doc(support_mu, pusher_mu, path=None):
    pusher = {"name": "pusher", "type": "kinematic", "shapes": [{"type": "disk", "radius": 0.02}]}
    if path is None:
        pusher["position"] = [-0.12, 0.0]
    else:
        pusher["path"] = path
    return {"name": "fit_push", "world": {"plane": "horizontal", "friction": 0.5,
                                           "friction_pairs": [{"a": "box", "b": "pusher", "mu": pusher_mu}]},
            "sim": {"h": 0.01, "t_end": 1.0},
            "bodies": [{"name": "box", "type": "dynamic", "mass": 1.0, "support_friction": support_mu,
                        "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}, pusher]}


def recordings(n, seconds):
    """The first `seconds` of n pushes (a disk from the box's left face at 0.1 m/s), poses at every step."""
    runs = []
    for i, (offset, direction) in enumerate(PUSHES[:n]):
        t = np.linspace(0.0, seconds, 9)
        path = np.column_stack([t, -0.12 + 0.1 * t * np.cos(direction), offset + 0.1 * t * np.sin(direction),
                                np.zeros_like(t)]).tolist()
        doc = scene_doc(*TRUE.values(), path=path)
        doc["sim"]["t_end"] = seconds
        traj = planar_lcp.simulate(doc)
        runs.append(Run(t=traj.t, names=("box", "pusher"), poses=np.stack([traj.q[:, 0], traj.qk[:, 0]], axis=1),
                        source=f"push {i}"))
    return runs


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pushes", type=int, default=len(PUSHES), help=f"recordings (1 to {len(PUSHES)})")
    p.add_argument("--seconds", type=float, default=0.4, help="each recording's length, s")
    p.add_argument("--rounds", type=int, default=3, help="alternating rounds of the two fits")
    a = p.parse_args(argv)
    if not 1 <= a.pushes <= len(PUSHES) or not 0.05 <= a.seconds <= 1.0 or a.rounds < 1:
        p.error(f"--pushes must be 1 to {len(PUSHES)}, --seconds 0.05 to 1, --rounds >= 1")
    runs = recordings(a.pushes, a.seconds)
    times = {"differences": [], "derivatives": []}
    for r in range(a.rounds):
        for how in times:
            t0 = time.thread_time()
            res = fit(scene_doc(*START), runs, params=list(TRUE), jacobian=how)
            times[how].append(time.thread_time() - t0)
            err = max(abs(res.values[k] - v) for k, v in TRUE.items())
            if r == 0:
                print(f"{how:12s} values {', '.join(f'{k} = {v:.9f}' for k, v in res.values.items())}; largest error "
                      f"{err:.1e}; {res.nfev} evaluations; success {res.success}")
            if not res.success or err > 1e-6:
                print(f"fit_jacobians: the fit by {how} did not recover the values (error {err:.1e})", file=sys.stderr)
                return 1
    ratios = [b / a_ for a_, b in zip(times["differences"], times["derivatives"])]
    print(f"{a.pushes} recordings of {a.seconds:g} s; thread CPU time per fit, median over {a.rounds} rounds: "
          f"differences {statistics.median(times['differences']):.2f} s, derivatives "
          f"{statistics.median(times['derivatives']):.2f} s; derivatives / differences "
          f"{statistics.median(ratios):.1f} [{min(ratios):.1f}-{max(ratios):.1f}]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
