"""Open loop and closed loop in pymunk, side by side, for the shipped tasks and the task files in tasks/.

    python examples/measurements/closed_loop_tasks.py --out docs/figures/closed_loop/tasks [--jobs 2]

For each task: a plan made by `planners.plan` with our simulator as the forward model (seed 1; the shipped tasks'
committed plans in docs/figures/ when present, else planned once and kept in OUT/plans/TASK/plan.json), executed in
pymunk through planar_lcp.bridges.pymunk (another contact model, pymunk's own friction) three ways:
open loop (the plan's controls in turn, `planar-lcp replay PLAN --simulator pymunk`), closed loop (`--closed-loop`:
planners.closed_loop.PlanTracker) and closed loop in a perturbed world (`--perturb mu=0.8,mass=1.2` by default).
Writes OUT/results.csv (one row per task and way), OUT/table.md and prints the table.
"""

import argparse
import csv
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ["push_box", "push_clutter", "push_table", "push_t", "tip_box"]
COMMITTED = {"push_box": "docs/figures/planning/push_box/plan.json",
             "push_clutter": "docs/figures/planning/push_clutter/plan.json",
             "push_table": "docs/figures/planning/push_table/plan.json",
             "tip_box": "docs/figures/planning/tip_box/plan.json",
             "push_t": "docs/figures/gym/push_t_plan/plan.json"}
COLUMNS = ["task", "way", "goal_holds", "goal_distance", "steps", "plan_steps", "compute_median_ms",
           "compute_max_ms", "step_ms"]


def task_list():
    return [(n, n) for n in SHIPPED] + [(p.stem, str(p)) for p in sorted((ROOT / "tasks").glob("*.toml"))]


def plan_file(name, source, out):
    """The plan of task `name`: the committed one, else OUT/plans/NAME/plan.json (planned once, seed 1)."""
    from planners import plan
    if name in COMMITTED and (ROOT / COMMITTED[name]).is_file():
        return ROOT / COMMITTED[name]
    path = out / "plans" / name / "plan.json"
    if not path.is_file():
        p = plan(source, seed=1)
        if not p.exact:
            raise RuntimeError(f"{name}: the planner found no exact plan")
        path.parent.mkdir(parents=True, exist_ok=True)
        p.save(path)
    return path


def run_task(name, source, out, perturb):
    from planners.plans import load_plan
    path = plan_file(name, source, out)
    plan = load_plan(path)
    rows = []
    for way, kw in (("open loop", {}), ("closed loop", {"closed_loop": True}),
                    ("closed loop, perturbed", {"closed_loop": True, "perturb": perturb})):
        res = plan.replay("pymunk", **kw)
        c = res.get("compute_s")
        timed = c is not None and len(c) > 0
        rows.append({"task": name, "way": way, "goal_holds": res["report"]["goal_holds"],
                     "goal_distance": round(res["report"]["goal_distance"], 4), "steps": res["steps"],
                     "plan_steps": int(plan.steps.sum()),
                     "compute_median_ms": round(1e3 * float(np.median(c)), 2) if timed else "",
                     "compute_max_ms": round(1e3 * float(np.max(c)), 2) if timed else "",
                     "step_ms": round(1e3 * plan.task.step_duration, 1)})
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--perturb", default="mu=0.8,mass=1.2")
    ap.add_argument("--tasks", nargs="*", default=None, help="only these tasks (names)")
    args = ap.parse_args(argv)
    from planar_lcp.spec.scene import parse_perturbation
    perturb = parse_perturbation(args.perturb)
    args.out.mkdir(parents=True, exist_ok=True)
    tasks = [t for t in task_list() if args.tasks is None or t[0] in args.tasks]
    t0 = time.monotonic()
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as ex:
            results = list(ex.map(run_task, *zip(*[(n, s, args.out, perturb) for n, s in tasks])))
    else:
        results = [run_task(n, s, args.out, perturb) for n, s in tasks]
    rows = [r for rs in results for r in rs]
    with open(args.out / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(rows)
    ways = ["open loop", "closed loop", "closed loop, perturbed"]
    lines = ["| task | " + " | ".join(ways) + " | closed-loop compute per step (median, max) |",
             "|---|" + "---|" * len(ways) + "---|"]
    for rs in results:
        by = {r["way"]: r for r in rs}
        cells = [("reached" if by[w]["goal_holds"] else f"missed ({by[w]['goal_distance']:.2g})") for w in ways]
        c = by["closed loop"]
        lines.append(f"| {rs[0]['task']} | " + " | ".join(cells) +
                     f" | {c['compute_median_ms']} ms, {c['compute_max_ms']} ms of {c['step_ms']} ms |")
    n = len(results)
    tot = {w: sum(by["goal_holds"] for rs in results for by in rs if by["way"] == w) for w in ways}
    lines.append("| **reached** | " + " | ".join(f"**{tot[w]} of {n}**" for w in ways) + " | |")
    table = "\n".join(lines) + "\n"
    (args.out / "table.md").write_text(table)
    print(table)
    print(f"({time.monotonic() - t0:.0f} s; perturbed world: {args.perturb}; goal distance in brackets: 1 is the "
          f"goal's tolerance)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
