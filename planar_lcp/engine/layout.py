"""Every struct the kernels take, declared once: one table per struct, from which its Python view (a namedtuple),
its numba structref type, the constructor of the struct over the view's buffers, and the allocator are made.

- `MODEL_LAYOUT` -> `ModelArrays` (written by `planar_lcp.model.compile_scene`, never changed after);
- `WORK_LAYOUT` -> `StepWork` (a step's buffers, `make_step_work`; each row names the stage that writes it);
- `OPTIONS_LAYOUT` -> `StepOptions` (scalars, passed by value);
- `STATS` -> `Stat` (the index of each entry of a step's stats vector).

Why structs: a namedtuple of arrays is passed by value, flattened into hundreds of scalar arguments of every jitted
call, each array reference-counted on the way in and out, and every function taking one costs the compiler close to
a second even when trivial. A structref is one pointer; its fields are read in place. Python keeps the namedtuples
(`Model.arrays`, `Simulator.work`): `model_struct` and `work_struct` wrap the same numpy buffers (no copy), so
whatever a kernel writes through the struct is visible in the namedtuple. Kernel code is the same for both
(attribute access), and with NUMBA_DISABLE_JIT=1 the namedtuples are used as they are.
"""

from collections import namedtuple
from enum import IntEnum

import numba
import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.experimental import structref
from numba.experimental.jitclass.base import imp_dtor
from numba.extending import intrinsic

#: One field of a struct. dtype: "f8", "i8", "bool" (arrays, C-contiguous) or "int", "float", "bool" with shape ""
#: (scalars). shape: sizes separated by " x ", each a number or a size name (`work_sizes`; model sizes for the
#: reader). writer: the stage that writes it. init: the value the allocator fills in.
Field = namedtuple("Field", ["name", "dtype", "shape", "unit", "writer", "meaning", "init"], defaults=(0,))

MODEL_LAYOUT = (
    Field("plane", "int", "", "", "compile", "PLANE_VERTICAL | PLANE_HORIZONTAL"),
    Field("gravity", "f8", "2", "m/s^2", "compile", "vertical plane (zero in the horizontal plane)"),
    Field("body_kind", "i8", "nbody", "", "compile", "BODY_*"),
    Field("body_slot", "i8", "nbody", "", "compile", "index among the dynamic (or kinematic) bodies; -1: static"),
    Field("static_pose", "f8", "nbody x 3", "m, rad", "compile", "world pose of static bodies (other rows unused)"),
    Field("dyn_body", "i8", "ndyn", "", "compile", "body index of each dynamic slot"),
    Field("dyn_mass", "f8", "ndyn", "kg", "compile", "mass"),
    Field("dyn_inertia", "f8", "ndyn", "kg m^2", "compile", "moment of inertia about the COM"),
    Field("shape_body", "i8", "nshape", "", "compile", "body of each shape"),
    Field("shape_kind", "i8", "nshape", "", "compile", "SHAPE_*"),
    Field("shape_vert_adr", "i8", "nshape", "", "compile", "first core vertex in vert_local"),
    Field("shape_vert_num", "i8", "nshape", "", "compile", "number of core vertices"),
    Field("shape_radius", "f8", "nshape", "m", "compile", "radius the core is inflated by"),
    Field("hp_point_w", "f8", "nshape x 2", "m", "compile", "half-plane point, world (half-planes are static)"),
    Field("hp_normal_w", "f8", "nshape x 2", "", "compile", "half-plane outward unit normal, world"),
    Field("vert_local", "f8", "nvert x 2", "m", "compile",
          "core vertices in the body's dynamics frame (the COM frame for dynamic bodies)"),
    Field("pair_a", "i8", "npair", "", "compile", "shape A of each candidate pair; A is dynamic, never a half-plane"),
    Field("pair_b", "i8", "npair", "", "compile", "shape B of each candidate pair"),
    Field("pair_mu", "f8", "npair", "", "compile", "Coulomb coefficient"),
    Field("sup_dyn", "i8", "nsup", "", "compile", "dynamic slot of the body a support point belongs to"),
    Field("sup_local", "f8", "nsup x 2", "m", "compile", "support point, COM frame"),
    Field("sup_load", "f8", "nsup", "N", "compile", "known normal load on the table (m g w)"),
    Field("sup_mu", "f8", "nsup", "", "compile", "body-table Coulomb coefficient"),
    Field("fric_dirs", "f8", "k x 2", "", "compile", "unit friction directions of the table friction"),
    Field("seed_friction_arm", "int", "", "", "compile", "1: contact friction at the shapes' core points (the seed's)"),
)

