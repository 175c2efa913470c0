"""Task files: a scene file's [task] table, its validation, its derived defaults, its goals and its
workspace, tested without OMPL (tests/planning/test_task_planning.py plans them).

The oracles: the exact one-line message of each bad task file (the scene loader's style); goal tests against poses
built by hand (the body frame, free coordinates, rest, cover); the workspace test against shapely's geometry of the
placed bodies; goal samples inside the goal region; and seeded random task files that all load."""

import math
import re

import numpy as np
import pytest

from planar_lcp.spec.random_scenes import random_task, scene_to_toml
from planar_lcp.spec.scene import read_document, scenes_dir
from planar_lcp.spec.task import TASK_KEYS, TaskError, load_task

pytest.importorskip("shapely")

MINIMAL = """
name = "minimal"
[world]
plane = "horizontal"
[[bodies]]
name = "box"
type = "dynamic"
mass = 0.5
shapes = [ { type = "box", width = 0.1, height = 0.1 } ]
[[bodies]]
name = "pusher"
type = "kinematic"
position = [-0.08, 0.0]
shapes = [ { type = "disk", radius = 0.015 } ]

[task]
object = "box"
pusher = "pusher"
goal = { x = 0.1, y = 0.0 }
"""


def test_a_minimal_task_is_three_lines_and_gets_every_default():
    t = load_task(MINIMAL)
    assert MINIMAL.split("[task]")[1].strip().count("\n") == 2            # three lines
    assert (t.name, t.source, t.object, t.pusher, t.obstacles) == ("minimal", "<string>", "box", "pusher", ())
    assert t.given == {"object", "pusher", "goal"}
    assert t.planner == "RRT" and t.time == 60.0 and t.goal_bias == 0.1
    L = math.hypot(0.05, 0.05)                                            # the box's circumradius
    assert t.object_extent["circumradius"] == pytest.approx(L) and t.object_extent["min_support"] == pytest.approx(0.05)
    assert t.control_max == pytest.approx(2 * L) and t.speed_max == pytest.approx(16 * L)
    assert t.omega_max == pytest.approx(16.0)
    h = 0.0025                                                            # the scene's default [sim] h
    assert t.step_duration == pytest.approx(40 * h) and (t.min_steps, t.max_steps) == (1, 10)
    assert t.weights == pytest.approx((1.0, math.sqrt(0.02 / 12), 0.02 * 0.1, 0.1))   # the box's radius of gyration
    # the workspace: the bodies (box -0.05..0.05, pusher -0.095..-0.065) and the object at the goal point at any
    # angle ((0.1, 0) +- L), grown by the object's diameter 2 L
    assert np.array(t.workspace) == pytest.approx(np.array(((-0.095 - 2 * L, 0.1 + 3 * L), (-3 * L, 3 * L))))
    (x0, x1), (y0, y1) = t.workspace
    assert np.array(t.pusher_workspace) == pytest.approx(np.array(((x0 - 0.03, x1 + 0.03), (y0 - 0.03, y1 + 0.03))))
    g = t.goal
    assert (g.x, g.y, g.angle, g.position_tol, g.at_rest, g.min_cover) == (0.1, 0.0, None, 0.01, False, None)


def test_the_shipped_tasks_are_files_and_keep_their_tuned_limits():
    from planners.tasks import TaskModel
    for name in ("push_box", "push_t", "tip_box", "push_clutter", "push_table"):
        t = load_task(name)
        assert t.source == f"scenes/{name}.toml" and t.name == name
        assert t.document == read_document(scenes_dir() / f"{name}.toml")[0]
    # the COM bounds the planner samples are the ones the tasks had before task files (the workspace less the
    # object's least half-width)
    assert np.array(TaskModel("push_box").com_bounds[0]) == pytest.approx(np.array(((-0.15, 0.40), (-0.20, 0.30))))
    assert np.array(TaskModel("push_t").com_bounds[0]) == pytest.approx(np.array(((-0.20, 0.25), (-0.20, 0.25))), abs=1e-4)
    assert np.array(TaskModel("tip_box").com_bounds[0]) == pytest.approx(np.array(((-0.30, 0.22), (0.0, 0.25))))
    assert np.array(TaskModel("push_clutter").com_bounds[0]) == pytest.approx(np.array(((-0.33, 0.33), (-0.18, 0.18))))
    assert load_task("push_clutter").obstacles == ("disk", "crate", "rod", "wedge")   # every other dynamic body


