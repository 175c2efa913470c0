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


def compile_scene(scene: Scene, friction_directions=None, seed_friction_arm=False, support_model=None,
                  limit_surface_twists=None, limit_surface_resolution=None) -> Model:
    """Flatten a validated Scene into a Model. `friction_directions`, `limit_surface_twists` and
    `limit_surface_resolution` override the scene's [sim] keys, `support_model` its world.support_model (the
    horizontal plane's table friction: docs/method.md, "Table friction").

    seed_friction_arm: apply contact friction at each shape's core point (a capsule's end-cap centre) instead of the
    contact point, reproducing Stewart & Trinkle's friction vectors d = [+-1, 0, +-(l/2) sin theta] (for comparison
    only; the moment arm to the contact point is the physically right one).

    Raises SceneError if bodies interpenetrate at the start by more than START_OVERLAP_TOL."""
    bodies = scene.bodies
    nbody = len(bodies)
    body_kind = np.empty(nbody, np.int64)
    body_slot = np.full(nbody, -1, np.int64)
    static_pose = np.zeros((nbody, 3))
    dyn_names, kin_names = [], []
    dyn_mass, dyn_inertia, com_local, q0, v0, qk0, vk0 = [], [], [], [], [], [], []
    kin_max_force, kin_max_torque = [], []
    kinds = {"dynamic": BODY_DYNAMIC, "static": BODY_STATIC, "kinematic": BODY_KINEMATIC}
    for i, b in enumerate(bodies):
        body_kind[i] = kinds[b.type]
        pose = np.array([b.position[0], b.position[1], b.angle], dtype=float)
        if b.type == "dynamic":
            body_slot[i] = len(dyn_names)
            dyn_names.append(b.name)
            com, inertia = body_mass_properties(b)
            com = np.asarray(com, dtype=float)
            com_local.append(com)
            dyn_mass.append(float(b.mass))
            dyn_inertia.append(float(inertia))
            rc = rotation(b.angle) @ com
            q0.append([pose[0] + rc[0], pose[1] + rc[1], pose[2]])
            v0.append([*com_velocity(b.angle, b.velocity, b.angular_velocity, com), b.angular_velocity])
        elif b.type == "kinematic":
            body_slot[i] = len(kin_names)
            kin_names.append(b.name)
            qk0.append(pose)
            vk0.append([b.velocity[0], b.velocity[1], b.angular_velocity])
            kin_max_force.append(b.max_force or 0.0)
            kin_max_torque.append(b.max_torque or 0.0)
        else:
            static_pose[i] = pose

    # shapes
    shape_body, shape_kind, vadr, vnum, radius, hp_p, hp_n, verts = [], [], [], [], [], [], [], []
    for i, b in enumerate(bodies):
        shift = com_local[body_slot[i]] if body_kind[i] == BODY_DYNAMIC else np.zeros(2)
        for s in b.shapes:
            shape_body.append(i)
            if s.type == "halfplane":
                shape_kind.append(SHAPE_HALFPLANE)
                R = rotation(static_pose[i, 2])
                hp_p.append(R @ np.asarray(s.point, float) + static_pose[i, :2])
                n = R @ np.asarray(s.normal, float)
                hp_n.append(n / np.linalg.norm(n))
                vadr.append(len(verts))
                vnum.append(0)
                radius.append(0.0)
            else:
                shape_kind.append(SHAPE_CORE)
                core = np.asarray(s.core_vertices_body(), float).reshape(-1, 2) - shift
                vadr.append(len(verts))
                vnum.append(core.shape[0])
                verts.extend(core.tolist())
                radius.append(float(s.radius))
                hp_p.append([0.0, 0.0])
                hp_n.append([0.0, 0.0])

    # candidate shape pairs: different bodies, at least one dynamic; A is never a half-plane
    pa, pb, pmu, pe = [], [], [], []
    nshape = len(shape_body)
    for s1 in range(nshape):
        for s2 in range(s1 + 1, nshape):
            b1, b2 = shape_body[s1], shape_body[s2]
            if b1 == b2:
                continue
            k1, k2 = body_kind[b1], body_kind[b2]
            if k1 != BODY_DYNAMIC and k2 != BODY_DYNAMIC:
                continue
            a, b_ = s1, s2
            # put the dynamic body first (and never a half-plane as A)
            if k1 != BODY_DYNAMIC or shape_kind[s1] == SHAPE_HALFPLANE:
                a, b_ = s2, s1
            if shape_kind[a] == SHAPE_HALFPLANE:
                raise SceneError(f"{scene.source}: shapes of bodies '{bodies[b1].name}' and '{bodies[b2].name}': "
                                 f"no contact model for half-plane against half-plane")
            pa.append(a)
            pb.append(b_)
            pmu.append(scene.friction_between(bodies[shape_body[a]].name, bodies[shape_body[b_]].name))
            pe.append(scene.restitution_between(bodies[shape_body[a]].name, bodies[shape_body[b_]].name))

    # horizontal plane: support points with known normal loads
    plane = PLANE_HORIZONTAL if scene.world.plane == "horizontal" else PLANE_VERTICAL
    k = int(friction_directions if friction_directions is not None else scene.sim.friction_directions)
    if k < 3:
        raise ValueError(f"friction_directions must be >= 3 (the directions must positively span the plane), got {k}")
    ang = 2.0 * np.pi * np.arange(k) / k
    fric_dirs = np.column_stack([np.cos(ang), np.sin(ang)])
    support = support_model if support_model is not None else scene.world.support_model
    if support not in SUPPORT_MODELS:
        raise ValueError(f"support_model must be one of {SUPPORT_MODELS}, got {support!r}")
    support_code = SUPPORT_MODELS.index(support)
    nls = int(limit_surface_twists if limit_surface_twists is not None else scene.sim.limit_surface_twists)
    res = int(limit_surface_resolution if limit_surface_resolution is not None
              else scene.sim.limit_surface_resolution)
    if res < 1:
        raise ValueError(f"limit_surface_resolution must be >= 1, got {res}")
    sup_dyn, sup_local, sup_load, sup_mu = [], [], [], []
    ls = dict(edge_adr=[], edge_num=[], edge_scale=[], node_adr=[], node_num=[], far_adr=[], far_num=[], disk_adr=[],
              disk_num=[], disks=[], disk_node_adr=[], disk_node_num=[], size=[], edges=[], nodes=[])
    ls_bodies = []
    if plane == PLANE_HORIZONTAL:
        g = float(scene.world.support_gravity)
        for i, b in enumerate(bodies):
            if body_kind[i] != BODY_DYNAMIC:
                continue
            slot = body_slot[i]
            if support_code == SUPPORT_POINTS:
                pts, w, mu = support_points(b, scene.world)
                for p, wi in zip(pts - com_local[slot], w):
                    sup_dyn.append(slot)
                    sup_local.append(p)
                    sup_load.append(dyn_mass[slot] * g * wi)
                    sup_mu.append(float(mu))
                continue
            # limit surface: one element per body, its whole load m g
            sup_dyn.append(slot)
            sup_local.append(np.zeros(2))
            sup_load.append(dyn_mass[slot] * g)
            sup_mu.append(support_friction(b, scene.world))
            _add_limit_surface(ls, b, res)
            ls_bodies.append(b)
        gravity = np.zeros(2)
    else:
        gravity = np.asarray(scene.world.gravity, float)

    def arr(x, dtype=float, shape=None):
        a = np.asarray(x, dtype=dtype)
        if shape is not None and a.size == 0:
            a = a.reshape(shape)
        return np.ascontiguousarray(a)

    arrays = ModelArrays(
        plane=plane, gravity=arr(gravity), damping=float(scene.world.damping), body_kind=body_kind,
        body_slot=body_slot, static_pose=static_pose,
        dyn_body=arr(np.flatnonzero(body_kind == BODY_DYNAMIC), np.int64),
        dyn_mass=arr(dyn_mass), dyn_inertia=arr(dyn_inertia), dyn_inv_mass=arr(1.0 / np.asarray(dyn_mass, float)),
        shape_body=arr(shape_body, np.int64), shape_kind=arr(shape_kind, np.int64),
        shape_vert_adr=arr(vadr, np.int64), shape_vert_num=arr(vnum, np.int64), shape_radius=arr(radius),
        hp_point_w=arr(hp_p, shape=(0, 2)), hp_normal_w=arr(hp_n, shape=(0, 2)), vert_local=arr(verts, shape=(0, 2)),
        pair_a=arr(pa, np.int64), pair_b=arr(pb, np.int64), pair_mu=arr(pmu), pair_e=arr(pe),
        sup_dyn=arr(sup_dyn, np.int64), sup_local=arr(sup_local, shape=(0, 2)), sup_load=arr(sup_load),
        sup_mu=arr(sup_mu), fric_dirs=arr(fric_dirs), seed_friction_arm=int(bool(seed_friction_arm)),
        support_model=support_code, sup_edge_adr=arr(ls["edge_adr"], np.int64),
        sup_edge_num=arr(ls["edge_num"], np.int64), sup_edge_scale=arr(ls["edge_scale"]),
        sup_node_adr=arr(ls["node_adr"], np.int64), sup_node_num=arr(ls["node_num"], np.int64),
        sup_far_adr=arr(ls["far_adr"], np.int64), sup_far_num=arr(ls["far_num"], np.int64),
        sup_size=arr(ls["size"]), ls_edge=arr(np.concatenate(ls["edges"]) if ls["edges"] else [], shape=(0, 4)),
        ls_node=arr(np.concatenate(ls["nodes"]) if ls["nodes"] else [], shape=(0, 3)),
        sup_disk_adr=arr(ls["disk_adr"], np.int64), sup_disk_num=arr(ls["disk_num"], np.int64),
        ls_disk=arr(ls["disks"], shape=(0, 3)), ls_disk_node_adr=arr(ls["disk_node_adr"], np.int64),
        ls_disk_node_num=arr(ls["disk_node_num"], np.int64), ls_disk_table=disk_table().copy(),
        ls_disk_step=float(DISK_TABLE_STEP),
        ls_wrench=np.zeros((len(ls_bodies), nls if support_code == SUPPORT_LIMIT_SURFACE else 0, 3)),
        kin_max_force=arr(kin_max_force), kin_max_torque=arr(kin_max_torque),
    )
    model = Model(scene=scene, arrays=arrays, dyn_names=tuple(dyn_names), kin_names=tuple(kin_names),
                  com_local=arr(com_local, shape=(0, 2)), q0=arr(q0, shape=(0, 3)), v0=arr(v0, shape=(0, 3)),
                  qk0=arr(qk0, shape=(0, 3)), vk0=arr(vk0, shape=(0, 3)))
    if ls_bodies:
        _fill_fixed_columns(model, ls_bodies, nls)
    # on a cold numba cache, the kernels compile in a background process from now on (planar_lcp/compilation/background.py)
    start_background()
    _check_start_overlaps(scene, model)
    return model
