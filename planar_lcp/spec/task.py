"""Planning tasks: a scene file's `[task]` table, validated against its scene, with every default derived.

A task names the dynamic body to bring to a goal (`object`), the kinematic body whose velocity (vx, vy) the planner
drives (`pusher`) and the goal (`[task.goal]`); everything else has a default derived from the scene, so that a
minimal task is three lines:

    [task]
    object = "box"
    pusher = "pusher"
    goal = { x = 0.25, y = 0.08 }

Every other dynamic body of the scene is a movable obstacle. The keys, their units and their defaults are documented
in docs/scene-format.md, "Task files"; the messages follow the scene loader's (`FILE: task.KEY must be ..., got
...`). This module is numpy only: the geometric checks that need shapely (a goal overlapping a static body, a start
state that is already invalid) are made by `planners.tasks.TaskModel`, also before any planning.
"""

from __future__ import annotations

import hashlib
import json
import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planar_lcp.frames import rotation
from planar_lcp.spec.massprops import body_area_properties
from planar_lcp.spec.scene import (MAX_LENGTH, MAX_SERVO_FORCE, SceneError, _fmt_num, _is_real, _Validator,
                                   display_source, find_scene_file, parse_scene, parse_toml, read_document, scene_files,
                                   scene_path)

#: The OMPL control planners that the 2.0.1 wheel can construct from Python (SST and PDST have no constructor
#: there, docs/planning.md). Here, not in planners.adapter, so that tasks and the CLI check them without ompl.
PLANNERS = ("RRT", "EST", "KPIECE1", "SyclopRRT", "SyclopEST")
DEFAULT_PLANNER = "RRT"            # the best measured on every shipped task (docs/planning.md)

TASK_KEYS = ("object", "pusher", "goal", "description", "planner", "time", "control_max", "step_duration",
             "control_steps", "workspace", "pusher_workspace", "speed_max", "omega_max", "goal_bias",
             "pusher_max_force")
GOAL_KEYS = ("x", "y", "angle_deg", "position_tol", "angle_tol_deg", "at_rest", "speed_tol", "omega_tol",
             "min_cover")

# Upper bounds that keep a typo from asking for days of planning or a control held for hours.
MAX_TIME = 86_400.0                # s of planning budget
MAX_CONTROL_STEPS = 1_000          # propagation steps one control is held
#: OMPL's seeds (ompl.util.RNG.setSeed) are a std::uint_fast32_t: 32 bits on every platform (64 on Linux x86-64,
#: where the 2.0.1 wheel raises TypeError only above 2**64 - 1); the 32-bit bound keeps a seed valid, and its plan
#: the same, on any machine
MAX_SEED = 2**32 - 1
#: runs per planner of a benchmark (seeds 1..N; at a second or more each, more than a day)
MAX_RUNS = 100_000
#: the default propagation step: the multiple of h nearest this (s)
DEFAULT_STEP = 0.1


class TaskError(SceneError):
    """A bad task file, task name, plan file or planning request; the message names the source, the key and what
    was expected."""


@dataclass(frozen=True)
class Goal:
    """The goal of a task, on the object's BODY-FRAME pose (as `position` / `angle` in the scene).

    Each of x, y (m) and angle (rad) is None when the goal leaves it free. Position errors are measured over the
    named coordinates (the distance in the plane when both are named), the angle error the shorter way round.
    """

    x: float | None
    y: float | None
    angle: float | None
    position_tol: float = 0.01
    angle_tol: float = math.radians(10.0)
    at_rest: bool = False
    speed_tol: float = 0.005
    omega_tol: float = 0.05
    min_cover: float | None = None

    @property
    def pose(self):
        """(x, y, angle) when the goal names all three, else None."""
        if self.x is None or self.y is None or self.angle is None:
            return None
        return (self.x, self.y, self.angle)