def _doc(name="push_box"):
    return read_document(scenes_dir() / f"{name}.toml")[0]


def _set(doc, path, value):
    """doc with the value at `path` (keys and indices) replaced; value DELETE removes it."""
    *head, last = path
    d = doc
    for k in head:
        d = d[k]
    if value is DELETE:
        del d[last]
    else:
        d[last] = value


DELETE = object()
G = ("task", "goal")

#: (id, base task, [(path, value)], the message after "FILE: ")
MUTATIONS = [
    ("unknown key", "push_box", [(("task", "planer"), "RRT")],
     "task: unknown key 'planer' (allowed: " + ", ".join(TASK_KEYS) + ")"),
    ("no object", "push_box", [(("task", "object"), DELETE)], "task.object is required"),
    ("misspelt object", "push_box", [(("task", "object"), "bx")],
     "task.object must name a dynamic body of the scene (one of 'box'), got 'bx'"),
    ("static object", "push_box", [(("task", "object"), "block")],
     "task.object must be a dynamic body (one of 'box'), got 'block', a static body"),
    ("object not a string", "push_box", [(("task", "object"), 3)], "task.object must be a non-empty string, got 3"),
    ("no pusher", "push_box", [(("task", "pusher"), DELETE)], "task.pusher is required"),
    ("misspelt pusher", "push_box", [(("task", "pusher"), "pushr")],
     "task.pusher must name a kinematic body of the scene (one of 'pusher'), got 'pushr'"),
    ("dynamic pusher", "push_box", [(("task", "pusher"), "box")],
     "task.pusher must be a kinematic body (one of 'pusher'), got 'box', a dynamic body"),
    ("no goal", "push_box", [(G, DELETE)], "task.goal is required"),
    ("goal not a table", "push_box", [(G, 3)], "task.goal must be a table, got 3"),
    ("empty goal", "push_box", [(G, {})], "task.goal must name at least one of x, y and angle_deg, got none"),
    ("goal unknown key", "push_box", [(G + ("theta_deg",), 0.0)],
     "task.goal: unknown key 'theta_deg' (allowed: x, y, angle_deg, position_tol, angle_tol_deg, at_rest, "
     "speed_tol, omega_tol, min_cover)"),
    ("goal x a string", "push_box", [(G + ("x",), "0.2")], "task.goal.x must be a number, got '0.2'"),
    ("zero position_tol", "push_box", [(G + ("position_tol",), 0.0)], "task.goal.position_tol must be > 0, got 0.0"),
    ("negative angle_tol", "push_box", [(G + ("angle_tol_deg",), -5)],
     "task.goal.angle_tol_deg must be > 0, got -5.0"),
    ("angle_tol without angle", "push_box", [(G + ("angle_deg",), DELETE), (G + ("angle_tol_deg",), 5.0)],
     "task.goal.angle_tol_deg needs angle_deg in the goal, got 5.0 without it"),
    ("position_tol without position", "tip_box", [(G + ("y",), DELETE)],
     "task.goal.position_tol needs x or y in the goal, got 0.005 with neither"),
    ("min_cover 0", "push_t", [(G + ("min_cover",), 0.0)], "task.goal.min_cover must be in (0, 1], got 0.0"),
    ("min_cover 1.5", "push_t", [(G + ("min_cover",), 1.5)], "task.goal.min_cover must be in (0, 1], got 1.5"),
    ("min_cover without angle", "push_t", [(G + ("angle_deg",), DELETE)],
     "task.goal.min_cover needs x, y and angle_deg (the goal footprint), got no angle_deg"),
    ("min_cover with a tolerance", "push_t", [(G + ("position_tol",), 0.01)],
     "task.goal.position_tol is not used with min_cover (the cover decides), got 0.01; remove one"),
    ("speed_tol without at_rest", "push_box", [(G + ("speed_tol",), 0.01)],
     "task.goal.speed_tol needs at_rest = true, got 0.01 without it"),
    ("at_rest a string", "push_box", [(G + ("at_rest",), "yes")], "task.goal.at_rest must be true or false, got 'yes'"),
    ("zero omega_tol", "tip_box", [(G + ("omega_tol",), 0)], "task.goal.omega_tol must be > 0, got 0.0"),
    ("goal outside the workspace", "push_box", [(G + ("x",), 5.0)],
     "task.goal must place the object inside task.workspace = [[-0.2, 0.45], [-0.25, 0.35]], got the object spanning "
     "x 4.95..5.05, y 0.03..0.13 at the goal"),
    ("goal y outside the workspace", "tip_box", [(G + ("y",), 0.5)],
     "task.goal.y must lie inside task.workspace (-0.05 .. 0.3), got 0.5"),
    ("step not a multiple of h", "push_box", [(("task", "step_duration"), 0.015)],
     "task.step_duration must be a multiple of the scene's sim.h = 0.02 s, got 0.015 (0.75 steps)"),
    ("negative step", "push_box", [(("task", "step_duration"), -0.1)], "task.step_duration must be > 0, got -0.1"),
    ("control_steps reversed", "push_box", [(("task", "control_steps"), [5, 2])],
     "task.control_steps must be [min, max] with min <= max, got [5, 2]"),
    ("control_steps zero", "push_box", [(("task", "control_steps"), [0, 3])],
     "task.control_steps[0] must be >= 1, got 0"),
    ("control_steps a float", "push_box", [(("task", "control_steps"), [1.5, 3])],
     "task.control_steps[0] must be an integer, got 1.5"),
    ("control_steps a string", "push_box", [(("task", "control_steps"), "1..10")],
     "task.control_steps must be [min, max], 2 integers, got '1..10'"),
    ("control_steps huge", "push_box", [(("task", "control_steps"), [1, 10**6])],
     "task.control_steps[1] must be <= 1000, got 1000000"),
    ("workspace reversed", "push_box", [(("task", "workspace"), [[0.45, -0.2], [-0.25, 0.35]])],
     "task.workspace[0] must be [xmin, xmax] with xmin < xmax, got [0.45, -0.2]"),
    ("workspace flat", "push_box", [(("task", "workspace"), [-0.2, 0.45])],
     "task.workspace must be [[xmin, xmax], [ymin, ymax]] in m, got [-0.2, 0.45]"),
    ("workspace infinite", "push_box", [(("task", "pusher_workspace"), [[-0.25, float("inf")], [-0.3, 0.4]])],
     "task.pusher_workspace[0][1] must be a finite number, got inf"),
    ("unknown planner", "push_box", [(("task", "planner"), "SST")],
     "task.planner must be one of 'RRT', 'EST', 'KPIECE1', 'SyclopRRT', 'SyclopEST', got 'SST'"),
    ("zero time", "push_box", [(("task", "time"), 0)], "task.time must be > 0, got 0.0"),
    ("a year of time", "push_box", [(("task", "time"), 3.2e7)], "task.time must be <= 86400, got 32000000.0"),
    ("negative control_max", "push_box", [(("task", "control_max"), -0.1)],
     "task.control_max must be > 0, got -0.1"),
    ("speed_max a string", "push_box", [(("task", "speed_max"), "fast")],
     "task.speed_max must be a number, got 'fast'"),
    ("goal_bias 1", "push_box", [(("task", "goal_bias"), 1.0)], "task.goal_bias must be in [0, 1), got 1.0"),
    ("description a number", "push_box", [(("task", "description"), 3)], "task.description must be a string, got 3"),
    ("task not a table", "push_box", [(("task",), 5)], "task must be a table, got 5"),
    ("a second kinematic body moves", "push_box",
     [(("bodies", 1), {"name": "belt", "type": "kinematic", "position": [0.3, 0.3], "velocity": [0.1, 0.0],
                       "shapes": [{"type": "disk", "radius": 0.01}]})],
     "bodies[1] ('belt') is a kinematic body other than task.pusher: it must stand still or follow a path in a task "
     "(velocity [0, 0], angular_velocity 0), got velocity [0.1, 0.0], angular_velocity 0.0"),
    # the checks that need the geometry (planners.tasks.TaskModel), also before any planning
    ("goal inside a static body", "push_box", [(G + ("x",), 0.13), (G + ("y",), -0.03)],
     "task.goal must not place the object inside a static body, got 40.0% of its area overlapping the static bodies "
     "at (0.13, -0.03, 0 deg)"),
    ("start outside the workspace", "push_box", [(("task", "workspace"), [[0.0, 0.45], [-0.25, 0.35]])],
     "the start state is already invalid: body 'box' is not inside task.workspace = [[0.0, 0.45], [-0.25, 0.35]]"),
    ("pusher outside its workspace", "push_box", [(("task", "pusher_workspace"), [[0.0, 0.5], [-0.3, 0.4]])],
     "the start state is already invalid: the pusher 'pusher' at (-0.08, 0) is outside task.pusher_workspace = "
     "[[0.0, 0.5], [-0.3, 0.4]]"),
    ("pusher starts in the block", "push_box", [(("bodies", 2, "position"), [0.13, -0.03])],
     "the start state is already invalid: the pusher 'pusher' at (0.13, -0.03) overlaps a static body"),
    ("workspace narrower than the object", "push_box", [(G + ("angle_deg",), DELETE),
                                                        (("task", "workspace"), [[-0.2, 0.45], [0.05, 0.12]])],
     "task.workspace must be wider than body 'box' in x and y (its least width is 0.1 m), got [[-0.2, 0.45], "
     "[0.05, 0.12]]"),
]


