"""Kinodynamic planning of pushing and tipping with OMPL, our simulator as the forward model: the API the CLI calls.

    import planners
    task = planners.load_task("push_box")          # a shipped task, a task file, its TOML text or a dict
    p = planners.plan(task, iterations=3000, seed=1)
    p.exact, p.controls, p.durations, p.goal_report
    p.save("plan.json"); p.plot("plan.png")
    planners.load_plan("plan.json").replay()       # bit for bit the planner's states
    planners.load_plan("plan.json").replay("pymunk", closed_loop=True)   # with feedback (planners.PlanTracker)
    planners.refine(p)                             # a shorter plan by gradients, the goal held

A task is a scene file with a [task] table (docs/scene-format.md, "Task files"; docs/planning.md, "Plan your own
task"). Importing this package does not import ompl: `plan` does, when it is called.

With gymnasium installed (the `gym` extra), importing this package registers the environments `planar_lcp/PushT-v0`
and `planar_lcp/Task-v0` (planners/environments/, docs/gym.md) by name: `gymnasium.make` imports them, and without
gymnasium nothing is registered and the rest works as before.
"""

from planar_lcp.spec.task import DEFAULT_PLANNER, PLANNERS, Goal, Task, TaskError, load_task, shipped_tasks

from .plans import Plan, ShorteningInterrupted, load_plan, plan
from .refine import refine
from .tasks import TaskModel

__all__ = ["DEFAULT_PLANNER", "PLANNERS", "Goal", "Plan", "PlanTracker", "PushController", "PushTPolicy",
           "ShorteningInterrupted", "Task", "TaskError", "TaskModel", "load_plan", "load_task", "plan", "refine",
           "shipped_tasks"]

# the feedback controllers (docs/closed_loop.md), imported when first named: planners.PushTPolicy needs shapely
_LAZY = {"PlanTracker": "closed_loop", "PushController": "closed_loop", "PushTPolicy": "pusht"}


def __getattr__(name):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _register_envs():
    """Register the Gymnasium environments (entry points as strings: nothing is imported until `make`)."""
    try:
        import gymnasium
    except ImportError:
        return
    if "planar_lcp/PushT-v0" not in gymnasium.registry:
        gymnasium.register(id="planar_lcp/PushT-v0", entry_point="planners.environments.push_t:PushTEnv",
                           max_episode_steps=300, kwargs={"obs_type": "state"})
    if "planar_lcp/Task-v0" not in gymnasium.registry:
        # truncation is the environment's own (its time_limit in the task's step durations)
        gymnasium.register(id="planar_lcp/Task-v0", entry_point="planners.environments.task_env:TaskEnv")


_register_envs()
