"""One markdown table of several plan-bench outputs: each directory's summary.json, one row per (task, planner).

    python examples/bench_table.py docs/figures/planning/tasks/*
    python examples/bench_table.py docs/figures/planning/bench_*

Used for docs/planning.md's benchmark tables; the last line totals the runs, the exact ones and the exact plans that
replayed to their goal.
"""

import json
import sys
from pathlib import Path


def main(dirs):
    rows, runs, exact, replayed = [], 0, 0, 0
    for d in dirs:
        f = Path(d) / "summary.json"
        if not f.is_file():
            print(f"bench_table.py: error: {f}: no such file (a plan-bench output directory holds one)", file=sys.stderr)
            sys.exit(2)
        s = json.loads(f.read_text())
        budget = f"{s['time_limit']:g} s" if s.get("time_limit") else f"{s['iterations']} iterations"
        for r in s["summary"]:
            t, du = r["time_q1_med_q3"], r["duration_q1_med_q3"]
            ft = f"{t[1]:.2f} ({t[0]:.2f}-{t[2]:.2f})" if r["exact"] else "-"
            fd = f"{du[1]:.2f} ({du[0]:.2f}-{du[2]:.2f})" if r["exact"] else "-"
            # a summary written before issue 25 has no first_ duration: its plans were the planner's first plans
            d1 = r.get("first_duration_q1_med_q3", du)
            f1 = f"{d1[1]:.2f} ({d1[0]:.2f}-{d1[2]:.2f})" if r["exact"] else "-"
            slowest = max((x["solve_time"] for x in s["records"] if x["planner"] == r["planner"] and x["exact"]),
                          default=float("nan"))
            rows.append(f"| {s['task']} | {r['planner']} | {budget} | {r['exact']}/{r['runs']} | "
                        f"{r.get('replayed', '?')}/{r['exact']} | {ft} | {slowest:.2f} | {f1} | {fd} | "
                        f"{r['steps_per_second_median']:.0f} |")
            runs, exact = runs + r["runs"], exact + r["exact"]
            replayed += r.get("replayed", 0)
    print("| task | planner | budget | exact | replayed to the goal | time to first exact [s] median (q1-q3) | "
          "slowest [s] | first path duration [s] median (q1-q3) | final path duration [s] median (q1-q3) | "
          "sim steps/s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print(f"\nall: {exact}/{runs} runs exact ({100.0 * exact / max(runs, 1):.0f} %), {replayed}/{exact} exact plans "
          "replayed to their goal")


if __name__ == "__main__":
    main(sys.argv[1:])
