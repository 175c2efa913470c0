"""Force-limited kinematic bodies (`max_force`, `max_torque`): a velocity servo with a bounded impulse per step
(docs/method.md, "Force-limited kinematic bodies"). Analytic oracles, every formulation and solver:

- a pusher that drives a box into a wall stalls: it presses with exactly max_force, its velocity drops to zero;
- a pusher that accelerates a free box (no table friction) moves it at a = F / m exactly until the box reaches the
  prescribed speed, then it is kinematic again;
- below the limit the run is the kinematic one, bit for bit;
- a rotating paddle with max_torque turns its load with exactly that torque until the load keeps up;
- the jam that has no rigid solution with a prescribed pusher is solved with a force-limited one.
"""

import numpy as np
import pytest

from planar_lcp import simulate
from planar_lcp.spec.scene import FORMULATIONS, SceneError, parse_scene

SOLVERS = ("lemke", "pgs", "osqp")
H = 0.01


def push_scene(max_force=None, table_mu=0.3, wall=True, speed=0.2, t_end=0.5):
    """A 1 kg box (0.2 x 0.2 m) touching a disk pusher on its left; a wall 1 cm to its right (or none)."""
    pusher = {"name": "pusher", "type": "kinematic", "position": [-0.15, 0.0], "velocity": [speed, 0.0],
              "shapes": [{"type": "disk", "radius": 0.05}]}
    if max_force is not None:
        pusher["max_force"] = max_force
    bodies = [{"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.0], "support_friction": table_mu,
               "shapes": [{"type": "box", "width": 0.2, "height": 0.2}]}, pusher]
    if wall:
        bodies.append({"name": "wall", "type": "static",
                       "shapes": [{"type": "box", "width": 0.1, "height": 1.0, "offset": [0.16, 0.0]}]})
    return parse_scene({"name": "servo", "world": {"plane": "horizontal", "friction": 0.0},
                        "sim": {"h": H, "t_end": t_end}, "bodies": bodies})


def _skip_without(solver):
    if solver == "osqp":
        pytest.importorskip("osqp")


def pusher_force(tr, i):
    """The pusher's contact force in step i (N, along +x): the normal impulses of its pair over h."""
    names = tr.contacts["shape_pairs"]
    c = tr.contacts
    return sum(c["cn"][i, k] * c["normal"][i, k, 0] for k in range(c["count"][i])
               if "pusher" in names[c["pair"][i, k]]) / H


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_a_pusher_against_a_wall_stalls_at_exactly_its_force(formulation, solver):
    _skip_without(solver)
    tr = simulate(push_scene(5.0), formulation=formulation, solver=solver, pgs_iterations=200)
    assert not tr.failures
    # the box reaches the wall (1 cm) within 0.1 s; from then on the pusher presses with exactly 5 N and stands still
    late = range(20, len(tr.t) - 1)
    forces = np.array([pusher_force(tr, i) for i in late])
    tol = 1e-9 if solver == "lemke" else 1e-6
    assert np.allclose(forces, 5.0, rtol=tol, atol=0), forces
    assert np.ptp(tr.qk[20:, 0, 0]) <= 1e-9 and tr.qk[-1, 0, 0] == pytest.approx(-0.14, abs=1e-6)
    assert tr.q[-1, 0, 0] == pytest.approx(0.01, abs=1e-6)           # the box against the wall
    assert tr.stats["servo_limited"][20:].min() >= 1


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_a_force_limited_pusher_accelerates_a_free_box_at_force_over_mass(formulation, solver):
    """No table friction, no wall: the box's speed after n steps is min(n h F / m, v_cmd)."""
    _skip_without(solver)
    tr = simulate(push_scene(2.0, table_mu=0.0, wall=False), formulation=formulation, solver=solver,
                  pgs_iterations=100)
    n = np.arange(len(tr.t))
    expect = np.minimum(n * H * 2.0 / 1.0, 0.2)
    tol = 1e-12 if solver != "osqp" else 1e-8
    assert np.abs(tr.v[:, 0, 0] - expect).max() <= tol
    # the pusher lags while the box accelerates, then keeps the box's speed: its advance is the box's
    assert np.allclose(np.diff(tr.qk[:, 0, 0]), H * tr.v[1:, 0, 0], atol=1e-9)


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_below_its_limit_a_force_limited_pusher_is_kinematic_bit_for_bit(formulation):
    """100 N is more than the push ever needs (20 N to reach the speed in one step): every output equals the run with a
    prescribed pusher, bit for bit, and no island was solved with the servo's unknowns."""
    limited = simulate(push_scene(100.0, wall=False), formulation=formulation)
    prescribed = simulate(push_scene(None, wall=False), formulation=formulation)
    for k in ("q", "v", "qk", "q_com", "v_com"):
        assert np.array_equal(getattr(limited, k), getattr(prescribed, k)), k
    for k in ("cn", "ft", "phi", "mode"):
        assert np.array_equal(limited.contacts[k], prescribed.contacts[k]), k
    assert limited.stats["servo_limited"].sum() == 0


