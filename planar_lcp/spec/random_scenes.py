"""Seeded random scenes: the simulator tried on scenes nobody wrote by hand.

`random_scene(seed)` returns a scene as a TOML-shaped dict (`planar_lcp.spec.scene.parse_scene` validates it,
`scene_to_toml` writes it to a file), so a failing seed can be saved as a regression scene as it is. Two kinds:

- "drop" (vertical plane): 1 to 12 convex bodies (disks, capsules, boxes, rounded boxes, polygons) dropped onto the
  ground from up to 2 m at up to 20 m/s, between two walls; masses log-uniform over 1e-3 .. 1e2 kg (ratios up to
  1e5), Coulomb friction 0 .. 5 with per-pair overrides.
- "push" (horizontal plane): a box or polygon (and sometimes a second object) pushed by a kinematic disk at up to
  2 m/s, with table friction 0 .. 5, pusher friction 0 .. 5, sometimes between two rails (walls along the push).

`jam_scene(seed)` is a third kind, a set of its own (its seeds draw from their own stream, so the two kinds above
stay as they were): a pusher driving one or two objects at up to 10 m/s towards a static block in its path, head on
or off centre, so that some runs jam (a kinematic pusher with no force limit and a block: no rigid-body solution,
reported as certified, planar_lcp.infeasibility) and others slide past the block.

The same seed always gives the same scene (numpy's default_rng). Bodies start separated (a grid with a clearance).

`random_task(seed)` is a scene with a [task] table (docs/scene-format.md, "Task files"): planning problems nobody
wrote by hand, valid by construction, with the derived defaults unless a key is drawn (tests/planning/test_tasks.py plans
each of them).
"""

import math

import numpy as np

MASS_RANGE = (1e-3, 1e2)      # kg: log-uniform, ratios up to 1e5 within a scene
FRICTION_MAX = 5.0
DROP_SPEED_MAX = 20.0         # m/s
PUSH_SPEED_MAX = 2.0          # m/s: the pusher is kinematic, its speed is prescribed
DROP_HEIGHT_MAX = 2.0         # m above the ground (of the lowest point of the body's cell)


