"""Shared by the planning-task layout tests (test_push_clutter.py, test_push_table.py): a body's shapes placed at
its start pose, and the region the task's object sweeps moving straight (no turn) from its start to the goal."""


def placed(body):
    """The union of a scene body's shapes at its start pose (shapely)."""
    from shapely.ops import unary_union

    from planar_lcp.geometry import shape_geometry
    from planners.tasks import _place
    return _place(unary_union([shape_geometry(s, quad_segs=8) for s in body.shapes]), body.position, body.angle)


def straight_sweep(tm):
    """The convex hull of the object at its start and the goal region of the TaskModel tm."""
    from shapely.ops import unary_union
    return unary_union([placed(tm.scene.body(tm.task.object)), tm.goal_poly]).convex_hull