def _mutated_file(tmp_path, base, changes):
    import copy
    doc = copy.deepcopy(_doc(base))
    for path, value in changes:
        if path[0] == "bodies" and len(path) == 2 and path[1] == 1:
            doc["bodies"].insert(1, value)                # a new body, so the others keep their places
        else:
            _set(doc, path, value)
    f = tmp_path / f"{base}_mutated.toml"
    if isinstance(doc.get("task"), dict):
        f.write_text(scene_to_toml(doc))
    else:                                   # a [task] that is not a table: a top-level key, before the tables
        value = doc.pop("task")
        text = scene_to_toml(doc)
        f.write_text(f"task = {value!r}\n" + text)
    return f


@pytest.mark.parametrize("case, base, changes, message", MUTATIONS, ids=[m[0] for m in MUTATIONS])
def test_a_bad_task_file_gives_one_line_naming_the_file_and_the_key(tmp_path, case, base, changes, message):
    from planners.tasks import TaskModel
    f = _mutated_file(tmp_path, base, changes)
    with pytest.raises(TaskError) as e:
        TaskModel(f)
    assert str(e.value) == f"{f}: {message}"
    assert "\n" not in str(e.value)


def test_at_least_25_mutations_are_tested():
    assert len(MUTATIONS) >= 25


