"""A kinematic body on a recorded path (`path`, spec/path.py; docs/scene-format.md, "Recorded paths").

Oracles: a two-row path of a constant velocity is the constant-velocity run (to round-off, our engine and pymunk);
the body lies on the linear interpolation of its rows at every step's end, rests at the first row's pose before it
and the last row's after it; a force-limited body below its limit follows the path exactly as a prescribed one; a
CSV file (a recording's columns, or one body's) gives the same run as the rows; each bad path is refused in one
line naming the field.
"""

import copy
import math

import numpy as np
import pytest

from planar_lcp import kinematic_velocities, simulate
from planar_lcp.spec.path import path_pose, path_velocities
from planar_lcp.spec.scene import SceneError, parse_scene

from cli_helpers import run_cli

H = 0.01


def push_doc(pusher_motion, t_end=0.4):
    """box_push's layout: a 0.2 x 0.1 box on a table and a disk pusher touching its left face 2 cm off centre."""
    pusher = {"name": "pusher", "type": "kinematic", "shapes": [{"type": "disk", "radius": 0.02}], **pusher_motion}
    return {"name": "path_push", "world": {"plane": "horizontal", "friction": 0.3},
            "sim": {"h": H, "t_end": t_end},
            "bodies": [{"name": "box", "type": "dynamic", "mass": 1.0, "support_friction": 0.35,
                        "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}, pusher]}


CONSTANT = {"position": [-0.12, 0.02], "velocity": [0.1, 0.0]}
AS_PATH = {"path": [[0.0, -0.12, 0.02, 0.0], [2.0, 0.08, 0.02, 0.0]]}
#: a curved path with a turn, a pause before its first row and a rest after its last
WIGGLE = {"path": [[0.05, -0.12, 0.02, 0.0], [0.1, -0.115, 0.025, 0.05], [0.2, -0.1, 0.015, 0.1],
                   [0.3, -0.08, 0.03, 0.0]]}


def test_a_constant_velocity_path_is_the_constant_velocity_run():
    a = simulate(parse_scene(push_doc(CONSTANT)))
    b = simulate(parse_scene(push_doc(AS_PATH)))
    assert np.abs(b.q - a.q).max() < 1e-15
    assert np.abs(b.qk - a.qk).max() < 1e-15
    assert np.abs(a.q[-1, 0, :2] - a.q[0, 0, :2]).max() > 0.01          # the box was pushed


def test_the_body_is_on_its_path_at_every_step_and_rests_outside_it():
    scene = parse_scene(push_doc(WIGGLE))
    traj = simulate(scene)
    rows = np.asarray(scene.body("pusher").path)
    assert np.abs(traj.qk[:, 0] - path_pose(rows, traj.t)).max() < 1e-15
    before, after = traj.t <= 0.05, traj.t >= 0.3
    assert np.all(traj.qk[before, 0] == rows[0, 1:])
    assert np.abs(traj.qk[after, 0] - rows[-1, 1:]).max() < 1e-15
    assert scene.body("pusher").position == (-0.12, 0.02) and scene.body("pusher").angle == 0.0


def test_velocities_per_step_are_the_path_differences():
    rows = np.asarray(WIGGLE["path"])
    vk = path_velocities(rows, H, 40)
    assert vk.shape == (40, 3)
    assert np.allclose(vk[:5], 0.0)                                 # before the first row (t = 0.05)
    assert vk[6] == pytest.approx([(0.005) / 0.05, 0.005 / 0.05, 0.05 / 0.05], rel=1e-12)
    assert np.allclose(vk[30:], 0.0)
    scene = parse_scene(push_doc(WIGGLE))
    assert kinematic_velocities(scene, ("pusher",), H, 40)[:, 0] == pytest.approx(vk, abs=0)
    still = parse_scene(push_doc(CONSTANT))
    assert kinematic_velocities(still, ("pusher",), H, 40).shape == (1, 1, 3)   # no path: one row for every step


def test_a_force_limited_body_below_its_limit_follows_the_path_as_a_prescribed_one():
    a = simulate(parse_scene(push_doc(WIGGLE)))
    b = simulate(parse_scene(push_doc({**WIGGLE, "max_force": 1e3})))
    assert np.abs(b.q - a.q).max() < 1e-12
    assert np.abs(b.qk - a.qk).max() < 1e-12


def test_pymunk_moves_the_body_along_the_same_path():
    pytest.importorskip("pymunk")
    from planar_lcp.bridges.pymunk import simulate_pymunk

    scene = parse_scene(push_doc(WIGGLE))
    ours, theirs = simulate(scene), simulate_pymunk(scene)
    assert np.abs(theirs.qk - ours.qk).max() < 1e-15
    const = simulate_pymunk(parse_scene(push_doc(CONSTANT)))
    as_path = simulate_pymunk(parse_scene(push_doc(AS_PATH)))
    assert np.abs(as_path.q - const.q).max() < 1e-15


def test_the_timed_pymunk_unit_moves_the_body_along_the_path_as_the_recorded_run():
    """`bench step`'s pymunk unit (PymunkRun: a whole run without recording) ends where simulate_pymunk does."""
    pytest.importorskip("pymunk")
    from planar_lcp.bridges.pymunk import PymunkRun, read_state, simulate_pymunk

    scene = parse_scene(push_doc(WIGGLE))
    run = PymunkRun(scene, 40)
    run.prepare(1)
    space, handles = run.spaces[0]
    run()
    q, _, qk, _ = read_state(handles)
    ref = simulate_pymunk(scene)
    assert np.abs(qk - ref.qk[-1]).max() < 1e-15 and np.abs(q - ref.q[-1]).max() < 1e-15
    assert np.abs(qk[0] - np.asarray(scene.body("pusher").path)[-1, 1:]).max() < 1e-15


def test_a_csv_path_relative_to_the_scene_file(tmp_path):
    """A recording's file (planar_lcp.spec.recordings) with the pusher's and another body's columns."""
    rows = np.asarray(WIGGLE["path"])
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "tip.csv").write_text("t,pusher.x,pusher.y,pusher.theta,box.x,box.y,box.theta\n" + "".join(
        ",".join(repr(float(x)) for x in r) + ",0,0,0\n" for r in rows))
    toml = tmp_path / "sub" / "scene.toml"
    toml.write_text('name = "csv_path"\n[world]\nplane = "horizontal"\nfriction = 0.3\n[sim]\nh = 0.01\n'
                    't_end = 0.4\n[[bodies]]\nname = "box"\ntype = "dynamic"\nmass = 1.0\nsupport_friction = 0.35\n'
                    'shapes = [ { type = "box", width = 0.2, height = 0.1 } ]\n[[bodies]]\nname = "pusher"\n'
                    'type = "kinematic"\npath = "tip.csv"\nshapes = [ { type = "disk", radius = 0.02 } ]\n')
    from_file = simulate(str(toml))
    from_rows = simulate(parse_scene(push_doc(WIGGLE)))
    assert np.array_equal(from_file.q, from_rows.q) and np.array_equal(from_file.qk, from_rows.qk)
    # the command line too, from another directory
    out = tmp_path / "run.csv"
    r = run_cli("simulate", str(toml), "--csv", str(out), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    last = np.loadtxt(out, delimiter=",", skiprows=1)[-1]
    assert last[1:4] == pytest.approx(from_rows.q[-1, 0], abs=1e-12)


BAD_PATHS = [
    ({"path": []}, "bodies[1].path must have at least 1 row"),
    ({"path": [[0.0, 1.0, 2.0]]}, "bodies[1].path[0] must be 4 numbers [t, x, y, angle], got [0.0, 1.0, 2.0]"),
    ({"path": [[0.0, 0.0, 0.0, 0.0], [0.0, 0.1, 0.0, 0.0]]},
     "bodies[1].path[1][0] (t) must be greater than the previous row's 0.0 s (times strictly increasing), got 0.0"),
    ({"path": [[-1.0, 0.0, 0.0, 0.0]]}, "bodies[1].path[0][0] (t) must be >= 0 s, got -1.0"),
    ({"path": [[0.0, 0.0, 0.0, 0.0], [0.001, 5.0, 0.0, 0.0]]},
     "bodies[1].path[1] must be reached from row 0 within +-1000 m/s in each component (a physical bound), got "
     "5000 m/s"),
    ({"path": [[0.0, 2e4, 0.0, 0.0]]}, "bodies[1].path[0] position must be within +-10000 m"),
    ({"path": [[0.0, 0.0, 0.0, math.nan]]}, "bodies[1].path[0] must be 4 finite numbers"),
    ({"path": [[0.0, 0.0, 0.0, 0.0]], "position": [0.0, 0.0]},
     "bodies[1].position is not allowed with bodies[1].path (the path gives the pose and the velocities)"),
    ({"path": [[0.0, 0.0, 0.0, 0.0]], "velocity": [1.0, 0.0]}, "bodies[1].velocity is not allowed with"),
    ({"path": 3}, "bodies[1].path must be an array of [t, x, y, angle] rows or a CSV file name, got 3"),
    ({"path": "missing.csv"}, "missing.csv: no such recording (CSV file)"),
]


@pytest.mark.parametrize("motion, message", BAD_PATHS)
def test_bad_paths_are_refused_in_one_line(motion, message):
    with pytest.raises(SceneError) as e:
        parse_scene(push_doc(motion))
    text = str(e.value)
    assert "\n" not in text and text.startswith("<dict>: ")
    assert message in text, text


def test_a_path_is_only_for_kinematic_bodies():
    doc = push_doc(CONSTANT)
    doc["bodies"][0]["path"] = [[0.0, 0.0, 0.0, 0.0]]
    with pytest.raises(SceneError, match=r"bodies\[0\]\.path is only allowed on a kinematic body"):
        parse_scene(doc)


def test_a_bad_csv_names_the_file_and_line(tmp_path):
    f = tmp_path / "tip.csv"
    f.write_text("t,box.x,box.y,box.theta\n0,0,0,0\n0.1,0,0,0\n")
    doc = push_doc({"path": str(f)})
    with pytest.raises(SceneError, match=r"tip\.csv: header must have the columns t, pusher\.x, pusher\.y, "
                                         r"pusher\.theta \(a recording of the body's poses\), got the bodies box"):
        parse_scene(doc)
    f.write_text("t,pusher.x,pusher.y,pusher.theta\n0,0,0,0\n0.1,zero,0,0\n")
    with pytest.raises(SceneError, match=r"tip\.csv: line 3, column pusher\.x must be a number, got 'zero'"):
        parse_scene(doc)
    f.write_text("t,pusher.x,pusher.y,pusher.theta\n0,0,0,0\n0.001,5,0,0\n")
    with pytest.raises(SceneError, match=r"path \(.*tip\.csv\)\[1\] must be reached from row 0 within \+-1000 m/s"):
        parse_scene(doc)


def test_a_task_refuses_a_path_on_its_pusher():
    """The planner drives the pusher; another kinematic body may follow a path (tests/planning/test_timed_tasks.py)."""
    from planar_lcp.spec.task import TaskError, parse_task

    doc = push_doc(AS_PATH)
    doc["task"] = {"object": "box", "pusher": "pusher", "goal": {"position": [0.3, 0.0]}}
    with pytest.raises(TaskError, match=r"\('pusher'\) is task\.pusher and has a path: the planner drives the "
                                        r"pusher, so it must not follow one"):
        parse_task(doc)


def test_a_path_scene_is_hashable_and_deep_copies():
    scene = parse_scene(push_doc(WIGGLE))
    hash(scene)
    assert copy.deepcopy(scene) == scene
