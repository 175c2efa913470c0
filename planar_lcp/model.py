"""Compile a Scene (spec) into a Model: flat arrays, never changed after compile.

Frames. A dynamic body's dynamics use its centre of mass (COM): its state q = (x, y, theta) is the COM pose and its
shape vertices are stored relative to the COM. Kinematic and static bodies use their body frame. Users see body-frame
poses (the scene's `position`); `Model.com_local` converts between the two.

Ragged data is flat with address/count arrays (MuJoCo's *_adr / *_num).
"""

import functools
from dataclasses import dataclass

import numpy as np

from planar_lcp.frames import com_to_frame, com_velocity, frame_to_com, rotation
from planar_lcp.spec.limit_surface import (DISK_TABLE_STEP, disk_table, gyration_radius, support_pressure,
                                           twist_directions)
from planar_lcp.spec.massprops import body_mass_properties, support_friction, support_points
from planar_lcp.spec.scene import SUPPORT_MODELS, Scene, SceneError

from planar_lcp.engine.constants import (BODY_DYNAMIC, BODY_KINEMATIC, BODY_STATIC,  # noqa: F401
                                         SERVO_FORCE_DIRECTIONS, SERVO_TORQUE_DIRECTIONS,
                                         PLANE_HORIZONTAL, PLANE_VERTICAL, SHAPE_CORE, SHAPE_HALFPLANE,
                                         SUPPORT_LIMIT_SURFACE, SUPPORT_POINTS)
# the kernels' arrays: engine/layout.py MODEL_LAYOUT
from planar_lcp.engine.interpreted import compiled, python_version
from planar_lcp.engine.layout import ModelArrays, model_struct, step_work_bytes
from planar_lcp.engine.limit_surface import unit_load_wrench
from planar_lcp.compilation.background import start_background


@dataclass(frozen=True)
class Model:
    """A compiled scene. `arrays` goes to the kernels; the rest is for Python-side bookkeeping."""

    scene: Scene
    arrays: ModelArrays
    dyn_names: tuple
    kin_names: tuple
    com_local: np.ndarray       # (ndyn, 2) COM in the body frame of each dynamic body
    q0: np.ndarray              # (ndyn, 3) initial COM poses
    v0: np.ndarray              # (ndyn, 3) initial COM velocities
    qk0: np.ndarray             # (nkin, 3) initial kinematic poses (body frame)
    vk0: np.ndarray             # (nkin, 3) prescribed kinematic velocities

    @functools.cached_property
    def struct(self):
        """The kernels' struct over `arrays` (engine/layout.py `model_struct`), made once per model: the arrays
        never change after compile, and each struct costs about 0.1 ms of typing to make."""
        return model_struct(self.arrays)

    @functools.cached_property
    def work_bytes(self):
        """Bytes of a Simulator's work buffers for this model (engine/layout.py `step_work_bytes`), computed once."""
        return step_work_bytes(self)

    def __getstate__(self):
        # pickled without the struct (numba's memory cannot be pickled); `struct` is made again on first use
        state = dict(self.__dict__)
        state.pop("struct", None)
        return state

    @property
    def ndyn(self):
        return len(self.dyn_names)

    @property
    def nkin(self):
        return len(self.kin_names)

    def max_contacts(self):
        return 2 * len(self.arrays.pair_a)

    def support_columns(self):
        """Friction columns of one support element: k directions (points), or K fixed twists and the re-centred one
        (limit surface). The kernels' `engine.assemble.support_column_count`."""
        a = self.arrays
        return a.fric_dirs.shape[0] if a.support_model == SUPPORT_POINTS else a.ls_wrench.shape[1] + 1

    def servo_unknowns(self):
        """LCP unknowns of the force-limited kinematic bodies: their lag velocities along SERVO_FORCE_DIRECTIONS (and
        SERVO_TORQUE_DIRECTIONS with a torque limit), in an island that needs them."""
        a = self.arrays
        return int(SERVO_FORCE_DIRECTIONS * np.count_nonzero(a.kin_max_force > 0.0)
                   + SERVO_TORQUE_DIRECTIONS * np.count_nonzero(a.kin_max_torque > 0.0))

    def max_unknowns(self):
        """LCP size bound: 4 per contact (normal, two friction rays, slack) plus columns + 1 per support element,
        plus the force-limited kinematic bodies' lag velocities."""
        return self._max_unknowns

    @functools.cached_property
    def _max_unknowns(self):
        # computed once (about 2.5 us): step_derivatives asks it per call, and the arrays' sizes and which kinematic
        # bodies are force-limited never change after compile
        return (4 * self.max_contacts() + (self.support_columns() + 1) * len(self.arrays.sup_dyn)
                + self.servo_unknowns())

    def com_to_frame(self, q):
        """COM poses (..., ndyn, 3) -> body-frame origin poses, as the scene file describes bodies."""
        return com_to_frame(q, self.com_local)

    def frame_to_com(self, qf):
        """Body-frame origin poses (..., ndyn, 3) -> COM poses."""
        return frame_to_com(qf, self.com_local)