@dataclass(frozen=True)
class Task:
    """A validated planning task: the scene, the bodies, the limits, the goal and the derived planner settings.

    Attributes
    ----------
    name : str
        The file's stem (a shipped task's name), or the scene's name for a task given as text or a dict.
    scene : Scene
    source : str
        Where the task came from, as reports name it (`scenes/push_box.toml`, a relative path, "<string>").
    document : dict
        The whole TOML document as parsed (scene and task): what a plan file stores to replay the task anywhere.
    sha256 : str
        Hash of `document` in its canonical JSON form (`canonical_json`).
    object, pusher : str
    obstacles : tuple of str
        The scene's other dynamic bodies, in scene order: movable obstacles, held in the planning state.
    planner : str
    time : float
        The planning budget in s when the command gives none.
    control_max : float
        Pusher velocity bound per axis, m/s.
    step_duration : float
        The propagation step, s (a multiple of the scene's h).
    min_steps, max_steps : int
        A control is held for min_steps..max_steps propagation steps (`control_steps`).
    workspace, pusher_workspace : ((xmin, xmax), (ymin, ymax))
        No point of any dynamic body may leave `workspace`; the pusher's centre stays in `pusher_workspace`. m.
    speed_max, omega_max : float
        Velocity bounds of every dynamic body (m/s, rad/s): faster states are invalid.
    goal_bias : float
        RRT's goal bias.
    goal : Goal
    weights : (position, angle, velocity, pusher)
        OMPL distance weights, derived (module `derived_weights`): per m of object position, per rad of its angle,
        per m/s and rad/s of velocity, per m of pusher position.
    obstacle_weight : float
        OMPL distance weight of an obstacle's position (per m).
    kpiece_cell : float
        KPIECE1's cell size on the object's position, m.
    object_extent : dict
        The object's sizes about its centre of mass (m): "circumradius", "min_support" (the least half-width over
        directions), "gyration" (radius of gyration of its area).
    given : frozenset of str
        The [task] keys the file gave (the rest are derived).
    moving : tuple of str
        The kinematic bodies other than the pusher that follow a `path` of two rows or more (scene order): the
        planning state then holds the time, since where they are depends on it ("timed").
    horizon : float
        When the last of them reaches its path's end (s), 0 without any: the state's time stops there, as the world
        holds still after it.
    time_weight : float
        OMPL distance weight of the state's time (per s; `derived_time_weight`), 0 without moving bodies.
    """

    name: str
    scene: object
    source: str
    document: dict
    sha256: str
    object: str
    pusher: str
    obstacles: tuple
    description: str
    planner: str
    time: float
    control_max: float
    step_duration: float
    min_steps: int
    max_steps: int
    workspace: tuple
    pusher_workspace: tuple
    speed_max: float
    omega_max: float
    goal_bias: float
    goal: Goal
    weights: tuple
    obstacle_weight: float
    kpiece_cell: float
    object_extent: dict
    given: frozenset
    moving: tuple = ()
    horizon: float = 0.0
    time_weight: float = 0.0

    @property
    def timed(self):
        """Whether the planning state holds the time (a kinematic body other than the pusher follows a path)."""
        return bool(self.moving)

    @property
    def nobj(self):
        """Dynamic bodies in the planning state: the object and the obstacles."""
        return 1 + len(self.obstacles)

    @property
    def state_dim(self):
        return 6 * self.nobj + 2 + (1 if self.timed else 0)

    def state_names(self):
        """Names of the flat planning state's entries (planners.tasks)."""
        names = ["x", "y", "theta", "vx", "vy", "omega"]
        for b in self.obstacles:
            names += [f"{b}_{n}" for n in ("x", "y", "theta", "vx", "vy", "omega")]
        return names + ["pusher_x", "pusher_y"] + (["t"] if self.timed else [])


def canonical_json(document) -> str:
    """The document as JSON with sorted keys and no spaces: the form a plan file hashes (floats as repr: exact)."""
    return json.dumps(document, sort_keys=True, separators=(",", ":"), allow_nan=False)


def document_sha256(document) -> str:
    return hashlib.sha256(canonical_json(document).encode()).hexdigest()


def shipped_tasks() -> list[str]:
    """Names of the scene files found by name (`planar_lcp.spec.scene.scene_files`: the shipped ones and
    $PLANAR_LCP_SCENES's) that carry a [task] table (their stems), sorted."""
    out = []
    for p in scene_files():
        try:
            data, _ = read_document(p)
        except SceneError:
            continue
        if isinstance(data.get("task"), dict):
            out.append(p.stem)
    return sorted(out)


