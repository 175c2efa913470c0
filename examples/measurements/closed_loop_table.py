"""The table of docs/closed_loop.md from the runs' summaries (`planar-lcp pusht-eval ... --out DIR`):

    python examples/measurements/closed_loop_table.py docs/figures/closed_loop/gym_pusht docs/figures/closed_loop/gym_pusht_500 \\
        docs/figures/closed_loop/ours_friction_045

One row per run: the environment and its world, the seeds, successes, the mean final coverage, the median actions of
the successes (and the most any took), and the policy's compute per action (thread CPU time: the median over episodes
of each episode's median, and the largest of any action).
"""

import csv
import json
import sys
from pathlib import Path


def row(folder):
    folder = Path(folder)
    s = json.loads((folder / "summary.json").read_text())
    with open(folder / "episodes.csv") as f:
        eps = list(csv.DictReader(f))
    most = max(int(e["actions"]) for e in eps if e["success"] == "True") if s["successes"] else None
    env = s["env"] + (f" {s['gym_pusht']}" if s.get("gym_pusht") else "")
    world = ", ".join(f"{k} {v:g}" for k, v in s["env_kwargs"].items()) or "as registered"
    return (f"| {env} | {world} | {s['world']} | {s['seeds'][0]}..{s['seeds'][1]} | {s['successes']}/{s['episodes']} "
            f"({100 * s['success_rate']:.1f} %) | {s['mean_final_coverage']:.3f} | "
            f"{s['median_actions_of_successes']:.0f} ({most}) | {s['compute_median_ms']:.2f} / "
            f"{s['compute_max_ms']:.1f} |")


def main(argv=None):
    folders = sys.argv[1:] if argv is None else argv
    print("| environment | its world | the policy's model | seeds | success | mean final coverage | actions to "
          "success: median (most) | compute per action: median / max (ms) |")
    print("|---|---|---|---|---|---|---|---|")
    for f in folders:
        print(row(f))


if __name__ == "__main__":
    main()
