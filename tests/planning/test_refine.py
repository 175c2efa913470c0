"""planners.refine: an exact plan's controls refined by gradients of the step's derivatives, the plan shorter or the
pusher's path shorter, the plan still exact and replaying bit for bit (docs/planning.md, "Refining a plan")."""

import numpy as np
import pytest

pytest.importorskip("ompl")


def test_refine_shortens_the_pushers_path_and_keeps_the_plan_exact(tip_plan, tmp_path):
    import planners
    from planners.refine import pusher_path_length
    _, out = tip_plan
    plan = planners.load_plan(out / "plan.json")
    r = planners.refine(plan, iterations=2, objective="pusher_path_length")
    info = r.data["refine"]
    assert info["objective"] == "pusher_path_length" and 1 <= info["accepted"] <= 2
    assert info["before"] == pytest.approx(pusher_path_length(plan.controls, plan.durations), rel=1e-12)
    assert info["after"] == pytest.approx(pusher_path_length(r.controls, r.durations), rel=1e-12)
    assert info["after"] < info["before"]
    # every gradient a rollout's derivatives over the plan's steps, most of them by the checked differences, the
    # others by the one-sided differences (a switch at the state) before the dual numbers
    assert info["derivative_steps"] >= plan.steps.sum()
    assert 0 <= info["dual_steps"] <= info["one_sided_steps"] + info["dual_steps"] < info["derivative_steps"] / 2
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


@pytest.fixture(scope="module")
def push_box_plan():
    """push_box planned as docs/planning.md plans it (seed 5, 15000 iterations, shortened): about 5 s."""
    import planners
    plan = planners.plan("push_box", iterations=15000, seed=5)
    assert plan.exact
    return plan


def test_refine_shortens_a_push_and_keeps_the_plan_exact(push_box_plan, tmp_path):
    """Two propagation steps fewer, each pulled back into the goal by Gauss-Newton steps on the controls."""
    import planners
    plan = push_box_plan
    t = plan.task
    r = planners.refine(plan, iterations=2)
    info = r.data["refine"]
    assert info["objective"] == "path_duration" and info["accepted"] == 2 and info["stopped_by"] == "iterations"
    assert info["before"] == pytest.approx(plan.steps.sum() * t.step_duration, rel=1e-12)
    assert info["after"] == pytest.approx(r.steps.sum() * t.step_duration, rel=1e-12)
    assert r.steps.sum() == plan.steps.sum() - 2
    assert r.data["path_duration"] == pytest.approx(info["after"], rel=1e-12)
    assert r.data["path_duration"] < plan.data["path_duration"]
    np.testing.assert_allclose(r.durations, r.steps * t.step_duration, rtol=1e-12)
    # every segment within the task's control durations and every control within its bound
    assert np.all((r.steps >= t.min_steps) & (r.steps <= t.max_steps))
    assert np.max(np.abs(r.controls)) <= t.control_max
    assert info["derivative_steps"] > 0 and info["replays"] >= info["accepted"]
    rep = r.replay()
    assert rep["report"]["goal_holds"] and r.exact
    np.testing.assert_array_equal(rep["bound"], r.states)
    r.save(tmp_path / "refined.json")
    again = planners.load_plan(tmp_path / "refined.json")
    np.testing.assert_array_equal(again.replay()["bound"], r.states)
    np.testing.assert_array_equal(again.steps, r.steps)


def test_a_time_limit_stops_the_refinement_with_the_plan_so_far(push_box_plan):
    import planners
    for objective in ("path_duration", "pusher_path_length"):
        r = planners.refine(push_box_plan, objective=objective, time_limit=0.0)
        info = r.data["refine"]
        assert info["stopped_by"] == "time_limit" and info["accepted"] == 0 and info["derivative_steps"] == 0
        np.testing.assert_array_equal(r.controls, push_box_plan.controls)
        np.testing.assert_array_equal(r.steps, push_box_plan.steps)


def test_a_failed_derivatives_run_gives_up_the_candidate_not_the_refinement(push_box_plan, monkeypatch):
    """The derivatives' steps are cold, the replay's warm-started: where a cold step of the run fails
    (rollout_derivatives' SimulationError), that candidate has no derivatives and the refinement goes on without it
    (the duration: no step pulled back, the plan as it was; the pusher's path: it stops, saying why)."""
    import importlib

    import planners
    from planar_lcp.sim import SimulationError
    refine_module = importlib.import_module("planners.refine")     # the module (planners.refine is the function)

    def failing(*args):
        raise SimulationError("rollout_derivatives: step 3 (t = 0.03 s) failed: no certified LCP answer")

    monkeypatch.setattr(refine_module, "object_jacobian", failing)
    r = planners.refine(push_box_plan, objective="pusher_path_length")
    assert r.data["refine"]["stopped_by"] == "rollout_derivatives: step 3 (t = 0.03 s) failed: no certified LCP answer"
    np.testing.assert_array_equal(r.controls, push_box_plan.controls)
    r = planners.refine(push_box_plan, iterations=1)
    assert r.data["refine"]["derivative_steps"] == 0
    assert r.steps.sum() <= push_box_plan.steps.sum() and r.replay()["report"]["goal_holds"]