#: Largest overlap allowed between two bodies at the start (m); a scene that starts deeper is rejected.
START_OVERLAP_TOL = 1e-6


def _check_start_overlaps(scene, model):
    """Reject a scene whose bodies interpenetrate at the start by more than START_OVERLAP_TOL."""
    from planar_lcp.engine.contacts import contacts_at, find_contacts
    a = model.arrays
    if a.pair_a.shape[0] == 0:
        return
    cold = not compiled(find_contacts)  # a cold cache: Python on the arrays, no struct made (engine/interpreted.py)
    con_pair, con_phi, _, con_p = contacts_at(a, model.q0, model.qk0, -START_OVERLAP_TOL,
                                              m=None if cold else model.struct, python=cold)
    n = len(con_phi)
    if n == 0:
        return
    j = int(np.argmin(con_phi[:n]))
    sa, sb = a.pair_a[con_pair[j]], a.pair_b[con_pair[j]]

    def where(s):
        b = int(a.shape_body[s])
        k = int(np.sum(a.shape_body[:s] == b))  # index of the shape within its body
        return f"bodies[{b}].shapes[{k}] ('{scene.bodies[b].name}')"

    raise SceneError(f"{scene.source}: {where(sa)} and {where(sb)} must not overlap at the start by more than "
                     f"{START_OVERLAP_TOL:g} m, got an overlap of {-con_phi[j]:.6g} m at "
                     f"({con_p[j, 0]:.6g}, {con_p[j, 1]:.6g})")


def _add_limit_surface(ls, body, resolution):
    """Append one body's limit-surface element to the lists in `ls`: its pressure's pieces about the COM
    (spec/limit_surface.py `support_pressure`). ls_node holds per element its curved-piece nodes, its far nodes,
    then its disks' nodes."""
    sp = support_pressure(body, resolution)
    adr = sum(len(n) for n in ls["nodes"])
    ls["edge_adr"].append(sum(len(e) for e in ls["edges"]))
    ls["edge_num"].append(len(sp.edges))
    ls["edge_scale"].append(sp.edge_scale)
    ls["node_adr"].append(adr)
    ls["node_num"].append(len(sp.nodes))
    ls["far_adr"].append(adr + len(sp.nodes))
    ls["far_num"].append(len(sp.far))
    ls["disk_adr"].append(len(ls["disks"]))
    ls["disk_num"].append(len(sp.disks))
    nadr = adr + len(sp.nodes) + len(sp.far)
    for disk, dn in zip(sp.disks, sp.disk_nodes):
        ls["disks"].append(disk)
        ls["disk_node_adr"].append(nadr)
        ls["disk_node_num"].append(len(dn))
        nadr += len(dn)
    ls["size"].append(sp.size)
    ls["edges"].append(sp.edges)
    ls["nodes"].append(np.concatenate([sp.nodes, sp.far, *sp.disk_nodes]))


def _fill_fixed_columns(model, bodies, nls):
    """ls_wrench[s, j] = L(t_j) for the fixed twists of each element, by the kernels' own `unit_load_wrench` (on the
    model struct, as the step calls it; on a cold cache as Python on the arrays, the same bits:
    engine/interpreted.py)."""
    if compiled(unit_load_wrench):
        kernel, m = unit_load_wrench, model.struct
    else:
        kernel, m = python_version(unit_load_wrench), model.arrays
    arrays = model.arrays
    for s, body in enumerate(bodies):
        for j, t in enumerate(twist_directions(nls, gyration_radius(body))):
            kernel(m, s, float(t[0]), float(t[1]), float(t[2]), arrays.ls_wrench[s, j])