def load_task(src) -> Task:
    """Load and validate a task.

    Parameters
    ----------
    src : str, os.PathLike, dict or Task
        A shipped task's name ("push_box"), a path to a scene file with a [task] table, the text of such a file (a
        string with a newline), or its document as a dict (as tomllib parses it). A Task is returned as it is.

    Raises
    ------
    TaskError
        One line naming the source, the key, the expected and the actual value.
    """
    if isinstance(src, Task):
        return src
    if isinstance(src, dict):
        return parse_task(src, source="<dict>", name=None)
    if isinstance(src, str) and "\n" in src:
        return parse_task(_as_task_error(parse_toml, src, "<string>"), source="<string>", name=None)
    if isinstance(src, str) and not (src.endswith(".toml") or "/" in src or os.sep in src):
        path = _as_task_error(find_scene_file, src)
        if path is None:
            raise TaskError(f"unknown task {src!r}: not a shipped task (shipped tasks: {', '.join(shipped_tasks())}); "
                            "give a path to a scene file with a [task] table to plan another")
    elif isinstance(src, (str, os.PathLike)):
        path = _as_task_error(scene_path, src)
    else:
        raise TypeError(f"load_task: expected a task name, a path, TOML text or a dict, got {type(src).__name__}")
    data, _ = _as_task_error(read_document, path)
    return parse_task(data, source=str(path), name=Path(path).stem)


def _as_task_error(fn, *args):
    try:
        return fn(*args)
    except TaskError:
        raise
    except SceneError as e:
        raise TaskError(str(e)) from None


@dataclass(frozen=True)
class _Roles:
    """What the bodies are in a task: the object, the pusher, the movable obstacles and the bodies that follow a path,
    with the object's and the pusher's sizes (`body_extent`)."""

    object: str
    pusher: str
    obstacles: tuple
    moving: tuple
    horizon: float
    extent: dict                # the object's, about its centre of mass
    pusher_extent: dict         # the pusher's, about its body-frame origin


def parse_task(document: dict, source: str = "<dict>", name: str | None = None, display: str | None = None) -> Task:
    """Validate a scene document with a [task] table; see `load_task`. `name` defaults to the scene's name; messages
    name `display` when given (a plan file's copy of a task), else the source."""
    # the stages run in this order so that a file with several errors is told the same first one
    scene, shown, v = _task_scene(document, source, display)
    t = scene.task
    roles = _roles(v, scene, t)
    goal = _parse_goal(v, t, roles.extent)
    control = _control(v, t, scene, roles.extent)
    bounds = _bounds(v, t, scene, roles, goal, control["control_max"])
    goal_bias = _goal_bias(v, t, goal)
    scene = _with_pusher_max_force(v, t, scene, roles.pusher)
    return _derived_task(document, scene, t, name, shown, roles, goal, control, bounds, goal_bias)


def _task_scene(document, source, display):
    """The document -> its Scene (parsed by the scene loader, its errors as TaskErrors naming `display` when given),
    the name reports give the task's source, and the validator whose messages name the file. Checks that there is a
    [task] table and that its keys are known."""
    if not isinstance(document, dict):
        raise TaskError(f"{display or source}: the scene must be a table, got {type(document).__name__}")
    try:
        scene = parse_scene(document, source)
    except SceneError as e:
        msg = str(e)
        if display and msg.startswith(f"{source}: "):
            msg = f"{display}: {msg[len(source) + 2:]}"
        raise TaskError(msg) from None
    if scene.task is None:
        raise TaskError(f"{display or source}: task is required: a [task] table with object, pusher and [task.goal] "
                        f"(docs/scene-format.md, \"Task files\"); scene {scene.name!r} has none")
    # how reports name the task: a shipped file as scenes/NAME.toml, another relative to the working directory
    shown = source if source.startswith("<") or display else display_source(scene)
    v = _TaskValidator(display or shown)
    v.keys("task", scene.task, TASK_KEYS)
    return scene, shown, v


