"""Shorter plans (issue 25, planners/shorten.py): the shortcutting keeps plans exact, replays bit for bit, is
deterministic, and `--no-shorten` gives the planner's plan as it was before the issue, bit for bit.

The unit tests shorten the tip_box plan behind docs/planning.md's figure (made before issue 25 by `planar-lcp plan
tip_box --seed 7 --iterations 5000`), which needs no OMPL; the end-to-end tests run the commands."""

import json
import sqlite3

import numpy as np
import pytest

pytest.importorskip("shapely")

from cli_helpers import ROOT, run_cli  # noqa: E402

#: the plan made before issue 25: the golden of --no-shorten
TIP_DOC_PLAN = ROOT / "docs" / "figures" / "planning" / "tip_box" / "plan.json"
TIP_DOC_ARGS = ("plan", "tip_box", "--planner", "RRT", "--seed", "7", "--iterations", "5000", "--no-gif")


@pytest.fixture(scope="module")
def tip():
    """(TaskModel of tip_box, the docs' tip_box plan as a dict)."""
    from planners import TaskModel
    return TaskModel("tip_box"), json.loads(TIP_DOC_PLAN.read_text())


@pytest.fixture(scope="module")
def shortened(tip):
    from planners.shorten import shorten
    tm, plan = tip
    return shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=7)


def test_compress_is_the_inverse_of_per_step_within_the_task_durations():
    from planners.shorten import compress, per_step
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, (12, 2))
    k = rng.integers(1, 25, 12)                     # runs longer than max_steps = 10 are split
    U = per_step(u, k)
    c, s = compress(U, 1, 10)
    np.testing.assert_array_equal(per_step(c, s), U)
    assert s.min() >= 1 and s.max() <= 10 and s.sum() == k.sum()
    assert len(c) == sum(-(-int(n) // 10) for n in k)      # as few chunks as the bound allows
    c3, s3 = compress(per_step(u[:2], [7, 3]), 3, 4)       # 7 = 4 + 3; 3
    assert s3.tolist() == [4, 3, 3]
    assert compress(per_step(u[:2], [5, 2]), 3, 4) is None  # 5 steps cannot be held as 3..4-step controls


def test_a_control_split_at_a_propagation_step_replays_bit_for_bit(tip):
    """The premise of cutting stretches anywhere: each propagation step is its own rollout from the full state."""
    tm, plan = tip
    u, k = np.asarray(plan["controls"]), np.asarray(plan["steps"])
    i = int(np.argmax(k))
    assert k[i] >= 2
    split_u = np.concatenate([u[:i], u[i:i + 1], u[i:]])
    split_k = np.concatenate([k[:i], [1, k[i] - 1], k[i + 1:]])
    _, dense, ok = tm.execute(plan["start"], u, k)
    _, dense2, ok2 = tm.execute(plan["start"], split_u, split_k)
    assert ok and ok2
    np.testing.assert_array_equal(dense, dense2)


def test_shortening_keeps_the_plan_exact_and_valid_and_replays_bit_for_bit_from_the_start(tip, shortened):
    from planners import TaskModel
    tm, plan = tip
    r = shortened
    assert r["exact_input"] and r["accepted"] > 0
    assert r["steps"].sum() < np.sum(plan["steps"]), (r["steps"].sum(), np.sum(plan["steps"]))
    assert r["steps"].min() >= tm.task.min_steps and r["steps"].max() <= tm.task.max_steps
    assert np.abs(r["controls"]).max() <= tm.task.control_max
    # each candidate was simulated from its change point only: the whole plan from the start, in a fresh model (as
    # replay does), gives the same states bit for bit
    fresh = TaskModel(plan["task_document"])
    _, dense, ok = fresh.execute(plan["start"], r["controls"], r["steps"])
    assert ok
    np.testing.assert_array_equal(dense, r["dense"])
    assert all(fresh.admissible(x) for x in dense)          # every propagation step, as the planner checks
    assert fresh.goal_distance(dense[-1]) <= 1.0
    # and the first plan did reach the goal too (the shortening judged an exact plan)
    _, d0, _ = fresh.execute(plan["start"], plan["controls"], plan["steps"])
    assert fresh.goal_distance(d0[-1]) <= 1.0


def test_shortening_is_deterministic_for_a_seed(tip, shortened):
    from planners.shorten import shorten
    tm, plan = tip
    again = shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=7)
    np.testing.assert_array_equal(again["controls"], shortened["controls"])
    np.testing.assert_array_equal(again["steps"], shortened["steps"])
    assert again["candidates"] == shortened["candidates"] and again["accepted"] == shortened["accepted"]


def test_a_plan_that_misses_the_goal_is_returned_unchanged(tip):
    from planners.shorten import shorten
    tm, plan = tip
    n = len(plan["steps"]) // 2
    r = shorten(tm, plan["start"], plan["controls"][:n], plan["steps"][:n], seed=7)
    assert not r["exact_input"] and r["candidates"] == 0
    assert r["controls"].tolist() == plan["controls"][:n] and r["steps"].tolist() == plan["steps"][:n]


def test_the_budget_bounds_the_shortening(tip):
    from planners.shorten import shorten
    tm, plan = tip
    r = shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=7, deadline=0.0)   # long past
    assert r["candidates"] == 0 and r["stopped_by_deadline"]
    r = shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=7, max_candidates=5)
    assert r["candidates"] == 5 and not r["stopped_by_deadline"]


