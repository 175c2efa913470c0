"""planners.refine: an exact plan's controls refined by gradients of the step's derivatives, the pusher's path
shorter, the plan still exact and replaying bit for bit (docs/planning.md, "Refining a plan")."""

import numpy as np
import pytest

pytest.importorskip("ompl")


def test_refine_shortens_the_pushers_path_and_keeps_the_plan_exact(tip_plan, tmp_path):
    import planners
    from planners.refine import pusher_path_length
    _, out = tip_plan
    plan = planners.load_plan(out / "plan.json")
    r = planners.refine(plan, iterations=2)
    info = r.data["refine"]
    assert info["objective"] == "pusher_path_length" and 1 <= info["accepted"] <= 2
    assert info["before"] == pytest.approx(pusher_path_length(plan.controls, plan.durations), rel=1e-12)
    assert info["after"] == pytest.approx(pusher_path_length(r.controls, r.durations), rel=1e-12)
    assert info["after"] < info["before"]
    # every gradient a rollout's derivatives over the plan's steps, most of them by the checked differences
    assert info["derivative_steps"] >= plan.steps.sum() and 0 <= info["dual_steps"] < info["derivative_steps"] / 2
    # the same steps and durations; every control within the task's bound
    np.testing.assert_array_equal(r.steps, plan.steps)
    assert np.max(np.abs(r.controls)) <= plan.task.control_max
    # exact: its replay (the planner's own forward model) holds the goal, and is its states bit for bit, also after
    # a round trip through its file
    rep = r.replay()
    assert rep["report"]["goal_holds"] and r.exact
    np.testing.assert_array_equal(rep["bound"], r.states)
    r.save(tmp_path / "refined.json")
    again = planners.load_plan(tmp_path / "refined.json").replay()
    np.testing.assert_array_equal(again["bound"], r.states)
    # the pusher's path as the replay measures it fell too
    assert r.data["pusher_path_length"] < plan.data["pusher_path_length"]


def test_refine_refuses_a_plan_that_does_not_reach_its_goal(tip_plan):
    import planners
    _, out = tip_plan
    plan = planners.load_plan(out / "plan.json")
    plan.data = dict(plan.data, exact=False)
    with pytest.raises(ValueError, match="not exact"):
        planners.refine(plan)


@pytest.mark.slow    # plans tip_box (5000 iterations) and refines it: about 15 s
def test_the_measurement_on_the_shipped_tasks_runs():
    """docs/planning.md's command, end to end on tip_box with one refinement step."""
    import subprocess
    import sys
    from pathlib import Path
    script = Path(__file__).resolve().parents[2] / "examples" / "measurements" / "refine_plans.py"
    r = subprocess.run([sys.executable, str(script), "--tasks", "tip_box", "--iterations", "1"], capture_output=True,
                       text=True, timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    row = next(line for line in r.stdout.splitlines() if line.startswith("| tip_box |"))
    before, after = (float(x) for x in row.split("|")[4:6])
    assert after < before
