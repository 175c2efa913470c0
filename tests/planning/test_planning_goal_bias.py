"""push_t's RRT goal bias, which makes the 95%-cover goal reachable in a few thousand
iterations (the cover goal needs the T's pose within a few millimetres and degrees; goal samples get there best).

The OMPL work runs in subprocesses, as in tests/planning/test_planning.py (the cyclic GC must stay off while planning)."""

import json
import subprocess
import sys

import numpy as np
import pytest
from cli_helpers import ROOT, cli_env, run_cli

pytest.importorskip("ompl")
pytest.importorskip("shapely")


def test_a_cover_goal_gets_the_higher_goal_bias_by_default():
    from planners import load_task
    assert load_task("push_t").goal_bias == 0.3          # derived: push_t's file gives no goal_bias
    assert "goal_bias" not in load_task("push_t").given
    # the other goals keep the default bias
    assert load_task("push_box").goal_bias == load_task("tip_box").goal_bias == 0.1


def test_rrt_gets_the_tasks_goal_bias():
    code = ("import gc; gc.disable()\n"
            "from planners.adapter import Problem\n"
            "for name in ('push_t', 'push_box'):\n"
            "    print(name, Problem(name, 'RRT').planner.getGoalBias())\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=cli_env(),
                       timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["push_t", "0.3", "push_box", "0.1"]


def test_push_t_rrt_solves_quickly_and_replays_exactly(tmp_path):
    # seed 1 needs 2191 iterations with the derived bias 0.3 (iteration counts are the same on every machine)
    r = run_cli("plan", "push_t", "--planner", "RRT", "--iterations", "8000", "--seed", "1", "--no-gif",
                "--out", tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    plan = json.loads((tmp_path / "plan.json").read_text())
    assert plan["exact"]
    from planners import load_plan
    res = load_plan(tmp_path / "plan.json").replay()
    np.testing.assert_array_equal(res["bound"], np.array(plan["states"]))
    assert res["report"]["goal_holds"] and res["report"]["cover"] >= 0.95
