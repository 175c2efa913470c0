"""A scene of your own, written in Python as a scene file's document, checked against Newton: a box sliding down a
20 degree ramp with friction 0.2 accelerates at g (sin a - mu cos a), here to the last digit printed.

    python examples/own_scene.py

The same document as a TOML file (docs/scene-format.md) runs with `planar-lcp simulate FILE.toml`.
"""

import math

import numpy as np

import planar_lcp

slope, mu, g = math.radians(20.0), 0.2, 9.81
normal = [-math.sin(slope), math.cos(slope)]                  # the ramp's outward normal, through the origin
scene = {
    "name": "my_ramp",
    "world": {"plane": "vertical", "gravity": [0.0, -g], "friction": mu},
    "sim": {"h": 0.002, "t_end": 0.5},
    "bodies": [
        {"name": "box", "type": "dynamic", "mass": 2.0, "angle_deg": 20.0,
         # the box's bottom face on the ramp: its centre half its height (0.05 m) along the normal
         "position": [0.05 * normal[0], 0.05 * normal[1]],
         "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]},
        {"name": "ramp", "type": "static",
         "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": normal}]},
    ],
}

traj = planar_lcp.simulate(scene)
down = np.array([-math.cos(slope), -math.sin(slope)])         # down the ramp
travelled = (traj.q[-1, 0, :2] - traj.q[0, 0, :2]) @ down
a, h, n = g * (math.sin(slope) - mu * math.cos(slope)), 0.002, len(traj.t) - 1
# the step's implicit Euler (v+ = v + h a, then q+ = q + h v+) travels a h^2 n (n + 1) / 2 in n steps
print(f"slid {travelled:.6f} m down the ramp in {traj.t[-1]:.2f} s; Newton, stepped as the scheme steps: "
      f"{a * h * h * n * (n + 1) / 2:.6f} m; in continuous time: {a * traj.t[-1] ** 2 / 2:.6f} m")