@pytest.mark.parametrize("case", ["misspelt object", "goal inside a static body", "step not a multiple of h"])
def test_plan_and_plan_bench_refuse_a_bad_task_file_before_any_work(tmp_path, case):
    from cli_helpers import run_cli
    pytest.importorskip("ompl")
    _, base, changes, message = next(m for m in MUTATIONS if m[0] == case)
    f = _mutated_file(tmp_path, base, changes)
    for cmd in (["plan", f, "--iterations", "10"], ["plan-bench", f, "--runs", "1", "--iterations", "10"]):
        out = tmp_path / "out"
        r = run_cli(*cmd, "--out", out, timeout=120)
        assert r.returncode == 2, r.stdout + r.stderr
        assert r.stderr == f"planar-lcp {cmd[0]}: error: {f}: {message}\n", r.stderr
        assert not out.exists() and r.stdout == ""                    # nothing written, no work started


def test_a_scene_without_a_task_and_an_unknown_name_are_named():
    with pytest.raises(TaskError, match=r"falling_rod.toml: task is required: a \[task\] table .* 'falling_rod' "
                                        r"has none"):
        load_task("falling_rod")
    with pytest.raises(TaskError, match=r"unknown task 'push_sofa': not a shipped task \(shipped tasks: push_box, "
                                        r"push_clutter, push_t, push_table, tip_box\)"):
        load_task("push_sofa")
    with pytest.raises(TaskError, match=r"<string>: invalid TOML"):
        load_task("[task\nobject = 1\n")


