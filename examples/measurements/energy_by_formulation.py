"""Energy behaviour of the three formulations on the Painleve rod (pivoting and sliding on its end, mu = 1.5).

Prints, per formulation and step size, the largest energy rise in one step and over any window, and the energy at
the start and the end. Used for the table in docs/method.md:

    python examples/measurements/energy_by_formulation.py
"""

import numpy as np

from planar_lcp import simulate
from planar_lcp.spec.scene import FORMULATIONS


def largest_rise(e):
    lo, rise = e[0], 0.0
    for x in e:
        lo = min(lo, x)
        rise = max(rise, x - lo)
    return rise


print("| formulation | h (s) | max one-step gain (J) | max cumulative rise (J) | E(0) (J) | E(0.5 s) (J) |")
print("|---|---:|---:|---:|---:|---:|")
for form in FORMULATIONS:
    for h in (0.002, 0.001, 0.0005):
        e = simulate("painleve_rod", h=h, t_end=0.5, formulation=form).stats["energy"]
        print(f"| {form} | {h} | {np.diff(e).max():.2e} | {largest_rise(e):.2e} | {e[0]:.4f} | {e[-1]:.4f} |")
