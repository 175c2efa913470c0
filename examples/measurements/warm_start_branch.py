"""Why the warm start is off by default: on the falling rod at h = 0.0003125 with the fixed point, the warm and the
cold run take different (both valid) LCP solutions one step before impact and then follow different branches.
Used for docs/method.md ("Warm start"):

    python examples/measurements/warm_start_branch.py
"""

import numpy as np

from planar_lcp import simulate

h = 0.0003125
warm = simulate("falling_rod", h=h, formulation="fixed_point", warm_start=True)
cold = simulate("falling_rod", h=h, formulation="fixed_point")
dv = np.abs(warm.v - cold.v).max(axis=(1, 2))
first = int(np.argmax(dv > 1e-6))
print(f"first velocity difference above 1e-6 at t = {warm.t[first]:.6g} s; largest {dv.max():.3g} "
      f"(m/s or rad/s); largest pose difference {np.abs(warm.q - cold.q).max():.3g}")
k = first - 1
print(f"step {k}: cold normal impulse {cold.contacts['cn'][k, 0]:.4g} N s, warm {warm.contacts['cn'][k, 0]:.4g} N s")