def test_a_task_from_text_a_dict_and_a_file_is_the_same_task(tmp_path):
    import tomllib
    f = tmp_path / "mine.toml"
    f.write_text(MINIMAL)
    a, b, c = load_task(MINIMAL), load_task(tomllib.loads(MINIMAL)), load_task(f)
    assert a.sha256 == b.sha256 == c.sha256 and a.document == c.document
    assert (a.source, b.source, c.name) == ("<string>", "<dict>", "mine")
    assert a.workspace == c.workspace and a.goal == c.goal


# ---- goals ----------------------------------------------------------------------------------------------------


def _model(text):
    from planners.tasks import TaskModel
    return TaskModel(load_task(text))


def _com_state(tm, frame_pose, v=(0.0, 0.0, 0.0)):
    """The flat state with the object's BODY FRAME at frame_pose (its COM computed), the pusher at its start."""
    from planar_lcp.frames import frame_to_com
    x = tm.initial_state()
    x[0:3] = frame_to_com(np.array([frame_pose], float), tm.com_local1)[0]
    x[3:6] = v
    return x


def test_a_position_goal_leaves_the_angle_free_and_is_on_the_body_frame():
    # the T's centre of mass is 2.6 cm below its frame: the goal names where the FRAME goes
    text = (scenes_dir() / "push_t.toml").read_text().split("[task]")[0] + (
        '[task]\nobject = "T"\npusher = "pusher"\ngoal = { x = 0.06, y = 0.08 }\n')
    tm = _model(text)
    assert tm.com_local[1] == pytest.approx(-0.0257, abs=1e-4)
    for angle in (0.0, 1.0, -2.5, math.pi):
        x = _com_state(tm, (0.06, 0.08, angle))
        assert tm.goal_distance(x) == pytest.approx(0.0, abs=1e-12)
        assert tm.goal_report(x)["goal_holds"] and "angle_error_deg" not in tm.goal_report(x)
    x = _com_state(tm, (0.06 + 0.006, 0.08 + 0.008, 0.3))          # 1 cm away: exactly the tolerance
    assert tm.goal_distance(x) == pytest.approx(1.0)
    x = _com_state(tm, (0.06, 0.08 + 0.0101, 0.3))
    assert tm.goal_distance(x) > 1
    # its COM at the goal point is not the frame there (the T turned by 90 degrees: the frame is 2.6 cm to the side)
    y = tm.initial_state()
    y[0:3] = (0.06, 0.08, math.pi / 2)
    assert tm.goal_distance(y) == pytest.approx(0.02571428571 / 0.01, rel=1e-6)


def test_an_angle_goal_is_a_turn_in_place_anywhere_and_a_tip_goal_leaves_x_free():
    text = MINIMAL.replace("goal = { x = 0.1, y = 0.0 }", "goal = { angle_deg = 45.0, angle_tol_deg = 5.0 }")
    tm = _model(text)
    for pos in ((0.0, 0.0), (0.1, -0.05), (-0.12, 0.07)):
        assert tm.goal_distance(_com_state(tm, (*pos, math.radians(45.0)))) == pytest.approx(0.0, abs=1e-12)
        assert tm.goal_distance(_com_state(tm, (*pos, math.radians(45.0 - 4.0)))) == pytest.approx(0.8)
        assert tm.goal_distance(_com_state(tm, (*pos, math.radians(45.0 + 90.0)))) == pytest.approx(18.0)
    # the angle the shorter way round
    assert tm.goal_distance(_com_state(tm, (0.0, 0.0, math.radians(45.0 - 360.0)))) == pytest.approx(0.0, abs=1e-9)
    tip = _model((scenes_dir() / "tip_box.toml").read_text())
    for bx in (-0.2, 0.0, 0.15):
        at_rest = _com_state(tip, (bx, 0.05, -math.pi / 2))
        assert tip.goal_distance(at_rest) == pytest.approx(0.0, abs=1e-12)
        assert tip.goal_distance(_com_state(tip, (bx, 0.05, math.pi / 2))) > 1        # the other side: the sign
        assert tip.goal_distance(_com_state(tip, (bx, 0.05, -math.pi / 2), v=(0.03, 0.0, 0.0))) == pytest.approx(1.5)
        assert tip.goal_distance(_com_state(tip, (bx, 0.05, -math.pi / 2), v=(0.0, 0.0, 0.1))) == pytest.approx(0.5)


