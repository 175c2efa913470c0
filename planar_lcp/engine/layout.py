"""The kernels' two big arguments, the model's arrays and a step's work buffers, as numba structrefs.

Why: the same data as a namedtuple is passed by value, a tuple of 25 or 45 arrays flattened into hundreds of scalar
arguments of every jitted call, each array reference-counted on the way in and out, and every function taking one
costs the compiler close to a second even when trivial. A structref is one pointer; its fields are read in place.
Measured (`python examples/struct_vs_namedtuple.py`, fresh numba cache): falling_rod 8.7 -> 2.4 us per step and
37 -> 20 s for the first rollout call (compile included); box_push 29.6 -> 21.9 us per step.

The Python side keeps the namedtuples (`Model.arrays`, `Simulator.work`): `model_struct` and `work_struct` wrap the
same numpy buffers (no copy), so whatever a kernel writes through the struct is visible in the namedtuple. Kernel
code is the same for both (attribute access), and with NUMBA_DISABLE_JIT=1 the namedtuples are used as they are.
"""

import numba
from numba import njit, types
from numba.experimental import structref

F1, F2, F3 = types.float64[::1], types.float64[:, ::1], types.float64[:, :, ::1]
I1, I2 = types.int64[::1], types.int64[:, ::1]
B1, B2 = types.boolean[::1], types.boolean[:, ::1]
INT = types.int64

#: field name -> numba type, in the order of the namedtuple's fields
MODEL_FIELDS = (
    ("plane", INT),
    ("gravity", F1),
    ("body_kind", I1),
    ("body_slot", I1),
    ("static_pose", F2),
    ("dyn_body", I1),
    ("dyn_mass", F1),
    ("dyn_inertia", F1),
    ("shape_body", I1),
    ("shape_kind", I1),
    ("shape_vert_adr", I1),
    ("shape_vert_num", I1),
    ("shape_radius", F1),
    ("hp_point_w", F2),
    ("hp_normal_w", F2),
    ("vert_local", F2),
    ("pair_a", I1),
    ("pair_b", I1),
    ("pair_mu", F1),
    ("sup_dyn", I1),
    ("sup_local", F2),
    ("sup_load", F1),
    ("sup_mu", F1),
    ("fric_dirs", F2),
    ("seed_friction_arm", INT),
)

#: field name -> numba type, in the order of the namedtuple's fields
WORK_FIELDS = (
    ("poses", F2),
    ("vw", F2),
    ("force_pair", B1),
    ("set_count", I1),
    ("con_pair", I1),
    ("con_phi", F1),
    ("con_n", F2),
    ("con_p", F2),
    ("tmp_phi", F1),
    ("tmp_n", F2),
    ("tmp_p", F2),
    ("chk_pair", I1),
    ("chk_phi", F1),
    ("chk_n", F2),
    ("chk_p", F2),
    ("parent", I1),
    ("island", I1),
    ("isl_con", I1),
    ("isl_sup", I1),
    ("col_dyn", I2),
    ("col_g", F3),
    ("Abuf", F1),
    ("bvec", F1),
    ("zvec", F1),
    ("lT", F1),
    ("lbasis", I1),
    ("lz", F1),
    ("lw", F1),
    ("lcand", I1),
    ("llu", F2),
    ("lrhs", F1),
    ("lperm", I1),
    ("lzb", I1),
    ("lzalt", F1),
    ("lwalt", F1),
    ("lprow", F1),
    ("ld", F1),
    ("v_tilde", F2),
    ("v_hat", F2),
    ("q_hat", F2),
    ("v_new", F2),
    ("q_new", F2),
    ("con_cn", F1),
    ("con_ft", F1),
    ("con_vt", F1),
    ("con_mode", I1),
    ("ws_n", I1),
    ("ws_zmask", B2),
    ("ws_n_saved", I1),
    ("ws_zmask_saved", B2),
)



@structref.register
class ModelStructType(types.StructRef):
    pass


@structref.register
class WorkStructType(types.StructRef):
    pass


MODEL_STRUCT = ModelStructType(list(MODEL_FIELDS))
WORK_STRUCT = WorkStructType(list(WORK_FIELDS))


class ModelStruct(structref.StructRefProxy):
    """Python handle of a model struct (fields are not exposed to Python: read `Model.arrays`)."""