WORK_LAYOUT = (
    Field("body_pose", "f8", "body x 3", "m, rad", "contacts", "world pose of every body at the pose being examined"),
    Field("vert_world", "f8", "vert x 2", "m", "contacts", "core vertices, world"),
    Field("pair_forced", "bool", "pair", "", "check", "pairs the active-set check added (contacts at any gap)"),
    Field("pair_set_count", "i8", "pair", "", "contacts", "contacts of each pair in the active set"),
    Field("con_pair", "i8", "contact", "", "contacts", "pair of each contact of the active set"),
    Field("con_phi", "f8", "contact", "m", "contacts", "gap (negative: penetration)"),
    Field("con_n", "f8", "contact x 2", "", "contacts", "unit normal from B to A, world"),
    Field("con_p", "f8", "contact x 2", "m", "contacts", "contact point, world"),
    Field("pair_phi", "f8", "2", "m", "contacts", "one pair's contacts, as the collision kernels return them"),
    Field("pair_n", "f8", "2 x 2", "", "contacts", "their normals"),
    Field("pair_p", "f8", "2 x 2", "m", "contacts", "their points"),
    Field("check_pair", "i8", "contact", "", "check", "contacts at q+ (active-set check, projection)"),
    Field("check_phi", "f8", "contact", "m", "check", "their gaps"),
    Field("check_n", "f8", "contact x 2", "", "check", "their normals"),
    Field("check_p", "f8", "contact x 2", "m", "check", "their points"),
    Field("island_parent", "i8", "dyn", "", "islands", "union-find parent of each dynamic slot"),
    Field("body_island", "i8", "dyn", "", "islands", "island of each dynamic slot"),
    Field("island_con", "i8", "contact", "", "islands", "the contacts of the island being solved"),
    Field("island_sup", "i8", "support", "", "islands", "the support points of the island being solved"),
    Field("column_slot", "i8", "unknown x 2", "", "assemble",
          "dynamic slots of the two bodies of each force unknown's generalized column (-1: none)"),
    Field("column_g", "f8", "unknown x 2 x 3", "", "assemble", "the column's generalized vectors on those bodies"),
    Field("lcp_matrix", "f8", "unknown2", "", "assemble", "the island's problem matrix (n x n, row-major)"),
    Field("lcp_vector", "f8", "unknown", "m/s", "assemble", "the island's problem constant vector"),
    Field("pgs_impulse", "f8", "unknown", "N s", "pgs", "PGS unknowns"),
    Field("lemke_tableau", "f8", "tableau", "", "lemke", "Lemke's tableau (n x 2n + 2, row-major)"),
    Field("lemke_basis", "i8", "unknown", "", "lemke", "basic variable of each tableau row"),
    Field("lemke_z", "f8", "unknown", "N s", "lemke", "the LCP's answer z"),
    Field("lemke_w", "f8", "unknown", "m/s", "lemke", "w = M z + q"),
    Field("lemke_rows", "i8", "unknown", "", "lemke", "candidate rows of the ratio test"),
    Field("lemke_lu", "f8", "unknown x unknown", "", "lemke", "basis refinement's LU factors"),
    Field("lemke_rhs", "f8", "unknown", "", "lemke", "basis refinement's right-hand side"),
    Field("lemke_perm", "i8", "unknown", "", "lemke", "basis refinement's row permutation"),
    Field("lemke_basic", "i8", "unknown", "", "lemke", "indices of the basic z"),
    Field("lemke_z_refined", "f8", "unknown", "N s", "lemke", "z recomputed from the original data"),
    Field("lemke_w_refined", "f8", "unknown", "m/s", "lemke", "its w"),
    Field("lemke_pivot_row", "f8", "tableau_row", "", "lemke", "the normalized pivot row"),
    Field("lemke_scaling", "f8", "unknown", "", "lemke", "equilibration (powers of two)"),
    Field("v_tilde", "f8", "dyn x 3", "m/s, rad/s", "begin", "free-motion velocity v + h M^-1 f_ext"),
    Field("v_hat", "f8", "dyn x 3", "m/s, rad/s", "begin", "velocity of the linearization pose q_hat = q + h v_hat"),
    Field("q_hat", "f8", "dyn x 3", "m, rad", "begin", "the linearization pose"),
    Field("v_new", "f8", "dyn x 3", "m/s, rad/s", "island solvers", "v+"),
    Field("q_new", "f8", "dyn x 3", "m, rad", "integrate", "q+"),
    Field("con_cn", "f8", "contact", "N s", "island solvers", "normal impulse of each contact"),
    Field("con_ft", "f8", "contact", "N s", "island solvers", "tangential impulse along t = (-n_y, n_x)"),
    Field("con_vt", "f8", "contact", "m/s", "island solvers", "post-solve tangential velocity, A minus B"),
    Field("con_mode", "i8", "contact", "", "island solvers", "MODE_*"),
    Field("warm_size", "i8", "dyn", "", "lemke", "per island: size of the last LCP solved (-1: none)", -1),
    Field("warm_basic_z", "bool", "dyn x unknown", "", "lemke", "per island: which z were basic in it"),
    Field("warm_size_saved", "i8", "dyn", "", "step", "warm_size before a step that may be handed back", -1),
    Field("warm_basic_z_saved", "bool", "dyn x unknown", "", "step", "warm_basic_z before that step"),
)