def test_path_lengths_are_the_polylines_through_the_propagation_steps(tip):
    """A free move of the finger straight up at 0.1 m/s for 0.5 s: a pusher path of 0.05 m, the box at rest."""
    from planners.shorten import costs
    tm, plan = tip
    _, dense, ok = tm.execute(plan["start"], [[0.0, 0.1]], [5])
    assert ok
    c = costs(tm, [5], dense)
    assert c["path_duration"] == pytest.approx(0.5, abs=1e-15)
    assert c["pusher_path_length"] == pytest.approx(0.05, rel=1e-12)
    assert c["object_path_length"] < 1e-9


# ---- end to end ----------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def tip_plans(tmp_path_factory):
    """`plan` of the docs' tip_box seed with and without --no-shorten: {"shortened"|"first": (process, plan dict)}."""
    pytest.importorskip("ompl")
    out = {}
    for name, extra in (("shortened", ()), ("first", ("--no-shorten",))):
        d = tmp_path_factory.mktemp(name)
        r = run_cli(*TIP_DOC_ARGS, *extra, "--out", d)
        assert r.returncode == 0, r.stdout + r.stderr
        out[name] = (r, json.loads((d / "plan.json").read_text()), d)
    return out


def test_no_shorten_gives_the_plan_made_before_shortening_bit_for_bit(tip_plans):
    _, first, _ = tip_plans["first"]
    before = json.loads(TIP_DOC_PLAN.read_text())
    for key in ("controls", "steps", "durations", "states", "path_duration", "iterations", "sim_steps", "goal",
                "start"):
        assert first[key] == before[key], key
    assert first["shorten"]["enabled"] is False and "first_plan" not in first
    assert first["first_path_duration"] == first["path_duration"]


def test_plan_shortens_by_default_and_records_first_and_final_costs(tip_plans, tmp_path):
    r, plan, d = tip_plans["shortened"]
    _, first, _ = tip_plans["first"]
    # the planner's search is the same: the first exact plan is the --no-shorten plan, found after as many iterations
    assert plan["first_plan"] == dict(controls=first["controls"], steps=first["steps"])
    assert (plan["iterations"], plan["sim_steps"]) == (first["iterations"], first["sim_steps"])
    for k in ("path_duration", "pusher_path_length", "object_path_length"):
        assert plan[f"first_{k}"] == first[k], k
    assert plan["path_duration"] < plan["first_path_duration"] and plan["pusher_path_length"] > 0
    assert plan["path_duration"] == pytest.approx(sum(plan["durations"]), abs=1e-9)
    assert plan["shorten"]["enabled"] and plan["shorten"]["accepted"] > 0 and plan["goal"]["goal_holds"]
    assert "first plan     " in r.stdout and "shortened      " in r.stdout, r.stdout
    rr = run_cli("replay", d / "plan.json", "--out", tmp_path)
    assert rr.returncode == 0 and "goal_holds       True" in rr.stdout, rr.stdout + rr.stderr
    from planners import load_plan
    res = load_plan(d / "plan.json").replay()
    np.testing.assert_array_equal(res["bound"], np.asarray(plan["states"]))


def test_plan_bench_reports_first_and_final_costs(tmp_path):
    pytest.importorskip("ompl")
    pytest.importorskip("distributed")
    out = tmp_path / "b"
    r = run_cli("plan-bench", "tip_box", "--planners", "RRT", "--runs", "2", "--iterations", "2000", "--jobs", "1",
                "--out", out)
    assert r.returncode == 0, r.stdout + r.stderr
    md = (out / "summary.md").read_text()
    for col in ("time to first exact solution [s]", "first path duration [s] median (q1-q3)",
                "final path duration [s] median (q1-q3)", "pusher path [m] first, final", "object path [m] first, final"):
        assert col in md, col
    s = json.loads((out / "summary.json").read_text())
    row = s["summary"][0]
    assert row["exact"] == 2 and row["replayed"] == 2
    assert row["duration_q1_med_q3"][1] < row["first_duration_q1_med_q3"][1]
    for rec in s["records"]:
        assert rec["path_duration"] < rec["first_path_duration"] and rec["shorten_time"] > 0
        assert rec["pusher_path_length"] > 0 and rec["first_object_path_length"] > 0
    with sqlite3.connect(out / "tip_box.db") as con:
        cols = [c[1] for c in con.execute("pragma table_info(runs)")]
        got = con.execute("select solution_length, first_solution_length from runs order by id").fetchall()
    assert "first_pusher_path_length" in cols and "object_path_length" in cols
    assert sorted(got) == sorted((rec["path_duration"], rec["first_path_duration"]) for rec in s["records"])
