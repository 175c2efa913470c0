"""Seeded random scenes: the simulator tried on scenes nobody wrote by hand.

`random_scene(seed)` returns a scene as a TOML-shaped dict (`planar_lcp.spec.scene.parse_scene` validates it,
`scene_to_toml` writes it to a file), so a failing seed can be saved as a regression scene as it is. Two kinds:

- "drop" (vertical plane): 1 to 12 convex bodies (disks, capsules, boxes, rounded boxes, polygons) dropped onto the
  ground from up to 2 m at up to 20 m/s, between two walls; masses log-uniform over 1e-3 .. 1e2 kg (ratios up to
  1e5), Coulomb friction 0 .. 5 with per-pair overrides.
- "push" (horizontal plane): a box or polygon (and sometimes a second object) pushed by a kinematic disk at up to
  2 m/s, with table friction 0 .. 5, pusher friction 0 .. 5, sometimes between two rails (walls along the push).

The same seed always gives the same scene (numpy's default_rng). Bodies start separated (a grid with a clearance).
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
    # no force limit; tests/test_reliability.py shows it is reported as such), and this set tests the solver.
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


def random_scene(seed):
    """The scene of `seed` as a TOML-shaped dict: three seeds in four are "drop" scenes, one in four "push"."""
    rng = np.random.default_rng([20261130, int(seed)])
    if rng.random() < 0.75:
        return drop_scene(rng, seed)
    return push_scene(rng, seed)


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
    """A scene dict (as `random_scene` returns) as TOML text that `load_scene` reads back to the same scene."""
    lines = [f"name = {_toml_value(data['name'])}", f"description = {_toml_value(data.get('description', ''))}"]
    for table in ("world", "sim"):
        if table in data:
            lines += ["", f"[{table}]"] + [f"{k} = {_toml_value(v)}" for k, v in data[table].items()]
    for body in data["bodies"]:
        lines += ["", "[[bodies]]"] + [f"{k} = {_toml_value(v)}" for k, v in body.items()]
    return "\n".join(lines) + "\n"
