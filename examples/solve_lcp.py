"""Solve a small LCP with planar_lcp's Lemke and check the answer by hand."""

import numpy as np

from planar_lcp import lemke

M = np.array([[2.0, 1.0], [1.0, 2.0]])
q = np.array([-5.0, -6.0])
r = lemke(M, q)
w = M @ r.z + q
print(f"status={r.status} pivots={r.pivots} z={r.z} w={w} z.w={r.z @ w:.1e}")
