"""Fit a friction coefficient with the step's derivatives: a block slides down a 30 degree incline (scenes/
block_on_incline.toml, mu = 0.3); from where it is after 0.1 s, Gauss-Newton steps on the rollout's derivative
d(pose)/d(mu) (`Simulator.rollout_derivatives`) recover mu from a wrong start, one rollout per step (the
sliding block's pose is linear in mu: the first step lands on it).

    python examples/fit_friction_gradient.py
"""

import planar_lcp
from planar_lcp import SimOptions, Simulator, load_scene
from planar_lcp.model import compile_scene
from planar_lcp.derivatives import scene_with_param

scene = load_scene("block_on_incline")
observed = planar_lcp.simulate(scene, t_end=0.1).q[-1, 0]          # the block's pose after 0.1 s (20 steps)
mu = 0.1                                                             # a wrong start
for step in range(3):
    sim = Simulator(compile_scene(scene_with_param(scene, "world.friction", mu)), SimOptions())
    q, v, qk, vk = sim.initial_state()
    r = sim.rollout_derivatives(q, v, qk, vk[None], 20, params=["world.friction"])
    residual, J = r.q[-1, 0] - observed, r.dx_dp[:3, 0]            # the pose's error and d(pose)/d(mu)
    mu -= (J @ residual) / (J @ J)                                   # Gauss-Newton: the least-squares step
    print(f"step {step}: mu = {mu:.6f}, pose error {abs(residual).max():.2e} m (exact derivatives: {r.exact})")