@dataclass
class _BodyTables:
    """Per-body tables and the dynamic bodies' mass properties, in scene order (the first stage's output)."""

    kind: np.ndarray            # (nbody,) int64: BODY_DYNAMIC / BODY_KINEMATIC / BODY_STATIC
    slot: np.ndarray            # (nbody,) int64: index among the bodies of its kind; -1 for a static body
    static_pose: np.ndarray     # (nbody, 3): a static body's pose, zeros for the others
    dyn_names: list
    dyn_mass: list
    dyn_inertia: list           # about the COM
    com_local: list             # (2,) arrays: the COM in the body frame
    q0: list                    # initial COM poses
    v0: list                    # initial COM velocities


@dataclass
class _KinematicData:
    """The kinematic bodies in scene order: initial poses, prescribed velocities and servo limits (0: none)."""

    names: list
    qk0: list
    vk0: list
    max_force: list
    max_torque: list


@dataclass
class _ShapeArrays:
    """Every shape in scene order (a body's shapes in its order): the ragged core vertices flattened with
    address/count, a half-plane's world point and unit normal (zeros for the other shapes)."""

    body: list
    kind: list
    vert_adr: list
    vert_num: list
    radius: list
    hp_point: list
    hp_normal: list
    verts: list                 # core vertices, COM frame for a dynamic body's shapes


@dataclass
class _Pairs:
    """Candidate shape pairs (A dynamic and never a half-plane) with their friction and restitution."""

    a: list
    b: list
    mu: list
    e: list


@dataclass
class _TableSettings:
    """The table-friction settings after the overrides, checked."""

    plane: int                  # PLANE_HORIZONTAL / PLANE_VERTICAL
    fric_dirs: np.ndarray       # (k, 2) unit directions of the support points' friction
    support_code: int           # index in SUPPORT_MODELS
    twists: int                 # fixed twists of a limit-surface element
    resolution: int


@dataclass
class _Support:
    """The table's support elements (horizontal plane): points with known normal loads, or one limit-surface element
    per dynamic body; and the in-plane gravity (zero on a table)."""

    dyn: list
    local: list                 # element position relative to the COM
    load: list
    mu: list
    ls: dict                    # the limit-surface lists (`_add_limit_surface`)
    ls_bodies: list             # the bodies with a limit-surface element, in element order
    gravity: np.ndarray


def _flat(x, dtype=float, shape=None):
    """x as a contiguous array; an empty one with `shape` (so that (0, 2) stays two-dimensional)."""
    a = np.asarray(x, dtype=dtype)
    if shape is not None and a.size == 0:
        a = a.reshape(shape)
    return np.ascontiguousarray(a)


def _body_tables(bodies) -> _BodyTables:
    """Bodies -> body tables: each body's kind, its slot among its kind, a static body's pose, and each dynamic
    body's mass, inertia and COM (spec/massprops.py) with its initial COM pose and velocity."""
    nbody = len(bodies)
    t = _BodyTables(kind=np.empty(nbody, np.int64), slot=np.full(nbody, -1, np.int64),
                    static_pose=np.zeros((nbody, 3)), dyn_names=[], dyn_mass=[], dyn_inertia=[], com_local=[],
                    q0=[], v0=[])
    kinds = {"dynamic": BODY_DYNAMIC, "static": BODY_STATIC, "kinematic": BODY_KINEMATIC}
    nkin = 0
    for i, b in enumerate(bodies):
        t.kind[i] = kinds[b.type]
        pose = np.array([b.position[0], b.position[1], b.angle], dtype=float)
        if b.type == "dynamic":
            t.slot[i] = len(t.dyn_names)
            t.dyn_names.append(b.name)
            com, inertia = body_mass_properties(b)
            com = np.asarray(com, dtype=float)
            t.com_local.append(com)
            t.dyn_mass.append(float(b.mass))
            t.dyn_inertia.append(float(inertia))
            rc = rotation(b.angle) @ com
            t.q0.append([pose[0] + rc[0], pose[1] + rc[1], pose[2]])
            t.v0.append([*com_velocity(b.angle, b.velocity, b.angular_velocity, com), b.angular_velocity])
        elif b.type == "kinematic":
            t.slot[i] = nkin
            nkin += 1
        else:
            t.static_pose[i] = pose
    return t