@pytest.mark.parametrize("solver", SOLVERS)
def test_a_paddle_turns_its_load_with_exactly_its_torque_limit(solver):
    """A kinematic paddle (0.4 x 0.02 m) turning at 1 rad/s about its origin under a 1 kg disk resting on it 0.15 m
    out: to follow at once it would need 0.0225 N m s in a step; with max_torque 0.5 N m it turns the disk with exactly
    0.5 N m until the disk keeps up, and lags behind its prescribed angle."""
    _skip_without(solver)
    sc = parse_scene({"name": "paddle", "world": {"plane": "horizontal", "friction": 0.0},
                      "sim": {"h": H, "t_end": 0.3},
                      "bodies": [{"name": "disk", "type": "dynamic", "mass": 1.0, "position": [0.15, 0.06],
                                  "support_friction": 0.0, "shapes": [{"type": "disk", "radius": 0.05}]},
                                 {"name": "paddle", "type": "kinematic", "angular_velocity": 1.0, "max_force": 1e3,
                                  "max_torque": 0.5, "shapes": [{"type": "box", "width": 0.4, "height": 0.02}]}]})
    tr = simulate(sc, solver=solver, pgs_iterations=100)
    c = tr.contacts
    torques = []
    for i in range(len(tr.t) - 1):
        tq = 0.0
        for k in range(c["count"][i]):
            n = c["normal"][i, k]
            on_paddle = -(c["cn"][i, k] * n + c["ft"][i, k] * np.array([-n[1], n[0]]))   # the paddle is side B
            r = c["point"][i, k] - tr.qk[i + 1, 0, :2]
            tq += r[0] * on_paddle[1] - r[1] * on_paddle[0]
        torques.append(tq / H)
    torques = np.array(torques)
    tol = 1e-9 if solver != "osqp" else 1e-6
    assert np.all(np.abs(torques) <= 0.5 * (1 + tol))
    assert np.allclose(torques[:4], -0.5, rtol=tol)                  # the disk resists: the paddle is held back
    assert tr.qk[-1, 0, 2] < 0.3 - 0.01                              # behind its prescribed angle, 0.3 rad


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_the_jam_without_a_rigid_solution_is_solved_with_a_force_limited_pusher(formulation):
    pytest.importorskip("scipy")
    from test_reliability import JAM
    import copy
    from planar_lcp.sim import NoRigidSolution
    with pytest.raises(NoRigidSolution):
        simulate(parse_scene(JAM, "<jam>"), formulation=formulation)
    data = copy.deepcopy(JAM)
    data["bodies"][1]["max_force"] = 3.0
    tr = simulate(parse_scene(data, "<jam>"), formulation=formulation)
    assert not tr.failures and tr.stats["servo_limited"].sum() > 0
    last = len(tr.t) - 2
    assert pusher_force(tr, last) == pytest.approx(3.0, rel=1e-9)


@pytest.mark.parametrize("mutation, message", [
    (lambda b: b[0].update(max_force=5.0),
     "bodies[0].max_force is only allowed on a kinematic body (a force-limited velocity servo), got a dynamic body"),
    (lambda b: b[1].update(max_force=-1.0), "bodies[1].max_force must be > 0, got -1.0"),
    (lambda b: b[1].update(max_force=1e12), "bodies[1].max_force must be within +- 1e+09 N (a physical bound), got "
                                            "1000000000000.0"),
    (lambda b: b[1].update(max_torque=1.0), "bodies[1].max_torque needs max_force on the same body (a servo limits "
                                            "its force first), got max_torque = 1.0 alone"),
])
def test_servo_keys_are_validated(mutation, message):
    import copy
    data = {"name": "x", "world": {"plane": "horizontal"}, "sim": {"h": H, "t_end": 0.1},
            "bodies": [{"name": "box", "type": "dynamic", "mass": 1.0,
                        "shapes": [{"type": "box", "width": 0.2, "height": 0.2}]},
                       {"name": "pusher", "type": "kinematic", "position": [-0.3, 0.0],
                        "shapes": [{"type": "disk", "radius": 0.05}]}]}
    d = copy.deepcopy(data)
    mutation(d["bodies"])
    with pytest.raises(SceneError) as e:
        parse_scene(d, "x.toml")
    assert str(e.value) == "x.toml: " + message