def _roles(v, scene, t) -> _Roles:
    """task.object and task.pusher -> the bodies' roles: the object (a dynamic body), the pusher (a kinematic body
    without a path), every other dynamic body an obstacle, every other kinematic body still or on a path; the bodies
    that move along a path and when the last one stops; the object's and the pusher's sizes."""
    bodies = {b.name: b for b in scene.bodies}
    obj = _body_of_type(v, t, "object", "dynamic", scene.bodies)
    pusher = _body_of_type(v, t, "pusher", "kinematic", scene.bodies)
    for b in scene.bodies:
        # the planner drives the pusher; another kinematic body stands still or follows a `path`, which the
        # planning state's time then places (a constant velocity would need an unbounded time)
        if b.path is not None and b.name == pusher:
            v.fail(f"bodies[{scene.bodies.index(b)}] ({b.name!r}) is task.pusher and has a path: the planner "
                   f"drives the pusher, so it must not follow one; got a path of {len(b.path)} rows")
        if b.type == "kinematic" and b.name != pusher and (b.velocity != (0.0, 0.0) or b.angular_velocity != 0.0):
            v.fail(f"bodies[{scene.bodies.index(b)}] ({b.name!r}) is a kinematic body other than task.pusher: it "
                   f"must stand still or follow a path in a task (velocity [0, 0], angular_velocity 0), got "
                   f"velocity {list(b.velocity)}, angular_velocity {b.angular_velocity}")
    moving = tuple(b.name for b in scene.bodies if b.path is not None and len(b.path) >= 2)
    horizon = max((float(b.path[-1][0]) for b in scene.bodies if b.name in moving), default=0.0)
    obstacles = tuple(b.name for b in scene.bodies if b.type == "dynamic" and b.name != obj)
    return _Roles(object=obj, pusher=pusher, obstacles=obstacles, moving=moving, horizon=horizon,
                  extent=body_extent(bodies[obj]), pusher_extent=body_extent(bodies[pusher], about_origin=True))


def _control(v, t, scene, extent) -> dict:
    """description, planner, time, control_max, step_duration and control_steps -> the Task's fields of that name
    (control_steps: min_steps, max_steps), each given one checked or its default: the scene's description, DEFAULT_PLANNER, 60 s, twice the object's circumradius per s,
    the multiple of the scene's h nearest DEFAULT_STEP, 1..10 steps."""
    h = scene.sim.h
    description = v.string("task.description", t["description"]) if "description" in t else scene.description
    planner = v.choice("task.planner", t["planner"], PLANNERS) if "planner" in t else DEFAULT_PLANNER
    time = v.bounded("task.time", t["time"], MAX_TIME) if "time" in t else 60.0
    L = extent["circumradius"]
    control_max = v.positive("task.control_max", t["control_max"]) if "control_max" in t else 2.0 * L
    if "step_duration" in t:
        step = v.positive("task.step_duration", t["step_duration"])
        n = step / h
        if not (round(n) >= 1 and abs(n - round(n)) <= 1e-9 * max(1.0, n)):
            v.fail(f"task.step_duration must be a multiple of the scene's sim.h = {h!r} s, got {step!r} "
                   f"({n:.6g} steps)")
    else:
        step = h * max(1, round(DEFAULT_STEP / h))
    if "control_steps" in t:
        cs = t["control_steps"]
        if not (isinstance(cs, (list, tuple)) and len(cs) == 2):
            v.fail(f"task.control_steps must be [min, max], 2 integers, got {cs!r}")
        lo = v.integer("task.control_steps[0]", cs[0], 1, MAX_CONTROL_STEPS)
        hi = v.integer("task.control_steps[1]", cs[1], 1, MAX_CONTROL_STEPS)
        if lo > hi:
            v.fail(f"task.control_steps must be [min, max] with min <= max, got {list(cs)}")
    else:
        lo, hi = 1, 10
    return dict(description=description, planner=planner, time=time, control_max=control_max,
                step_duration=step, min_steps=lo, max_steps=hi)


