"""Island solvers side by side, each behind the same signature (engine/step.py `solve_island`): Lemke (lemke.py,
the certified default), projected Gauss-Seidel (pgs.py) and OSQP's convex relaxation (osqp.py, Python level)."""
