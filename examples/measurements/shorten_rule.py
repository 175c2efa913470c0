"""When shortening stops: the first exact plans of shipped tasks shortened under the default stopping rule and under
the rule `plan` had before it (4000 candidates, 1000 rejected in a row, no bound on the simulated steps), side by
side (docs/planning.md, "When shortening stops").

    python examples/measurements/shorten_rule.py --tasks push_box push_t push_clutter tip_box --seeds 1 2 3 4 5 --iterations 30000

Each (task, seed) is planned as `planar-lcp plan TASK --seed S --iterations N` plans it (the same first exact plan),
then shortened from it with the plan's seed under the old rule, every candidate traced (accepted or not, the
plan's propagation steps, the simulated steps and the process's CPU seconds so far). A stricter rule stops the same
sequence of candidates earlier, so the default rule's result is read off the trace where its rule stops it (its
CPU time too: both rules' times then come from the same run on the same loaded machine), and checked against a run
of the default rule itself (`planners.shorten.default_rule`, what `planar-lcp plan TASK --seed S --iterations N`
does): the same plan, candidates and simulated steps. Prints a markdown table, one row per run, and the medians.
`--trace FILE` writes the traces as JSON.
"""

import argparse
import json
import statistics
import time

from planners import TaskModel
from planners.plans import plan_task
from planners.shorten import default_rule, shorten

OLD = dict(max_candidates=4000, patience=1000)


def stop_on_trace(trace, rule):
    """Where `rule` (shorten's max_candidates, patience, max_sim_steps) stops the candidates of `trace` (rows: kind,
    accepted, plan steps, simulated steps, CPU s, after each candidate): (candidates, plan steps, simulated steps,
    CPU s, stopped by), checked before each candidate as `shorten` checks them."""
    n = rejected = sim = 0
    steps, cpu = None, 0.0
    for row in trace + [None]:
        if n >= rule["max_candidates"]:
            return n, steps, sim, cpu, "candidates"
        if rejected >= rule["patience"]:
            return n, steps, sim, cpu, "patience"
        if rule["max_sim_steps"] is not None and sim >= rule["max_sim_steps"]:
            return n, steps, sim, cpu, "effort"
        if row is None:
            return n, steps, sim, cpu, "the trace's end"
        kind, accepted, k, s, c = row
        n, steps, sim, cpu = n + 1, k, s, c
        rejected = 0 if accepted else rejected + 1


ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--tasks", nargs="+", default=["push_box", "push_t", "push_clutter", "tip_box"])
ap.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3, 4, 5])
ap.add_argument("--iterations", type=int, default=30000)
ap.add_argument("--trace", metavar="FILE", help="write the old rule's candidates, run by run, as JSON")
args = ap.parse_args()

runs = []
print("| task | seed | planner: iterations, simulated steps | first plan [s] | final plan [s], old / default "
      "| candidates, old / default | simulated steps, old / default | CPU [s], old / default | default stopped by |")
print("|---|---|---|---|---|---|---|---|---|")
for task in args.tasks:
    for seed in args.seeds:
        tm = TaskModel(task)
        data = plan_task(task, seed=seed, iterations=args.iterations, tm=tm, shorten=False)
        if not data["exact"]:
            print(f"| {task} | {seed} | {data['iterations']}, {data['sim_steps']} | no exact plan | | | | | |")
            continue
        dt = tm.task.step_duration
        replayed = tm.execute(data["start"], data["controls"], data["steps"])[1:]
        trace = []
        s0, c0 = tm.nsteps_total, time.process_time()
        old = shorten(tm, data["start"], data["controls"], data["steps"], seed, replayed=replayed, **OLD,
                      trace=lambda kind, accepted, s: trace.append(
                          [kind, bool(accepted), len(s.U), tm.nsteps_total - s0, round(time.process_time() - c0, 4)]))
        rule = default_rule(data["sim_steps"])
        n, k, sim, cpu, why = stop_on_trace(trace, rule)
        new = shorten(tm, data["start"], data["controls"], data["steps"], seed, replayed=replayed, **rule)
        # the trace's reading is the default rule's own result
        assert (n, k, sim, why) == (new["candidates"], int(new["steps"].sum()), new["sim_steps"],
                                    new["stopped_by"]), ((n, k, sim, why), new)
        run = dict(task=task, seed=seed, iterations=data["iterations"], planner_sim_steps=data["sim_steps"],
                   first=data["path_duration"], trace=trace, rule=rule,
                   old=dict(final=float(old["steps"].sum() * dt), candidates=old["candidates"],
                            sim_steps=old["sim_steps"], cpu=trace[-1][4] if trace else 0.0),
                   default=dict(final=float(k * dt), candidates=n, sim_steps=sim, cpu=cpu, stopped_by=why))
        runs.append(run)
        o, d = run["old"], run["default"]
        print(f"| {task} | {seed} | {data['iterations']}, {data['sim_steps']} | {data['path_duration']:.1f} | "
              f"{o['final']:.1f} / {d['final']:.1f} | {o['candidates']} / {d['candidates']} | {o['sim_steps']} / "
              f"{d['sim_steps']} | {o['cpu']:.1f} / {d['cpu']:.1f} | {why} |", flush=True)

print()
for task in args.tasks:
    rs = [r for r in runs if r["task"] == task]
    if rs:
        def med(rule, key):
            return statistics.median(r[rule][key] for r in rs)
        print(f"{task}: medians: first plan {statistics.median(r['first'] for r in rs):.1f} s; final "
              f"{med('old', 'final'):.1f} s / {med('default', 'final'):.1f} s; candidates "
              f"{med('old', 'candidates'):.0f} / {med('default', 'candidates'):.0f}; CPU {med('old', 'cpu'):.1f} s / "
              f"{med('default', 'cpu'):.1f} s")
tot = {rule: (sum(r[rule]["sim_steps"] for r in runs), sum(r[rule]["cpu"] for r in runs))
       for rule in ("old", "default")}
print(f"all {len(runs)} runs: simulated steps {tot['old'][0]} / {tot['default'][0]}, CPU {tot['old'][1]:.1f} s / "
      f"{tot['default'][1]:.1f} s; final plans {sum(r['old']['final'] for r in runs):.1f} s / "
      f"{sum(r['default']['final'] for r in runs):.1f} s in all")
if args.trace:
    with open(args.trace, "w") as f:
        json.dump(runs, f)
