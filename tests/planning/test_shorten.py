"""Shorter plans (planners/shorten.py): the shortcutting keeps plans exact, replays bit for bit, is
deterministic, and `--no-shorten` gives the planner's plan as it was before shortening, bit for bit.

The unit tests shorten the tip_box plan behind docs/planning.md's figure (made before plans were shortened, by
`planar-lcp plan tip_box --seed 7 --iterations 5000`), which needs no OMPL; the end-to-end tests run the commands."""

import json
import sqlite3

import numpy as np
import pytest

pytest.importorskip("shapely")

from cli_helpers import ROOT, run_cli  # noqa: E402

#: the plan made before plans were shortened: the golden of --no-shorten
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
    assert r["candidates"] == 0 and r["stopped_by_deadline"] and r["stopped_by"] == "deadline"
    r = shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=7, max_candidates=5)
    assert r["candidates"] == 5 and not r["stopped_by_deadline"] and r["stopped_by"] == "candidates"


def test_the_default_rule_stops_by_its_patience_well_before_its_budget(tip):
    """`plan`'s default rule on the docs' tip_box plan: it stops because `patience` candidates in a row were
    rejected (counted: the trace's last `patience` candidates, none accepted, after an accepted one), well inside
    its bounds on candidates and simulated steps; the same seed with the rule of before (4000 candidates, 1000 in
    a row) draws the same candidates and goes on after them."""
    from planners.shorten import default_rule, shorten
    tm, plan = tip
    rule = default_rule(plan["sim_steps"])
    seen, before = [], []
    r = shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=7,
                trace=lambda kind, accepted, s: seen.append((kind, accepted, len(s.U))), **rule)
    assert r["stopped_by"] == "patience", r["stopped_by"]
    P = rule["patience"]
    assert len(seen) == r["candidates"] and not any(a for _, a, _ in seen[-P:]) and seen[-P - 1][1]
    assert r["candidates"] < rule["max_candidates"] / 2 and r["sim_steps"] < rule["max_sim_steps"] / 2, r
    old = shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=7, max_candidates=4000, patience=1000,
                  trace=lambda kind, accepted, s: before.append((kind, accepted, len(s.U))))
    assert before[:len(seen)] == seen and old["candidates"] > r["candidates"]
    assert old["steps"].sum() <= r["steps"].sum()


def test_the_default_rule_bounds_the_simulated_steps_by_the_planner_s():
    """The effort bound: EFFORT_SHARE of the steps the planner simulated to find the plan, at least EFFORT_MIN."""
    from planners.shorten import EFFORT_MIN, EFFORT_SHARE, MAX_CANDIDATES, PATIENCE, default_rule
    assert default_rule(0) == dict(max_candidates=MAX_CANDIDATES, patience=PATIENCE, max_sim_steps=EFFORT_MIN)
    big = int(10 * EFFORT_MIN / EFFORT_SHARE)
    assert default_rule(big)["max_sim_steps"] == int(EFFORT_SHARE * big) > EFFORT_MIN


def test_the_effort_bound_stops_the_shortening_after_that_many_simulated_steps(tip):
    from planners.shorten import shorten
    tm, plan = tip
    r = shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=7, max_sim_steps=3000, patience=None)
    assert r["stopped_by"] == "effort" and r["sim_steps"] >= 3000 and r["candidates"] > 0
    # it stops at the first check past the bound: the last candidate simulated at most the plan's steps (and the
    # rest of it) once more
    assert r["sim_steps"] < 3000 + 3 * np.sum(plan["steps"]) * tm.steps_per_prop, r["sim_steps"]


def test_stop_ends_the_shortening_at_once_with_an_exact_plan(tip):
    """What Ctrl-C does (plan_task's flag): `stop` is read before each candidate; the plan returned is the best so
    far, still exact."""
    from planners.shorten import shorten
    tm, plan = tip
    calls = []
    r = shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=7,
                stop=lambda: calls.append(1) or len(calls) > 40)
    assert r["stopped_by"] == "interrupted" and 0 < r["candidates"] <= 40
    _, dense, ok = tm.execute(plan["start"], r["controls"], r["steps"])
    assert ok and tm.goal_distance(dense[-1]) <= 1.0 and r["steps"].sum() <= np.sum(plan["steps"])


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


def test_the_default_plan_stops_shortening_by_its_patience(tip_plans):
    """The shortening of `plan` under the default rule ends by its patience, far inside its candidate and
    simulated-step bounds, and the "shortened" line says so."""
    r, plan, _ = tip_plans["shortened"]
    sh = plan["shorten"]
    assert sh["status"] == "done" and sh["stopped_by"] == "patience", sh
    assert sh["candidates"] < sh["max_candidates"] / 2 and sh["sim_steps"] < sh["max_sim_steps"], sh
    assert f"(stopped by its patience: {sh['patience']} rejected in a row)" in r.stdout, r.stdout
    assert sh["shorten_time"] is None and sh["cpu_time"] > 0


