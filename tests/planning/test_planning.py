"""Planning with OMPL over the LCP simulator (planners/). Skipped when ompl is not installed.

The OMPL work runs in subprocesses: the 2.0.1 bindings must run with the cyclic GC off (see docs/planning.md), and
a subprocess keeps that, and nanobind's exit-time leak report, out of the test process."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from cli_helpers import ROOT, TIP_PLAN_ARGS, run_cli

pytest.importorskip("ompl")
pytest.importorskip("shapely")


def test_small_problem_solves_and_replays_to_goal(tip_plan):
    r, out = tip_plan
    assert r.returncode == 0, r.stdout + r.stderr
    plan = json.loads((out / "plan.json").read_text())
    assert plan["exact"] and plan["task"] == "tip_box" and plan["planner"] == "RRT" and plan["seed"] == 1
    assert len(plan["controls"]) == len(plan["steps"]) == len(plan["durations"]) == len(plan["states"]) - 1
    assert (out / "plan.png").stat().st_size > 1000
    rr = run_cli("replay", out / "plan.json", "--out", out)
    assert rr.returncode == 0, rr.stdout + rr.stderr
    assert "goal_holds       True" in rr.stdout and "unchanged since planning" in rr.stdout


def test_replay_reproduces_planner_states_exactly(tip_plan):
    from planners import load_plan
    _, out = tip_plan
    plan = load_plan(out / "plan.json")
    res = plan.replay()
    # the states at the control boundaries are the planner's, bit for bit
    np.testing.assert_array_equal(res["bound"], plan.states)
    assert res["report"]["goal_holds"]
    # and the goal test is not vacuous: the start is far from it
    assert res["tm"].goal_distance(np.array(plan.data["start"])) > 5


def test_plan_json_round_trips(tip_plan, tmp_path):
    from planners import load_plan
    _, out = tip_plan
    plan = load_plan(out / "plan.json")
    plan.save(tmp_path / "p.json")
    assert load_plan(tmp_path / "p.json").data == plan.data


def test_same_seed_and_iterations_give_the_same_plan(tip_plan, tmp_path):
    _, out = tip_plan
    r = run_cli(*TIP_PLAN_ARGS, "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    a = json.loads((out / "plan.json").read_text())
    b = json.loads((tmp_path / "plan.json").read_text())
    for key in ("controls", "steps", "states", "iterations", "sim_steps"):
        assert a[key] == b[key], key
    seed2 = list(TIP_PLAN_ARGS)
    seed2[seed2.index("--seed") + 1] = "2"
    r2 = run_cli(*seed2, "--out", tmp_path / "s2")
    c = json.loads((tmp_path / "s2" / "plan.json").read_text())
    assert c["controls"] != a["controls"], r2.stderr


def test_bad_names_bounds_and_files_give_clear_errors(tmp_path):
    r = run_cli("plan", "push_sofa", "--iterations", "1")
    assert r.returncode == 2 and "unknown task 'push_sofa'" in r.stderr and "push_box" in r.stderr
    r = run_cli("plan", "falling_rod", "--iterations", "1")
    assert r.returncode == 2 and "task is required" in r.stderr and "'falling_rod' has none" in r.stderr
    r = run_cli("plan", "tip_box", "--planner", "SST", "--iterations", "1")
    assert r.returncode == 2 and "unknown planner 'SST'" in r.stderr and "KPIECE1" in r.stderr
    r = run_cli("plan", "tip_box", "--time", "-3")
    assert r.returncode == 2 and "--time" in r.stderr and "must be > 0" in r.stderr
    r = run_cli("plan", "tip_box", "--time", "1", "--iterations", "5")
    assert r.returncode == 2 and "not both" in r.stderr
    r = run_cli("replay", tmp_path / "missing.json")
    assert r.returncode == 2 and "no such plan file" in r.stderr
    (tmp_path / "bad.json").write_text("{not json")
    r = run_cli("replay", tmp_path / "bad.json")
    assert r.returncode == 2 and "not a JSON plan file" in r.stderr
    (tmp_path / "old.json").write_text(json.dumps({"format": 1, "task": "tip_box", "controls": [[0.1, 0]],
                                                   "steps": [1], "start": [0] * 8}))
    r = run_cli("replay", tmp_path / "old.json")
    assert r.returncode == 2 and "made before task files" in r.stderr and "plan it again" in r.stderr
    r = run_cli("plan-bench", "tip_box", "--planners", "RRT", "PDST")
    assert r.returncode == 2 and "unknown planner 'PDST'" in r.stderr


def test_goal_and_validity_tests():
    import math

    from planners.tasks import TaskModel
    tm = TaskModel("push_box")
    g = tm.goal_com.copy()
    x = tm.initial_state()
    x[0:3] = g
    assert tm.goal_distance(x) == 0
    x[0] += 0.011
    assert tm.goal_distance(x) > 1
    x[0] -= 0.002
    x[2] += math.radians(9)
    assert tm.goal_distance(x) <= 1
    y = tm.initial_state()
    y[6:8] = (0.13, -0.03)          # the pusher inside the static block
    assert not tm.valid(y)
    tt = TaskModel("push_t")
    z = tt.initial_state()
    z[0:3] = tt.goal_com
    assert tt.cover(z) == pytest.approx(1.0)
    z[1] += 0.004                    # 4 mm off: the T's bar is 30 mm wide, so the cover drops below 95%
    assert tt.cover(z) < 0.95 and tt.goal_distance(z) > 1


def test_state_space_distance_is_the_documented_weighted_sum():
    """planners/adapter.py's docstring: w_pos |dxy| + w_ang |dtheta| + w_vel |dv| + w_pus |dpusher|, angles the
    shorter way round, with each task's weights."""
    from planners.adapter import state_space, write_state
    from planners.tasks import TaskModel, shipped_tasks
    rng = np.random.default_rng(3)
    for name in shipped_tasks():
        tm = TaskModel(name)
        task = tm.task
        if task.obstacles:
            continue                # tests/planning/test_push_clutter.py: the same formula with the obstacles' terms
        space = state_space(tm)
        a, b = space.allocState(), space.allocState()
        w_pos, w_ang, w_vel, w_pus = task.weights
        for _ in range(5):
            x, y = rng.uniform(-0.1, 0.1, 8), rng.uniform(-0.1, 0.1, 8)
            x[2], y[2] = 3.0, -3.0                      # 0.28 rad apart across +-pi, not 6 rad
            write_state(a, x)
            write_state(b, y)
            d = x - y
            expected = (w_pos * math.hypot(d[0], d[1]) + w_ang * (2 * math.pi - 6.0) + w_vel * np.linalg.norm(d[3:6])
                        + w_pus * math.hypot(d[6], d[7]))
            assert space.distance(a, b) == pytest.approx(expected, rel=1e-12), task.name
        del a, b


