"""The points model converges to the limit-surface model as its support points fill the body and its friction
directions fill the circle (docs/method.md, "Table friction").

A 0.2 m x 0.1 m box slides and spins on the table (v0 = 0.5 m/s along x, w0 = 8 rad/s, mu = 0.4) until it stops.
It runs with support_model = "limit_surface" and with support_model = "points" on an n x n grid of cell-centre
support points (equal shares: the midpoint rule of the uniform pressure) and k friction directions. The table gives,
per points setting, the stop time and the final pose's distance from the limit-surface run's, relative to the
distance the box slid and the angle it turned.

    python examples/measurements/limit_surface_convergence.py            # the table in docs/method.md
"""

import sys

import numpy as np

from planar_lcp.sim import simulate
from planar_lcp.spec.scene import parse_scene

W, H, MU = 0.2, 0.1, 0.4


def box_scene(support_model, grid=None, k=8, h=0.005, t_end=0.25):
    body = {"name": "box", "type": "dynamic", "mass": 1.0, "support_friction": MU, "velocity": [0.5, 0.0],
            "angular_velocity": 8.0, "shapes": [{"type": "box", "width": W, "height": H}]}
    if grid:
        xs = (np.arange(grid) + 0.5) / grid * W - W / 2
        ys = (np.arange(grid) + 0.5) / grid * H - H / 2
        body["support_points"] = [[float(x), float(y)] for x in xs for y in ys]
    return parse_scene({"name": "slide_spin", "world": {"plane": "horizontal", "support_model": support_model},
                        "sim": {"h": h, "t_end": t_end, "friction_directions": k}, "bodies": [body]})


def stop_and_pose(tr):
    speed = np.abs(tr.v_com[:, 0]).max(axis=1)
    idx = np.flatnonzero(speed < 1e-9)
    return (float(tr.t[idx[0]]) if idx.size else np.inf), tr.q_com[-1, 0]


def convergence(settings, **kw):
    """Rows (grid, k, stop time, relative position error, relative angle error) against the limit surface."""
    ref = simulate(box_scene("limit_surface", **kw), record_contacts=False)
    t_ref, q_ref = stop_and_pose(ref)
    moved = float(np.hypot(*(q_ref[:2] - ref.q_com[0, 0, :2])))
    turned = abs(float(q_ref[2] - ref.q_com[0, 0, 2]))
    rows = [("limit surface", "-", t_ref, 0.0, 0.0)]
    for grid, k in settings:
        t, q = stop_and_pose(simulate(box_scene("points", grid, k, **kw), record_contacts=False))
        rows.append((f"{grid} x {grid}", k, t, float(np.hypot(*(q[:2] - q_ref[:2]))) / moved,
                     abs(float(q[2] - q_ref[2])) / turned))
    return rows


def main():
    settings = [(2, 8), (2, 64), (4, 8), (4, 32), (8, 8), (8, 16)]
    print("| support | directions k | stop time (s) | final position error / distance slid | "
          "final angle error / angle turned |")
    print("|---|---|---|---|---|")
    for name, k, t, ep, ea in convergence(settings):
        print(f"| {name} | {k} | {t:.3f} | {ep:.4f} | {ea:.4f} |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
