"""Shorten a plan file's plan with a given budget: what a larger budget than `plan`'s buys (docs/planning.md,
"Shorter plans").

    planar-lcp plan push_box --seed 3 --iterations 100000 --no-shorten --out s3
    python examples/measurements/shorten_budget.py s3/plan.json --candidates 10000 --patience 2000

Prints the plan's path duration, the shortened one's, the candidates tried and kept, and the time it took (the
shortening seed is the plan's, as `plan` uses it).
"""

import argparse
import time

from planners import load_plan
from planners.shorten import MAX_CANDIDATES, PATIENCE, shorten

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("plan", help="a plan file (planar-lcp plan ... --no-shorten)")
ap.add_argument("--candidates", type=int, default=MAX_CANDIDATES)
ap.add_argument("--patience", type=int, default=PATIENCE)
args = ap.parse_args()
p = load_plan(args.plan)
t0 = time.perf_counter()
r = shorten(p.model, p.data["start"], p.controls, p.steps, p.data["seed"], max_candidates=args.candidates,
            patience=args.patience)
dt = time.perf_counter() - t0
print(f"{args.plan}: {p.path_duration:.1f} s -> {r['steps'].sum() * p.task.step_duration:.1f} s "
      f"({r['accepted']} of {r['candidates']} candidates kept, {dt:.1f} s)")
