"""Scenes and states the derivative tests share."""

import math

import numpy as np

from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec.scene import parse_scene


def disk_at_wall():
    """A frictionless disk on the floor touching a wall on its right (x = 0.1), pressing nothing: its Simulator. In
    the position form one step gives v+_x = min(vx, -dx / h) for a shift dx of the disk towards the wall: it keeps its
    velocity away from the wall and stops at it."""
    doc = {"name": "wall", "world": {"plane": "vertical", "friction": 0.0}, "sim": {"h": 0.01, "t_end": 0.1},
           "bodies": [
               {"name": "floor", "type": "static",
                "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]},
               {"name": "wall", "type": "static",
                "shapes": [{"type": "halfplane", "point": [0.1, 0.0], "normal": [-1.0, 0.0]}]},
               {"name": "disk", "type": "dynamic", "mass": 1.0, "position": [0.05, 0.05],
                "shapes": [{"type": "disk", "radius": 0.05}]}]}
    return Simulator(compile_scene(parse_scene(doc)), SimOptions())


SHIPPED = ["falling_rod", "block_on_incline", "box_push", "box_tip", "tip_box", "push_box", "push_t", "four_disks",
           "painleve_rod", "bouncing_disk"]


def options(formulation):
    """The step's options; the fixed-point form's iteration converged far below its default 1e-9 m: the finite
    differences of a step that stops at 1e-9 see its iteration count change (jumps of 1e-9 over steps of 1e-5)."""
    if formulation == "fixed_point":
        return SimOptions(formulation=formulation, fixed_point_tol=1e-14, fixed_point_iterations=60)
    return SimOptions(formulation=formulation)


def states_along(sim, q, v, qk, vk, nsteps, every):
    rec = sim.rollout(q, v, qk, vk[None], nsteps, stop_on_failure=False)
    return [(rec["q"][i], rec["v"][i], rec["qk"][i], vk) for i in range(0, nsteps, every)]


def _random_shape(rng):
    kind = rng.choice(["disk", "box", "capsule", "polygon"])
    if kind == "disk":
        return {"type": "disk", "radius": float(rng.uniform(0.02, 0.06))}
    if kind == "box":
        return {"type": "box", "width": float(rng.uniform(0.04, 0.2)), "height": float(rng.uniform(0.04, 0.12)),
                "radius": float(rng.choice([0.0, 0.005]))}
    if kind == "capsule":
        return {"type": "capsule", "length": float(rng.uniform(0.05, 0.3)), "radius": float(rng.uniform(0.01, 0.03))}
    r = rng.uniform(0.03, 0.07)
    ang = rng.uniform(0, 2 * np.pi) + np.array([0.0, rng.uniform(1.6, 2.6), rng.uniform(3.7, 4.8)])  # CCW
    return {"type": "polygon", "vertices": [[float(r * np.cos(a)), float(r * np.sin(a))] for a in ang]}


def random_vertical_scene(seed):
    """One to three random bodies dropped close above a tilted ground, random velocities and friction."""
    rng = np.random.default_rng(seed)
    tilt = rng.uniform(-0.3, 0.3)
    bodies = [{"name": "ground", "type": "static",
               "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [-math.sin(tilt), math.cos(tilt)]}]}]
    for i in range(int(rng.integers(1, 4))):
        bodies.append({"name": f"b{i}", "type": "dynamic", "mass": float(rng.uniform(0.2, 2.0)),
                       "position": [x := float(0.35 * i + rng.uniform(-0.05, 0.05)),
                                    float(x * math.tan(tilt) + 0.2 + 0.05 * rng.random())],
                       "angle": float(rng.uniform(-1, 1)),
                       "velocity": [float(rng.uniform(-1, 1)), float(rng.uniform(-1, 0.5))],
                       "angular_velocity": float(rng.uniform(-3, 3)), "shapes": [_random_shape(rng)]})
    doc = {"name": f"random_vertical_{seed}", "world": {"plane": "vertical", "friction": float(rng.uniform(0.1, 0.9))},
           "sim": {"h": 0.005, "t_end": 0.2}, "bodies": bodies}
    return parse_scene(doc)


def random_pushing_scene(seed):
    """A random object on a table (limit surface or support points) and a disk or box pusher moving into it."""
    rng = np.random.default_rng(seed)
    obj = {"name": "object", "type": "dynamic", "mass": float(rng.uniform(0.2, 1.0)), "position": [0.0, 0.0],
           "angle": float(rng.uniform(-0.5, 0.5)), "support_friction": float(rng.uniform(0.2, 0.6)),
           "shapes": [_random_shape(rng)]}
    ang = rng.uniform(-0.6, 0.6)
    pusher_shape = {"type": "disk", "radius": 0.01} if rng.random() < 0.6 else \
        {"type": "box", "width": 0.02, "height": 0.04}
    speed = rng.uniform(0.05, 0.2)
    pusher = {"name": "pusher", "type": "kinematic",
              "position": [float(-0.12 * math.cos(ang)), float(-0.12 * math.sin(ang))],
              "velocity": [float(speed * math.cos(ang)), float(speed * math.sin(ang))],
              "angular_velocity": float(rng.uniform(-0.5, 0.5)), "shapes": [pusher_shape]}
    doc = {"name": f"random_push_{seed}",
           "world": {"plane": "horizontal", "friction": float(rng.uniform(0.1, 0.8)),
                     "support_model": str(rng.choice(["limit_surface", "points"]))},
           "sim": {"h": 0.01, "t_end": 1.0}, "bodies": [obj, pusher]}
    return parse_scene(doc)
