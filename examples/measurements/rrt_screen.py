"""Screen one planning setting: RRT on a task with seeds 1..N and an ITERATION budget, so the iteration counts are the
same on every machine. Prints each seed's (exact, iterations, solve time) and a summary line.

    python examples/measurements/rrt_screen.py push_t --goal-bias 0.1 --iterations 60000
    python examples/measurements/rrt_screen.py push_box --goal-bias 0.3 --iterations 60000
    python examples/measurements/rrt_screen.py push_t --angle-weight circumradius --iterations 30000

Used for docs/planning.md ("Faster planning"). TASK is a shipped task or a task file. Runs in this process with the
cyclic GC off (planners.plans.plan_task does it).
"""

import argparse
import dataclasses

import numpy as np

from planners import load_task
from planners.plans import plan_task


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("task", help="a shipped task's name or a task file")
    ap.add_argument("--goal-bias", type=float, default=None, help="RRT's goal bias (default: the task's)")
    ap.add_argument("--angle-weight", default=None,
                    help="OMPL's weight of the object's angle, m per rad: 'gyration' (the derived default), "
                         "'circumradius', or a number (default: the task's)")
    ap.add_argument("--iterations", type=int, default=60000)
    ap.add_argument("--seeds", type=int, default=10, help="seeds 1..N")
    a = ap.parse_args()
    task = load_task(a.task)
    if a.goal_bias is not None:
        task = dataclasses.replace(task, goal_bias=a.goal_bias)
    if a.angle_weight is not None:
        w = task.object_extent.get(a.angle_weight)
        w = float(a.angle_weight) if w is None else w
        task = dataclasses.replace(task, weights=(task.weights[0], w, *task.weights[2:]))
    its = []
    for seed in range(1, a.seeds + 1):
        p = plan_task(task, "RRT", seed=seed, iterations=a.iterations)
        print(f"{a.task} goal bias {task.goal_bias}, angle weight {task.weights[1]:.4g}: seed {seed} exact {p['exact']} "
              f"iterations {p['iterations']} "
              f"time {p['solve_time']:.1f} s", flush=True)
        if p["exact"]:
            its.append(p["iterations"])
    print(f"SUMMARY {a.task} goal bias {task.goal_bias}: {len(its)}/{a.seeds} exact within {a.iterations} iterations; "
          f"iterations of the exact runs: median {np.median(its) if its else float('nan'):.0f}, "
          f"max {max(its) if its else float('nan')}")


if __name__ == "__main__":
    main()
