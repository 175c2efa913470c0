"""One markdown table of several plan-bench outputs: each directory's summary.json, one row per (task, planner).

    python examples/measurements/bench_table.py docs/figures/planning/tasks/*
    python examples/measurements/bench_table.py docs/figures/planning/bench_*
    python examples/measurements/bench_table.py --shorter docs/figures/planning/shorter/bench_*

Used for docs/planning.md's benchmark tables; the last line totals the runs, the exact ones and the exact plans that
replayed to their goal. --shorter: the columns of "Shorter plans" (the first and the final plans' costs, the
shortening's time) instead of the budget, the slowest run and the simulated steps per second.
"""

import json
import statistics
import sys
from pathlib import Path


def q(v, fmt=".2f"):
    """A (q1, median, q3) triple as 'median (q1-q3)'."""
    return f"{v[1]:{fmt}} ({v[0]:{fmt}}-{v[2]:{fmt}})"


def shorter_row(s, r):
    """One row of the "Shorter plans" table: a summary's row r of summary.json s."""
    if not r["exact"]:
        return f"| {s['task']} | 0/{r['runs']} | - | - | - | - | - | - | - | - |"
    times = [x["shorten_time"] for x in s["records"] if x["planner"] == r["planner"] and x["exact"]]
    d1, d = r["first_duration_q1_med_q3"], r["duration_q1_med_q3"]
    return (f"| {s['task']} | {r['exact']}/{r['runs']} | {r.get('replayed', '?')}/{r['exact']} | "
            f"{q(r['time_q1_med_q3'])} | {q(d1)} | {q(d)} | {d[1] / d1[1]:.2f} | "
            f"{r['first_pusher_path_q1_med_q3'][1]:.3f}, {r['pusher_path_q1_med_q3'][1]:.3f} | "
            f"{r['first_object_path_q1_med_q3'][1]:.3f}, {r['object_path_q1_med_q3'][1]:.3f} | "
            f"{statistics.median(times):.1f} ({max(times):.1f}) |")


HEADER = ("| task | planner | budget | exact | replayed to the goal | time to first exact [s] median (q1-q3) | "
          "slowest [s] | first path duration [s] median (q1-q3) | final path duration [s] median (q1-q3) | "
          "sim steps/s |")
SHORTER_HEADER = ("| task | exact | replayed to the goal | time to first exact [s] median (q1-q3) | "
                  "first path duration [s] median (q1-q3) | final path duration [s] median (q1-q3) | "
                  "final / first (medians) | pusher path [m] first, final (medians) | "
                  "object path [m] first, final (medians) | shortening [s] median (slowest) |")


def main(dirs):
    shorter = "--shorter" in dirs
    dirs = [d for d in dirs if d != "--shorter"]
    rows, runs, exact, replayed = [], 0, 0, 0
    for d in dirs:
        f = Path(d) / "summary.json"
        if not f.is_file():
            print(f"bench_table.py: error: {f}: no such file (a plan-bench output directory holds one)", file=sys.stderr)
            sys.exit(2)
        s = json.loads(f.read_text())
        budget = f"{s['time_limit']:g} s" if s.get("time_limit") else f"{s['iterations']} iterations"
        for r in s["summary"]:
            runs, exact, replayed = runs + r["runs"], exact + r["exact"], replayed + r.get("replayed", 0)
            if shorter:
                rows.append(shorter_row(s, r))
                continue
            du = r["duration_q1_med_q3"]
            ft = q(r["time_q1_med_q3"]) if r["exact"] else "-"
            fd = q(du) if r["exact"] else "-"
            # a summary written by older versions has no first_ duration: its plans were the planner's first plans
            f1 = q(r.get("first_duration_q1_med_q3", du)) if r["exact"] else "-"
            slowest = max((x["solve_time"] for x in s["records"] if x["planner"] == r["planner"] and x["exact"]),
                          default=float("nan"))
            rows.append(f"| {s['task']} | {r['planner']} | {budget} | {r['exact']}/{r['runs']} | "
                        f"{r.get('replayed', '?')}/{r['exact']} | {ft} | {slowest:.2f} | {f1} | {fd} | "
                        f"{r['steps_per_second_median']:.0f} |")
    print(SHORTER_HEADER if shorter else HEADER)
    print("|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print(f"\nall: {exact}/{runs} runs exact ({100.0 * exact / max(runs, 1):.0f} %), {replayed}/{exact} exact plans "
          "replayed to their goal")


if __name__ == "__main__":
    main(sys.argv[1:])
