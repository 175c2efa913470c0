"""Codes shared by the model compiler and the kernels (numba freezes module globals: these never change)."""

BODY_DYNAMIC, BODY_STATIC, BODY_KINEMATIC = 0, 1, 2
SHAPE_CORE, SHAPE_HALFPLANE = 0, 1
PLANE_VERTICAL, PLANE_HORIZONTAL = 0, 1

#: Contact modes after a step's solve (Trajectory.contacts["mode"]): no load, loaded without slip, loaded slipping.
MODE_SEPARATED, MODE_STICKING, MODE_SLIDING = 0, 1, 2

#: Table-friction models: the index of each name in spec.scene.SUPPORT_MODELS.
SUPPORT_LIMIT_SURFACE, SUPPORT_POINTS = 0, 1

#: The sparse island solver (engine/solvers/sparse.py): the widest band of its reduced system it factors (larger
#: islands' bands go to dense Lemke), and the reduced unknowns per dynamic body its buffers hold.
SPARSE_MAX_BAND = 256
SPARSE_UNKNOWNS_PER_BODY = 16
# islands with at least this many unknowns try the sparse solver first by default (SimOptions.sparse_min_unknowns)
SPARSE_MIN_UNKNOWNS = 128

#: A force-limited kinematic body (a velocity servo, docs/method.md "Force-limited kinematic bodies"): its contact
#: force is bounded along these many world directions (a regular polygon whose faces are max_force from the origin,
#: two of them along x and two along y), its torque along +-z when it has max_torque.
SERVO_FORCE_DIRECTIONS = 8
SERVO_TORQUE_DIRECTIONS = 2
