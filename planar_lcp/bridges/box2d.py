"""A vertical-plane scene as a Box2D v3 world (PyPI `pyb2d3`, the `bench` extra): the peer of `bench pile`.

Box2D is a comparison simulator only: soft contacts (a spring of `contact_hertz`), substepping, warm starting,
graph-coloured sweeps; sleeping is off so every step does the work. Mapped: dynamic bodies with their mass and moment
of inertia about the centre of mass (set directly, not from a density), disks, boxes (and polygons, at most 8
vertices), capsules, each shape's Coulomb coefficient (Box2D mixes the two shapes' by the geometric mean, so both get
the pair's mu, which must then be one value for the whole scene: the default `world.friction`); static half-planes
as a box 100 m wide under the line, static boxes and polygons. Kinematic bodies and restitution are not mapped.
"""

import numpy as np

#: a half-plane's stand-in: a static box this wide (and half as deep) whose top edge is the line
HALFPLANE_BOX = 100.0


def _import():
    try:
        import pyb2d3
    except ImportError as e:  # pragma: no cover - the bench extra installs it
        raise SystemExit("bench pile needs pyb2d3 (Box2D v3): pip install -e \".[bench]\"") from e
    return pyb2d3


def _rot(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _add_shapes(b2, body, shapes, mu, offset_com=(0.0, 0.0)):
    """Create the shapes (spec ShapeSpec) on a Box2D body whose origin is at the body frame's COM offset."""
    sd = b2.shape_def(density=1.0, material=b2.surface_material(friction=float(mu)))
    cx, cy = offset_com
    for s in shapes:
        ox, oy = s.offset[0] - cx, s.offset[1] - cy
        R = _rot(s.angle)
        if s.type == "disk":
            body.create_circle_shape(sd, b2.circle(center=(ox, oy), radius=float(s.radius)))
        elif s.type == "capsule":
            d = R @ np.array([0.5 * s.length, 0.0])
            body.create_capsule_shape(sd, b2.capsule((ox - d[0], oy - d[1]), (ox + d[0], oy + d[1]), float(s.radius)))
        elif s.type in ("box", "polygon"):
            pts = s.core_vertices_body() - np.array([cx, cy])
            poly = b2.polygon(points=[tuple(map(float, p)) for p in pts],
                              radius=float(s.radius) if s.radius else None)
            body.create_polygon_shape(sd, poly)
        elif s.type == "halfplane":
            n = np.asarray(s.normal, float)
            n = n / np.linalg.norm(n)
            t = np.array([-n[1], n[0]])
            p = np.asarray(s.point, float)
            w, d = HALFPLANE_BOX, HALFPLANE_BOX / 2
            corners = [p + t * w / 2, p - n * d + t * w / 2, p - n * d - t * w / 2, p - t * w / 2]
            body.create_polygon_shape(sd, b2.polygon(points=[tuple(map(float, c)) for c in corners]))
        else:
            raise ValueError(f"planar_lcp.bridges.box2d: shape type {s.type!r} is not mapped")


def box2d_world(model, substeps=4):
    """A Box2D world of the compiled scene `model` (vertical plane) at its initial state. Returns (world, bodies):
    bodies the dynamic bodies in the model's dynamic order (Box2D's origin at each body's centre of mass)."""
    b2 = _import()
    scene = model.scene
    if scene.world.plane != "vertical":
        raise ValueError("planar_lcp.bridges.box2d: only vertical-plane scenes")
    mus = {scene.friction_between(a.name, b.name) for a in scene.bodies for b in scene.bodies if a is not b}
    if len(mus) > 1:
        raise ValueError(f"planar_lcp.bridges.box2d: one Coulomb coefficient for the whole scene, got {sorted(mus)}")
    mu = mus.pop() if mus else scene.world.friction
    world = b2.World(gravity=tuple(map(float, scene.world.gravity)))
    world.sleeping_enabled = False
    dyn = []
    q0 = model.q0
    for i, d in enumerate(model.arrays.dyn_body):
        spec = scene.bodies[int(d)]
        x, y, th = (float(c) for c in q0[i])
        body = world.create_dynamic_body(position=(x, y), rotation=float(th))
        _add_shapes(b2, body, spec.shapes, mu, offset_com=tuple(model.com_local[i]))
        md = body.mass_data
        md.mass = float(model.arrays.dyn_mass[i])
        md.center = (0.0, 0.0)
        md.rotational_inertia = float(model.arrays.dyn_inertia[i])
        body.mass_data = md
        v = model.v0[i]
        body.linear_velocity = (float(v[0]), float(v[1]))
        body.angular_velocity = float(v[2])
        dyn.append(body)
    for spec in scene.bodies:
        if spec.type == "static":
            body = world.create_static_body(position=tuple(map(float, spec.position)), rotation=float(spec.angle))
            _add_shapes(b2, body, spec.shapes, mu)
        elif spec.type == "kinematic":
            raise ValueError("planar_lcp.bridges.box2d: kinematic bodies are not mapped")
    return world, dyn


def box2d_poses(bodies):
    """(ndyn, 3) COM poses of the Box2D bodies."""
    out = np.empty((len(bodies), 3))
    for i, b in enumerate(bodies):
        p = b.position              # the origin is the centre of mass (`box2d_world`)
        out[i] = (p[0], p[1], b.angle)
    return out
