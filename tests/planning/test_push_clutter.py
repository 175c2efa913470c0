"""The push_clutter planning task: a box pushed to a goal pose through four movable obstacles.

The task's claims, each checked here: the obstacles differ in shape and mass and each stands in the box's straight
way; the OMPL state holds every object's full physics state, so propagation is a pure function of it; an obstacle
leaving the table (any point outside the workspace) or the pusher entering the static post makes a state invalid; the goal needs the box at
rest; `planar-lcp plan push_clutter` finds a plan that moves obstacles and replays bit for bit."""

import json
import math

import numpy as np
import pytest
from cli_helpers import run_cli
from task_geometry import placed, straight_sweep

pytest.importorskip("ompl")
pytest.importorskip("shapely")

#: seed 1 needs 1496 iterations (docs/planning.md): the budget leaves a margin of 6
PLAN_ARGS = ("plan", "push_clutter", "--planner", "RRT", "--seed", "1", "--iterations", "9000")


@pytest.fixture(scope="module")
def tm():
    from planners.tasks import TaskModel
    return TaskModel("push_clutter")


@pytest.fixture(scope="module")
def clutter_plan(tmp_path_factory):
    out = tmp_path_factory.mktemp("clutter_plan")
    r = run_cli(*PLAN_ARGS, "--out", out)
    assert r.returncode == 0, r.stdout + r.stderr
    return r, out


def test_four_obstacles_of_different_shapes_and_masses_block_the_straight_way(tm):
    sc = tm.scene
    names = tm.task.obstacles
    assert len(names) >= 4
    bodies = [sc.body(n) for n in names]
    assert len({b.shapes[0].type for b in bodies}) == len(bodies)            # disk, box, capsule, polygon
    assert len({b.mass for b in bodies}) == len(bodies)
    # the region the box sweeps moving straight (no turn) from its start to the goal
    sweep = straight_sweep(tm)
    for b in bodies:
        g = placed(b)
        assert g.intersection(sweep).area > 0.25 * g.area, b.name
    # and they do not overlap at the start (a scene error the simulator would resolve with a jump)
    for i, a in enumerate(bodies):
        for b in bodies[i + 1:] + [sc.body(tm.task.object)]:
            assert placed(a).distance(placed(b)) > 1e-3, (a.name, b.name)


def test_the_ompl_state_holds_every_object(tm):
    """read_state(write_state(x)) is x for the 32 numbers, and OMPL's distance is the documented weighted sum over
    the object, each obstacle and the pusher."""
    from planners.adapter import read_state, state_space, write_state
    t = tm.task
    assert t.state_dim == 6 * 5 + 2 == len(t.state_names()) == len(tm.initial_state())
    space = state_space(tm)
    a, b = space.allocState(), space.allocState()
    rng = np.random.default_rng(5)
    w_pos, w_ang, w_vel, w_pus = t.weights
    for _ in range(5):
        x, y = rng.uniform(-0.1, 0.1, t.state_dim), rng.uniform(-0.1, 0.1, t.state_dim)
        write_state(a, x, tm.nobj)
        write_state(b, y, tm.nobj)
        np.testing.assert_array_equal(read_state(a, tm.nobj), x)
        d = x - y
        expected = w_pus * math.hypot(*d[-2:])
        for i in range(tm.nobj):
            wp = w_pos if i == 0 else t.obstacle_weight
            di = d[6 * i:6 * i + 6]
            expected += wp * math.hypot(di[0], di[1]) + wp * w_ang / w_pos * abs(di[2]) + w_vel * np.linalg.norm(di[3:])
        assert space.distance(a, b) == pytest.approx(expected, rel=1e-12)
    del a, b