def test_a_task_gives_its_pusher_a_force_limit():
    """`pusher_max_force` in a [task] sets the pusher's max_force in the task's scene (the planners' forward model)."""
    from planar_lcp.spec.scene import read_document, scenes_dir
    from planar_lcp.spec.task import TaskError, load_task
    doc, _ = read_document(scenes_dir() / "push_box.toml")
    doc["task"]["pusher_max_force"] = 4.0
    task = load_task(doc)
    assert task.scene.body(task.pusher).max_force == 4.0
    doc["task"]["pusher_max_force"] = 0.0
    with pytest.raises(TaskError, match=r"task.pusher_max_force must be > 0, got 0.0"):
        load_task(doc)


def test_the_pymunk_bridge_makes_a_force_limited_pusher_a_servo():
    """pymunk's mapping: a dynamic body held to a kinematic control body by a PivotJoint with max_force (and a
    GearJoint); in the stall it stops short of where the prescribed motion would take it, near where ours stops."""
    pytest.importorskip("pymunk")
    from planar_lcp.bridges.pymunk import build_space, simulate_pymunk
    space, handles = build_space(push_scene(5.0, t_end=0.5))
    pivot, gear = handles.servo_joints["pusher"]
    assert pivot.max_force == 5.0 and pivot.max_bias == 0.0 and gear.max_force == float("inf")
    tr = simulate_pymunk(push_scene(5.0))
    assert tr.qk[-1, 0, 0] < -0.12                   # prescribed: -0.15 + 0.5 s x 0.2 m/s = -0.05


def test_a_task_with_a_force_limited_pusher_plans_and_replays_on_the_command_line(tmp_path):
    """`planar-lcp plan` on a task file whose [task] sets pusher_max_force, then `planar-lcp replay` of its plan.json:
    the plan is exact and replays to its goal (100 N is above what tipping the box asks, so the finger is the
    prescribed one: the same plan as the shipped task's, bit for bit)."""
    pytest.importorskip("ompl")
    import json
    from cli_helpers import run_cli
    from planar_lcp.spec.scene import scenes_dir
    text = (scenes_dir() / "tip_box.toml").read_text()
    assert "\n[task]\n" in text
    task_file = tmp_path / "tip_box_servo.toml"
    task_file.write_text(text.replace("\n[task]\n", "\n[task]\npusher_max_force = 100.0\n", 1))
    args = ("--planner", "RRT", "--iterations", "400", "--seed", "1", "--no-gif")
    r = run_cli("plan", task_file, *args, "--out", tmp_path / "servo", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    plan = json.loads((tmp_path / "servo" / "plan.json").read_text())
    ref = run_cli("plan", "tip_box", *args, "--out", tmp_path / "ref", cwd=tmp_path)
    assert ref.returncode == 0, ref.stderr[-3000:]
    plain = json.loads((tmp_path / "ref" / "plan.json").read_text())
    assert plan["exact"] is True and plan["controls"] == plain["controls"] and plan["states"] == plain["states"]
    rr = run_cli("replay", tmp_path / "servo" / "plan.json", "--out", tmp_path / "replay", cwd=tmp_path)
    import re
    assert rr.returncode == 0 and re.search(r"^goal_holds\s+True$", rr.stdout, re.M), rr.stdout + rr.stderr[-2000:]


def test_a_stalling_pusher_on_the_command_line(tmp_path):
    """`planar-lcp simulate` of a scene file with a force-limited pusher driving a box into a wall: the run ends, no
    failed step (with a prescribed pusher it stops: tests/commands/test_bad_input.py, the jam)."""
    from cli_helpers import run_cli
    from planar_lcp.spec.random_scenes import scene_to_toml
    data = {"name": "stall", "world": {"plane": "horizontal", "friction": 0.0}, "sim": {"h": H, "t_end": 0.5},
            "bodies": [{"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.0], "support_friction": 0.3,
                        "shapes": [{"type": "box", "width": 0.2, "height": 0.2}]},
                       {"name": "pusher", "type": "kinematic", "position": [-0.15, 0.0], "velocity": [0.2, 0.0],
                        "max_force": 5.0, "shapes": [{"type": "disk", "radius": 0.05}]},
                       {"name": "wall", "type": "static",
                        "shapes": [{"type": "box", "width": 0.1, "height": 1.0, "offset": [0.16, 0.0]}]}]}
    f = tmp_path / "stall.toml"
    f.write_text(scene_to_toml(data))
    r = run_cli("simulate", f, "--csv", tmp_path / "stall.csv", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "failed steps   0" in r.stdout
