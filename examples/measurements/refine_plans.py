"""planners.refine on the shipped tasks, after the shortener (docs/planning.md, "Refining a plan"): each task planned
with its documented seed and iteration budget (shortened by the default rule, as `planar-lcp plan` does), then
refined; printed per task: the pusher's path length after shortening and after refining, the refinement's accepted
and tried steps, why it stopped, whether every derivative run was exact, and its CPU time; then, per task, the last
candidate that missed the goal: the goal's coordinates' change its replay gave against the derivatives'
prediction.

    python examples/measurements/refine_plans.py [--tasks NAME ...] [--iterations N]

(default tasks push_box and tip_box)
"""

import argparse
import sys

import planners

#: the shipped tasks with the seed and iteration budget docs/planning.md plans them with
TASKS = {"push_box": (5, 15000), "tip_box": (7, 5000), "push_clutter": (1, 9000), "push_table": (3, 5000)}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tasks", nargs="+", choices=list(TASKS), default=["push_box", "tip_box"],
                   help="default push_box tip_box: push_clutter's and push_table's (5 and 13 dynamic bodies, "
                        "hundreds of steps) are planned first, for minutes")
    p.add_argument("--iterations", type=int, default=10, help="refinement steps at most (default 10)")
    a = p.parse_args(argv)
    print("| task | controls | steps | pusher path after shortening (m) | after refining (m) | change | steps "
          "accepted / tried | stopped by | derivatives exact | steps by dual numbers | refine CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    failed = False
    misses = []
    for name in a.tasks:
        seed, budget = TASKS[name]
        plan = planners.plan(name, iterations=budget, seed=seed)
        if not plan.exact:
            print(f"| {name} | no exact plan within {budget} iterations (seed {seed}) | | | | | | | | | |")
            failed = True
            continue
        r = planners.refine(plan, iterations=a.iterations)
        info = r.data["refine"]
        if not (r.exact and r.replay()["report"]["goal_holds"]):
            failed = True
        print(f"| {name} | {len(plan.controls)} | {int(plan.steps.sum())} | {info['before']:.4f} | "
              f"{info['after']:.4f} | {100 * (info['after'] / info['before'] - 1):+.1f} % | {info['accepted']} / "
              f"{info['tried']} | {info['stopped_by']} | {'yes' if info['exact_derivatives'] else 'no'} | "
              f"{info['dual_steps']} of {info['derivative_steps']} | {info['cpu_time']:.1f} |")
        if info["last_miss"] is not None:
            miss = info["last_miss"]
            misses.append(f"{name}: a change of {miss['control_change']:.1e} m/s in the controls moved the goal's "
                          f"coordinates by {', '.join(f'{x:+.3g}' for x in miss['replayed'])} where the derivatives "
                          f"predicted {', '.join(f'{x:+.3g}' for x in miss['predicted'])} (the last candidate "
                          "replayed that missed the goal)")
    print("")
    for line in misses:
        print(line)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