def _kinematic_data(bodies) -> _KinematicData:
    """Bodies -> the kinematic bodies' data: body-frame initial poses, prescribed velocities, and the servo limits
    of a force-limited body (0.0 where the scene gives none)."""
    k = _KinematicData(names=[], qk0=[], vk0=[], max_force=[], max_torque=[])
    for b in bodies:
        if b.type != "kinematic":
            continue
        k.names.append(b.name)
        k.qk0.append(np.array([b.position[0], b.position[1], b.angle], dtype=float))
        k.vk0.append([b.velocity[0], b.velocity[1], b.angular_velocity])
        k.max_force.append(b.max_force or 0.0)
        k.max_torque.append(b.max_torque or 0.0)
    return k


def _shape_arrays(bodies, bt: _BodyTables) -> _ShapeArrays:
    """Shapes -> shape arrays: a dynamic body's core vertices moved to its COM frame (the others keep their body
    frame), a half-plane placed in the world once (it belongs to a static body)."""
    sh = _ShapeArrays(body=[], kind=[], vert_adr=[], vert_num=[], radius=[], hp_point=[], hp_normal=[], verts=[])
    for i, b in enumerate(bodies):
        shift = bt.com_local[bt.slot[i]] if bt.kind[i] == BODY_DYNAMIC else np.zeros(2)
        for s in b.shapes:
            sh.body.append(i)
            if s.type == "halfplane":
                sh.kind.append(SHAPE_HALFPLANE)
                R = rotation(bt.static_pose[i, 2])
                sh.hp_point.append(R @ np.asarray(s.point, float) + bt.static_pose[i, :2])
                n = R @ np.asarray(s.normal, float)
                sh.hp_normal.append(n / np.linalg.norm(n))
                sh.vert_adr.append(len(sh.verts))
                sh.vert_num.append(0)
                sh.radius.append(0.0)
            else:
                sh.kind.append(SHAPE_CORE)
                core = np.asarray(s.core_vertices_body(), float).reshape(-1, 2) - shift
                sh.vert_adr.append(len(sh.verts))
                sh.vert_num.append(core.shape[0])
                sh.verts.extend(core.tolist())
                sh.radius.append(float(s.radius))
                sh.hp_point.append([0.0, 0.0])
                sh.hp_normal.append([0.0, 0.0])
    return sh


def _candidate_pairs(scene, bt: _BodyTables, sh: _ShapeArrays) -> _Pairs:
    """Shapes -> candidate pairs: shapes of different bodies, at least one dynamic, in (s1 < s2) order; side A is the
    dynamic one and never a half-plane (engine/islands.py relies on it). Raises SceneError for two half-planes."""
    bodies = scene.bodies
    p = _Pairs(a=[], b=[], mu=[], e=[])
    nshape = len(sh.body)
    for s1 in range(nshape):
        for s2 in range(s1 + 1, nshape):
            b1, b2 = sh.body[s1], sh.body[s2]
            if b1 == b2:
                continue
            k1, k2 = bt.kind[b1], bt.kind[b2]
            if k1 != BODY_DYNAMIC and k2 != BODY_DYNAMIC:
                continue
            a, b_ = s1, s2
            if k1 != BODY_DYNAMIC or sh.kind[s1] == SHAPE_HALFPLANE:
                a, b_ = s2, s1
            if sh.kind[a] == SHAPE_HALFPLANE:
                raise SceneError(f"{scene.source}: shapes of bodies '{bodies[b1].name}' and '{bodies[b2].name}': "
                                 f"no contact model for half-plane against half-plane")
            name_a, name_b = bodies[sh.body[a]].name, bodies[sh.body[b_]].name
            p.a.append(a)
            p.b.append(b_)
            p.mu.append(scene.friction_between(name_a, name_b))
            p.e.append(scene.restitution_between(name_a, name_b))
    return p


