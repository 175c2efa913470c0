"""A plan made in our simulator, executed in another one (pymunk, with its own contact model and the friction and
masses changed): open loop it misses, with feedback (planners.PlanTracker: docs/closed_loop.md) it gets there.

    python examples/closed_loop.py

Needs the `plan` and `compare` extras (OMPL, pymunk).
"""

import planners

plan = planners.plan("push_box", iterations=15000, seed=5)      # the shipped task, as `planar-lcp demo` plans it
print(f"planned: exact {plan.exact}, {sum(plan.durations):.2f} s of pushing")
world = {"mu": 0.8, "mass": 1.2}                                 # pymunk's world: 0.8 x every friction, 1.2 x masses
for closed_loop in (False, True):
    run = plan.replay("pymunk", closed_loop=closed_loop, perturb=world)
    report = run["report"]
    print(f"{'closed' if closed_loop else 'open'} loop in pymunk: goal reached {report['goal_holds']}, "
          f"{report['position_error_m']:.3f} m and {report['angle_error_deg']:.1f} deg from the goal")
