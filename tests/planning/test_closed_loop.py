"""Closed loop for any task (planners.closed_loop.PlanTracker; `planar-lcp replay --closed-loop --perturb`).

Oracles: in our own simulator, unperturbed, the tracker's choice is the plan's own control at every step its horizon
stays within the plan (the candidate without offset reproduces the reference exactly, distance 0), so the executed
states equal the planner's bit for bit; perturbed_scene scales exactly the coefficients and masses it names; in a
world the plan was not made in (pymunk, or ours with other friction and masses) the committed push_box plan misses
its goal open loop and reaches it closed loop; examples/measurements/closed_loop_tasks.py's table is reproduced.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import ROOT, run_cli

pytest.importorskip("shapely")

PUSH_BOX = ROOT / "docs" / "figures" / "planning" / "push_box" / "plan.json"
TASK_PLANS = ROOT / "docs" / "figures" / "closed_loop" / "tasks" / "plans"


@pytest.fixture(scope="module")
def push_box():
    from planners import load_plan
    return load_plan(PUSH_BOX)


def test_perturbed_scene_scales_every_friction_coefficient_and_dynamic_mass():
    from planar_lcp.spec.scene import SceneError, load_scene, perturbed_scene
    sc = load_scene("push_table")
    p = perturbed_scene(sc, friction=0.8, mass=1.2)
    assert p.world.friction == pytest.approx(0.8 * sc.world.friction, rel=1e-15)
    for a, b in zip(sc.bodies, p.bodies):
        assert (a.name, a.type, a.shapes, a.position) == (b.name, b.type, b.shapes, b.position)
        for x, y in zip((c.name for c in sc.bodies), (c.name for c in sc.bodies)):
            assert p.friction_between(x, y) == pytest.approx(0.8 * sc.friction_between(x, y), rel=1e-15)
        if a.support_friction is not None:
            assert b.support_friction == pytest.approx(0.8 * a.support_friction, rel=1e-15)
        if a.type == "dynamic":
            assert b.mass == pytest.approx(1.2 * a.mass, rel=1e-15)
        else:
            assert b.mass == a.mass
    assert perturbed_scene(sc) == sc
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(SceneError, match="factor must be a positive number"):
            perturbed_scene(sc, mass=bad)


def test_the_tracker_in_our_own_model_executes_the_plan_exactly(push_box):
    from planners.closed_loop import PlanTracker
    ref = push_box.replay("lcp")["dense"]
    r = push_box.replay("lcp", closed_loop=True)
    assert r["report"]["goal_holds"]
    # while the tracker's horizon stays within the plan it chooses the plan's own control: the same states, bit for
    # bit; in its last steps it aims at the goal itself, which holds in the end
    n = len(ref) - 1 - PlanTracker(push_box).horizon
    np.testing.assert_array_equal(r["dense"][:n + 1], ref[:n + 1])


def test_closed_loop_reaches_the_goal_the_open_loop_misses_in_a_perturbed_world(push_box):
    perturb = {"mu": 0.8, "mass": 1.2}
    open_loop = push_box.replay("lcp", perturb=perturb)
    assert open_loop["steps"] == int(push_box.steps.sum())
    assert open_loop["report"]["goal_distance"] > 3.0          # measured 8.5: a plan made for friction 0.3
    closed = push_box.replay("lcp", closed_loop=True, perturb=perturb)
    assert closed["report"]["goal_holds"], closed["report"]
    # real time: the tracker's thread CPU per step within the step it decides
    assert np.median(closed["compute_s"]) < push_box.task.step_duration


def test_closed_loop_in_pymunk_reaches_the_goal_the_open_loop_misses(push_box):
    pytest.importorskip("pymunk")
    open_loop = push_box.replay("pymunk")
    assert not open_loop["report"]["goal_holds"] and open_loop["report"]["goal_distance"] > 3.0   # measured 16.6
    closed = push_box.replay("pymunk", closed_loop=True)
    assert closed["report"]["goal_holds"], closed["report"]
    assert closed["steps"] < 3 * int(push_box.steps.sum()) + 100


def test_replay_closed_loop_perturbed_in_pymunk_end_to_end(tmp_path):
    pytest.importorskip("pymunk")
    plan = TASK_PLANS / "turn_box" / "plan.json"
    r = run_cli("replay", plan, "--simulator", "pymunk", "--closed-loop", "--perturb", "mu=0.8,mass=1.2",
                "--out", tmp_path, "--no-gif")
    assert r.returncode == 0, r.stdout + r.stderr
    out = r.stdout
    assert ("simulator      pymunk\nexecution      closed loop (PlanTracker), world perturbed: mu x0.8, mass x1.2\n"
            in out), out
    assert "goal_holds       True" in out and r.stderr.strip() == "", out + r.stderr
    steps = next(x for x in out.splitlines() if x.startswith("steps  "))
    assert int(steps.split()[1]) <= 3 * 22 + 100 and "(the plan: 22)" in steps, steps
    assert next(x for x in out.splitlines() if x.startswith("compute  ")).endswith("of thread CPU per step")
    assert (tmp_path / "replay_pymunk_closed_loop.png").stat().st_size > 1000


def test_a_closed_loop_that_misses_exits_1_and_says_so(tmp_path):
    pytest.importorskip("pymunk")
    # push_gate's plan in pymunk with 0.8 times the friction and 1.2 times the mass: the tracker loses the box and
    # ends 21 goal tolerances off after its 3 x 42 + 100 steps (docs/figures/closed_loop/tasks/table.md)
    r = run_cli("replay", TASK_PLANS / "push_gate" / "plan.json", "--simulator", "pymunk", "--closed-loop",
                "--perturb", "mu=0.8,mass=1.2", "--out", tmp_path, "--no-gif")
    assert r.returncode == 1 and "goal_holds       False" in r.stdout and r.stderr.strip() == "", r.stdout + r.stderr
    assert "steps            226 propagation steps of 0.1 s (the plan: 42)" in r.stdout, r.stdout


def test_the_table_of_open_and_closed_loops_is_reproduced(tmp_path):
    """examples/measurements/closed_loop_tasks.py on one task (its three runs; a pushing task's closed loops are
    test_closed_loop_in_pymunk_reaches_the_goal_the_open_loop_misses's): the outcomes and step counts equal
    the committed results, the goal distances to 1e-3 (the controller's budget is counted in simulated steps, not
    seconds, so its choices do not depend on the machine's speed)."""
    pytest.importorskip("pymunk")
    import csv
    import subprocess
    import sys
    tasks = ("tip_left",)
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "measurements" / "closed_loop_tasks.py"), "--out", str(tmp_path),
                        "--tasks", *tasks], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stdout + r.stderr

    def rows(path):
        with open(path, newline="") as fh:
            return {(row["task"], row["way"]): row for row in csv.DictReader(fh) if row["task"] in tasks}
    got = rows(tmp_path / "results.csv")
    want = rows(ROOT / "docs" / "figures" / "closed_loop" / "tasks" / "results.csv")
    assert sorted(got) == sorted(want) and len(got) == 3
    for key, w in want.items():
        g = got[key]
        assert (g["goal_holds"], g["steps"], g["plan_steps"]) == (w["goal_holds"], w["steps"], w["plan_steps"]), key
        assert float(g["goal_distance"]) == pytest.approx(float(w["goal_distance"]), abs=1e-3), key