def _log_uniform(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _polygon(rng, size):
    """A strictly convex CCW polygon of 3..7 vertices inscribed in a circle of radius `size`."""
    k = int(rng.integers(3, 8))
    # angles spread around the circle with jitter, at least a few degrees apart (strict convexity)
    base = np.sort(rng.uniform(0.0, 2 * math.pi, k))
    gaps = np.diff(np.concatenate([base, [base[0] + 2 * math.pi]]))
    if np.min(gaps) < 0.2:
        base = np.arange(k) * 2 * math.pi / k + rng.uniform(0, 2 * math.pi)
    return [[round(size * math.cos(a), 12), round(size * math.sin(a), 12)] for a in base]


def _shape(rng, size, allow=("disk", "capsule", "box", "rounded_box", "polygon")):
    """A random shape whose extent fits a disk of radius `size` about the body origin."""
    kind = allow[int(rng.integers(len(allow)))]
    if kind == "disk":
        return {"type": "disk", "radius": size * rng.uniform(0.4, 1.0)}
    if kind == "capsule":
        r = size * rng.uniform(0.1, 0.4)
        return {"type": "capsule", "radius": r, "length": 2 * (size - r) * rng.uniform(0.3, 1.0)}
    if kind in ("box", "rounded_box"):
        r = size * rng.uniform(0.02, 0.2) if kind == "rounded_box" else 0.0
        w, hgt = (size - r) * rng.uniform(0.3, 1.4, 2)
        s = {"type": "box", "width": float(w), "height": float(hgt)}
        if r:
            s["radius"] = r
        return s
    return {"type": "polygon", "vertices": _polygon(rng, size * rng.uniform(0.5, 1.0))}


def _friction(rng):
    # a few exact zeros (frictionless contacts change the LCP's structure), else uniform up to FRICTION_MAX
    return 0.0 if rng.random() < 0.1 else float(rng.uniform(0.0, FRICTION_MAX))


def drop_scene(rng, seed):
    nb = int(rng.integers(1, 13))
    size = 0.05 * _log_uniform(rng, 0.5, 4.0)          # body radius scale, m
    cell = 2.6 * size
    ncol = int(math.ceil(math.sqrt(nb)))
    half_width = 0.5 * ncol * cell + size
    bodies = [
        {"name": "ground", "type": "static", "shapes": [{"type": "halfplane", "point": [0.0, 0.0],
                                                          "normal": [0.0, 1.0]}]},
        {"name": "walls", "type": "static", "shapes": [
            {"type": "box", "width": 0.2, "height": 6.0, "offset": [-half_width - 0.1, 3.0]},
            {"type": "box", "width": 0.2, "height": 6.0, "offset": [half_width + 0.1, 3.0]}]},
    ]
    base = rng.uniform(0.0, DROP_HEIGHT_MAX)
    names = []
    for i in range(nb):
        row, col = divmod(i, ncol)
        x = -0.5 * ncol * cell + (col + 0.5) * cell
        y = base + size * 1.05 + row * cell
        speed = rng.uniform(0.0, DROP_SPEED_MAX) if rng.random() < 0.5 else rng.uniform(0.0, 2.0)
        direction = rng.uniform(0.0, 2 * math.pi)
        body = {"name": f"b{i}", "type": "dynamic", "mass": _log_uniform(rng, *MASS_RANGE),
                "position": [x, y], "angle": float(rng.uniform(-math.pi, math.pi)),
                "velocity": [speed * math.cos(direction), speed * math.sin(direction)],
                "angular_velocity": float(rng.uniform(-10.0, 10.0)),
                "shapes": [_shape(rng, size)]}
        bodies.append(body)
        names.append(body["name"])
    pairs = []
    for i, n in enumerate(names):
        if rng.random() < 0.3:
            pairs.append({"a": n, "b": "ground", "mu": _friction(rng)})
    return {"name": f"random_drop_{seed}", "description": f"random scene, seed {seed}: {nb} bodies dropped",
            "world": {"plane": "vertical", "friction": _friction(rng), "friction_pairs": pairs},
            "sim": {"h": 0.005, "t_end": 0.75}, "bodies": bodies}


def push_scene(rng, seed):
    size = 0.05 * _log_uniform(rng, 0.5, 3.0)
    nobj = 1 if rng.random() < 0.7 else 2
    bodies = []
    for i in range(nobj):
        shape = _shape(rng, size, allow=("box", "rounded_box", "polygon"))
        body = {"name": f"o{i}", "type": "dynamic", "mass": _log_uniform(rng, *MASS_RANGE),
                "position": [i * 2.6 * size, float(rng.uniform(-0.3, 0.3) * size * i)],
                "angle": float(rng.uniform(-math.pi, math.pi)),
                "support_friction": _friction(rng), "shapes": [shape]}
        bodies.append(body)
    r_pusher = size * rng.uniform(0.2, 0.6)
    speed = rng.uniform(0.05, PUSH_SPEED_MAX)
    lateral = rng.uniform(-0.6, 0.6) * size
    rails = rng.random() < 0.5
    # With rails the pusher moves parallel to them and they stand farther from its path than two objects can span:
    # a kinematic pusher that drives a body against a static one has no rigid-body solution (a jam: the pusher has
    # no force limit; tests/simulation/test_reliability.py shows it is reported as such), and this set tests the solver.
    heading = 0.0 if rails else rng.uniform(-0.2, 0.2)
    bodies.append({"name": "pusher", "type": "kinematic", "position": [-1.6 * size - r_pusher, float(lateral)],
                   "velocity": [speed, float(heading * speed)], "shapes": [{"type": "disk", "radius": r_pusher}]})
    if rails:
        rail_y = abs(lateral) + r_pusher + 4.5 * size * nobj
        length = 40 * size
        bodies.append({"name": "rails", "type": "static", "shapes": [
            {"type": "box", "width": length, "height": 0.1, "offset": [0.3 * length, rail_y + 0.05]},
            {"type": "box", "width": length, "height": 0.1, "offset": [0.3 * length, -rail_y - 0.05]}]})
    t_end = min(1.0, 6.0 * size / speed + 0.2)
    return {"name": f"random_push_{seed}", "description": f"random scene, seed {seed}: pushing {nobj} object(s)",
            "world": {"plane": "horizontal", "friction": _friction(rng), "support_gravity": 9.81},
            "sim": {"h": 0.005, "t_end": round(t_end, 3), "friction_directions": int(rng.choice([4, 8]))},
            "bodies": bodies}


JAM_SPEED_RANGE = (0.05, 10.0)   # m/s, log-uniform


def jam_scene(seed):
    """A pusher, one or two objects and a static block in the pusher's path (module docstring), as a TOML-shaped
    dict."""
    rng = np.random.default_rng([20261203, int(seed)])
    size = 0.05 * _log_uniform(rng, 0.5, 3.0)
    nobj = 1 if rng.random() < 0.6 else 2
    bodies = []
    for i in range(nobj):
        bodies.append({"name": f"o{i}", "type": "dynamic", "mass": _log_uniform(rng, *MASS_RANGE),
                       "position": [i * 2.6 * size, float(rng.uniform(-0.3, 0.3) * size * i)],
                       "angle": float(rng.uniform(-math.pi, math.pi)), "support_friction": _friction(rng),
                       "shapes": [_shape(rng, size)]})
    r_pusher = size * rng.uniform(0.2, 0.6)
    speed = _log_uniform(rng, *JAM_SPEED_RANGE)
    lateral = rng.uniform(-0.6, 0.6) * size
    bodies.append({"name": "pusher", "type": "kinematic", "position": [-1.6 * size - r_pusher, float(lateral)],
                   "velocity": [speed, 0.0], "shapes": [{"type": "disk", "radius": r_pusher}]})
    # the block: across the path (head on) or off centre by up to its own half height
    gap = rng.uniform(1.5, 4.0) * size
    x_block = (nobj - 1) * 2.6 * size + size + gap
    half = size * rng.uniform(0.5, 3.0)
    y_block = float(lateral + rng.uniform(-1.0, 1.0) * half * (0.0 if rng.random() < 0.5 else 1.5))
    bodies.append({"name": "block", "type": "static", "position": [x_block + 0.5 * size, y_block],
                   "shapes": [{"type": "box", "width": size, "height": 2 * half}]})
    travel = x_block + 1.6 * size + r_pusher
    t_end = min(2.0, travel / speed + 0.1)
    h = 0.005 if speed < 2.0 else 0.001
    return {"name": f"random_jam_{seed}", "description": f"random scene, seed {seed}: a pusher drives "
                                                         f"{nobj} object(s) towards a block",
            "world": {"plane": "horizontal", "friction": _friction(rng), "support_gravity": 9.81},
            "sim": {"h": h, "t_end": round(max(t_end, 4 * h), 4)}, "bodies": bodies}


def random_scene(seed):
    """The scene of `seed` as a TOML-shaped dict: three seeds in four are "drop" scenes, one in four "push"."""
    rng = np.random.default_rng([20261130, int(seed)])
    if rng.random() < 0.75:
        return drop_scene(rng, seed)
    return push_scene(rng, seed)


#: the goal kinds of random_task: (kind, weight)
TASK_GOALS = (("pose", 3), ("position", 2), ("angle", 1), ("rest", 1), ("cover", 1), ("tip", 2))


def random_task(seed):
    """A valid planning task (a scene dict with a [task] table) for `seed`.

    Horizontal tasks: an object of one or two shapes (box, rounded box, polygon, disk, capsule), a disk pusher, 0 to
    3 movable obstacles and 0 to 2 static blocks, each in its own cell of a grid 3 object sizes wide (so nothing
    overlaps at the start or at the goal), and a goal in a free cell: a full pose, a position, an angle (a turn in
    place), a pose at rest, or a cover. Vertical tasks: a box standing on a static table, a finger beside it, the
    goal tipped onto either side at rest. Some tasks draw optional keys (control_max, control_steps, goal_bias, the
    tolerances)."""
    rng = np.random.default_rng([20261201, int(seed)])
    kinds = [k for k, _ in TASK_GOALS]
    w = np.array([wt for _, wt in TASK_GOALS], float)
    kind = kinds[int(rng.choice(len(kinds), p=w / w.sum()))]
    size = float(rng.uniform(0.03, 0.06))
    if kind == "tip":
        return _random_tip_task(rng, seed, size)
    cell = 3.2 * size
    free = [(i, j) for i in range(-2, 3) for j in range(-2, 3) if (i, j) != (0, 0)]
    order = rng.permutation(len(free))
    cells = [free[k] for k in order]
    shapes = [_shape(rng, size, allow=("box", "rounded_box", "polygon", "disk", "capsule"))]
    if rng.random() < 0.3 and kind != "cover":      # a compound object: a second shape offset along x
        extra = _shape(rng, 0.5 * size, allow=("box", "disk", "polygon"))
        extra["offset"] = [float(0.5 * size), 0.0]
        shapes.append(extra)
    if kind == "cover":                             # a cover needs an object with area that turns visibly
        shapes = [{"type": "box", "width": 1.4 * size, "height": 0.7 * size}]
    a0 = float(rng.uniform(-math.pi, math.pi))
    bodies = [{"name": "object", "type": "dynamic", "mass": _log_uniform(rng, 0.05, 2.0), "position": [0.0, 0.0],
               "angle": a0, "support_friction": float(rng.uniform(0.1, 0.6)),
               "shapes": shapes}]
    # the goal's cell is the nearest free one in a random direction (short problems: seconds of pushing)
    near = [c for c in cells if max(abs(c[0]), abs(c[1])) == 1]
    goal_cell = near[0]
    cells.remove(goal_cell)
    pusher_cell = cells.pop(0)
    r_p = size * float(rng.uniform(0.25, 0.45))
    bodies.append({"name": "pusher", "type": "kinematic",
                   "position": [pusher_cell[0] * cell, pusher_cell[1] * cell],
                   "shapes": [{"type": "disk", "radius": r_p}]})
    for k in range(int(rng.integers(0, 4))):
        c = cells.pop(0)
        bodies.append({"name": f"obstacle{k}", "type": "dynamic", "mass": _log_uniform(rng, 0.02, 0.5),
                       "position": [c[0] * cell, c[1] * cell], "angle": float(rng.uniform(-math.pi, math.pi)),
                       "support_friction": float(rng.uniform(0.1, 0.6)),
                       "shapes": [_shape(rng, 0.6 * size, allow=("box", "disk", "polygon", "capsule"))]})
    for k in range(int(rng.integers(0, 3))):
        c = cells.pop(0)
        bodies.append({"name": f"block{k}", "type": "static", "position": [c[0] * cell, c[1] * cell],
                       "shapes": [{"type": "box", "width": float(rng.uniform(0.5, 1.0) * size),
                                   "height": float(rng.uniform(0.5, 1.0) * size)}]})
    gx, gy = goal_cell[0] * cell, goal_cell[1] * cell
    # the goal angle 60 to 180 degrees from the start's (an angle goal is never solved at the start)
    turn = float(rng.uniform(60.0, 180.0)) * (1.0 if rng.random() < 0.5 else -1.0)
    ga = float((math.degrees(a0) + turn + 180.0) % 360.0 - 180.0)
    goal = {"pose": {"x": gx, "y": gy, "angle_deg": ga}, "position": {"x": gx, "y": gy},
            "angle": {"angle_deg": ga}, "rest": {"x": gx, "y": gy, "angle_deg": ga, "at_rest": True},
            "cover": {"x": gx, "y": gy, "angle_deg": ga, "min_cover": float(rng.uniform(0.8, 0.95))}}[kind]
    if kind in ("pose", "position", "rest") and rng.random() < 0.3:
        goal["position_tol"] = float(rng.uniform(0.01, 0.03))
    if kind in ("pose", "angle", "rest") and rng.random() < 0.3:
        goal["angle_tol_deg"] = float(rng.uniform(10.0, 30.0))
    task = {"object": "object", "pusher": "pusher", "goal": goal,
            "description": f"random task, seed {seed}: {kind} goal"}
    _random_task_options(rng, task)
    return {"name": f"random_task_{seed}", "description": f"random task, seed {seed}: {kind} goal",
            "world": {"plane": "horizontal", "friction": float(rng.uniform(0.1, 0.8)), "support_gravity": 9.81},
            "sim": {"h": float(rng.choice([0.01, 0.02])), "t_end": 1.0}, "bodies": bodies, "task": task}


def _random_tip_task(rng, seed, size):
    w, hgt = 2 * size, 2 * size * float(rng.uniform(1.5, 2.5))
    side = 1.0 if rng.random() < 0.5 else -1.0
    r_f = size * float(rng.uniform(0.15, 0.3))
    bodies = [{"name": "object", "type": "dynamic", "mass": _log_uniform(rng, 0.1, 1.0), "position": [0.0, hgt / 2],
               "shapes": [{"type": "box", "width": w, "height": hgt}]},
              {"name": "table", "type": "static", "position": [0.0, -0.05],
               "shapes": [{"type": "box", "width": 6 * hgt, "height": 0.1}]},
              {"name": "finger", "type": "kinematic", "position": [-side * (w / 2 + 2 * r_f), 0.75 * hgt],
               "shapes": [{"type": "disk", "radius": r_f}]}]
    task = {"object": "object", "pusher": "finger", "description": f"random task, seed {seed}: tip goal",
            "goal": {"y": w / 2, "angle_deg": -90.0 * side, "position_tol": 0.005, "at_rest": True,
                     "speed_tol": 0.02, "omega_tol": 0.2}}
    _random_task_options(rng, task)
    return {"name": f"random_task_{seed}", "description": f"random task, seed {seed}: tip goal",
            "world": {"plane": "vertical", "gravity": [0.0, -9.81], "friction": float(rng.uniform(0.5, 1.0))},
            "sim": {"h": 0.01, "t_end": 1.0}, "bodies": bodies, "task": task}


def _random_task_options(rng, task):
    """Some optional [task] keys, drawn (each task has the derived defaults otherwise)."""
    if rng.random() < 0.2:
        task["control_steps"] = [1, int(rng.integers(5, 16))]
    if rng.random() < 0.2:
        task["goal_bias"] = float(rng.uniform(0.05, 0.3))
    if rng.random() < 0.2:
        task["planner"] = "RRT"


def _toml_value(x):
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        return repr(float(x))
    if isinstance(x, str):
        return '"' + x.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_toml_value(e) for e in x) + "]"
    if isinstance(x, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in x.items()) + " }"
    raise TypeError(f"cannot write {type(x).__name__} as TOML")


def scene_to_toml(data):
    """A scene dict (as `random_scene` or `random_task` returns) as TOML text that `load_scene` reads back to the
    same scene (and `load_task` to the same task)."""
    lines = [f"name = {_toml_value(data['name'])}", f"description = {_toml_value(data.get('description', ''))}"]
    for table in ("world", "sim"):
        if table in data:
            lines += ["", f"[{table}]"] + [f"{k} = {_toml_value(v)}" for k, v in data[table].items()]
    for body in data["bodies"]:
        lines += ["", "[[bodies]]"] + [f"{k} = {_toml_value(v)}" for k, v in body.items()]
    if "task" in data:
        lines += ["", "[task]"] + [f"{k} = {_toml_value(v)}" for k, v in data["task"].items()]
    return "\n".join(lines) + "\n"
