"""Every struct the kernels take, declared once: one table per struct, from which its Python view (a namedtuple),
its numba structref type, the constructor of the struct over the view's buffers, and the allocator are made.

- `MODEL_LAYOUT` -> `ModelArrays` (written by `planar_lcp.model.compile_scene`, never changed after);
- `WORK_LAYOUT` -> `StepWork` (a step's buffers, `make_step_work`; each row names the stage that writes it);
- `OPTIONS_LAYOUT` -> `StepOptions` (scalars, passed by value);
- `LEMKE_LAYOUT` -> `LemkeWork`, and with `BLOCK_LAYOUT` -> `BlockLemkeWork` (Lemke's and block Lemke's buffers on
  their own, `make_lemke_work`; a step's work holds the same fields, so the kernels take either struct);
- `LEMKE_SETTINGS_LAYOUT` -> `LemkeSettings` (Lemke's pivot cap and tolerances: scalars, passed by value);
- `STATS` -> `Stat` (the index of each entry of a step's stats vector).

Why structs: a namedtuple of arrays is passed by value, flattened into hundreds of scalar arguments of every jitted
call, each array reference-counted on the way in and out, and every function taking one costs the compiler close to
a second even when trivial. A structref is one pointer; its fields are read in place. Python keeps the namedtuples
(`Model.arrays`, `Simulator.work`): `model_struct` and `work_struct` wrap the same numpy buffers (no copy), so
whatever a kernel writes through the struct is visible in the namedtuple. Kernel code is the same for both
(attribute access), and with NUMBA_DISABLE_JIT=1 the namedtuples are used as they are.
"""

import functools
import math
from collections import namedtuple
from enum import IntEnum

import numba
import numpy as np
from llvmlite import ir as llvmir
from numba import njit, types
from numba.core import cgutils, imputils
from numba.core.datamodel import default_manager, models
from numba.core.runtime.nrtdynmod import _meminfo_struct_type
from numba.core.typing.templates import AttributeTemplate
from numba.experimental import structref
from numba.experimental.jitclass.base import imp_dtor
from numba.extending import NativeValue, box, infer_getattr, intrinsic, lower_getattr_generic, overload, unbox
from numba.np.arrayobj import populate_array

from planar_lcp.engine.constants import SPARSE_MAX_BAND, SPARSE_UNKNOWNS_PER_BODY

#: One field of a struct. dtype: "f8", "i8", "bool" (arrays, C-contiguous) or "int", "float", "bool" with shape ""
#: (scalars). shape: sizes separated by " x ", each a number or a size name (`work_sizes`; model sizes for the
#: reader). writer: the stage that writes it. init: the value the allocator fills in.
Field = namedtuple("Field", ["name", "dtype", "shape", "unit", "writer", "meaning", "init"], defaults=(0,))


def _table(text, init=None):
    """The fields of a text table: a header line, then one line per field with the columns name, dtype, shape, unit,
    writer and meaning separated by "|" ("-": empty); init: {name: fill value} where not 0."""
    fields = []
    for line in text.strip().splitlines()[1:]:
        cells = [c.strip() for c in line.split("|", 5)]
        cells = ["" if c == "-" else c for c in cells]
        fields.append(Field(*cells, init=(init or {}).get(cells[0], 0)))
    return tuple(fields)