def test_propagation_is_a_pure_function_of_the_state_and_moves_obstacles(tm):
    x0 = tm.initial_state()
    # the pusher just left of the disk (an obstacle), pushing right: the disk moves, the rest of the state is input
    x = x0.copy()
    disk = 6 * (1 + tm.task.obstacles.index("disk"))
    x[tm.ip:tm.ip + 2] = (x[disk] - 0.03 - 0.015 - 0.002, x[disk + 1])
    y1, ok = tm.advance(x, (0.1, 0.0), 20)
    assert ok and y1[disk] - x[disk] > 0.01
    tm.advance(x0, (-0.1, 0.05), 7)              # anything in between: no state is kept outside x
    y2, _ = tm.advance(x, (0.1, 0.0), 20)
    np.testing.assert_array_equal(y1, y2)
    # the same push with the disk elsewhere on the table: the pusher meets nothing, only it moves
    x[disk:disk + 2] = (0.25, -0.15)
    y3, _ = tm.advance(x, (0.1, 0.0), 20)
    assert y3[disk] == 0.25 and y3[disk + 1] == -0.15


def test_validity_workspace_static_post_and_rest(tm):
    from planar_lcp.spec.task import placed_bounds
    x = tm.initial_state()
    assert tm.in_bounds(x) and tm.valid(x)
    (wx0, wx1), _ = tm.task.workspace
    for i in range(1, tm.nobj):                   # any point of an obstacle leaving the table invalidates the state
        name = tm.task.obstacles[i - 1]
        y = x.copy()
        # the body's right-most point 1 mm past the edge (and 1 mm inside it: valid), at its start angle
        b = tm.scene.body(name)
        (_, right), _ = placed_bounds(b, (0.0, 0.0), b.angle)
        com_to_right = right - (y[6 * i] - b.position[0])
        for past, ok in ((1e-3, False), (-1e-3, True)):
            y[6 * i] = wx1 + past - com_to_right
            assert tm.admissible(y) == ok, (name, past)
    post = tm.scene.body("post").position
    y = x.copy()
    y[tm.ip:tm.ip + 2] = post
    assert not tm.valid(y)
    g = tm.task.goal
    y = x.copy()
    y[0:3] = tm.goal_com
    assert tm.goal_distance(y) == 0
    y[3] = 1.5 * g.speed_tol                      # at the goal pose but still sliding: not the goal
    assert tm.goal_distance(y) > 1
    y[3], y[5] = 0.0, 1.5 * g.omega_tol
    assert tm.goal_distance(y) > 1


def test_plan_push_clutter_moves_obstacles_and_replays_bit_for_bit(clutter_plan, tm, tmp_path):
    from planners import load_plan
    from planners.plans import replay_lcp
    _, out = clutter_plan
    for f in ("plan.json", "plan.png", "plan.gif"):
        assert (out / f).stat().st_size > 1000, f
    plan = load_plan(out / "plan.json")
    assert plan.exact and plan.data["state_names"] == tm.task.state_names()
    res = replay_lcp(plan.data, tm=tm)
    np.testing.assert_array_equal(res["bound"], plan.states)
    assert res["report"]["goal_holds"] and res["report"]["speed_m_s"] <= tm.task.goal.speed_tol
    dense = res["dense"]
    assert all(tm.in_bounds(x) and tm.valid(x) for x in dense)      # every propagation step, not only the ends
    moved = [float(np.hypot(*(dense[-1, 6 * i:6 * i + 2] - dense[0, 6 * i:6 * i + 2]))) for i in range(1, tm.nobj)]
    assert max(moved) > 0.01, moved
    r = run_cli("replay", out / "plan.json", "--out", tmp_path)
    assert r.returncode == 0 and "goal_holds       True" in r.stdout, r.stdout + r.stderr


def test_a_plan_file_with_the_wrong_state_size_is_refused(clutter_plan, tmp_path):
    _, out = clutter_plan
    plan = json.loads((out / "plan.json").read_text())
    plan["start"] = plan["start"][:8]
    (tmp_path / "p.json").write_text(json.dumps(plan))
    r = run_cli("replay", tmp_path / "p.json")
    assert r.returncode == 2 and "32-number start" in r.stderr and "Traceback" not in r.stderr, r.stderr