def _table_settings(scene, friction_directions, support_model, limit_surface_twists,
                    limit_surface_resolution) -> _TableSettings:
    """The compile_scene overrides over the scene's [sim] and world keys -> the checked table-friction settings.
    Raises ValueError for a bad value, checked in this order: friction directions, support model, resolution."""
    plane = PLANE_HORIZONTAL if scene.world.plane == "horizontal" else PLANE_VERTICAL
    k = int(friction_directions if friction_directions is not None else scene.sim.friction_directions)
    if k < 3:
        raise ValueError(f"friction_directions must be >= 3 (the directions must positively span the plane), got {k}")
    ang = 2.0 * np.pi * np.arange(k) / k
    fric_dirs = np.column_stack([np.cos(ang), np.sin(ang)])
    support = support_model if support_model is not None else scene.world.support_model
    if support not in SUPPORT_MODELS:
        raise ValueError(f"support_model must be one of {SUPPORT_MODELS}, got {support!r}")
    nls = int(limit_surface_twists if limit_surface_twists is not None else scene.sim.limit_surface_twists)
    res = int(limit_surface_resolution if limit_surface_resolution is not None
              else scene.sim.limit_surface_resolution)
    if res < 1:
        raise ValueError(f"limit_surface_resolution must be >= 1, got {res}")
    return _TableSettings(plane=plane, fric_dirs=fric_dirs, support_code=SUPPORT_MODELS.index(support), twists=nls,
                          resolution=res)


def _support_elements(scene, bt: _BodyTables, ts: _TableSettings) -> _Support:
    """Bodies, mass properties and settings -> the table's support elements. On the horizontal plane each dynamic
    body rests on support points sharing its weight m g (positions relative to the COM), or on one limit-surface
    element carrying all of it; in the vertical plane there is no table, only gravity."""
    sup = _Support(dyn=[], local=[], load=[], mu=[], ls_bodies=[], gravity=None,
                   ls=dict(edge_adr=[], edge_num=[], edge_scale=[], node_adr=[], node_num=[], far_adr=[], far_num=[],
                           disk_adr=[], disk_num=[], disks=[], disk_node_adr=[], disk_node_num=[], size=[],
                           edges=[], nodes=[]))
    if ts.plane != PLANE_HORIZONTAL:
        sup.gravity = np.asarray(scene.world.gravity, float)
        return sup
    g = float(scene.world.support_gravity)
    for i, b in enumerate(scene.bodies):
        if bt.kind[i] != BODY_DYNAMIC:
            continue
        slot = bt.slot[i]
        if ts.support_code == SUPPORT_POINTS:
            pts, w, mu = support_points(b, scene.world)
            for p, wi in zip(pts - bt.com_local[slot], w):
                sup.dyn.append(slot)
                sup.local.append(p)
                sup.load.append(bt.dyn_mass[slot] * g * wi)
                sup.mu.append(float(mu))
            continue
        sup.dyn.append(slot)
        sup.local.append(np.zeros(2))
        sup.load.append(bt.dyn_mass[slot] * g)
        sup.mu.append(support_friction(b, scene.world))
        _add_limit_surface(sup.ls, b, ts.resolution)
        sup.ls_bodies.append(b)
    sup.gravity = np.zeros(2)
    return sup