def test_at_rest_needs_speed_and_spin_within_their_tolerances():
    tm = _model(MINIMAL.replace("goal = { x = 0.1, y = 0.0 }", "goal = { x = 0.1, y = 0.0, at_rest = true }"))
    assert tm.goal_distance(_com_state(tm, (0.1, 0.0, 2.0))) == 0.0
    assert tm.goal_distance(_com_state(tm, (0.1, 0.0, 2.0), v=(0.003, 0.004, 0.0))) == pytest.approx(1.0)
    assert tm.goal_distance(_com_state(tm, (0.1, 0.0, 2.0), v=(0.0, 0.0, 0.06))) == pytest.approx(1.2)
    r = tm.goal_report(_com_state(tm, (0.1, 0.0, 2.0), v=(0.0, 0.0, 0.06)))
    assert r["omega_rad_s"] == pytest.approx(0.06) and not r["goal_holds"]


def test_the_cover_goal_is_the_covered_share_of_the_goal_footprint():
    from planners.tasks import TaskModel, _place
    tm = TaskModel("push_t")
    rng = np.random.default_rng(11)
    g = tm.task.goal
    n_goal = 0
    for _ in range(400):
        # poses around the goal: the proxy (a cheap pose bound) never rejects a pose the cover accepts
        d = rng.normal(0.0, 1.0, 3) * (0.004, 0.004, 0.05)
        x = _com_state(tm, (g.x + d[0], g.y + d[1], g.angle + d[2]))
        pf = tm.object_frame_pose(x)
        cover = _place(tm.object_poly_body, pf[:2], pf[2]).intersection(tm.goal_poly).area / tm.goal_poly.area
        holds = cover >= g.min_cover
        n_goal += holds
        assert (tm.goal_distance(x) <= 1.0) == holds, (d, cover)
    assert 20 < n_goal < 380             # both sides of the boundary were tried
    # the cheap bound is the centroid inequality |a' - a| <= 2 L (1 - cover) / cover (TaskModel._cover_bound),
    # checked at any angle and for the cover each pose has, not only the goal's min_cover
    L = tm.object_radius
    for _ in range(400):
        d = np.array([*rng.uniform(-0.01, 0.01, 2), rng.uniform(-math.pi, math.pi)])
        x = _com_state(tm, (g.x + d[0], g.y + d[1], g.angle + d[2]))
        pf = tm.object_frame_pose(x)
        cover = _place(tm.object_poly_body, pf[:2], pf[2]).intersection(tm.goal_poly).area / tm.goal_poly.area
        if cover > 0:
            assert math.hypot(*(x[:2] - tm.goal_com[:2])) <= 2 * L * (1 - cover) / cover + 1e-12, (d, cover)


def test_goal_samples_lie_in_the_goal_region_and_the_bounds():
    from planners.tasks import TaskModel
    rng = np.random.default_rng(5)
    draw = lambda lo, hi: float(rng.uniform(lo, hi))       # noqa: E731 - OMPL's uniformReal
    tasks = ["push_box", "push_t", "tip_box", "push_clutter"] + [scene_to_toml(random_task(s)) for s in range(12)]
    for src in tasks:
        tm = TaskModel(load_task(src))
        for _ in range(50):
            x = tm.sample_goal(draw)
            assert tm.goal_distance(x) <= 1.0, tm.task.name
            (x0, x1), (y0, y1) = tm.com_bounds[0]
            assert x0 <= x[0] <= x1 and y0 <= x[1] <= y1, tm.task.name


# ---- workspace ------------------------------------------------------------------------------------------------