@pytest.mark.parametrize("value, expected", [
    ("mu=0.8,mass", "must be mu=F,mass=G (factors, either or both), got 'mu=0.8,mass'"),
    ("friction=0.8", "must be mu=F,mass=G (factors, either or both), got 'friction=0.8'"),
    ("mu=0.8,mu=0.9", "must be mu=F,mass=G (factors, either or both), got 'mu=0.8,mu=0.9'"),
    ("mu=0", "mu must be a positive finite factor, got '0'"),
    ("mass=nan", "mass must be a positive finite factor, got 'nan'"),
    ("mass=x", "mass must be a positive finite factor, got 'x'"),
])
def test_bad_perturbations_are_refused_in_one_line(tmp_path, value, expected, capsys):
    from planar_lcp.cli import main             # in this process: argparse refuses before any work
    with pytest.raises(SystemExit) as e:
        main(["replay", str(PUSH_BOX), "--perturb", value, "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert e.value.code == 2 and out == "", out + err
    assert err == f"planar-lcp replay: error: argument --perturb: {expected}\n", err
    assert list(Path(tmp_path).iterdir()) == []


def test_the_controllers_are_named_by_the_package_and_imported_when_named():
    import subprocess
    import sys
    code = ("import sys, planners; assert 'planners.closed_loop' not in sys.modules and 'planners.pusht' not in "
            "sys.modules; from planners import PlanTracker, PushController, PushTPolicy; "
            "print(PlanTracker.__module__, PushController.__module__, PushTPolicy.__module__)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["planners.closed_loop", "planners.closed_loop", "planners.pusht"]
