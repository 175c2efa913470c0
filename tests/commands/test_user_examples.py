"""The examples for users (examples/*.py, outside examples/measurements/), each run as a user runs it, in a fresh
process from another folder, and its printed answer held to an oracle: Newton for the ramp, the known coefficient for
the fit, the goal for the plans, the hand solution for the LCP."""

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"


def run_example(name, tmp_path, *args, timeout=600):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    r = subprocess.run([sys.executable, str(EXAMPLES / name), *args], cwd=tmp_path, capture_output=True, text=True,
                       timeout=timeout, env=env)
    assert r.returncode == 0, r.stderr
    return r.stdout


def numbers(line):
    return [float(x) for x in re.findall(r"-?\d+\.\d+(?:e[-+]?\d+)?", line)]


def test_every_example_for_users_is_run_here():
    ran = set(re.findall(r'run_example\("(\w+\.py)"', Path(__file__).read_text()))
    shipped = {p.name for p in EXAMPLES.glob("*.py")}
    # gym_pusht_policy.py is run by tests/environments/test_gym.py (it needs the gym extra and draws a GIF)
    assert shipped - ran == {"gym_pusht_policy.py"}, shipped - ran


def test_hello_simulate_prints_the_rods_last_pose(tmp_path):
    import planar_lcp
    out = run_example("hello_simulate.py", tmp_path).splitlines()
    traj = planar_lcp.simulate("falling_rod")
    t, x, y, theta = numbers(out[0])
    assert out[0].startswith("rod at t = ")
    assert (t, x, y, theta) == tuple(round(float(a), 4 if i else 3) for i, a in
                                     enumerate([traj.t[-1], *traj.q[-1, 0]]))
    assert f"{len(traj.t) - 1} steps, {int(traj.stats['pivots'].sum())} Lemke pivots" in out[1]


def test_own_scene_slides_as_newton_says(tmp_path):
    out = run_example("own_scene.py", tmp_path)
    travelled, _, stepped, continuous = numbers(out)
    assert travelled == pytest.approx(stepped, rel=1e-5)
    assert abs(travelled - continuous) > 1e-4          # the oracle tells the step's Euler from continuous time


@pytest.mark.slow
def test_own_task_plans_reaches_its_goal_and_writes_a_plan_file(tmp_path):
    pytest.importorskip("ompl")
    out = run_example("own_task.py", tmp_path, "--out", "p.json")
    assert "exact: True" in out and "the replay reaches the goal: True" in out, out
    import planners
    replayed = planners.load_plan(tmp_path / "p.json").replay()
    assert replayed["report"]["goal_holds"]


def test_fit_friction_recovers_the_recorded_coefficient(tmp_path):
    pytest.importorskip("scipy")
    out = run_example("fit_friction.py", tmp_path)
    mu, stderr = numbers(out)[:2]
    assert 0.0 < stderr < 0.05
    assert abs(mu - 0.35) < 3.0 * stderr, out


def test_fit_friction_gradient_recovers_mu_from_the_derivatives(tmp_path):
    """Gauss-Newton on the rollout's exact derivative: the incline's mu (0.3) from 0.1, to round-off."""
    lines = run_example("fit_friction_gradient.py", tmp_path).splitlines()
    assert len(lines) == 3
    for line in lines:
        assert "exact derivatives: True" in line
    mu, err = numbers(lines[-1])[:2]
    assert mu == pytest.approx(0.3, abs=1e-9)
    assert err < 1e-12


@pytest.mark.slow
def test_closed_loop_reaches_the_goal_where_open_loop_misses(tmp_path):
    pytest.importorskip("ompl")
    pytest.importorskip("pymunk")
    out = run_example("closed_loop.py", tmp_path)
    assert "open loop in pymunk: goal reached False" in out, out
    assert "closed loop in pymunk: goal reached True" in out, out


def test_solve_lcp_prints_the_hand_solution(tmp_path):
    out = run_example("solve_lcp.py", tmp_path)
    z = [float(a) for a in re.search(r"z=\[([^\]]*)\]", out).group(1).split()]
    w = [float(a) for a in re.search(r"w=\[([^\]]*)\]", out).group(1).split()]
    # z = M^-1 (-q) = (4/3, 7/3) > 0, so w = 0
    np.testing.assert_allclose(z, [4.0 / 3.0, 7.0 / 3.0], rtol=1e-7)
    assert all(math.isclose(a, 0.0, abs_tol=1e-12) for a in w)
