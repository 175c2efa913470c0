"""When shortening stops: the first exact plans of shipped tasks shortened under the default stopping rule and under
the rule `plan` had before it (4000 candidates, 1000 rejected in a row, no bound on the work), side by side
(docs/planning.md, "When shortening stops").

    python examples/shorten_rule.py --tasks push_box push_t push_clutter tip_box --seeds 1 2 3 4 5 --iterations 30000

Each (task, seed) is planned as `planar-lcp plan TASK --seed S --iterations N --no-shorten` plans it (the same first
exact plan), then shortened twice from it with the plan's seed, as `plan` shortens: once with the old budget, once
with the default rule (`planners.shorten.default_rule`, which is what `planar-lcp plan TASK --seed S --iterations N`
does). Printed per run: the first plan's path duration, each rule's final duration, candidates, simulated steps and
CPU seconds (the process's CPU time: on a shared machine wall time measures the other jobs too), and why the
default stopped. `--trace FILE` writes every candidate of the old budget's run (accepted or not, the plan's
propagation steps, the simulated steps and CPU seconds so far) as JSON: a stricter rule stops the same sequence of
candidates earlier, so the trace shows what any rule would have kept.
"""

import argparse
import json
import statistics
import time

from planners import TaskModel
from planners.plans import plan_task
from planners.shorten import default_rule, shorten

OLD = dict(max_candidates=4000, patience=1000)

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--tasks", nargs="+", default=["push_box", "push_t", "push_clutter", "tip_box"])
ap.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3, 4, 5])
ap.add_argument("--iterations", type=int, default=30000)
ap.add_argument("--trace", metavar="FILE", help="write the old budget's candidates, run by run, as JSON")
ap.add_argument("--rules", nargs="+", choices=["old", "default"], default=["old", "default"],
                help="which rules to run (default both)")
args = ap.parse_args()

runs = []
print("| task | seed | planner: iterations, simulated steps | first plan [s] | old rule: final [s], candidates, "
      "simulated steps, CPU [s] | default rule: final [s], candidates, simulated steps, CPU [s], stopped by |")
print("|---|---|---|---|---|---|")
for task in args.tasks:
    for seed in args.seeds:
        tm = TaskModel(task)
        data = plan_task(task, seed=seed, iterations=args.iterations, tm=tm, shorten=False)
        if not data["exact"]:
            print(f"| {task} | {seed} | {data['iterations']}, {data['sim_steps']} | no exact plan | | |")
            continue
        dt = tm.task.step_duration
        run = dict(task=task, seed=seed, iterations=data["iterations"], planner_sim_steps=data["sim_steps"],
                   solve_time=data["solve_time"], first_steps=int(sum(data["steps"])), trace=[])
        replayed = tm.execute(data["start"], data["controls"], data["steps"])[1:]
        cells = []
        for name, rule in (("old", OLD), ("default", default_rule(data["sim_steps"]))):
            if name not in args.rules:
                cells.append("")
                continue
            s0, c0, t0 = tm.nsteps_total, time.process_time(), time.perf_counter()

            def trace(kind, accepted, s, run=run, s0=s0, c0=c0):
                run["trace"].append([kind, bool(accepted), len(s.U), tm.nsteps_total - s0,
                                     round(time.process_time() - c0, 4)])

            r = shorten(tm, data["start"], data["controls"], data["steps"], seed, replayed=replayed,
                        trace=trace if name == "old" else None, **rule)
            final = float(r["steps"].sum() * dt)
            run[name] = dict(final=final, candidates=r["candidates"], accepted=r["accepted"],
                             sim_steps=r["sim_steps"], cpu=r["cpu_time"], wall=time.perf_counter() - t0,
                             stopped_by=r["stopped_by"])
            cells.append(f"{final:.1f}, {r['candidates']}, {r['sim_steps']}, {r['cpu_time']:.1f}"
                         + (f", {r['stopped_by']}" if name == "default" else ""))
        runs.append(run)
        print(f"| {task} | {seed} | {data['iterations']}, {data['sim_steps']} | "
              f"{data['path_duration']:.1f} | {' | '.join(cells)} |", flush=True)

for task in args.tasks:
    rs = [r for r in runs if r["task"] == task]
    if not rs:
        continue
    dt = TaskModel(task).task.step_duration
    line = [f"{task}: median first {statistics.median(r['first_steps'] for r in rs) * dt:.2f} s"]
    for name in ("old", "default"):
        if all(name in r for r in rs):
            line.append(f"{name}: final {statistics.median(r[name]['final'] for r in rs):.2f} s, "
                        f"{statistics.median(r[name]['candidates'] for r in rs):.0f} candidates, "
                        f"CPU {statistics.median(r[name]['cpu'] for r in rs):.1f} s")
    print("; ".join(line))
if args.trace:
    with open(args.trace, "w") as f:
        json.dump(runs, f)