def test_benchmark_statuses_are_ompls():
    """plan-bench writes each run's status as the value of OMPL's PlannerStatus, under OMPL's label."""
    from ompl import base as ob

    from planners.bench import STATUS, STATUS_ENUM, STATUS_LABELS
    assert STATUS is ob.PlannerStatus.PlannerStatusType
    assert len(STATUS_LABELS) == STATUS.TYPE_COUNT.value and STATUS_ENUM.split("|")[1:] == list(STATUS_LABELS)
    for s in (STATUS.UNKNOWN, STATUS.TIMEOUT, STATUS.APPROXIMATE_SOLUTION, STATUS.EXACT_SOLUTION, STATUS.CRASH):
        assert STATUS_LABELS[s.value] == ob.PlannerStatus(s).asString()


def test_import_planar_lcp_does_not_import_ompl():
    r = subprocess.run([sys.executable, "-c", "import sys, planar_lcp, planar_lcp.cli; "
                        "planar_lcp.cli.build_parser(); print('ompl' in sys.modules)"],
                       capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert r.stdout.strip() == "False", r.stderr


def test_benchmark_runs_on_two_machines_give_one_log_each_and_one_database(tmp_path):
    """OMPL's log describes one machine ("Running on", its CPU); runs from two hosts (and one Dask gave up on) go to
    one log per host, and ompl_benchmark_statistics merges them into one database with each run under its host."""
    import sqlite3

    from planners.bench import UNKNOWN_HOST, _crash_record, make_database, write_logs
    recs = []
    for seed, host in ((1, "alpha"), (2, "beta"), (3, "alpha")):
        r = _crash_record("RRT", seed, "x", 1.0, f"tcp://{host}:1", host, f"{host} cpu model\nCPU(s): 4")
        r.update(exact=True, status=6, solve_time=float(seed))
        recs.append(r)
    recs.append(_crash_record("RRT", 4, "KilledWorker", float("nan"), None))
    from planners import load_task
    logs = write_logs(tmp_path, load_task("push_box"), ["RRT"], recs, 60.0, 10.0)
    assert sorted(p.name for p in logs) == ["push_box_alpha.log", "push_box_beta.log", "push_box_unknown-host.log"]
    alpha = (tmp_path / "push_box_alpha.log").read_text()
    assert "Running on alpha\n" in alpha and "<<<|\nalpha cpu model\nCPU(s): 4\n|>>>" in alpha
    assert "2 runs per planner" in alpha
    assert f"Running on {UNKNOWN_HOST}\n" in (tmp_path / "push_box_unknown-host.log").read_text()
    db = make_database(logs, tmp_path / "push_box.db")
    with sqlite3.connect(db) as con:
        rows = con.execute("select experiments.hostname, experiments.cpuinfo, runs.time from runs join experiments "
                           "on runs.experimentid = experiments.id order by runs.time is null, runs.time").fetchall()
    assert [(h, t) for h, _, t in rows[:3]] == [("alpha", 1.0), ("beta", 2.0), ("alpha", 3.0)]
    assert rows[0][1].startswith("alpha cpu model") and rows[3][0] == UNKNOWN_HOST


@pytest.mark.parametrize("plan_dir", sorted(p.name for p in (ROOT / "docs" / "figures" / "planning").iterdir()
                                             if (p / "plan.json").is_file()))
def test_the_plans_in_the_docs_replay_bit_for_bit(plan_dir):
    """The plans behind docs/planning.md's figures are what the code makes now: replayed, they reach their states
    exactly and the goal."""
    from planners import load_plan
    plan = load_plan(ROOT / "docs" / "figures" / "planning" / plan_dir / "plan.json")
    assert plan.task_file == "unchanged"
    res = plan.replay()
    np.testing.assert_array_equal(res["bound"], plan.states)
    assert res["report"]["goal_holds"]