class WorkStruct(structref.StructRefProxy):
    """Python handle of a work struct (fields are not exposed to Python: read `Simulator.work`)."""


structref.define_boxing(ModelStructType, ModelStruct)
structref.define_boxing(WorkStructType, WorkStruct)


@njit(cache=True)
def _new_model_struct(a):
    s = structref.new(MODEL_STRUCT)
    s.plane = a.plane
    s.gravity = a.gravity
    s.body_kind = a.body_kind
    s.body_slot = a.body_slot
    s.static_pose = a.static_pose
    s.dyn_body = a.dyn_body
    s.dyn_mass = a.dyn_mass
    s.dyn_inertia = a.dyn_inertia
    s.shape_body = a.shape_body
    s.shape_kind = a.shape_kind
    s.shape_vert_adr = a.shape_vert_adr
    s.shape_vert_num = a.shape_vert_num
    s.shape_radius = a.shape_radius
    s.hp_point_w = a.hp_point_w
    s.hp_normal_w = a.hp_normal_w
    s.vert_local = a.vert_local
    s.pair_a = a.pair_a
    s.pair_b = a.pair_b
    s.pair_mu = a.pair_mu
    s.sup_dyn = a.sup_dyn
    s.sup_local = a.sup_local
    s.sup_load = a.sup_load
    s.sup_mu = a.sup_mu
    s.fric_dirs = a.fric_dirs
    s.seed_friction_arm = a.seed_friction_arm
    return s


@njit(cache=True)
def _new_work_struct(a):
    s = structref.new(WORK_STRUCT)
    s.poses = a.poses
    s.vw = a.vw
    s.force_pair = a.force_pair
    s.set_count = a.set_count
    s.con_pair = a.con_pair
    s.con_phi = a.con_phi
    s.con_n = a.con_n
    s.con_p = a.con_p
    s.tmp_phi = a.tmp_phi
    s.tmp_n = a.tmp_n
    s.tmp_p = a.tmp_p
    s.chk_pair = a.chk_pair
    s.chk_phi = a.chk_phi
    s.chk_n = a.chk_n
    s.chk_p = a.chk_p
    s.parent = a.parent
    s.island = a.island
    s.isl_con = a.isl_con
    s.isl_sup = a.isl_sup
    s.col_dyn = a.col_dyn
    s.col_g = a.col_g
    s.Abuf = a.Abuf
    s.bvec = a.bvec
    s.zvec = a.zvec
    s.lT = a.lT
    s.lbasis = a.lbasis
    s.lz = a.lz
    s.lw = a.lw
    s.lcand = a.lcand
    s.llu = a.llu
    s.lrhs = a.lrhs
    s.lperm = a.lperm
    s.lzb = a.lzb
    s.lzalt = a.lzalt
    s.lwalt = a.lwalt
    s.lprow = a.lprow
    s.ld = a.ld
    s.v_tilde = a.v_tilde
    s.v_hat = a.v_hat
    s.q_hat = a.q_hat
    s.v_new = a.v_new
    s.q_new = a.q_new
    s.con_cn = a.con_cn
    s.con_ft = a.con_ft
    s.con_vt = a.con_vt
    s.con_mode = a.con_mode
    s.ws_n = a.ws_n
    s.ws_zmask = a.ws_zmask
    s.ws_n_saved = a.ws_n_saved
    s.ws_zmask_saved = a.ws_zmask_saved
    return s


def _check(a, fields, what):
    names = tuple(k for k, _ in fields)
    if tuple(a._fields) != names:
        raise TypeError(f"{what}: fields {a._fields} do not match the struct's {names}")
    for (k, t), v in zip(fields, a):
        got = numba.typeof(v)
        if got != t:
            raise TypeError(f"{what}.{k}: expected {t}, got {got}")


def model_struct(arrays):
    """The kernels' view of a ModelArrays namedtuple (same buffers). With NUMBA_DISABLE_JIT, the namedtuple."""
    if numba.config.DISABLE_JIT:
        return arrays
    _check(arrays, MODEL_FIELDS, "ModelArrays")
    return _new_model_struct(arrays)


def work_struct(work):
    """The kernels' view of a StepWork namedtuple (same buffers). With NUMBA_DISABLE_JIT, the namedtuple."""
    if numba.config.DISABLE_JIT:
        return work
    _check(work, WORK_FIELDS, "StepWork")
    return _new_work_struct(work)