MODEL_LAYOUT = _table("""
name              | dtype | shape      | unit   | writer  | meaning
plane             | int   | -          | -      | compile | PLANE_VERTICAL | PLANE_HORIZONTAL
gravity           | f8    | 2          | m/s^2  | compile | vertical plane (zero in the horizontal plane)
damping           | float | -          | -      | compile | velocity kept after 1 s: a step starts from v damping^h
body_kind         | i8    | nbody      | -      | compile | BODY_*
body_slot         | i8    | nbody      | -      | compile | index among the dynamic (or kinematic) bodies; -1: static
static_pose       | f8    | nbody x 3  | m, rad | compile | world pose of static bodies (other rows unused)
dyn_body          | i8    | ndyn       | -      | compile | body index of each dynamic slot
dyn_mass          | f8    | ndyn       | kg     | compile | mass
dyn_inertia       | f8    | ndyn       | kg m^2 | compile | moment of inertia about the COM
dyn_inv_mass      | f8    | ndyn       | 1/kg   | compile | 1 / mass (the Delassus loop multiplies: a division costs more)
shape_body        | i8    | nshape     | -      | compile | body of each shape
shape_kind        | i8    | nshape     | -      | compile | SHAPE_*
shape_vert_adr    | i8    | nshape     | -      | compile | first core vertex in vert_local
shape_vert_num    | i8    | nshape     | -      | compile | number of core vertices
shape_radius      | f8    | nshape     | m      | compile | radius the core is inflated by
hp_point_w        | f8    | nshape x 2 | m      | compile | half-plane point, world (half-planes are static)
hp_normal_w       | f8    | nshape x 2 | -      | compile | half-plane outward unit normal, world
vert_local        | f8    | nvert x 2  | m      | compile | core vertices, dynamics frame (dynamic bodies: COM frame)
pair_a            | i8    | npair      | -      | compile | shape A of each pair (dynamic, never a half-plane)
pair_b            | i8    | npair      | -      | compile | shape B of each candidate pair
pair_mu           | f8    | npair      | -      | compile | Coulomb coefficient
pair_e            | f8    | npair      | -      | compile | Newton's coefficient of restitution (0: inelastic)
support_model     | int   | -          | -      | compile | SUPPORT_LIMIT_SURFACE | SUPPORT_POINTS (table friction)
sup_dyn           | i8    | nsup       | -      | compile | dynamic slot of a support element's body (points: a point)
sup_local         | f8    | nsup x 2   | m      | compile | points: the support point, COM frame (limit surface: 0)
sup_load          | f8    | nsup       | N      | compile | known normal load on the table (m g w)
sup_mu            | f8    | nsup       | -      | compile | body-table Coulomb coefficient
fric_dirs         | f8    | k x 2      | -      | compile | points: unit friction directions of the table friction
sup_edge_adr      | i8    | nsup       | -      | compile | limit surface: first edge of the element in ls_edge
sup_edge_num      | i8    | nsup       | -      | compile | its number of polygon-piece edges
sup_edge_scale    | f8    | nsup       | 1/m^2  | compile | 1 / the element's support area
sup_node_adr      | i8    | nsup       | -      | compile | first quadrature node of the element in ls_node
sup_node_num      | i8    | nsup       | -      | compile | its number of nodes (curved pieces, support points)
sup_far_adr       | i8    | nsup       | -      | compile | first far node (polygon pieces, far twists) in ls_node
sup_far_num       | i8    | nsup       | -      | compile | its number of far nodes
sup_disk_adr      | i8    | nsup       | -      | compile | first full disk of the element in ls_disk
sup_disk_num      | i8    | nsup       | -      | compile | its number of full disks
sup_size          | f8    | nsup       | m      | compile | largest distance of its support from the COM
ls_edge           | f8    | nedge x 4  | m      | compile | edges (a_x, a_y, b_x, b_y) of polygon pieces, COM frame
ls_node           | f8    | nnode x 3  | m, -   | compile | quadrature nodes (x, y, weight), COM frame
ls_disk           | f8    | ndisk x 3  | m      | compile | full disks (centre x, y, radius), COM frame
ls_disk_node_adr  | i8    | ndisk      | -      | compile | first polar node of each disk in ls_node
ls_disk_node_num  | i8    | ndisk      | -      | compile | its number of nodes
ls_disk_table     | f8    | ntab x 2   | -      | compile | the unit disk's (Phi, G_x) by distance (spec `disk_table`)
ls_disk_step      | float | -          | -      | compile | the table's distance step, radii
ls_wrench         | f8    | nsup x K x 3 | -, m | compile | unit-load wrenches L(t_j) of the K fixed twists, COM frame
seed_friction_arm | int   | -          | -      | compile | 1: contact friction at the shapes' core points (Stewart & Trinkle's)
kin_max_force     | f8    | nkin       | N      | compile | a kinematic body's force limit (0: none, its velocity is prescribed)
kin_max_torque    | f8    | nkin       | N m    | compile | its torque limit (0: none, its rotation is prescribed)
""")

#: Lemke's work (engine/solvers/lemke.py `lemke_kernel`): part of a step's work, and on its own a `LemkeWork`
#: (`make_lemke_work`). The kernel reads these fields by name from either struct.
LEMKE_LAYOUT = _table("""
name               | dtype | shape             | unit       | writer    | meaning
lemke_tableau      | f8    | tableau           | -          | lemke     | tableau (n x 2n + 2, row-major)
lemke_basis        | i8    | unknown           | -          | lemke     | basic variable of each tableau row
lemke_z            | f8    | unknown           | N s        | lemke     | the LCP's answer z
lemke_w            | f8    | unknown           | m/s        | lemke     | w = M z + q
lemke_rows         | i8    | unknown           | -          | lemke     | candidate rows of the ratio test
lemke_lu           | f8    | dense x dense     | -          | lemke     | basis refinement's LU factors
lemke_rhs          | f8    | unknown           | -          | lemke     | basis refinement's right-hand side
lemke_perm         | i8    | unknown           | -          | lemke     | basis refinement's row permutation
lemke_basic        | i8    | unknown           | -          | lemke     | indices of the basic z
lemke_z_refined    | f8    | unknown           | N s        | lemke     | z recomputed from the original data
lemke_w_refined    | f8    | unknown           | m/s        | lemke     | its w
lemke_pivot_row    | f8    | tableau_row       | -          | lemke     | the normalized pivot row
lemke_scaling      | f8    | unknown           | -          | lemke     | equilibration (powers of two)
""")