@pytest.mark.parametrize("value, expected", [
    ("-1", "must be a number of seconds in [0, 86400], got '-1'"),
    ("nan", "must be a number of seconds in [0, 86400], got 'nan'"),
    ("inf", "must be a number of seconds in [0, 86400], got 'inf'"),
    ("1e6", "must be a number of seconds in [0, 86400], got '1e6'"),
    ("soon", "must be a number of seconds, got 'soon'"),
])
def test_shorten_time_is_checked_before_any_work(tmp_path, value, expected):
    out = tmp_path / "out"
    r = run_cli("plan", "tip_box", "--iterations", "400", "--shorten-time", value, "--out", out, timeout=120)
    assert r.returncode == 2, r.stdout + r.stderr
    assert r.stderr == f"planar-lcp plan: error: argument --shorten-time: {expected}\n", r.stderr
    assert r.stdout == "" and not out.exists()


def test_shorten_time_is_refused_with_no_shorten(tmp_path):
    out = tmp_path / "out"
    r = run_cli("plan", "tip_box", "--iterations", "400", "--shorten-time", "5", "--no-shorten", "--out", out,
                timeout=120)
    assert r.returncode == 2, r.stdout + r.stderr
    assert r.stderr == ("planar-lcp plan: error: --shorten-time sets how long the shortening runs: not with "
                        "--no-shorten, got --shorten-time 5\n"), r.stderr
    assert r.stdout == "" and not out.exists()


def test_the_shortened_line_says_when_the_plan_was_only_truncated(tmp_path):
    """--shorten-time 0: no candidate, but a plan whose goal holds before its end is still cut there; the
    "shortened" line says it was only truncated (tip_box seed 1: the goal holds 2 s before the plan ends)."""
    pytest.importorskip("ompl")
    out = tmp_path / "out"
    r = run_cli("plan", "tip_box", "--planner", "RRT", "--iterations", "400", "--seed", "1", "--no-gif",
                "--shorten-time", "0", "--out", out)
    assert r.returncode == 0, r.stdout + r.stderr
    plan = json.loads((out / "plan.json").read_text())
    sh = plan["shorten"]
    assert sh["truncated"] and sh["candidates"] == 0 and sh["stopped_by"] == "shorten_time", sh
    assert plan["path_duration"] < plan["first_path_duration"] and plan["goal"]["goal_holds"]
    line = next(x for x in r.stdout.splitlines() if x.startswith("shortened      "))
    assert line.startswith("shortened      0 of 0 candidates accepted in ") and line.endswith(
        "; only truncated: cut where the goal first holds, no candidate accepted"), line
    assert "(stopped after --shorten-time 0 s)" in line, line


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


# ---- the push primitive (a local re-plan of the object's path) -----------------------------------------------------

LONE_BOX = """
name = "lone_box"
[world]
plane = "horizontal"
support_gravity = 9.81
friction = 0.3
[sim]
h = 0.02
[[bodies]]
name = "box"
type = "dynamic"
mass = 0.5
support_friction = 0.3
shapes = [ { type = "box", width = 0.1, height = 0.1 } ]
[[bodies]]
name = "pusher"
type = "kinematic"
position = [-0.08, 0.0]
shapes = [ { type = "disk", radius = 0.015 } ]
[task]
object = "box"
pusher = "pusher"
control_max = 0.15
goal = { x = GX, y = GY, angle_deg = GA }
"""


def _lone_push(gx, gy, ga_deg, first=0):
    """The push primitive from a lone box at rest at the origin (the pusher 3 cm behind it) to the goal (gx, gy,
    ga_deg), with mid-range parameters: (TaskModel, controls, states, whole)."""
    from planners import TaskModel
    from planners.shorten import Shortener
    tm = TaskModel(LONE_BOX.replace("GX", str(gx)).replace("GY", str(gy)).replace("GA", str(ga_deg)))
    x0 = tm.initial_state()
    s = Shortener(tm, x0, np.zeros((12, 2)), [10] * 12)      # a plan that waits 12 s: room for the push
    U, S, whole = s.push(0, len(s.U), 0.03, 0.75, 0.8, 0, first)
    return tm, U, S, whole