def _bounds(v, t, scene, roles, goal, control_max) -> dict:
    """workspace, pusher_workspace, speed_max and omega_max -> the Task's fields of that name, given or derived from the scene, the
    goal and the control; checks that the goal lies inside the workspace."""
    if "workspace" in t:
        workspace = v.region("task.workspace", t["workspace"])
    else:
        workspace = _default_workspace(scene, roles.object, goal, roles.extent)
    if "pusher_workspace" in t:
        pusher_workspace = v.region("task.pusher_workspace", t["pusher_workspace"])
    else:
        # the pusher must be able to reach every side of a body that touches the workspace's edge
        g = 2.0 * roles.pusher_extent["circumradius"]
        pusher_workspace = ((workspace[0][0] - g, workspace[0][1] + g), (workspace[1][0] - g, workspace[1][1] + g))
    _check_goal_in_workspace(v, goal, workspace, scene.body(roles.object))

    if "speed_max" in t:
        speed_max = v.positive("task.speed_max", t["speed_max"])
    else:
        speed_max = 8.0 * control_max
        if scene.world.plane == "vertical":         # room to fall across the workspace
            height = workspace[1][1] - workspace[1][0]
            speed_max = max(speed_max, math.sqrt(2.0 * math.hypot(*scene.world.gravity) * height))
    L = roles.extent["circumradius"]
    omega_max = v.positive("task.omega_max", t["omega_max"]) if "omega_max" in t else speed_max / L
    return dict(workspace=workspace, pusher_workspace=pusher_workspace, speed_max=speed_max, omega_max=omega_max)


def _goal_bias(v, t, goal) -> float:
    """task.goal_bias, checked in [0, 1), or its default for the goal's kind."""
    if "goal_bias" in t:
        goal_bias = v.number("task.goal_bias", t["goal_bias"])
        if not 0.0 <= goal_bias < 1.0:
            v.fail(f"task.goal_bias must be in [0, 1), got {goal_bias!r}")
        return goal_bias
    # a cover goal needs the pose within millimetres and degrees, which goal samples reach best (push_t:
    # docs/planning.md, "Faster planning")
    return 0.3 if goal.min_cover is not None else 0.1


def _with_pusher_max_force(v, t, scene, pusher):
    """The scene with task.pusher_max_force, when given, as the pusher's max_force; the scene itself otherwise."""
    if "pusher_max_force" not in t:
        return scene
    # the pusher as a force-limited velocity servo (docs/method.md): a push into a jam stalls instead of having
    # no solution. The body's own max_force, if any, is what this replaces.
    limit = v.positive("task.pusher_max_force", t["pusher_max_force"])
    if limit > MAX_SERVO_FORCE:
        v.fail(f"task.pusher_max_force must be at most {MAX_SERVO_FORCE:g} N (a physical bound), got {limit!r}")
    i = [b.name for b in scene.bodies].index(pusher)
    bodies_list = list(scene.bodies)
    bodies_list[i] = dataclasses.replace(bodies_list[i], max_force=limit)
    return dataclasses.replace(scene, bodies=tuple(bodies_list))


def _derived_task(document, scene, t, name, shown, roles, goal, control, bounds, goal_bias) -> Task:
    """The checked values -> the Task, with the defaults derived from them: OMPL's distance weights, KPIECE1's cell,
    the time's weight, and the document (paths inlined) with its hash."""
    document = _inline_paths(document, scene)
    extent = roles.extent
    return Task(name=name if name is not None else scene.name, scene=scene, source=shown, document=document,
                sha256=document_sha256(document), object=roles.object, pusher=roles.pusher,
                obstacles=roles.obstacles, **control, **bounds,
                goal_bias=goal_bias, goal=goal, weights=derived_weights(extent, control["step_duration"]),
                obstacle_weight=0.05, kpiece_cell=extent["circumradius"] / 3.0, object_extent=extent,
                given=frozenset(t), moving=roles.moving, horizon=roles.horizon,
                time_weight=derived_time_weight(scene, roles.moving, extent))


def derived_weights(extent, step_duration):
    """OMPL's distance weights (position, angle, velocity, pusher) of a task, from the object's size.

    A radian of the object's angle weighs its radius of gyration about its centre of mass: the RMS distance its
    points move when it turns by a radian about it (0.041 m for push_box's 0.1 m box, 0.044 m for push_t's T), so
    that OMPL's distance between two poses of the object is the position change plus the points' RMS displacement
    by the turn. A velocity weighs like a fiftieth of the distance it covers in one propagation step (pushing is
    nearly quasi-static: velocities must not decide which tree state is nearest); the pusher's position a tenth of
    the object's. Measured (docs/planning.md, "Distance weights"): the circumradius in its place (the first choice)
    needed 1.8 times the iterations at the median on push_box and left 3 of 10 push_t seeds unsolved in 60 s."""
    return (1.0, extent["gyration"], 0.02 * step_duration, 0.1)