#: Block Lemke's own work (engine/solvers/block_lemke.py `block_lemke`), beside LEMKE_LAYOUT's fields, which it
#: uses too (K^-1 and the values of M's compressed columns in lemke_tableau's buffer): part of a step's work,
#: and with LEMKE_LAYOUT on its own a `BlockLemkeWork` (`make_lemke_work(n, block=True)`).
BLOCK_LAYOUT = _table("""
name               | dtype | shape             | unit       | writer    | meaning
block_cols         | i8    | unknown           | -          | block     | the basic z (and z0) of block Lemke, by position
block_col_row      | i8    | dense2            | -          | block     | the rows of M's nonzeros, column by column
block_col_start    | i8    | dense1            | -          | block     | each column's first entry in block_col_row
block_rows         | i8    | unknown           | -          | block     | the rows whose w is not basic, by position
block_col_pos      | i8    | unknown           | -          | block     | each z's position in block_cols (-1: not basic)
block_row_pos      | i8    | unknown           | -          | block     | each row's position in block_rows (-1: w basic)
block_xz           | f8    | unknown           | N s        | block     | the basic z's values
block_xw           | f8    | unknown           | m/s        | block     | the basic w's values
block_dz           | f8    | unknown           | -          | block     | their rates along the entering variable
block_dw           | f8    | unknown           | -          | block     | the w's rates
block_y            | f8    | unknown           | -          | block     | a row of the Schur complement's inverse update
""")