@pytest.mark.parametrize("gx, gy", [(0.15, 0.0), (0.0, -0.12)])
def test_the_push_primitive_moves_a_lone_box_straight_along_a_face_normal(gx, gy):
    """Oracle: a target straight ahead of a face is one push through the middle of that face; the box's centre of
    mass goes straight (its path no longer than the distance, up to the stop and the slide after it, and at most
    a few mm off the line) without turning, and ends within the goal's tolerances, at rest."""
    tm, U, S, whole = _lone_push(gx, gy, 0.0)
    assert whole and tm.goal_distance(S[-1]) <= 1.0
    assert np.abs(U).max() <= tm.task.control_max
    dist = np.hypot(gx, gy)
    path = np.hypot(*np.diff(S[:, 0:2], axis=0).T).sum()
    assert dist - tm.task.goal.position_tol <= path <= dist + 0.01, (path, dist)
    e = np.array([gx, gy]) / dist
    off_line = np.abs(S[:, 0:2] @ np.array([-e[1], e[0]]))
    assert off_line.max() < 0.003, off_line.max()
    assert np.abs(S[:, 2]).max() < tm.task.goal.angle_tol
    assert np.hypot(S[-1, 3], S[-1, 4]) <= tm.task.goal.speed_tol


def test_the_push_primitive_moves_a_box_to_a_diagonal_target_as_a_rook():
    """Oracle: a point pusher moves a box without turning it only by pushes through a face's middle (within the
    contact's friction cone about the face's normal, 17 deg for mu = 0.3), so a diagonal target is two legs along
    the box's axes: the centre of mass's path is |dx| + |dy| (up to the stops and slides), not the straight
    distance; one order of the legs passes the corner (gx, 0), the other (0, gy); the box ends at the goal."""
    gx, gy = 0.12, 0.09
    corners = []
    for first in (0, 1):
        tm, U, S, whole = _lone_push(gx, gy, 0.0, first)
        assert whole and tm.goal_distance(S[-1]) <= 1.0
        assert np.abs(U).max() <= tm.task.control_max
        path = np.hypot(*np.diff(S[:, 0:2], axis=0).T).sum()
        assert abs(path - (gx + gy)) < 0.01, path
        near = [np.min(np.hypot(S[:, 0] - gx, S[:, 1])), np.min(np.hypot(S[:, 0], S[:, 1] - gy))]
        assert min(near) < 0.005 and max(near) > 0.05, near
        corners.append(int(np.argmin(near)))
        assert np.abs(S[:, 2]).max() < tm.task.goal.angle_tol
    assert sorted(corners) == [0, 1]


def test_the_push_primitive_pushes_a_disk_straight_to_a_position_goal():
    """Oracle: a disk has no face to hold (and a goal without an angle): one straight push along the line from its
    centre to the goal, its path the straight distance (0.15 m here), whatever the gains."""
    from planners import TaskModel
    from planners.shorten import Shortener
    disk = LONE_BOX.replace('{ type = "box", width = 0.1, height = 0.1 }', '{ type = "disk", radius = 0.035 }')
    tm = TaskModel(disk.replace("goal = { x = GX, y = GY, angle_deg = GA }", "goal = { x = 0.12, y = 0.09 }"))
    s = Shortener(tm, tm.initial_state(), np.zeros((12, 2)), [10] * 12)
    assert s.can_push and tm.goal_com is None
    for k_angle, lateral_gain, speed, side, first in ((0.03, 0.75, 0.8, 0, 0), (0.01, 0.5, 0.6, 1, 1)):
        U, S, whole = s.push(0, len(s.U), k_angle, lateral_gain, speed, side, first)
        assert whole and tm.goal_distance(S[-1]) <= 1.0
        assert np.abs(U).max() <= tm.task.control_max
        path = np.hypot(*np.diff(S[:, 0:2], axis=0).T).sum()
        assert abs(path - 0.15) < 0.002, path
        off_line = np.abs(S[:, 0:2] @ np.array([-0.09, 0.12]) / 0.15)
        assert off_line.max() < 0.002, off_line.max()


def test_a_push_being_built_stops_at_the_deadline():
    """Under --time the shortening's deadline stops a push candidate while it is built (it simulates up to as many
    steps as it replaces): past the deadline it is rejected without a step; without one, the same push is built."""
    from planners import TaskModel
    from planners.shorten import Shortener
    tm = TaskModel(LONE_BOX.replace("GX", "0.15").replace("GY", "0.0").replace("GA", "0.0"))
    s = Shortener(tm, tm.initial_state(), np.zeros((12, 2)), [10] * 12)
    s.deadline = 0.0                                          # long past
    U, S, whole = s.push(0, len(s.U), 0.03, 0.75, 0.8, 0, 0)
    assert not whole and len(U) == 0 and len(S) == 1
    s.deadline = None
    U, S, whole = s.push(0, len(s.U), 0.03, 0.75, 0.8, 0, 0)
    assert whole and len(U) > 0