def _inline_paths(document, scene):
    """The document with each body's `path` given as a CSV file name replaced by its rows (a copy; the document
    itself when none is): a plan file stores the task's document to replay it anywhere, without the CSV beside it."""
    bodies = document.get("bodies")
    if not isinstance(bodies, list) or not any(isinstance(b, dict) and isinstance(b.get("path"), str)
                                               for b in bodies):
        return document
    out = dict(document)
    out["bodies"] = [dict(b, path=[list(r) for r in scene.body(b["name"]).path])
                     if isinstance(b, dict) and isinstance(b.get("path"), str) else b for b in bodies]
    return out


def derived_time_weight(scene, moving, extent):
    """OMPL's distance weight of a timed task's time (per s): the fastest any point of a moving body goes along its
    path (m/s), times the object position's weight (1 per m). A time difference then weighs as far as the moving
    bodies can be apart over it, so that two states whose obstacles are in different places are far apart, while
    states after every path's end, where time no longer matters, share one time (Task.horizon). 0 without moving
    bodies."""
    fastest = 0.0
    for name in moving:
        b = scene.body(name)
        rows = np.asarray(b.path, float)
        dt = np.diff(rows[:, 0])
        speed = np.hypot(np.diff(rows[:, 1]), np.diff(rows[:, 2])) / dt
        spin = np.abs(np.diff(rows[:, 3])) / dt
        reach = body_extent(b, about_origin=True)["circumradius"]
        fastest = max(fastest, float(np.max(speed + spin * reach)))
    # a path that stands still in every row still holds time in the state: a small positive weight keeps OMPL's
    # distance a metric
    return max(fastest, 1e-3 * extent["circumradius"]) if moving else 0.0


def body_extent(body, about_origin: bool = False) -> dict:
    """Sizes of a body about its area centroid (its centre of mass at uniform density), or about its body-frame
    origin with `about_origin` (a pusher: the planning state holds its origin), m: "circumradius" (the farthest
    point), "min_support" (the least, over directions, of the farthest extent in that direction), "gyration" (the
    radius of gyration of its area about the centroid; 0 about the origin) and "com" (the centre used, body frame).
    Exact for rounded convex shapes: a shape's extreme point in a direction is one of its core vertices pushed out
    by its radius (min_support over 720 directions)."""
    pts, radii = body_core_points(body)
    if about_origin:
        com, gyration = np.zeros(2), 0.0
    else:
        area, com, polar = body_area_properties(body)
        gyration = math.sqrt(polar / area)
    rel = pts - com
    ang = np.linspace(0.0, 2.0 * math.pi, 720, endpoint=False)
    support = np.max(rel @ np.stack([np.cos(ang), np.sin(ang)]) + radii[:, None], axis=0)
    return dict(circumradius=float(np.max(np.hypot(rel[:, 0], rel[:, 1]) + radii)),
                min_support=float(np.min(support)), gyration=float(gyration), com=(float(com[0]), float(com[1])))


def body_core_points(body):
    """(k, 2) core vertices of every shape of a body in its body frame, and (k,) the radius of each vertex's shape
    (halfplanes have none)."""
    pts, radii = [], []
    for s in body.shapes:
        if s.type == "halfplane":
            continue
        c = s.core_vertices_body()
        pts.append(c)
        radii.append(np.full(len(c), float(s.radius)))
    return np.concatenate(pts), np.concatenate(radii)


def placed_bounds(body, position, angle):
    """((xmin, xmax), (ymin, ymax)) of a body placed at a body-frame pose, m (halfplanes excluded)."""
    pts, r = body_core_points(body)
    w = pts @ rotation(angle).T + np.asarray(position, float)
    return ((float(np.min(w[:, 0] - r)), float(np.max(w[:, 0] + r))),
            (float(np.min(w[:, 1] - r)), float(np.max(w[:, 1] + r))))


