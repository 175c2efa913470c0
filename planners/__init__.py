"""Kinodynamic planning of pushing and tipping with OMPL, our simulator as the forward model: the API the CLI calls.

    import planners
    task = planners.load_task("push_box")          # a shipped task, a task file, its TOML text or a dict
    p = planners.plan(task, iterations=3000, seed=1)
    p.exact, p.controls, p.durations, p.goal_report
    p.save("plan.json"); p.plot("plan.png")
    planners.load_plan("plan.json").replay()       # bit for bit the planner's states

A task is a scene file with a [task] table (docs/scene-format.md, "Task files"; docs/planning.md, "Plan your own
task"). Importing this package does not import ompl: `plan` does, when it is called.

With gymnasium installed (the `gym` extra), importing this package registers the environments `planar_lcp/PushT-v0`
and `planar_lcp/Task-v0` (planners/envs.py, docs/gym.md) by name: `gymnasium.make` imports them, and without
gymnasium nothing is registered and the rest works as before.
"""

from planar_lcp.spec.task import DEFAULT_PLANNER, PLANNERS, Goal, Task, TaskError, load_task, shipped_tasks

from .plans import Plan, ShorteningInterrupted, load_plan, plan
from .tasks import TaskModel

__all__ = ["DEFAULT_PLANNER", "PLANNERS", "Goal", "Plan", "ShorteningInterrupted", "Task", "TaskError", "TaskModel",
           "load_plan", "load_task", "plan", "shipped_tasks"]


def _register_envs():
    """Register the Gymnasium environments (entry points as strings: nothing is imported until `make`)."""
    try:
        import gymnasium
    except ImportError:
        return
    if "planar_lcp/PushT-v0" not in gymnasium.registry:
        gymnasium.register(id="planar_lcp/PushT-v0", entry_point="planners.envs:PushTEnv", max_episode_steps=300,
                           kwargs={"obs_type": "state"})
    if "planar_lcp/Task-v0" not in gymnasium.registry:
        # truncation is the environment's own (its time_limit in the task's step durations)
        gymnasium.register(id="planar_lcp/Task-v0", entry_point="planners.envs:TaskEnv")


_register_envs()
