"""Speed at which a disk (r = 5 cm) dropped on a thin static segment (1 mm thick) passes through it, per step size.

Used for docs/limits.md:  python examples/measurements/tunnelling_threshold.py
"""

import numpy as np

from planar_lcp import simulate
from planar_lcp.spec.scene import parse_scene


def passes_through(speed, h, y0=0.5):
    sc = parse_scene({
        "name": "wire", "world": {"plane": "vertical", "gravity": [0.0, -9.81], "friction": 0.5},
        "sim": {"h": h, "t_end": 2 * y0 / speed + 0.05},
        "bodies": [{"name": "disk", "type": "dynamic", "mass": 1.0, "position": [0.0, y0], "velocity": [0.0, -speed],
                    "shapes": [{"type": "disk", "radius": 0.05}]},
                   {"name": "wire", "type": "static",
                    "shapes": [{"type": "segment", "a": [-1.0, 0.0], "b": [1.0, 0.0], "radius": 0.0005}]}]})
    return simulate(sc, record_contacts=False).q[:, 0, 1].min() < 0.0


print("| h (s) | slowest tunnelling speed found (m/s) | per-step motion h v (m) | (2 r + thickness) / h (m/s) |")
print("|---:|---:|---:|---:|")
for h in (0.01, 0.0025, 0.001):
    speeds = np.linspace(1.0, 150.0, 150)
    # several start heights, because whether a step lands inside the segment depends on the phase
    hits = [v for v in speeds if any(passes_through(v, h, y0) for y0 in (0.5, 0.5 + 0.3 * v * h, 0.5 + 0.6 * v * h))]
    vmin = min(hits) if hits else float("nan")
    print(f"| {h} | {vmin:.0f} | {vmin * h:.3f} | {(0.1 + 0.001) / h:.0f} |")
