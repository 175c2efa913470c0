"""planners.refine on the shipped tasks, after the shortener (docs/planning.md, "Refining a plan"): each task planned
with its documented seed and iteration budget (shortened by the default rule, as `planar-lcp plan` does), then
refined from that plan by each objective; printed per objective, one table, a row per task: the objective after
shortening and after refining, the refinement's kept and tried steps, why it stopped, whether every derivative run
was exact, the steps the one-sided differences and the dual numbers differentiated, and its CPU time; for the path duration also the shortener
alone given as long again (its randomised shortcutting of the same plan, with no bound but the refinement's wall
time); then, per task, the last candidate of the pusher-path refinement that missed the goal: the goal's
coordinates' change its replay gave against the derivatives' prediction.

    python examples/measurements/refine_plans.py [--tasks NAME ...] [--objectives NAME ...] [--iterations N]
                                                 [--time-limit S]

(default tasks push_box and tip_box, both objectives, until nothing more is kept)
"""

import argparse
import sys
import time

import planners
from planners.refine import OBJECTIVES

#: the shipped tasks with the seed and iteration budget docs/planning.md plans them with
TASKS = {"push_box": (5, 15000), "tip_box": (7, 5000), "push_clutter": (1, 9000), "push_table": (3, 5000)}

HEADERS = {
    "path_duration": ("path duration after shortening (s)", "after refining (s)",
                      ("shortener alone for as long (s)", "pusher path after shortening (m)", "after refining (m)"),
                      "steps dropped / shortenings tried"),
    "pusher_path_length": ("pusher path after shortening (m)", "after refining (m)", (), "steps accepted / tried"),
}


def shortener_for(plan, seconds, seed):
    """The path duration (s) the shortener alone reaches from `plan` in `seconds` of wall time, no other bound."""
    from planners.shorten import shorten
    tm = plan.model
    r = shorten(tm, plan.data["start"], plan.controls, plan.steps, seed, max_candidates=None, patience=None,
                deadline=time.perf_counter() + seconds)
    return float(r["steps"].sum() * tm.task.step_duration)


def _row(name, plan, r, seed):
    info = r.data["refine"]
    cells = [name, str(len(plan.controls)), str(int(plan.steps.sum())), f"{info['before']:.4f}",
             f"{info['after']:.4f}", f"{100 * (info['after'] / info['before'] - 1):+.1f} %"]
    if info["objective"] == "path_duration":
        # seed + 1: a stream of candidates apart from the one that shortened the plan
        cells += [f"{shortener_for(plan, info['time'], seed + 1):.4f}", f"{plan.data['pusher_path_length']:.4f}",
                  f"{r.data['pusher_path_length']:.4f}"]
    cells += [f"{info['accepted']} / {info['tried']}", info["stopped_by"],
              "yes" if info["exact_derivatives"] else "no",
              f"{info['one_sided_steps']} and {info['dual_steps']} of {info['derivative_steps']}",
              f"{info['cpu_time']:.1f}"]
    return "| " + " | ".join(cells) + " |"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tasks", nargs="+", choices=list(TASKS), default=["push_box", "tip_box"],
                   help="default push_box tip_box: push_clutter's and push_table's (5 and 13 dynamic bodies, "
                        "hundreds of steps) are planned first, for minutes")
    p.add_argument("--objectives", nargs="+", choices=OBJECTIVES, default=list(OBJECTIVES),
                   help="what refine lowers (default both, each from the shortened plan)")
    p.add_argument("--iterations", type=int, default=None,
                   help="steps kept at most per refinement (default: until nothing more is kept)")
    p.add_argument("--time-limit", type=float, default=None, help="wall seconds per refinement (default none)")
    a = p.parse_args(argv)
    if a.iterations is not None and a.iterations < 0:
        p.error(f"--iterations must be >= 0, got {a.iterations}")
    if a.time_limit is not None and not a.time_limit > 0:
        p.error(f"--time-limit must be > 0, got {a.time_limit}")
    failed = False
    rows = {objective: [] for objective in a.objectives}
    misses = []
    for name in a.tasks:
        seed, budget = TASKS[name]
        plan = planners.plan(name, iterations=budget, seed=seed)
        if not plan.exact:
            print(f"{name}: no exact plan within {budget} iterations (seed {seed})")
            failed = True
            continue
        for objective in a.objectives:
            r = planners.refine(plan, iterations=a.iterations, objective=objective, time_limit=a.time_limit)
            if not (r.exact and r.replay()["report"]["goal_holds"]):
                failed = True
            rows[objective].append(_row(name, plan, r, seed))
            miss = r.data["refine"]["last_miss"]
            if miss is not None:
                misses.append(f"{name}: a change of {miss['control_change']:.1e} m/s in the controls moved the "
                              f"goal's coordinates by {', '.join(f'{x:+.3g}' for x in miss['replayed'])} where the "
                              f"derivatives predicted {', '.join(f'{x:+.3g}' for x in miss['predicted'])} (the last "
                              "candidate of the pusher path's refinement replayed that missed the goal)")
    for objective in a.objectives:
        before, after, more, kept = HEADERS[objective]
        cols = ["task", "controls", "steps", before, after, "change", *more, kept, "stopped by", "derivatives exact",
                "steps by one-sided differences and dual numbers", "refine CPU s"]
        print(f"\nobjective {objective}\n")
        print("| " + " | ".join(cols) + " |")
        print("|" + "---|" * len(cols))
        for row in rows[objective]:
            print(row)
    if misses:
        print("")
    for line in misses:
        print(line)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
