"""Planning tasks with a moving body: a kinematic body other than the pusher on a `path` (Task.moving; docs/planning.md,
"Moving bodies"). The planning state then ends with the time.

Oracles: propagation is `simulate` of the same scene with the pusher at the same velocity, bit for bit up to
round-off, however the steps are split into propagations, on the paths and after their end; the pusher is judged
against a moving body where that body is at the state's time; a plan of the shipped gate task keeps the box behind
the closed gate and replays to its goal; OMPL's distance is the documented weighted sum with the time's term.
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from planar_lcp import simulate
from planar_lcp.spec.scene import parse_scene
from planar_lcp.spec.task import TaskError, load_task, parse_task

from cli_helpers import run_cli

pytest.importorskip("shapely")

ROOT = Path(__file__).resolve().parents[2]
GATE = ROOT / "tasks" / "push_gate.toml"
H = 0.02
#: the sweeper waits 0.2 s, then sweeps in +x through the box's start at 0.28 m/s until t = 0.8 s
SWEEP = [[0.0, -0.12, 0.0, 0.0], [0.2, -0.12, 0.0, 0.0], [0.8, 0.05, 0.0, 0.3]]


def sweep_doc(pusher=None):
    """A box on a table that a kinematic sweeper on a path pushes (and turns), the pusher above them."""
    return {"name": "sweep", "world": {"plane": "horizontal", "friction": 0.3}, "sim": {"h": H, "t_end": 1.2},
            "bodies": [{"name": "box", "type": "dynamic", "mass": 0.5, "support_friction": 0.3,
                        "shapes": [{"type": "box", "width": 0.1, "height": 0.1}]},
                       {"name": "sweeper", "type": "kinematic", "path": SWEEP,
                        "shapes": [{"type": "box", "width": 0.04, "height": 0.2}]},
                       {"name": "pusher", "type": "kinematic", **(pusher or {"position": [0.0, 0.15]}),
                        "shapes": [{"type": "disk", "radius": 0.015}]}],
            "task": {"object": "box", "pusher": "pusher", "goal": {"x": 0.3, "y": 0.0}}}


def test_the_state_ends_with_the_time_and_the_task_names_its_moving_bodies():
    from planners.tasks import TaskModel
    t = load_task(GATE)
    assert t.timed and t.moving == ("gate",) and t.horizon == 2.0
    assert t.state_dim == 9 and t.state_names()[-1] == "t"
    assert t.time_weight == pytest.approx(0.16, rel=1e-12)            # the gate's speed, 0.16 m in 1 s, no spin
    tm = TaskModel(t)
    x0 = tm.initial_state()
    assert x0.shape == (9,) and x0[-1] == 0.0
    untimed = load_task("push_box")
    assert not untimed.timed and untimed.state_dim == 8 and untimed.moving == () and untimed.time_weight == 0.0


def test_propagation_is_the_simulation_of_the_scene_however_it_is_split():
    """60 steps (1.2 s, past the sweeper's path end at 0.8 s) at one pusher velocity: the propagations' end state is
    simulate()'s, the object pushed and turned by the sweeper, for three ways of splitting the steps."""
    from planners.tasks import TaskModel
    u = (0.05, -0.01)
    tm = TaskModel(sweep_doc())
    assert tm.task.moving == ("sweeper",) and tm.task.horizon == 0.8
    ref = simulate(parse_scene(sweep_doc({"position": [0.0, 0.15], "velocity": list(u)})), warm_start=True)
    assert len(ref.t) == 61
    box, pusher = ref.q_com[-1, 0], ref.qk[-1, ref.kinematic_names.index("pusher")]
    assert box[0] > 0.05 and abs(box[2]) > 0.01                  # the sweeper pushed and turned it
    for split in ([60], [5] * 12, [7, 23, 1, 29]):
        x = tm.initial_state()
        for n in split:
            x, ok = tm.advance(x, u, n)
            assert ok
        assert x[-1] == 0.8                                        # the time stops at the horizon
        assert np.abs(x[0:3] - box).max() < 1e-9, split
        assert np.abs(x[3:6] - ref.v_com[-1, 0]).max() < 1e-9, split
        assert np.abs(x[6:8] - pusher[:2]).max() < 1e-12, split


def test_the_time_counts_whole_steps_and_stops_at_the_horizon():
    from planners.tasks import TaskModel
    tm = TaskModel(sweep_doc())
    x = tm.initial_state()
    times = []
    for _ in range(9):
        x, ok = tm.advance(x, (0.0, 0.0), 5)
        times.append(x[-1])
    assert times == [min(5 * (k + 1), 40) * H for k in range(9)]
    assert tm.in_bounds(x) and tm.step_index(x) == 40
    late = x.copy()
    late[-1] = 0.8 + H
    assert not tm.in_bounds(late)
    assert "the time 0.82 s is outside [0, 0.8] s" in tm.why_invalid(late)


def test_the_pusher_is_judged_against_a_moving_body_where_it_is_at_the_states_time():
    from planners.tasks import TaskModel
    tm = TaskModel(GATE)
    x = tm.initial_state()
    x[6:8] = (0.13, 0.0)                                  # in the gateway: the gate is there until t = 1 s
    for t, valid in ((0.0, False), (1.0, False), (1.5, False), (1.7, True), (2.0, True)):   # its top at y -0.032 at 1.7
        x[-1] = t
        assert tm.admissible(x) == valid, t
    x[-1] = 0.5
    assert tm.why_invalid(x) == "the pusher 'pusher' at (0.13, 0) overlaps body 'gate' at t = 0.5 s"
    x[6:8] = (0.13, -0.05)                                # where the gate goes down: free only once it is down
    for t, valid in ((0.0, False), (1.7, False), (2.0, True)):
        x[-1] = t
        assert tm.admissible(x) == valid, t


def test_a_pusher_on_a_path_is_refused():
    doc = sweep_doc({"path": SWEEP})
    doc["bodies"][1] = {**doc["bodies"][1], "path": None}
    del doc["bodies"][1]["path"]
    with pytest.raises(TaskError, match=r"bodies\[2\] \('pusher'\) is task\.pusher and has a path: the planner drives "
                                        r"the pusher, so it must not follow one; got a path of 3 rows"):
        parse_task(doc)


def test_a_csv_path_is_stored_in_the_task_document(tmp_path):
    """A plan file stores the task's document to replay it anywhere: the CSV's rows are in it, and the task is
    the one whose rows are given inline (the same hash)."""
    with open(tmp_path / "sweep.csv", "w") as f:
        f.write("t,sweeper.x,sweeper.y,sweeper.theta\n" + "".join(",".join(map(repr, r)) + "\n" for r in SWEEP))
    from planar_lcp.spec.random_scenes import scene_to_toml
    doc = sweep_doc()
    (tmp_path / "inline.toml").write_text(scene_to_toml(doc))
    inline = load_task(tmp_path / "inline.toml")
    doc["bodies"][1]["path"] = "sweep.csv"
    (tmp_path / "sweep.toml").write_text(scene_to_toml(doc))
    t = load_task(tmp_path / "sweep.toml")
    assert t.document["bodies"][1]["path"] == SWEEP
    assert t.sha256 == inline.sha256 and t.horizon == 0.8


def test_state_space_distance_has_the_times_term():
    """planners/adapter.py's docstring: the weighted sum plus Task.time_weight |dt|."""
    pytest.importorskip("ompl")
    from planners.adapter import state_space, write_state
    from planners.tasks import TaskModel
    tm = TaskModel(GATE)
    space = state_space(tm)
    a, b = space.allocState(), space.allocState()
    w_pos, w_ang, w_vel, w_pus = tm.task.weights
    rng = np.random.default_rng(5)
    for _ in range(5):
        x, y = rng.uniform(-0.1, 0.1, 9), rng.uniform(-0.1, 0.1, 9)
        x[8], y[8] = rng.uniform(0.0, 2.0, 2)
        write_state(a, x, 1, True)
        write_state(b, y, 1, True)
        d = x - y
        expected = (w_pos * math.hypot(d[0], d[1]) + w_ang * abs(d[2]) + w_vel * np.linalg.norm(d[3:6])
                    + w_pus * math.hypot(d[6], d[7]) + tm.task.time_weight * abs(d[8]))
        assert space.distance(a, b) == pytest.approx(expected, rel=1e-12)
    del a, b


def test_a_plan_waits_for_the_gate_and_replays_to_its_goal(tmp_path):
    """`plan` of tasks/push_gate.toml (a fixed iteration budget: reproducible): an exact plan whose states' times are
    whole steps, non-decreasing up to the horizon; replayed, the box stays behind the closed gate (its right face
    short of the gate's left one at x = 0.12 until the gate starts to open at t = 1 s) and reaches its goal, in our
    simulator and, open loop, run in pymunk through the bridge."""
    from planners.plans import load_plan, replay_lcp
    r = run_cli("plan", GATE, "--iterations", 20000, "--seed", 3, "--out", tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "gate on its path (the state holds the time, up to 2 s)" in r.stdout
    plan = json.loads((tmp_path / "plan.json").read_text())
    assert plan["exact"] and plan["state_names"][-1] == "t"
    t = np.array(plan["states"])[:, -1]
    assert np.all(np.diff(t) >= 0) and t[-1] == min(plan["path_duration"], 2.0)
    assert np.abs(t / H - np.round(t / H)).max() < 1e-9
    res = replay_lcp(load_plan(tmp_path / "plan.json").data)
    assert res["report"]["goal_holds"]
    X = res["dense"]
    closed = X[:, -1] <= 1.0 + 1e-9
    assert closed.any() and (X[closed, 0] + 0.05).max() < 0.12 + 1e-3
    assert (X[:, 0] + 0.05).max() > 0.14                       # and it went through
    rp = run_cli("replay", tmp_path / "plan.json", "--simulator", "pymunk", "--out", tmp_path)
    assert rp.returncode == 0, rp.stdout + rp.stderr
    assert "goal_holds" in rp.stdout and "simulation_ok    True" in rp.stdout
