"""Recordings (planar_lcp.spec.recordings): the CSV format of a recorded run read back bit for bit, the columns of
`simulate --csv` accepted, every rule of the format refused with one line naming the file, the line or column, the
expected and the actual; the scene decides which bodies are inputs and which are observed."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from planar_lcp.spec.recordings import RecordedRun, RecordingError, read_recording
from planar_lcp.spec.scene import parse_scene


def _run(T=5, names=("box", "pusher"), seed=0):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.001, 0.01, T))
    poses = rng.normal(size=(T, len(names), 3)) * [0.1, 0.1, 0.5]
    return RecordedRun(t, names, poses, "<test>")


def _scene():
    return parse_scene({
        "name": "push", "world": {"plane": "horizontal"},
        "bodies": [
            {"name": "box", "type": "dynamic", "mass": 0.5, "shapes": [{"type": "box", "width": 0.1, "height": 0.1}]},
            {"name": "pusher", "type": "kinematic", "position": [-0.2, 0.0],
             "shapes": [{"type": "disk", "radius": 0.01}]},
            {"name": "post", "type": "static", "position": [0.5, 0.0],
             "shapes": [{"type": "disk", "radius": 0.01}]},
        ]})


def test_round_trip_is_bit_for_bit(tmp_path):
    run = _run()
    run.to_csv(tmp_path / "r.csv")
    back = read_recording(tmp_path / "r.csv")
    assert back.names == run.names
    assert np.array_equal(back.t, run.t) and np.array_equal(back.poses, run.poses)
    assert back.source == str(tmp_path / "r.csv")
    assert (tmp_path / "r.csv").read_text().splitlines()[0] == \
        "t,box.x,box.y,box.theta,pusher.x,pusher.y,pusher.theta"


def test_arrays_are_read_only_copies():
    t = np.array([0.0, 1.0])
    poses = np.zeros((2, 1, 3))
    run = RecordedRun(t, ("a",), poses)
    t[0] = -5.0
    assert run.t[0] == 0.0
    with pytest.raises(ValueError):
        run.poses[0, 0, 0] = 1.0


def test_simulate_csv_columns_and_other_extra_columns_are_ignored(tmp_path):
    # the columns Trajectory.to_csv writes (velocities after each pose), a text column and a dotted body name
    text = ("t,box.x,box.y,box.theta,box.vx,box.vy,box.omega,note,arm.link.x,arm.link.y,arm.link.theta\n"
            "0.0,1.0,2.0,0.5,9,9,9,start,3.0,4.0,-0.5\n"
            "0.01,1.5,2.5,0.75,9,9,9,,3.5,4.5,-0.25\n")
    (tmp_path / "s.csv").write_text(text)
    run = read_recording(tmp_path / "s.csv")
    assert run.names == ("box", "arm.link")
    assert run.poses.tolist() == [[[1.0, 2.0, 0.5], [3.0, 4.0, -0.5]], [[1.5, 2.5, 0.75], [3.5, 4.5, -0.25]]]
    assert run.pose("arm.link")[:, 2].tolist() == [-0.5, -0.25]


def test_path_rows_are_what_a_kinematic_path_takes():
    run = _run()
    rows = run.path_rows("pusher")
    assert rows.shape == (5, 4)
    assert np.array_equal(rows[:, 0], run.t) and np.array_equal(rows[:, 1:], run.poses[:, 1])
    assert all(len(r) == 4 and all(isinstance(x, float) for x in r) for r in rows.tolist())
    with pytest.raises(KeyError, match="no body 'finger' in the recording"):
        run.path_rows("finger")


def test_the_scene_decides_inputs_and_observations():
    assert _run(names=("pusher", "box")).split(_scene()) == (("pusher",), ("box",))
    assert _run(names=("box",)).split(_scene()) == ((), ("box",))


@pytest.mark.parametrize("names, got", [
    (("box", "finger"), "'finger', not a body of the scene"),
    (("post", "box"), "a static body 'post'"),
])
def test_a_name_the_scene_cannot_take_is_one_line(names, got):
    with pytest.raises(RecordingError) as e:
        _run(names=names).split(_scene())
    bad = names[1] if names[1] != "box" else names[0]
    assert str(e.value) == (f"<test>: column {bad}.x must name a kinematic or dynamic body of scene 'push' (one of "
                            f"'box', 'pusher'), got {got}")


def test_select_and_from_trajectory():
    run = _run(names=("a", "b", "c"))
    sub = run.select(["c", "a"])
    assert sub.names == ("c", "a") and np.array_equal(sub.poses[:, 0], run.poses[:, 2])
    traj = SimpleNamespace(t=run.t, q=run.poses[:, :2], qk=run.poses[:, 2:], body_names=("a", "b"),
                           kinematic_names=("c",))
    back = RecordedRun.from_trajectory(traj)
    assert back.names == ("a", "b", "c") and np.array_equal(back.poses, run.poses)


HEADER = "t,box.x,box.y,box.theta"


@pytest.mark.parametrize("text, message", [
    ("", "line 1 must be a header (t, NAME.x, NAME.y, NAME.theta, ...), got an empty file"),
    ("time,box.x,box.y,box.theta\n0,0,0,0\n1,0,0,0\n", "line 1, column 1 must be 't' (the time, s), got 'time'"),
    ("t,box.x,,box.theta\n0,0,0,0\n1,0,0,0\n", "line 1, column 3 must be a column name, got an empty one"),
    ("t,box.x,box.y,box.theta,box.x\n0,0,0,0,0\n1,0,0,0,0\n",
     "line 1, column 5 must not repeat column 2, got 'box.x' twice"),
    ("t,box.vx,note\n0,0,a\n1,0,b\n",
     "line 1 must name at least one body's columns NAME.x, NAME.y, NAME.theta after t, got t, box.vx, note"),
    ("t,box.x,box.theta\n0,0,0\n1,0,0\n",
     "line 1 must have the columns box.x, box.y, box.theta of body 'box', got no box.y"),
    (HEADER + "\n0,0,0,0\n", "must have at least 2 rows of samples after the header, got 1"),
    (HEADER + "\n", "must have at least 2 rows of samples after the header, got 0"),
    (HEADER + "\n0,0,0,0\n1,0,0\n", "line 3 must have 4 fields (as the header), got 3"),
    (HEADER + "\n0,0,0,0\n\n1,0,abc,0\n", "line 4, column box.y must be a number, got 'abc'"),
    (HEADER + "\n0,0,0,0\n1,0,0,nan\n", "line 3, column box.theta must be a finite number, got nan"),
    (HEADER + "\n0,0,0,0\ninf,0,0,0\n", "line 3, column t must be a finite number, got inf"),
    (HEADER + "\n0,0,0,0\n1,0,0,0\n1,0,0,0\n",
     "line 4, column t must be greater than the previous sample's 1.0 s (strictly increasing), got 1.0"),
    (HEADER + "\n0,0,0,3.1\n1,0,0,-3.1\n",
     "line 3, column box.theta must be continuous (unwrapped: within pi of the previous sample's 3.1 rad), got -3.1"),
])
def test_every_rule_of_the_format_is_one_line(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(RecordingError) as e:
        read_recording(path)
    assert str(e.value) == f"{path}: {message}"
    assert "\n" not in str(e.value)
    assert isinstance(e.value, ValueError)


def test_files_that_cannot_be_read(tmp_path):
    with pytest.raises(RecordingError, match=r"no such recording \(CSV file\)$"):
        read_recording(tmp_path / "absent.csv")
    with pytest.raises(RecordingError, match="is a directory, not a recording"):
        read_recording(tmp_path)
    (tmp_path / "latin1.csv").write_bytes(HEADER.encode() + b"\n0,0,0,0\n1,0,\xe9,0\n")
    with pytest.raises(RecordingError, match=r"latin1.csv: must be UTF-8 text, got byte 0xe9 at byte offset 36 "
                                             r"\(invalid continuation byte\)$"):
        read_recording(tmp_path / "latin1.csv")


def test_a_byte_order_mark_and_spaces_in_the_header_are_accepted(tmp_path):
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbft, box.x, box.y, box.theta\n0, 1, 2, 3\n1, 1, 2, 3\n")
    assert read_recording(tmp_path / "bom.csv").poses[1, 0].tolist() == [1.0, 2.0, 3.0]


@pytest.mark.parametrize("kw, message", [
    (dict(t=[0.0, 1.0], names=("a", "a"), poses=np.zeros((2, 2, 3))), "names must be unique, got 'a' twice"),
    (dict(t=[0.0, 1.0], names=(), poses=np.zeros((2, 0, 3))),
     "names must be a non-empty tuple of non-empty strings, got ()"),
    (dict(t=[0.0, 1.0], names=("a",), poses=np.zeros((3, 1, 3))),
     "poses must have shape (T, nbody, 3) = (2, 1, 3), got (3, 1, 3)"),
    (dict(t=[0.0], names=("a",), poses=np.zeros((1, 1, 3))), "must have at least 2 samples, got 1"),
    (dict(t=[0.0, 0.0], names=("a",), poses=np.zeros((2, 1, 3))),
     "row 1, t must be greater than the previous sample's 0.0 s (strictly increasing), got 0.0"),
    (dict(t=[0.0, 1.0], names=("a",), poses=[[[0, 0, 0]], [[0, math.inf, 0]]]),
     "row 1, a.y must be a finite number, got inf"),
])
def test_the_constructor_checks_the_same_rules(kw, message):
    with pytest.raises(RecordingError) as e:
        RecordedRun(source="mine", **kw)
    assert str(e.value) == f"mine: {message}"
