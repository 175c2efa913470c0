"""The bin of 40 mixed shapes (`planar_lcp.spec.piles.bin_scene(40)`) dropped in: the deepest penetration at the end
of each step (Stat.PENETRATION) over 2 s, with the defaults at h = 1/60 s and 1/240 s (Box2D's substep at its
default 4 substeps of 1/60 s), and in the fixed-point formulation at 1/60 s; the final state's deepest penetration.

Used for docs/performance.md ("Piles", the bin):   python examples/measurements/bin_penetration.py
"""

import numpy as np

from planar_lcp.sim import simulate
from planar_lcp.spec import piles
from planar_lcp.spec.scene import parse_scene

scene = parse_scene(piles.bin_scene(40))
print("| h (s) | formulation | deepest penetration over the run (m) | steps deeper than 1 mm | at the end (m) | "
      "step failures |")
print("|---|---|---:|---:|---:|---:|")
for h, form in ((1 / 60, "position"), (1 / 60, "fixed_point"), (1 / 240, "position")):
    r = simulate(scene, t_end=2.0, h=h, formulation=form)
    pen = np.asarray(r.stats["penetration"])
    print(f"| 1/{round(1 / h)} | {form} | {pen.max():.2e} | {int((pen > 1e-3).sum())} of {len(pen)} | "
          f"{pen[-1]:.1e} | {len(r.failures)} |")