WORK_LAYOUT = _table("""
name               | dtype | shape             | unit       | writer    | meaning
body_pose          | f8    | body x 3          | m, rad     | contacts  | world pose of every body at the pose examined
vert_world         | f8    | vert x 2          | m          | contacts  | core vertices, world
pair_forced        | bool  | pair              | -          | check     | pairs the active-set check added (any gap)
pair_set_count     | i8    | pair              | -          | contacts  | contacts of each pair in the active set
con_pair           | i8    | contact           | -          | contacts  | pair of each contact of the active set
con_phi            | f8    | contact           | m          | contacts  | gap (negative: penetration)
con_n              | f8    | contact x 2       | -          | contacts  | unit normal from B to A, world
con_p              | f8    | contact x 2       | m          | contacts  | contact point, world
pair_phi           | f8    | 2                 | m          | contacts  | one pair's contacts (collision)
pair_n             | f8    | 2 x 2             | -          | contacts  | their normals
pair_p             | f8    | 2 x 2             | m          | contacts  | their points
check_pair         | i8    | contact           | -          | check     | contacts at q+ (check, projection)
check_phi          | f8    | contact           | m          | check     | their gaps
check_n            | f8    | contact x 2       | -          | check     | their normals
check_p            | f8    | contact x 2       | m          | check     | their points
island_parent      | i8    | dyn               | -          | islands   | union-find parent of each dynamic slot
body_island        | i8    | dyn               | -          | islands   | island of each dynamic slot
island_con         | i8    | contact           | -          | islands   | the contacts of the island being solved
island_sup         | i8    | support           | -          | islands   | the support elements of that island
sup_recentred      | f8    | support x 3       | -, m       | contacts  | limit surface: -L(v_tilde), body frame
column_slot        | i8    | unknown x 2       | -          | assemble  | its 2 bodies' slots (-1: none)
column_g           | f8    | unknown x 2 x 3   | -          | assemble  | its generalized vectors on them
lcp_matrix         | f8    | dense2            | -          | assemble  | the island's matrix (n x n, row-major)
lcp_vector         | f8    | unknown           | m/s        | assemble  | the island's constant vector
pgs_impulse        | f8    | unknown           | N s        | pgs       | PGS unknowns
""") + LEMKE_LAYOUT + _table("""
name               | dtype | shape             | unit       | writer    | meaning
v_start            | f8    | dyn x 3           | m/s, rad/s | begin     | v damping^h, the velocity at the start of the step
v_tilde            | f8    | dyn x 3           | m/s, rad/s | begin     | free-motion velocity v + h M^-1 f_ext
v_hat              | f8    | dyn x 3           | m/s, rad/s | begin     | the linearization pose is q_hat = q + h v_hat
q_hat              | f8    | dyn x 3           | m, rad     | begin     | the linearization pose
v_new              | f8    | dyn x 3           | m/s, rad/s | solvers   | v+
q_new              | f8    | dyn x 3           | m, rad     | integrate | q+
con_cn             | f8    | contact           | N s        | solvers   | normal impulse of each contact
con_ft             | f8    | contact           | N s        | solvers   | tangential impulse along t = (-n_y, n_x)
con_vt             | f8    | contact           | m/s        | solvers   | post-solve tangential velocity, A minus B
con_mode           | i8    | contact           | -          | solvers   | MODE_*
sparse_fric        | i8    | contact           | -          | sparse    | island contact a's friction index (-1: none)
sparse_mode        | i8    | contact           | -          | sparse    | island contact a's guessed mode (SPARSE_*)
sparse_unknown     | i8    | contact           | -          | sparse    | its first reduced unknown (-1: separated)
sparse_order       | i8    | contact           | -          | sparse    | the island's contacts in band order
sparse_key         | i8    | contact           | -          | sparse    | each contact's band-order key
sparse_mu          | f8    | contact           | -          | sparse    | +-mu for a contact sliding along +-t, else 0
sparse_vt          | f8    | contact           | m/s        | sparse    | tangential velocity of the mode's solution
sparse_rank        | i8    | dyn               | -          | sparse    | breadth-first rank of each body (-1: none)
sparse_queue       | i8    | dyn               | -          | sparse    | breadth-first queue
sparse_body_start  | i8    | dyn1              | -          | sparse    | each body's first entry in sparse_body_con
sparse_body_con    | i8    | contact2          | -          | sparse    | the island contacts of each body
sparse_cursor      | i8    | dyn               | -          | sparse    | fill cursor of sparse_body_con per body
sparse_band        | f8    | band              | -          | sparse    | the reduced matrix W, band storage
sparse_lu          | f8    | band              | -          | sparse    | its regularized LU factors
sparse_rhs         | f8    | reduced           | m/s        | sparse    | the reduced system's right-hand side
sparse_x           | f8    | reduced           | N s        | sparse    | its solution
sparse_r           | f8    | reduced           | m/s        | sparse    | refinement residual, then correction
sparse_dv          | f8    | dyn x 3           | m/s, rad/s | sparse    | M^-1 G z of the candidate answer
""") + BLOCK_LAYOUT + _table("""
name               | dtype | shape             | unit       | writer    | meaning
dense_needed       | i8    | 1                 | -          | solvers   | dense size a step asked for (NEEDS_SPACE)
fail_size          | i8    | 5                 | -          | lemke     | the step's first island no method certified: n, nci, nsi, nf, ns
fail_matrix        | f8    | dense2            | -          | lemke     | its LCP matrix (n x n, row-major), as first assembled
fail_vector        | f8    | unknown           | m/s        | lemke     | its LCP vector, as first assembled
fail_con           | i8    | contact           | -          | lemke     | its contacts' pair indices
fail_sup           | i8    | support           | -          | lemke     | its support elements
fail_servo         | i8    | kin               | -          | lemke     | its force-limited kinematic slots (its lag rows)
qk_hat             | f8    | kin x 3           | m, rad     | begin     | kinematic poses at the linearization: qk + h vk
kin_velocity       | f8    | kin x 3           | m/s, rad/s | solvers   | kinematic velocities in the step: vk plus any lag
kin_lag            | f8    | kin x 3           | m/s, rad/s | solvers   | a force-limited body's lag behind vk (its servo)
servo_root         | i8    | kin               | -          | islands   | a dynamic slot each force-limited body touches
island_servo       | i8    | kin               | -          | assemble  | the island's force-limited kinematic slots
column_servo       | i8    | unknown           | -          | assemble  | the island servo index of a column's kinematic side
column_gk          | f8    | unknown x 3       | -          | assemble  | that side's generalized vector (origin frame)
servo_basis        | f8    | 3 x 3             | -          | pgs       | PGS: the directions a force-limited body lags along
warm_size          | i8    | dyn               | -          | lemke     | per island: last LCP's size (-1: none)
warm_basic_z       | bool  | dyn x unknown     | -          | lemke     | per island: which z were basic in it
warm_size_saved    | i8    | dyn               | -          | step      | warm_size before a step
sparse_pair_mode   | i8    | pair x 2          | -          | sparse    | its contacts' modes in the last sparse answer
sparse_pair_saved  | i8    | pair x 2          | -          | step      | sparse_pair_mode before a step
warm_basic_z_saved | bool  | dyn x unknown     | -          | step      | warm_basic_z before a step
body_energy        | f8    | dyn               | J          | rollout   | each body's energy term (Trajectory rows)
""", init={'fail_size': -1, 'warm_size': -1, 'warm_size_saved': -1, 'sparse_pair_mode': -1, 'sparse_pair_saved': -1})

