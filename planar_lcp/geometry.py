"""Scene shapes as shapely geometries, for drawing (`viz`) and for planning constraints (`planners.tasks`).

shapely is imported inside the function: `import planar_lcp.geometry` does not need it.
"""

import numpy as np


def shape_geometry(shape, quad_segs=16):
    """A finite shape (not a half-plane) in its body frame: its convex core (a Point, LineString or Polygon) inflated
    by its radius, the arcs approximated by `quad_segs` segments per quarter circle; the bare core if the radius is
    0."""
    from shapely.geometry import LineString, Point, Polygon

    core = np.asarray(shape.core_vertices_body(), dtype=np.float64).reshape(-1, 2)
    r = float(shape.radius)
    base = Point(core[0]) if len(core) == 1 else LineString(core) if len(core) == 2 else Polygon(core)
    return base.buffer(r, quad_segs=quad_segs) if r > 0.0 else base