def test_the_push_primitive_turns_the_box_to_the_goal_angle():
    """A goal turned 40 deg: the primitive first pushes a face off its middle (the torque of the offset push turns
    the box towards the goal's angle), then pushes it to the goal position; it ends within both tolerances."""
    tm, U, S, whole = _lone_push(0.1, 0.05, 40.0)
    assert whole and tm.goal_distance(S[-1]) <= 1.0
    assert abs(np.degrees(S[-1, 2]) - 40.0) <= 10.0
    assert np.abs(U).max() <= tm.task.control_max


#: the push_clutter plan behind docs/planning.md's figure, made before plans were shortened (`planar-lcp plan
#: push_clutter --seed 1 --iterations 9000 --no-shorten`): the box's path 0.68 m where its start and goal are 0.47 m
#: apart
CLUTTER_DOC_PLAN = ROOT / "docs" / "figures" / "planning" / "push_clutter" / "plan.json"
CLUTTER_BUDGET = 800


@pytest.fixture(scope="module")
def clutter():
    """(TaskModel of push_clutter, the docs' plan, its shortening with CLUTTER_BUDGET candidates)."""
    from planners import TaskModel
    from planners.shorten import shorten
    plan = json.loads(CLUTTER_DOC_PLAN.read_text())
    tm = TaskModel(plan["task_document"])
    return tm, plan, shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=1,
                             max_candidates=CLUTTER_BUDGET)


def test_push_candidates_shorten_the_object_path_through_clutter_and_replay_bit_for_bit(clutter):
    """The push kind re-plans the box's path (the other kinds keep it: a stretch that moves the box differently
    moves the obstacles differently and is rejected); the shortened plan replays from the start in a fresh model bit
    for bit, every state admissible, to the goal, with controls within the bounds."""
    from planners import TaskModel
    from planners.shorten import costs
    tm, plan, r = clutter
    assert r["exact_input"] and r["accepted_by_kind"]["push"] > 0, r["accepted_by_kind"]
    assert np.abs(r["controls"]).max() <= tm.task.control_max
    assert r["steps"].min() >= tm.task.min_steps and r["steps"].max() <= tm.task.max_steps
    fresh = TaskModel(plan["task_document"])
    _, dense, ok = fresh.execute(plan["start"], r["controls"], r["steps"])
    assert ok
    np.testing.assert_array_equal(dense, r["dense"])
    assert all(fresh.admissible(x) for x in dense) and fresh.goal_distance(dense[-1]) <= 1.0
    _, d0, _ = fresh.execute(plan["start"], plan["controls"], plan["steps"])
    first, final = costs(fresh, plan["steps"], d0), costs(fresh, r["steps"], dense)
    straight = np.hypot(*(fresh.goal_com[:2] - np.asarray(plan["start"][0:2])))
    # the box's path: from 0.68 m to within 20 % of the straight distance start to goal (0.47 m)
    assert final["object_path_length"] < 1.2 * straight < first["object_path_length"], (first, final, straight)
    assert final["path_duration"] < 0.5 * first["path_duration"]


def test_push_candidates_are_deterministic_for_a_seed(clutter):
    from planners.shorten import shorten
    tm, plan, r = clutter
    again = shorten(tm, plan["start"], plan["controls"], plan["steps"], seed=1, max_candidates=CLUTTER_BUDGET)
    np.testing.assert_array_equal(again["controls"], r["controls"])
    np.testing.assert_array_equal(again["steps"], r["steps"])
    assert again["accepted_by_kind"] == r["accepted_by_kind"] and again["candidates"] == r["candidates"]


def test_the_docs_before_and_after_table_is_what_its_command_gives():
    """docs/planning.md "First and shortened plans": the benchmark table is examples/measurements/bench_table.py
    --shorter's output on the committed benchmark files, row for row (the command is the one the page gives)."""
    import re
    import subprocess
    import sys
    from cli_helpers import cli_env
    text = (ROOT / "docs" / "planning.md").read_text()
    sec = text[text.index("\n### First and shortened plans\n"):]
    cmd = re.search(r"^python (examples/measurements/bench_table\.py --shorter .*)$", sec, re.M).group(1).split()
    r = subprocess.run([sys.executable, *cmd], capture_output=True, text=True, cwd=ROOT, env=cli_env(), timeout=60)
    assert r.returncode == 0, r.stderr
    got = [line for line in r.stdout.splitlines() if line.startswith("|")]
    table = re.search(r"^(\| task \| exact .*?)\n\n", sec, re.M | re.S).group(1).splitlines()
    assert got == table
    assert "all: 40/40 runs exact (100 %), 40/40 exact plans replayed to their goal" in r.stdout
