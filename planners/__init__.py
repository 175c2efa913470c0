"""Kinodynamic planning of pushing and tipping with OMPL, our simulator as the forward model: the API the CLI calls.

    import planners
    task = planners.load_task("push_box")          # a shipped task, a task file, its TOML text or a dict
    p = planners.plan(task, iterations=3000, seed=1)
    p.exact, p.controls, p.durations, p.goal_report
    p.save("plan.json"); p.plot("plan.png")
    planners.load_plan("plan.json").replay()       # bit for bit the planner's states

A task is a scene file with a [task] table (docs/scene-format.md, "Task files"; docs/planning.md, "Plan your own
task"). Importing this package does not import ompl: `plan` does, when it is called.
"""

from planar_lcp.spec.task import DEFAULT_PLANNER, PLANNERS, Goal, Task, TaskError, load_task, shipped_tasks

from .plans import Plan, load_plan, plan
from .tasks import TaskModel

__all__ = ["DEFAULT_PLANNER", "PLANNERS", "Goal", "Plan", "Task", "TaskError", "TaskModel", "load_plan",
           "load_task", "plan", "shipped_tasks"]