OPTIONS_LAYOUT = _table("""
name         | dtype | shape | unit   | writer | meaning
formulation  | int   | -     | -      | sim    | FORM_*
fp_iters     | int   | -     | -      | sim    | fixed point: most re-linearizations
fp_tol       | float | -     | m, rad | sim    | fixed point: stop when q_hat moves less
pgs_iters    | int   | -     | -      | sim    | PGS sweeps
margin       | float | -     | m      | sim    | a smaller gap at q_hat enters the LCP
pen_tol      | float | -     | m      | sim    | the active-set check adds a pair penetrating deeper
max_resolves | int   | -     | -      | sim    | most active-set re-solves
piv_tol      | float | -     | -      | sim    | Lemke's pivot tolerance (relative to the column)
ratio_tol    | float | -     | -      | sim    | Lemke's tie tolerance
res_tol      | float | -     | -      | sim    | certification: residual tolerance, relative
slip_tol     | float | -     | m/s    | sim    | a loaded contact slipping faster is sliding
impulse_tol  | float | -     | N s    | sim    | a contact with a smaller normal impulse is separated
warm_start   | bool  | -     | -      | sim    | try each island's previous basis first
sparse_min   | int   | -     | -      | sim    | a larger island without table friction: sparse solver first (0: never)
""")

#: Lemke's settings (engine/solvers/lemke.py `lemke_kernel`, block_lemke.py `block_lemke`), one value passed by value
LEMKE_SETTINGS_LAYOUT = _table("""
name        | dtype | shape | unit | writer | meaning
max_pivots  | int   | -     | -    | caller | the pivot cap
piv_tol     | float | -     | -    | caller | pivot tolerance, relative to the entering column's largest magnitude
ratio_tol   | float | -     | -    | caller | the ratio test's tie tolerance, relative to the problem's scale
res_tol     | float | -     | -    | caller | certification: residual tolerance, relative to lcp_scale(M, q)
equilibrate | bool  | -     | -    | caller | lemke_kernel: pivot on the equilibrated problem (block_lemke: not read)
""")

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
    ("solved_sparse", True, "island LCPs solved by the sparse solver (large islands)"),
    ("sparse_fallbacks", True, "large islands the sparse solver left to dense Lemke"),
    ("solved_block", True, "island LCPs solved by Lemke on the Schur complement of its basis (large islands; "
                            "as assembled, else equilibrated)"),
    ("solved_lemke", True, "island LCPs solved by Lemke as assembled"),
    ("solved_equilibrated", True, "island LCPs solved by Lemke on the equilibrated problem"),
    ("solved_strict", True, "island LCPs solved by Lemke with stricter pivot tolerances"),
    ("solved_velocity", True, "island LCPs solved in the velocity form's normal rows"),
    ("solved_inelastic", True, "island LCPs with restitution solved inelastically (e = 0): no elastic answer found"),
    ("pgs_uncertified", True, "islands that took PGS's uncertified answer after every certified method failed"),
    ("servo_limited", True, "island LCPs solved with force-limited kinematic bodies at their limits (lagging)"),
)
Stat = IntEnum("Stat", [(name.upper(), i) for i, (name, _, _) in enumerate(STATS)], module=__name__)
NSTAT = len(STATS)
#: the integer-valued stats' indices, in STATS order (a rollout's integer stat rows: engine/rollout.py)
INT_STATS = np.array([i for i, (_, integer, _) in enumerate(STATS) if integer], dtype=np.int64)

ModelArrays = namedtuple("ModelArrays", [f.name for f in MODEL_LAYOUT])
StepWork = namedtuple("StepWork", [f.name for f in WORK_LAYOUT])
StepOptions = namedtuple("StepOptions", [f.name for f in OPTIONS_LAYOUT])
LemkeWork = namedtuple("LemkeWork", [f.name for f in LEMKE_LAYOUT])
BlockLemkeWork = namedtuple("BlockLemkeWork", [f.name for f in LEMKE_LAYOUT + BLOCK_LAYOUT])
LemkeSettings = namedtuple("LemkeSettings", [f.name for f in LEMKE_SETTINGS_LAYOUT])

_DTYPES = {"f8": (types.float64, np.float64), "i8": (types.int64, np.int64), "bool": (types.boolean, np.bool_)}
_SCALARS = {"int": types.int64, "float": types.float64, "bool": types.boolean}


def numba_type(field):
    """The numba type of a field: a C-contiguous array of its dtype and number of dimensions, or a scalar."""
    if not field.shape:
        return _SCALARS[field.dtype]
    return types.Array(_DTYPES[field.dtype][0], len(field.shape.split(" x ")), "C")


#: The dense buffers' first capacity (LCP unknowns): an island's dense LCP, tableau and LU take O(n^2) memory, and
#: `Model.max_unknowns` bounds n by every shape pair in contact at once (16640 for a tower of 64 boxes: 9 GB). They
#: start at this size (8 MB) and grow when a step needs more (`Simulator`, STEP_NEEDS_SPACE).
DENSE_CAPACITY = 512


