"""A planning task of your own, written as TOML text, planned with OMPL on our simulator and replayed.

    python examples/own_task.py [--out plan.json]

A task is a scene with a [task] table (docs/scene-format.md, "Task files"): which body to move, where to, with which
pusher. Here a disk pusher slides a box 15 cm to the right and turns it by 30 degrees. An iteration budget (not a
time limit) and a seed make the plan the same on every machine.
"""

import argparse

import planners

TASK = """
name = "my_push"
description = "Slide a box 15 cm and turn it by 30 degrees"

[world]
plane = "horizontal"
friction = 0.3

[sim]
h = 0.02

[[bodies]]
name = "box"
type = "dynamic"
mass = 0.5
support_friction = 0.3
shapes = [ { type = "box", width = 0.08, height = 0.06 } ]

[[bodies]]
name = "pusher"
type = "kinematic"
position = [-0.07, 0.0]
shapes = [ { type = "disk", radius = 0.01 } ]

[task]
object = "box"
pusher = "pusher"
goal = { x = 0.15, y = 0.0, angle_deg = 30.0 }
"""

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", help="write the plan file here (planar-lcp replay reads it)")
args = parser.parse_args()

task = planners.load_task(TASK)
plan = planners.plan(task, iterations=10000, seed=2)
print(f"exact: {plan.exact}, {len(plan.controls)} controls, {sum(plan.durations):.2f} s of pushing")
replayed = plan.replay()                                         # our simulator again: the planner's states, exactly
print("the replay reaches the goal:", replayed["report"]["goal_holds"])
if args.out:
    plan.save(args.out)
    print("wrote", args.out)