OPTIONS_LAYOUT = (
    Field("formulation", "int", "", "", "sim", "FORM_*"),
    Field("fp_iters", "int", "", "", "sim", "fixed point: most re-linearizations"),
    Field("fp_tol", "float", "", "m, rad", "sim", "fixed point: stop when q_hat moves less"),
    Field("pgs_iters", "int", "", "", "sim", "PGS sweeps"),
    Field("margin", "float", "", "m", "sim", "contacts with a smaller gap at the linearization pose enter the LCP"),
    Field("pen_tol", "float", "", "m", "sim", "the active-set check adds a pair penetrating deeper"),
    Field("max_resolves", "int", "", "", "sim", "most active-set re-solves"),
    Field("piv_tol", "float", "", "", "sim", "Lemke's pivot tolerance (relative to the column)"),
    Field("ratio_tol", "float", "", "", "sim", "Lemke's tie tolerance"),
    Field("res_tol", "float", "", "", "sim", "certification: residual tolerance, relative"),
    Field("slip_tol", "float", "", "m/s", "sim", "a loaded contact slipping faster is sliding"),
    Field("impulse_tol", "float", "", "N s", "sim", "a contact with a smaller normal impulse is separated"),
    Field("warm_start", "bool", "", "", "sim", "try each island's previous basis first"),
)

#: A step's diagnostics, one float64 entry each in the stats vector (the kernels' `stats`, `Simulator.stats`, a
#: rollout's stats rows), in this order: (name, integer-valued, meaning). `Stat.<NAME>` is the index of each;
#: `simulate` hands every entry but lemke_status to Trajectory.stats under its name (those keys are a contract).
STATS = (
    ("lcp_size", True, "unknowns summed over the step's island problems (the last solve of the step)"),
    ("lcp_max", True, "unknowns of the largest island problem"),
    ("pivots", True, "Lemke pivots, all islands and all tries"),
    ("lemke_status", True, "worst lemke STATUS_* code among the islands no certified method solved (0: none)"),
    ("n_contacts", True, "contacts in the step's active set"),
    ("n_islands", True, "islands of dynamic bodies"),
    ("fp_iterations", True, "fixed-point re-linearizations"),
    ("resolves", True, "active-set re-solves (a pair penetrating at q+ added)"),
    ("residual", False, "largest certified LCP residual (absolute; the QP's primal residual for osqp)"),
    ("fp_change", False, "m or rad: the last fixed-point iterate's largest pose change"),
    ("pgs_update", False, "largest last-sweep PGS update (N s)"),
    ("penetration", False, "m: deepest penetration at the end of the step (>= 0)"),
    ("lemke_retries", True, "Lemke tries after the first one of each island"),
    ("warm_starts", True, "island LCPs solved by the previous step's basis"),
    ("solved_lemke", True, "island LCPs solved by Lemke as assembled"),
    ("solved_equilibrated", True, "island LCPs solved by Lemke on the equilibrated problem"),
    ("solved_strict", True, "island LCPs solved by Lemke with stricter pivot tolerances"),
    ("solved_velocity", True, "island LCPs solved in the velocity form's normal rows"),
    ("pgs_uncertified", True, "islands that took PGS's uncertified answer after every certified method failed"),
)
Stat = IntEnum("Stat", [(name.upper(), i) for i, (name, _, _) in enumerate(STATS)], module=__name__)
NSTAT = len(STATS)

ModelArrays = namedtuple("ModelArrays", [f.name for f in MODEL_LAYOUT])
StepWork = namedtuple("StepWork", [f.name for f in WORK_LAYOUT])
StepOptions = namedtuple("StepOptions", [f.name for f in OPTIONS_LAYOUT])

_DTYPES = {"f8": (types.float64, np.float64), "i8": (types.int64, np.int64), "bool": (types.boolean, np.bool_)}
_SCALARS = {"int": types.int64, "float": types.float64, "bool": types.boolean}


def numba_type(field):
    """The numba type of a field: a C-contiguous array of its dtype and number of dimensions, or a scalar."""
    if not field.shape:
        return _SCALARS[field.dtype]
    return types.Array(_DTYPES[field.dtype][0], len(field.shape.split(" x ")), "C")