def work_sizes(model, dense_capacity=None):
    """The sizes WORK_LAYOUT's shapes name, for `model` (each at least 1: numba needs no empty-array special cases).
    unknown is the LCP size bound `Model.max_unknowns`, contact the contact capacity (2 per shape pair), dense the
    capacity of the dense buffers (default min(unknown, DENSE_CAPACITY))."""
    a = model.arrays
    U = max(1, model.max_unknowns())
    D = min(U, int(dense_capacity or DENSE_CAPACITY))
    contact = max(1, 2 * a.pair_a.shape[0])
    dyn = max(1, model.ndyn)
    reduced = min(2 * contact, SPARSE_UNKNOWNS_PER_BODY * dyn)
    sizes = dict(body=a.body_kind.shape[0], vert=max(1, a.vert_local.shape[0]), pair=max(1, a.pair_a.shape[0]),
                 contact=contact, contact2=2 * contact, dyn=dyn, dyn1=dyn + 1, support=max(1, a.sup_dyn.shape[0]),
                 kin=max(1, model.nkin), reduced=reduced, band=reduced * (2 * SPARSE_MAX_BAND + 1))
    # the dense buffers as Lemke's own work for islands of up to D unknowns; `unknown` the LCP size bound U
    return sizes | lemke_work_sizes(D) | dict(unknown=U)


#: each work field's shape as (dimension: an int, or the name of a `work_sizes` entry), parsed once; and its itemsize
def _dims(field):
    """A field's shape: each dimension an int, or the name of a size (`work_sizes`, `lemke_work_sizes`)."""
    return tuple(int(d) if d.isdigit() else d for d in field.shape.split(" x "))


_WORK_DIMS = [_dims(f) for f in WORK_LAYOUT]
_WORK_ITEMSIZES = [np.dtype(_DTYPES[f.dtype][1]).itemsize for f in WORK_LAYOUT]


def _work_shapes(model, dense_capacity=None):
    return _shapes_of(tuple(work_sizes(model, dense_capacity).items()))


@functools.lru_cache(maxsize=64)
def _shapes_of(sizes):
    """The work fields' shapes for the `work_sizes` items `sizes` (remembered: a sweep makes the same ones often)."""
    sizes = dict(sizes)
    return tuple(tuple(d if isinstance(d, int) else sizes[d] for d in dims) for dims in _WORK_DIMS)


def make_step_work(model, dense_capacity=None):
    """Allocate every buffer a step needs, sized from the model (no allocation happens inside the kernels); the dense
    buffers for islands of up to `dense_capacity` unknowns (`work_sizes`)."""
    shapes = _work_shapes(model, dense_capacity)
    # np.zeros where the start value is 0 (most fields): half the cost of np.full, a Simulator makes 85 of them
    dtypes = (_DTYPES[f.dtype][1] for f in WORK_LAYOUT)
    return StepWork(*(np.zeros(shape, dt) if f.init == 0 else np.full(shape, f.init, dt)
                      for f, shape, dt in zip(WORK_LAYOUT, shapes, dtypes)))


def step_work_bytes(model, dense_capacity=None):
    """What `make_step_work(model, dense_capacity)` allocates, in bytes, without allocating it."""
    return sum(math.prod(shape) * size for size, shape in zip(_WORK_ITEMSIZES, _work_shapes(model, dense_capacity)))


def lemke_work_sizes(n):
    """The sizes LEMKE_LAYOUT's and BLOCK_LAYOUT's shapes name, for problems of up to n unknowns (`work_sizes`' with
    unknown = dense = n)."""
    return dict(unknown=n, dense=n, dense1=n + 1, dense2=n * n, tableau=n * (2 * n + 2), tableau_row=2 * n + 2)


def make_lemke_work(n, block=False):
    """Allocate `lemke_kernel`'s buffers for problems of up to n unknowns, a LemkeWork; with block, `block_lemke`'s
    too, a BlockLemkeWork. `lemke_work_struct` gives the kernels' view of it."""
    sizes = lemke_work_sizes(n)
    layout, view = (LEMKE_LAYOUT + BLOCK_LAYOUT, BlockLemkeWork) if block else (LEMKE_LAYOUT, LemkeWork)
    return view(*(np.zeros(tuple(d if isinstance(d, int) else sizes[d] for d in _dims(f)), _DTYPES[f.dtype][1])
                  for f in layout))