def _model_arrays(scene, bt: _BodyTables, kin: _KinematicData, sh: _ShapeArrays, pairs: _Pairs,
                  ts: _TableSettings, sup: _Support, seed_friction_arm) -> ModelArrays:
    """The stages' lists -> the kernels' flat arrays (engine/layout.py MODEL_LAYOUT): int64 indices, float64 values,
    C-contiguous, empty ragged arrays keeping their trailing dimension. ls_wrench is left zero for
    `_fill_fixed_columns`."""
    ls = sup.ls
    return ModelArrays(
        plane=ts.plane, gravity=_flat(sup.gravity), damping=float(scene.world.damping), body_kind=bt.kind,
        body_slot=bt.slot, static_pose=bt.static_pose,
        dyn_body=_flat(np.flatnonzero(bt.kind == BODY_DYNAMIC), np.int64),
        dyn_mass=_flat(bt.dyn_mass), dyn_inertia=_flat(bt.dyn_inertia),
        dyn_inv_mass=_flat(1.0 / np.asarray(bt.dyn_mass, float)),
        shape_body=_flat(sh.body, np.int64), shape_kind=_flat(sh.kind, np.int64),
        shape_vert_adr=_flat(sh.vert_adr, np.int64), shape_vert_num=_flat(sh.vert_num, np.int64),
        shape_radius=_flat(sh.radius), hp_point_w=_flat(sh.hp_point, shape=(0, 2)),
        hp_normal_w=_flat(sh.hp_normal, shape=(0, 2)), vert_local=_flat(sh.verts, shape=(0, 2)),
        pair_a=_flat(pairs.a, np.int64), pair_b=_flat(pairs.b, np.int64), pair_mu=_flat(pairs.mu),
        pair_e=_flat(pairs.e),
        sup_dyn=_flat(sup.dyn, np.int64), sup_local=_flat(sup.local, shape=(0, 2)), sup_load=_flat(sup.load),
        sup_mu=_flat(sup.mu), fric_dirs=_flat(ts.fric_dirs), seed_friction_arm=int(bool(seed_friction_arm)),
        support_model=ts.support_code, sup_edge_adr=_flat(ls["edge_adr"], np.int64),
        sup_edge_num=_flat(ls["edge_num"], np.int64), sup_edge_scale=_flat(ls["edge_scale"]),
        sup_node_adr=_flat(ls["node_adr"], np.int64), sup_node_num=_flat(ls["node_num"], np.int64),
        sup_far_adr=_flat(ls["far_adr"], np.int64), sup_far_num=_flat(ls["far_num"], np.int64),
        sup_size=_flat(ls["size"]), ls_edge=_flat(np.concatenate(ls["edges"]) if ls["edges"] else [], shape=(0, 4)),
        ls_node=_flat(np.concatenate(ls["nodes"]) if ls["nodes"] else [], shape=(0, 3)),
        sup_disk_adr=_flat(ls["disk_adr"], np.int64), sup_disk_num=_flat(ls["disk_num"], np.int64),
        ls_disk=_flat(ls["disks"], shape=(0, 3)), ls_disk_node_adr=_flat(ls["disk_node_adr"], np.int64),
        ls_disk_node_num=_flat(ls["disk_node_num"], np.int64), ls_disk_table=disk_table().copy(),
        ls_disk_step=float(DISK_TABLE_STEP),
        ls_wrench=np.zeros((len(sup.ls_bodies), ts.twists if ts.support_code == SUPPORT_LIMIT_SURFACE else 0, 3)),
        kin_max_force=_flat(kin.max_force), kin_max_torque=_flat(kin.max_torque),
    )


def compile_scene(scene: Scene, friction_directions=None, seed_friction_arm=False, support_model=None,
                  limit_surface_twists=None, limit_surface_resolution=None, *, background=True) -> Model:
    """Flatten a validated Scene into a Model. `friction_directions`, `limit_surface_twists` and
    `limit_surface_resolution` override the scene's [sim] keys, `support_model` its world.support_model (the
    horizontal plane's table friction: docs/method.md, "Table friction").

    seed_friction_arm: apply contact friction at each shape's core point (a capsule's end-cap centre) instead of the
    contact point, reproducing Stewart & Trinkle's friction vectors d = [+-1, 0, +-(l/2) sin theta] (for comparison
    only; the moment arm to the contact point is the physically right one).

    background: on a cold numba cache, start compiling the kernels in a background process once the scene is
    checked (planar_lcp/compilation/background.py); False leaves that to the `Simulator` made from the model (a
    caller that checks more before it runs, as `simulate` checks the run's size: bad input starts nothing).

    Raises SceneError if bodies interpenetrate at the start by more than START_OVERLAP_TOL."""
    bt = _body_tables(scene.bodies)
    kin = _kinematic_data(scene.bodies)
    shapes = _shape_arrays(scene.bodies, bt)
    pairs = _candidate_pairs(scene, bt, shapes)
    settings = _table_settings(scene, friction_directions, support_model, limit_surface_twists,
                               limit_surface_resolution)
    support = _support_elements(scene, bt, settings)
    arrays = _model_arrays(scene, bt, kin, shapes, pairs, settings, support, seed_friction_arm)
    model = Model(scene=scene, arrays=arrays, dyn_names=tuple(bt.dyn_names), kin_names=tuple(kin.names),
                  com_local=_flat(bt.com_local, shape=(0, 2)), q0=_flat(bt.q0, shape=(0, 3)),
                  v0=_flat(bt.v0, shape=(0, 3)), qk0=_flat(kin.qk0, shape=(0, 3)), vk0=_flat(kin.vk0, shape=(0, 3)))
    if support.ls_bodies:
        # the fixed twists' load wrenches are computed by the kernels themselves, so they need the model
        _fill_fixed_columns(model, support.ls_bodies, settings.twists)
    _check_start_overlaps(scene, model)
    if background:
        # on a cold numba cache, the kernels compile in a background process from now on
        start_background()
    return model
