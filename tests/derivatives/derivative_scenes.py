"""Scenes the derivative tests share."""

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