def _register_struct(struct_typeclass):
    """`structref.register` for the kernels' structs, without field assignment, and with a field read that needs no
    numba runtime: numba's own reads the payload's address through its runtime (`meminfo_data`), which a kernel
    compiled without it (`_nrt=False`, docs/performance.md "Reference counts") cannot call. The same load of the
    meminfo's data pointer (what numba's `NRT_MemInfo_data_fast` is), and the field is returned borrowed, as numba's
    (referenced only in a kernel with the runtime)."""
    default_manager.register(struct_typeclass, models.StructRefModel)

    @infer_getattr
    class StructFields(AttributeTemplate):
        key = struct_typeclass

        def generic_resolve(self, typ, attr):
            return typ.field_dict.get(attr)

    @lower_getattr_generic(struct_typeclass)
    def struct_field(context, builder, typ, val, attr):
        meminfo = cgutils.create_struct_proxy(typ)(context, builder, value=val).meminfo
        mi = builder.bitcast(meminfo, _meminfo_struct_type.as_pointer())
        data = builder.load(cgutils.gep(builder, mi, 0, 3))
        payload = typ.get_data_type()
        alloc_type = context.data_model_manager[payload].get_value_type()
        fields = cgutils.create_struct_proxy(payload)(context, builder,
                                                      ref=builder.bitcast(data, alloc_type.as_pointer()))
        return imputils.impl_ret_borrowed(context, builder, typ.field_dict[attr], getattr(fields, attr))

    return struct_typeclass


def _define_boxing(struct_typeclass, obj_class):
    """`structref.define_boxing`, with an unboxing that also balances its reference in a kernel compiled without
    numba's runtime: numba's takes a reference to the struct (NRT_meminfo_from_pyobject) that the call wrapper of
    such a kernel would never drop (it drops the arguments' references only with the runtime), so that every call
    from Python would leak the struct and its arrays. There the unboxing's clean-up releases it after the call."""
    obj_ctor = obj_class._numba_box_

    @box(struct_typeclass)
    def box_struct(typ, val, c):
        meminfo = structref._Utils(c.context, c.builder, typ).get_struct_ref(val).meminfo
        boxed_meminfo = c.box(types.MemInfoPointer(types.voidptr), meminfo)
        ctor_pyfunc = c.pyapi.unserialize(c.pyapi.serialize_object(obj_ctor))
        ty_pyobj = c.pyapi.unserialize(c.pyapi.serialize_object(typ))
        res = c.pyapi.call_function_objargs(ctor_pyfunc, [ty_pyobj, boxed_meminfo])
        c.pyapi.decref(ctor_pyfunc)
        c.pyapi.decref(ty_pyobj)
        c.pyapi.decref(boxed_meminfo)
        return res

    @unbox(struct_typeclass)
    def unbox_struct(typ, obj, c):
        mi_obj = c.pyapi.object_getattr_string(obj, "_meminfo")
        mi = c.unbox(types.MemInfoPointer(types.voidptr), mi_obj).value     # a new reference to the struct
        c.pyapi.decref(mi_obj)
        out = structref._Utils(c.context, c.builder, typ).new_struct_ref(mi)._getvalue()
        if c.context.enable_nrt:
            return NativeValue(out)                 # the wrapper drops the reference after the call

        def release():
            fnty = llvmir.FunctionType(llvmir.VoidType(), [cgutils.voidptr_t])
            c.builder.call(cgutils.get_or_insert_function(c.builder.module, fnty, "NRT_MemInfo_release"), [mi])

        return NativeValue(out, cleanup=release)


@_register_struct
class ModelStructType(types.StructRef):
    pass


@_register_struct
class WorkStructType(types.StructRef):
    pass


MODEL_STRUCT = ModelStructType([(f.name, numba_type(f)) for f in MODEL_LAYOUT])
WORK_STRUCT = WorkStructType([(f.name, numba_type(f)) for f in WORK_LAYOUT])
#: the types of LemkeWork's and BlockLemkeWork's structs (work structs too: boxed as WorkStruct)
LEMKE_WORK_STRUCT = WorkStructType([(f.name, numba_type(f)) for f in LEMKE_LAYOUT])
BLOCK_LEMKE_WORK_STRUCT = WorkStructType([(f.name, numba_type(f)) for f in LEMKE_LAYOUT + BLOCK_LAYOUT])


class ModelStruct(structref.StructRefProxy):
    """Python handle of a model struct (fields are not exposed to Python: read its `view`, `Model.arrays`)."""


class WorkStruct(structref.StructRefProxy):
    """Python handle of a work struct (fields are not exposed to Python: read its `view`, `Simulator.work`)."""


_define_boxing(ModelStructType, ModelStruct)
_define_boxing(WorkStructType, WorkStruct)


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


#: Python types whose numba type is each scalar field's (`numba_type`)
_SCALAR_TYPES = {"int": (int, np.int64), "float": (float, np.float64), "bool": (bool, np.bool_)}


def _has_field_type(field, v):
    """True only if numba.typeof(v) is `numba_type(field)`, from numpy's attributes: typeof costs microseconds an
    array and a Simulator's structs have about 190. An array's numba type is its dtype, ndim, layout ('C'
    when C-contiguous), readonly (not writeable) and aligned flags. False means: ask numba.typeof."""
    if not field.shape:
        return type(v) in _SCALAR_TYPES[field.dtype]
    fl = v.flags if type(v) is np.ndarray else None
    return (fl is not None and v.dtype == _DTYPES[field.dtype][1] and v.ndim == field.shape.count(" x ") + 1
            and fl.c_contiguous and fl.writeable and fl.aligned)


