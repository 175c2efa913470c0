"""Island solvers side by side, each behind the island-solver signature of engine/step.py `step_pipeline`:
`solve_island_lemke` (lemke.py, the certified default), `solve_island_pgs` (pgs.py, projected Gauss-Seidel) and
`solve_island_osqp` (osqp.py, OSQP's convex relaxation, Python level)."""