def test_a_plan_that_gives_up_no_step_comes_back_as_it_was(tip_plan):
    """tip_box's tip is all or nothing, its box at rest at the end: no step fewer is pulled back into the goal, and
    the plan is returned unchanged, with why."""
    import planners
    _, out = tip_plan
    plan = planners.load_plan(out / "plan.json")
    r = planners.refine(plan)
    info = r.data["refine"]
    assert info["accepted"] == 0 and info["stopped_by"] == "no step can be dropped"
    assert info["tried"] == len(plan.steps) and info["after"] == info["before"]
    np.testing.assert_array_equal(r.controls, plan.controls)
    np.testing.assert_array_equal(r.steps, plan.steps)
    np.testing.assert_array_equal(r.states, plan.states)


def test_one_step_fewer_keeps_the_tasks_fewest_steps():
    """A segment above the task's fewest steps gives up one; one at the fewest is dropped whole; a plan of one step
    gives up nothing."""
    from types import SimpleNamespace

    from planners.refine import _one_step_fewer
    tm = SimpleNamespace(task=SimpleNamespace(min_steps=2))
    U = np.array([[0.1, 0.0], [0.0, 0.1], [0.1, 0.1]])
    k = np.array([3, 2, 4])
    c, s = _one_step_fewer(tm, U, k, 0)
    np.testing.assert_array_equal(s, [2, 2, 4])
    np.testing.assert_array_equal(c, U)
    c, s = _one_step_fewer(tm, U, k, 1)
    np.testing.assert_array_equal(s, [3, 4])
    np.testing.assert_array_equal(c, U[[0, 2]])
    np.testing.assert_array_equal(k, [3, 2, 4])     # the caller's steps untouched
    assert _one_step_fewer(SimpleNamespace(task=SimpleNamespace(min_steps=1)), U[:1], np.array([1]), 0) is None
    assert _one_step_fewer(tm, U[:1], np.array([2]), 0) is None


def test_refine_names_a_bad_objective(tip_plan):
    import planners
    _, out = tip_plan
    plan = planners.load_plan(out / "plan.json")
    with pytest.raises(ValueError, match="objective must be one of path_duration, pusher_path_length, got 'effort'"):
        planners.refine(plan, objective="effort")
    with pytest.raises(ValueError, match="iterations must be >= 0 or None, got -1"):
        planners.refine(plan, iterations=-1)


def test_refine_refuses_a_plan_that_does_not_reach_its_goal(tip_plan):
    import planners
    _, out = tip_plan
    plan = planners.load_plan(out / "plan.json")
    plan.data = dict(plan.data, exact=False)
    with pytest.raises(ValueError, match="not exact"):
        planners.refine(plan)


@pytest.mark.slow    # plans push_box and tip_box and refines each by both objectives, one step kept at most: ~10 s
def test_the_measurement_on_the_shipped_tasks_runs():
    """docs/planning.md's command, end to end on push_box and tip_box with one refinement step: push_box one
    propagation step shorter, tip_box's pusher path shorter."""
    import subprocess
    import sys
    from pathlib import Path
    script = Path(__file__).resolve().parents[2] / "examples" / "measurements" / "refine_plans.py"
    r = subprocess.run([sys.executable, str(script), "--tasks", "push_box", "tip_box", "--iterations", "1"],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    duration, path = r.stdout.split("objective pusher_path_length")
    assert "objective path_duration" in duration

    def cells(table, task):
        return next(line for line in table.splitlines() if line.startswith(f"| {task} |")).split("|")

    row = cells(duration, "push_box")
    before, after = (float(x) for x in row[4:6])
    assert after == pytest.approx(before - 0.1, abs=1e-9)      # one propagation step (0.1 s) fewer
    assert row[10].strip().startswith("1 / ")
    row = cells(path, "tip_box")
    before, after = (float(x) for x in row[4:6])
    assert after < before


def test_the_measurement_names_a_bad_flag():
    import subprocess
    import sys
    from pathlib import Path
    script = Path(__file__).resolve().parents[2] / "examples" / "measurements" / "refine_plans.py"
    r = subprocess.run([sys.executable, str(script), "--iterations", "-1"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and "--iterations must be >= 0, got -1" in r.stderr and "Traceback" not in r.stderr