def _default_workspace(scene, obj, goal, extent):
    """The bounding box of the scene's finite bodies (dynamic, kinematic and static, halfplanes excluded) and of
    the goal (the object placed at a full goal pose; else its circumradius about each named coordinate), grown by
    the object's diameter (twice its circumradius about its centre of mass)."""
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for b in scene.bodies:
        if all(s.type == "halfplane" for s in b.shapes):
            continue
        (x0, x1), (y0, y1) = placed_bounds(b, b.position, b.angle)
        lo, hi = np.minimum(lo, [x0, y0]), np.maximum(hi, [x1, y1])
    ob = scene.body(obj)
    if goal.pose is not None:
        (x0, x1), (y0, y1) = placed_bounds(ob, goal.pose[:2], goal.pose[2])
        lo, hi = np.minimum(lo, [x0, y0]), np.maximum(hi, [x1, y1])
    else:                        # the object at the named coordinates, at any angle
        for i, c in enumerate((goal.x, goal.y)):
            if c is not None:
                lo[i], hi[i] = min(lo[i], c - extent["circumradius"]), max(hi[i], c + extent["circumradius"])
    # the object's diameter: room to pass a static body that stands at the edge of the rest
    m = 2.0 * extent["circumradius"]
    return ((float(lo[0] - m), float(hi[0] + m)), (float(lo[1] - m), float(hi[1] + m)))


def _check_goal_in_workspace(v, goal, workspace, body):
    (x0, x1), (y0, y1) = workspace
    if goal.pose is not None:
        (gx0, gx1), (gy0, gy1) = placed_bounds(body, goal.pose[:2], goal.pose[2])
        if not (x0 <= gx0 and gx1 <= x1 and y0 <= gy0 and gy1 <= y1):
            v.fail(f"task.goal must place the object inside task.workspace = [[{x0:g}, {x1:g}], [{y0:g}, {y1:g}]], "
                   f"got the object spanning x {gx0:.4g}..{gx1:.4g}, y {gy0:.4g}..{gy1:.4g} at the goal")
        return
    for key, c, (lo, hi) in (("x", goal.x, (x0, x1)), ("y", goal.y, (y0, y1))):
        if c is not None and not lo <= c <= hi:
            v.fail(f"task.goal.{key} must lie inside task.workspace ({lo:g} .. {hi:g}), got {c!r}")


def _parse_goal(v, t, extent) -> Goal:
    g = v.table("task.goal", v.require("task", t, "goal"))
    v.keys("task.goal", g, GOAL_KEYS)
    x = v.coordinate("task.goal.x", g["x"]) if "x" in g else None
    y = v.coordinate("task.goal.y", g["y"]) if "y" in g else None
    ang = math.radians(v.number("task.goal.angle_deg", g["angle_deg"])) if "angle_deg" in g else None
    if x is None and y is None and ang is None:
        v.fail("task.goal must name at least one of x, y and angle_deg, got none")
    kw = {}
    if "min_cover" in g:
        c = v.number("task.goal.min_cover", g["min_cover"])
        if not 0.0 < c <= 1.0:
            v.fail(f"task.goal.min_cover must be in (0, 1], got {c!r}")
        if x is None or y is None or ang is None:
            missing = [k for k, val in (("x", x), ("y", y), ("angle_deg", ang)) if val is None]
            v.fail(f"task.goal.min_cover needs x, y and angle_deg (the goal footprint), got no {', '.join(missing)}")
        for k in ("position_tol", "angle_tol_deg"):
            if k in g:
                v.fail(f"task.goal.{k} is not used with min_cover (the cover decides), got {g[k]!r}; remove one")
        kw["min_cover"] = c
    if "position_tol" in g:
        if x is None and y is None:
            v.fail(f"task.goal.position_tol needs x or y in the goal, got {g['position_tol']!r} with neither")
        kw["position_tol"] = v.positive("task.goal.position_tol", g["position_tol"])
    if "angle_tol_deg" in g:
        if ang is None:
            v.fail(f"task.goal.angle_tol_deg needs angle_deg in the goal, got {g['angle_tol_deg']!r} without it")
        a = v.positive("task.goal.angle_tol_deg", g["angle_tol_deg"])
        if not a <= 180.0:
            v.fail(f"task.goal.angle_tol_deg must be <= 180, got {a!r}")
        kw["angle_tol"] = math.radians(a)
    at_rest = False
    if "at_rest" in g:
        at_rest = g["at_rest"]
        if not isinstance(at_rest, bool):
            v.fail(f"task.goal.at_rest must be true or false, got {at_rest!r}")
    for k in ("speed_tol", "omega_tol"):
        if k in g:
            if not at_rest:
                v.fail(f"task.goal.{k} needs at_rest = true, got {g[k]!r} without it")
            kw[k] = v.positive(f"task.goal.{k}", g[k])
    return Goal(x=x, y=y, angle=ang, at_rest=at_rest, **kw)