def test_no_point_of_any_body_may_leave_the_workspace_exactly_as_shapely_places_it():
    """TaskModel.valid against the placed geometry's bounds (shapely, arcs with 64 segments per quarter: within
    3e-5 of the true circle), over random states of push_clutter's five bodies of four shapes."""
    from shapely.ops import unary_union

    from planar_lcp.frames import com_to_frame
    from planar_lcp.geometry import shape_geometry
    from planners.tasks import TaskModel, _place
    tm = TaskModel("push_clutter")
    t = tm.task
    (wx0, wx1), (wy0, wy1) = t.workspace
    names = [t.object, *t.obstacles]
    geoms = [unary_union([shape_geometry(s, quad_segs=64) for s in tm.scene.body(n).shapes]) for n in names]
    rng = np.random.default_rng(2)
    seen = {True: 0, False: 0}
    for _ in range(1500):
        x = tm.initial_state()
        i = int(rng.integers(len(names)))
        x[6 * i:6 * i + 2] = rng.uniform((wx0 - 0.02, wy0 - 0.02), (wx1 + 0.02, wy1 + 0.02))
        x[6 * i + 2] = rng.uniform(-math.pi, math.pi)
        pf = com_to_frame(x[6 * i:6 * i + 3][None], tm.model.com_local[tm.dyn_order[i:i + 1]])[0]
        bx0, by0, bx1, by1 = _place(geoms[i], pf[:2], pf[2]).bounds
        margin = min(bx0 - wx0, wx1 - bx1, by0 - wy0, wy1 - by1)
        if abs(margin) < 1e-4:
            continue                                       # within shapely's arc approximation of the edge
        inside = margin > 0
        assert tm.inside_workspace(x, i) == inside, (names[i], margin)
        seen[inside] += 1
    assert min(seen.values()) > 200


def test_seeded_random_task_files_all_load_with_derived_defaults():
    from planners.tasks import TaskModel
    kinds = set()
    for seed in range(40):
        doc = random_task(seed)
        assert random_task(seed) == doc                                  # seeded
        t = load_task(scene_to_toml(doc))
        tm = TaskModel(t)
        assert tm.admissible(tm.initial_state())
        assert tm.goal_distance(tm.initial_state()) > 1                  # not already solved
        kinds.add(re.search(r": (\w+) goal", t.description).group(1))
    assert kinds == {"pose", "position", "angle", "rest", "cover", "tip"}


def test_the_benchmark_task_files_load_each_of_a_different_kind():
    """tasks/*.toml (docs/planning.md, "New problems"): at least 8 files, each a valid task, with the derived defaults
    except the keys it names; among them a non-convex compound object, a triangle, a disk, a capsule, a
    position-only goal, an angle-only goal, a goal at rest, a cover goal, a vertical tip goal, six or more movable
    obstacles, a heavy high-friction object and a gate on a path (a timed task)."""
    from pathlib import Path

    from planners.tasks import TaskModel
    files = sorted((Path(__file__).resolve().parents[2] / "tasks").glob("*.toml"))
    assert len(files) >= 8
    seen = set()
    for f in files:
        tm = TaskModel(f)
        t, g = tm.task, tm.task.goal
        assert t.given == {"object", "pusher", "goal"}, (f.name, t.given)      # every other key derived
        body = t.scene.body(t.object)
        types = {s.type for s in body.shapes}
        seen |= {f"shape:{ty}" for ty in types} | ({"compound"} if len(body.shapes) > 1 else set())
        if not tm.object_poly_body.equals(tm.object_poly_body.convex_hull):
            seen.add("non-convex")
        if len(body.shapes) == 1 and body.shapes[0].type == "polygon" and len(body.shapes[0].vertices) == 3:
            seen.add("triangle")
        seen.add("position only" if g.angle is None and g.x is not None and g.y is not None else
                 "angle only" if g.x is None and g.y is None else "")
        seen |= {"at rest"} if g.at_rest and t.scene.world.plane == "horizontal" else set()
        seen |= {"cover"} if g.min_cover is not None else set()
        seen |= {"tip"} if t.scene.world.plane == "vertical" and g.x is None else set()
        seen |= {"crowd"} if len(t.obstacles) >= 6 else set()
        seen |= {"heavy"} if body.mass >= 5.0 and (body.support_friction or 0.0) >= 0.8 else set()
        seen |= {"moving body"} if t.timed else set()
    assert {"compound", "non-convex", "triangle", "shape:disk", "shape:capsule", "position only", "angle only",
            "at rest", "cover", "tip", "crowd", "heavy", "moving body"} <= seen, seen