def work_sizes(model):
    """The sizes WORK_LAYOUT's shapes name, for `model` (each at least 1: numba needs no empty-array special cases).
    unknown is the LCP size bound `Model.max_unknowns`, contact the contact capacity (2 per shape pair)."""
    a = model.arrays
    U = max(1, model.max_unknowns())
    return dict(body=a.body_kind.shape[0], vert=max(1, a.vert_local.shape[0]), pair=max(1, a.pair_a.shape[0]),
                contact=max(1, 2 * a.pair_a.shape[0]), dyn=max(1, model.ndyn), support=max(1, a.sup_dyn.shape[0]),
                unknown=U, unknown2=U * U, tableau=U * (2 * U + 2), tableau_row=2 * U + 2)


def make_step_work(model):
    """Allocate every buffer a step needs, sized from the model (no allocation happens inside the kernels)."""
    sizes = work_sizes(model)
    return StepWork(*(np.full(tuple(int(d) if d.isdigit() else sizes[d] for d in f.shape.split(" x ")), f.init,
                              _DTYPES[f.dtype][1]) for f in WORK_LAYOUT))


@structref.register
class ModelStructType(types.StructRef):
    pass


@structref.register
class WorkStructType(types.StructRef):
    pass


MODEL_STRUCT = ModelStructType([(f.name, numba_type(f)) for f in MODEL_LAYOUT])
WORK_STRUCT = WorkStructType([(f.name, numba_type(f)) for f in WORK_LAYOUT])


class ModelStruct(structref.StructRefProxy):
    """Python handle of a model struct (fields are not exposed to Python: read its `view`, `Model.arrays`)."""


class WorkStruct(structref.StructRefProxy):
    """Python handle of a work struct (fields are not exposed to Python: read its `view`, `Simulator.work`)."""


structref.define_boxing(ModelStructType, ModelStruct)
structref.define_boxing(WorkStructType, WorkStruct)


@intrinsic
def _struct_from_tuple(typingctx, struct_type, values):
    """A new struct of type `struct_type` whose fields are the entries of the tuple `values`, in order (each
    referenced, not copied). One generic constructor for every struct, instead of one assignment per field:
    numba's own `define_constructor` builds its code with exec, which numba cannot cache. The allocation is that of
    `structref.new`."""
    inst_type = struct_type.instance_type

    def codegen(context, builder, sig, args):
        alloc_type = context.data_model_manager[inst_type.get_data_type()].get_value_type()
        meminfo = context.nrt.meminfo_alloc_dtor(builder, context.get_constant(types.uintp,
                                                                              context.get_abi_sizeof(alloc_type)),
                                                 imp_dtor(context, builder.module, inst_type))
        data = builder.bitcast(context.nrt.meminfo_data(builder, meminfo), alloc_type.as_pointer())
        builder.store(cgutils.get_null_value(alloc_type), data)
        inst = context.make_helper(builder, inst_type)
        inst.meminfo = meminfo
        fields = structref._Utils(context, builder, inst_type).get_data_struct(inst._getvalue())
        for i, (name, ftype) in enumerate(inst_type.field_dict.items()):
            val = context.cast(builder, builder.extract_value(args[1], i), values[i], ftype)
            context.nrt.incref(builder, ftype, val)
            setattr(fields, name, val)
        return inst._getvalue()

    return inst_type(struct_type, values), codegen


@njit(cache=True)
def _new_struct(struct_type, values):
    return _struct_from_tuple(struct_type, values)


def _struct(view, struct_type, layout):
    """The struct of `struct_type` over the buffers of the namedtuple `view` (checked against `layout`), with the
    view attached; with NUMBA_DISABLE_JIT, the view itself."""
    if numba.config.DISABLE_JIT:
        return view
    what = type(view).__name__
    names = tuple(f.name for f in layout)
    if tuple(view._fields) != names:
        raise TypeError(f"{what}: fields {view._fields} do not match the struct's {names}")
    for f, v in zip(layout, view):
        got, want = numba.typeof(v), numba_type(f)
        if got != want:
            raise TypeError(f"{what}.{f.name}: expected {want}, got {got}")
    s = _new_struct(struct_type, view)
    s.view = view
    return s


def model_struct(arrays):
    """The kernels' view of a ModelArrays namedtuple (same buffers). With NUMBA_DISABLE_JIT, the namedtuple."""
    return _struct(arrays, MODEL_STRUCT, MODEL_LAYOUT)


def work_struct(work):
    """The kernels' view of a StepWork namedtuple (same buffers). With NUMBA_DISABLE_JIT, the namedtuple."""
    return _struct(work, WORK_STRUCT, WORK_LAYOUT)


def python_view(s):
    """The namedtuple over the same buffers as a struct made by `model_struct` or `work_struct`, for Python code
    that reads the arrays (a struct's fields are not exposed to Python); without the JIT, s itself."""
    return getattr(s, "view", s)