def _struct(view, struct_type, layout, check=True):
    """The struct of `struct_type` over the buffers of the namedtuple `view` (checked against `layout` unless
    check is False), with the view attached; with NUMBA_DISABLE_JIT, the view itself."""
    if numba.config.DISABLE_JIT:
        return view
    what = type(view).__name__
    names = tuple(f.name for f in layout)
    if tuple(view._fields) != names:
        raise TypeError(f"{what}: fields {view._fields} do not match the struct's {names}")
    if check:
        for f, v in zip(layout, view):
            if not _has_field_type(f, v):
                got, want = numba.typeof(v), numba_type(f)
                if got != want:
                    raise TypeError(f"{what}.{f.name}: expected {want}, got {got}")
    s = _new_struct(struct_type, view)
    s.view = view
    return s


def model_struct(arrays):
    """The kernels' view of a ModelArrays namedtuple (same buffers). With NUMBA_DISABLE_JIT, the namedtuple."""
    return _struct(arrays, MODEL_STRUCT, MODEL_LAYOUT)


def work_struct(work, check=True):
    """The kernels' view of a StepWork namedtuple (same buffers). With NUMBA_DISABLE_JIT, the namedtuple.
    check=False skips the per-field type check (about 50 µs of a Simulator's set-up), for buffers made by
    `make_step_work`, which makes them with the layout's types."""
    return _struct(work, WORK_STRUCT, WORK_LAYOUT, check)


def lemke_work_struct(work):
    """The kernels' view of a LemkeWork or BlockLemkeWork namedtuple (same buffers). With NUMBA_DISABLE_JIT, the
    namedtuple."""
    if isinstance(work, BlockLemkeWork):
        return _struct(work, BLOCK_LEMKE_WORK_STRUCT, LEMKE_LAYOUT + BLOCK_LAYOUT)
    return _struct(work, LEMKE_WORK_STRUCT, LEMKE_LAYOUT)


def lemke_struct(arrays):
    """A LemkeWork struct over the tuple `arrays` (LEMKE_LAYOUT's fields, in order), for a kernel that allocates its
    own work (engine/solvers/lemke.py `lemke_solve`); run as Python, the LemkeWork namedtuple of them."""
    return LemkeWork(*arrays)


@overload(lemke_struct, jit_options={"_nrt": True})
def _lemke_struct_overload(arrays):
    def impl(arrays):
        return _struct_from_tuple(LEMKE_WORK_STRUCT, arrays)
    return impl


def python_view(s):
    """The namedtuple over the same buffers as a struct made by `model_struct`, `work_struct` or `lemke_work_struct`,
    for Python code that reads the arrays (a struct's fields are not exposed to Python); without the JIT, s
    itself."""
    return getattr(s, "view", s)


def matrix_view(buf, rows, cols):
    """The first rows * cols entries of the 1-D buffer `buf` as a C-contiguous (rows, cols) array, a view (the dense
    buffers hold one island's matrix of any size): `buf[:rows * cols].reshape((rows, cols))`, which is what runs as
    Python. Compiled, the view is built in place (`_matrix_view`): numba's reshape calls a C helper
    (numba_attempt_nocopy_reshape, about 150 instructions a call, 2 % of a falling_rod step) to find strides that
    are known here. The same array type as the reshape's, so its callees compile once."""
    return buf[:rows * cols].reshape((rows, cols))


@intrinsic
def _matrix_view(typingctx, buf, rows, cols):
    if not (isinstance(buf, types.Array) and buf.ndim == 1 and buf.layout == "C"):
        return None
    ret = buf.copy(ndim=2, layout="C")

    def codegen(context, builder, sig, args):
        src = context.make_array(buf)(context, builder, args[0])
        out = context.make_array(ret)(context, builder)
        r = context.cast(builder, args[1], sig.args[1], types.intp)
        c = context.cast(builder, args[2], sig.args[2], types.intp)
        itemsize = src.itemsize
        populate_array(out, data=src.data, shape=cgutils.pack_array(builder, [r, c]),
                       strides=cgutils.pack_array(builder, [builder.mul(c, itemsize), itemsize]), itemsize=itemsize,
                       meminfo=src.meminfo, parent=src.parent)
        return imputils.impl_ret_borrowed(context, builder, ret, out._getvalue())

    return ret(buf, rows, cols), codegen


@overload(matrix_view, inline="always", jit_options={"_nrt": True})
def _matrix_view_overload(buf, rows, cols):
    def impl(buf, rows, cols):
        if rows < 0 or cols < 0 or rows * cols > buf.shape[0]:
            raise ValueError("matrix_view: the buffer is smaller than rows * cols")   # what the reshape raises
        return _matrix_view(buf, rows, cols)
    return impl
