"""Hello, planar_lcp: Stewart & Trinkle's falling rod, simulated, and what the solver did.

    python examples/hello_simulate.py
"""

import planar_lcp

traj = planar_lcp.simulate("falling_rod")          # a shipped scene's name; a .toml path or a dict works the same
x, y, theta = traj.q[-1, 0]                         # the rod's last pose (body frame origin, world frame)
print(f"{traj.body_names[0]} at t = {traj.t[-1]:.3f} s: x = {x:.4f} m, y = {y:.4f} m, theta = {theta:.4f} rad")
print(f"{len(traj.t) - 1} steps, {int(traj.stats['pivots'].sum())} Lemke pivots, "
      f"deepest overlap {traj.stats['penetration'].max():.1e} m, energy {traj.stats['energy'][0]:.3f} J "
      f"-> {traj.stats['energy'][-1]:.3f} J")