def _body_of_type(v, t, key, btype, bodies):
    """The body named by task.KEY, which must be a body of type `btype`."""
    of_type = _names([b.name for b in bodies if b.type == btype])
    name = v.string(f"task.{key}", v.require("task", t, key), nonempty=True)
    found = [b for b in bodies if b.name == name]
    if not found:
        v.fail(f"task.{key} must name a {btype} body of the scene (one of {of_type}), got {name!r}")
    if found[0].type != btype:
        v.fail(f"task.{key} must be a {btype} body (one of {of_type}), got {name!r}, a {found[0].type} body")
    return name


def _names(names):
    return ", ".join(repr(n) for n in names) or "none"


class _TaskValidator(_Validator):
    def fail(self, msg: str):
        raise TaskError(f"{self.source}: {msg}")

    def bounded(self, path, value, maximum):
        x = self.positive(path, value)
        if not x <= maximum:
            self.fail(f"{path} must be <= {maximum:g}, got {x!r}")
        return x

    def coordinate(self, path, value):
        """A coordinate in m, bounded as a scene's positions are (+-MAX_LENGTH)."""
        x = self.number(path, value)
        if not abs(x) <= MAX_LENGTH:
            self.fail(f"{path} must be within +-{MAX_LENGTH:g} m (a physical bound, as for positions), got "
                      f"{_fmt_num(x)}")
        return x

    def region(self, path, value):
        """[[xmin, xmax], [ymin, ymax]], finite, min < max."""
        ok = isinstance(value, (list, tuple)) and len(value) == 2 and all(
            isinstance(r, (list, tuple)) and len(r) == 2 and all(_is_real(c) for c in r) for r in value)
        if not ok:
            self.fail(f"{path} must be [[xmin, xmax], [ymin, ymax]] in m, got {value!r}")
        out = []
        for i, axis in enumerate("xy"):
            lo = self.coordinate(f"{path}[{i}][0]", value[i][0])
            hi = self.coordinate(f"{path}[{i}][1]", value[i][1])
            if not lo < hi:
                self.fail(f"{path}[{i}] must be [{axis}min, {axis}max] with {axis}min < {axis}max, got "
                          f"[{lo!r}, {hi!r}]")
            out.append((lo, hi))
        return tuple(out)


def check_seed(seed, name="the seed"):
    """`seed` as an int if it is an integer in 1..MAX_SEED (what OMPL's RNG.setSeed takes on any machine); a
    TaskError naming `name` (a flag, or the API's keyword) otherwise."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise TaskError(f"{name} must be an integer from 1 to {MAX_SEED} (OMPL's seed), got {seed!r}")
    if not 1 <= seed <= MAX_SEED:
        raise TaskError(f"{name} must be from 1 to {MAX_SEED} (OMPL's seed), got {seed}")
    return int(seed)


def check_time_limit(seconds, name="the time limit"):
    """`seconds` as a float if it is a planning budget in (0, MAX_TIME] s, the bound of a task file's `time`; a
    TaskError naming `name` otherwise."""
    try:
        x = float(seconds) if _is_real(seconds) else math.nan
    except OverflowError:                 # an int beyond a float
        x = math.inf
    if not (math.isfinite(x) and 0.0 < x <= MAX_TIME):
        raise TaskError(f"{name} must be > 0 and <= {MAX_TIME:g} s (as a task file's time), got {seconds!r}")
    return x


__all__ = ["DEFAULT_PLANNER", "GOAL_KEYS", "Goal", "MAX_RUNS", "MAX_SEED", "MAX_TIME", "PLANNERS", "TASK_KEYS", "Task",
           "TaskError", "canonical_json", "check_seed", "check_time_limit", "document_sha256", "load_task", "parse_task",
           "shipped_tasks"]
