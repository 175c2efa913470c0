"""One time step (Stewart & Trinkle's sections 3-4 in 2D): contacts, islands, one LCP per island, integration.

    M (v+ - v) = h f_ext + G z        q+ = q + h v+

Formulations (all over the same contact model):
- position (default, seed 3.1): linearize the gap at q_hat = q + h v:  phi(q_hat)/h + n.(v+ - v) >= 0.
- fixed_point (seed 3.4): re-linearize at q_hat <- q+ until it moves less than fp_tol (or fp_iters times).
- velocity (Anitescu-Potra, seed 3.3): contacts at q; n.v+ >= -max(phi, 0)/h (touching contacts: n.v+ >= 0),
  then a position-only projection removes penetration (velocities untouched: no kinetic energy is added).
Active set (seed 4): contacts with gap < margin at the linearization pose; after the solve the configuration q+ is
checked, and if a shape pair without contacts in the set is penetrating by more than pen_tol it is added and the
step is solved again (at most max_resolves times).
"""

import numpy as np
from numba import njit

from planar_lcp.engine.assemble import apply_impulses, contact_column, delassus, recentre_limit_surfaces
from planar_lcp.engine.constants import SUPPORT_LIMIT_SURFACE
from planar_lcp.engine.contacts import body_poses, find_contacts, world_vertices
from planar_lcp.engine.islands import find_islands, island_members
from planar_lcp.engine.layout import Stat, matrix_view
from planar_lcp.engine.solvers.certificate import STATUS_NEEDS_SPACE, STATUS_SOLVED
from planar_lcp.engine.solvers.lemke import lemke_in_work, solve_island_lemke
from planar_lcp.engine.solvers.pgs import solve_island_pgs

# The stages are inline='always' (and so are the island solvers, through the pipeline's arguments): every separately
# compiled numba function links in its callees and generates their machine code again, so a stack of separately
# compiled stages would compile the collision, assembly and Lemke kernels once per stage. The step kernels below, the
# rollout kernels (engine/rollout.py) and the leaf kernels they call (find_contacts, assemble_lcp, lemke_kernel, ...)
# are the separately compiled functions.

# formulation codes: the index of each name in spec.scene.FORMULATIONS (sim.FORMULATIONS maps the names to them)
FORM_POSITION, FORM_FIXED_POINT, FORM_VELOCITY = 0, 1, 2

STEP_OK = 0
STEP_LCP_FAILED = 1      # no method gave a certified answer for an island; the fallback's uncertified answer was used
STEP_NONFINITE = 2       # the new state is not finite
STEP_NEEDS_FALLBACK = 3  # a variant without fallback: an island had no certified answer; nothing was written
STEP_NEEDS_SPACE = 4     # an island's dense problem is larger than the dense buffers (w.dense_needed); nothing was
                         # written: the caller grows them and runs the step again


@njit(cache=True, inline='always')
def check_end_configuration(m, w, opt, qk_new, stats):
    """Seed section 4: check q+ for penetrating shape pairs that had no contact in the set and mark them for the
    re-solve. Also records the deepest penetration at q+ (stats[Stat.PENETRATION], m, >= 0). Returns how many pairs
    were added."""
    body_poses(m, w.q_new, qk_new, w.body_pose)
    world_vertices(m, w.body_pose, w.vert_world)
    nchk = find_contacts(m, w.vert_world, 0.0, w.pair_forced, w.check_pair, w.check_phi, w.check_n, w.check_p,
                         w.pair_phi, w.pair_n, w.pair_p)
    added = 0
    deepest = 0.0
    for j in range(nchk):
        deepest = max(deepest, -w.check_phi[j])
        p = w.check_pair[j]
        # The set is per contact, not per pair: a pair with one contact in the set can penetrate at another feature
        # (the far end of a rod at slap-down). Forcing the pair adds all its candidates (at most 2) at any gap.
        if w.check_phi[j] < -opt.pen_tol and w.pair_set_count[p] < 2 and not w.pair_forced[p]:
            w.pair_forced[p] = True
            added += 1
    stats[Stat.PENETRATION] = deepest
    return added


@njit(cache=True, inline='always')
def project_positions(m, w, opt, qk_new, stats):
    """The velocity form's last stage: the drift correction (`project_out_of_penetration`), then the penetration at
    the end of the step measured again (stats[Stat.PENETRATION]; no pair is added: the step is done). Returns False
    when the dense buffers are too small for the projection."""
    if not project_out_of_penetration(m, w, opt, qk_new, stats):
        return False
    for p in range(w.pair_set_count.shape[0]):
        w.pair_set_count[p] = 2
    check_end_configuration(m, w, opt, qk_new, stats)
    return True


@njit(cache=True, inline='always')
def project_out_of_penetration(m, w, opt, qk_new, stats):
    """Velocity form's drift correction: move q+ (positions only) out of penetration by the smallest
    mass-weighted displacement, dq = M^-1 N y with 0 <= y _|_ phi(q+) + N^T M^-1 N y >= 0 (normal rows only).
    Velocities are not touched, so no kinetic energy is added. Returns False when the dense buffers are too small
    (w.dense_needed says how large they must be; q+ is then unchanged)."""
    body_poses(m, w.q_new, qk_new, w.body_pose)
    world_vertices(m, w.body_pose, w.vert_world)
    # Every contact within the margin is a constraint of the projection, not only the penetrating ones: lifting one
    # end of a rod by rotating it would otherwise push its resting other end into the table.
    n = find_contacts(m, w.vert_world, opt.margin, w.pair_forced, w.check_pair, w.check_phi, w.check_n, w.check_p,
                      w.pair_phi, w.pair_n, w.pair_p)
    deepest = 0.0
    for j in range(n):
        deepest = max(deepest, -w.check_phi[j])
    if deepest <= opt.pen_tol:
        return True
    if n > w.lemke_lu.shape[0]:
        w.dense_needed[0] = max(w.dense_needed[0], n)
        return False
    for j in range(n):
        contact_column(m, w.body_pose, w.check_pair, w.check_p, j, w.check_n[j, 0], w.check_n[j, 1], w.column_slot,
                       w.column_g, j)
    A = matrix_view(w.lcp_matrix, n, n)
    delassus(m, n, w.column_slot, w.column_g, A)
    for j in range(n):
        w.lcp_vector[j] = w.check_phi[j]
    # np.bool_: typed as the island solvers' calls (a literal True compiled lemke_kernel a second time)
    st, piv, res = lemke_in_work(w, A, w.lcp_vector[:n], n, opt, opt.piv_tol, np.bool_(True))
    if st != STATUS_SOLVED:
        stats[Stat.LEMKE_STATUS] = max(stats[Stat.LEMKE_STATUS], st)
        return True
    # dq = M^-1 G y (reuse the impulse application on a zeroed buffer)
    ndyn = w.q_new.shape[0]
    for d in range(ndyn):
        for c in range(3):
            w.v_hat[d, c] = 0.0
    apply_impulses(n, w.column_slot, w.column_g, w.lemke_z, m, w.v_hat)
    for d in range(ndyn):
        for c in range(3):
            w.q_new[d, c] += w.v_hat[d, c]
    return True


@njit(cache=True, inline='always')
def begin_step(m, q, v, qk, vk, h, opt, w, qk_out, stats):
    """Free-motion velocity v_tilde = v + h M^-1 f_ext, the first linearization pose, the kinematic end poses; v
    itself (w.v_start: the approach velocity of restitution's impact law). v is first scaled by the world's damping
    over the step, damping^h (1 without damping: v exactly)."""
    for i in range(stats.shape[0]):
        stats[i] = 0.0
    velocity_form = opt.formulation == FORM_VELOCITY
    keep = 1.0 if m.damping == 1.0 else m.damping ** h
    for d in range(q.shape[0]):
        for c in range(3):
            w.v_start[d, c] = keep * v[d, c]
        w.v_tilde[d, 0] = w.v_start[d, 0] + h * m.gravity[0]
        w.v_tilde[d, 1] = w.v_start[d, 1] + h * m.gravity[1]
        w.v_tilde[d, 2] = w.v_start[d, 2]
        for c in range(3):
            w.v_hat[d, c] = 0.0 if velocity_form else w.v_start[d, c]
            w.q_hat[d, c] = q[d, c] + h * w.v_hat[d, c]
    for kk in range(qk.shape[0]):
        for c in range(3):
            qk_out[kk, c] = qk[kk, c] + h * vk[kk, c]
            # the kinematic poses the position forms linearize at; qk_out moves on with a force-limited body's lag
            w.qk_hat[kk, c] = qk_out[kk, c]
            w.kin_velocity[kk, c] = vk[kk, c]
    for p in range(w.pair_forced.shape[0]):
        w.pair_forced[p] = False
    w.dense_needed[0] = 0
    w.fail_size[0] = -1


@njit(cache=True, inline='always')
def prepare_contacts(m, w, opt, qk_lin, stats, recentre=True):
    """Contacts at (w.q_hat, qk_lin), the per-pair count of the set, islands; w.v_new = v_tilde; the limit surfaces'
    re-centred columns at that pose (recentre=False keeps them as they are: engine/tangent.py, where a pose moves
    that they do not depend on).
    Returns (number of contacts, number of islands)."""
    body_poses(m, w.q_hat, qk_lin, w.body_pose)
    if recentre and m.support_model == SUPPORT_LIMIT_SURFACE:
        recentre_limit_surfaces(m, w)
    world_vertices(m, w.body_pose, w.vert_world)
    ncon = find_contacts(m, w.vert_world, opt.margin, w.pair_forced, w.con_pair, w.con_phi, w.con_n, w.con_p,
                         w.pair_phi, w.pair_n, w.pair_p)
    for p in range(w.pair_set_count.shape[0]):
        w.pair_set_count[p] = 0
    for kk in range(w.kin_lag.shape[0]):
        for c in range(3):
            w.kin_lag[kk, c] = 0.0                  # each solve finds the force-limited bodies' lag anew
    for j in range(ncon):
        w.pair_set_count[w.con_pair[j]] += 1
        w.con_cn[j] = 0.0
        w.con_ft[j] = 0.0
    nisl = find_islands(m, ncon, w.con_pair, w.island_parent, w.body_island, w.servo_root)
    stats[Stat.N_ISLANDS] = nisl
    for d in range(w.v_new.shape[0]):
        for c in range(3):
            w.v_new[d, c] = w.v_tilde[d, c]
    return ncon, nisl


@njit(cache=True, inline='always')
def kinematic_linearization(w, qk, velocity_form):
    """The kinematic poses contacts are taken at: qk (velocity form), or qk + h vk (w.qk_hat, the position forms':
    a force-limited body's lag moves qk_out, not them). A function, so that the osqp solver's Python pipeline reads
    the struct's field through numba."""
    return qk if velocity_form else w.qk_hat


@njit(cache=True, inline='always')
def integrate_positions(q, h, w):
    for d in range(q.shape[0]):
        for c in range(3):
            w.q_new[d, c] = q[d, c] + h * w.v_new[d, c]


@njit(cache=True, inline='always')
def integrate_servos(m, qk, vk, h, w, qk_out):
    """A force-limited kinematic body moves at its prescribed velocity plus its lag (w.kin_lag, from the solve):
    its end pose qk_out and its velocity w.kin_velocity. The others keep begin_step's, untouched."""
    for kk in range(qk.shape[0]):
        if m.kin_max_force[kk] > 0.0:
            for c in range(3):
                w.kin_velocity[kk, c] = vk[kk, c] + w.kin_lag[kk, c]
                qk_out[kk, c] = qk[kk, c] + h * w.kin_velocity[kk, c]


@njit(cache=True, inline='always')
def needs_another_solve(m, w, opt, q, h, qk_out, fp_iter, stats):
    """After a solve: (True, fp_iter) to re-linearize at q+ (fixed point, not converged, under the cap);
    (True, -1) if the active-set check added a pair; (False, fp_iter) when the step is done."""
    if opt.formulation == FORM_FIXED_POINT and fp_iter < opt.fp_iters:
        change = 0.0
        for d in range(q.shape[0]):
            for c in range(3):
                change = max(change, abs(w.q_new[d, c] - w.q_hat[d, c]))
                w.q_hat[d, c] = w.q_new[d, c]
                w.v_hat[d, c] = (w.q_hat[d, c] - q[d, c]) / h
        fp_iter += 1
        stats[Stat.FP_CHANGE] = change
        if change > opt.fp_tol:
            return True, fp_iter
    if check_end_configuration(m, w, opt, qk_out, stats) > 0 and stats[Stat.RESOLVES] < opt.max_resolves:
        stats[Stat.RESOLVES] += 1
        return True, -1
    return False, fp_iter


@njit(cache=True, inline='always')
def write_outputs(w, ncon, q_out, v_out, stats, fp_iter, worst):
    """The step's outputs and status (finish_step without the velocity form's projection)."""
    stats[Stat.N_CONTACTS] = ncon
    stats[Stat.FP_ITERATIONS] = fp_iter
    finite = True
    for d in range(q_out.shape[0]):
        for c in range(3):
            q_out[d, c] = w.q_new[d, c]
            v_out[d, c] = w.v_new[d, c]
            if not (np.isfinite(q_out[d, c]) and np.isfinite(v_out[d, c])):
                finite = False
    if not finite:
        return STEP_NONFINITE
    if worst != STATUS_SOLVED:
        return STEP_LCP_FAILED
    return STEP_OK


@njit(cache=True, inline='always')
def copy_warm_start(size_from, basic_z_from, size_to, basic_z_to):
    """Copy the warm-start memory (per island: LCP size and basic-z mask): kept before a step that a variant without
    fallback may hand back (w.warm_size_saved, w.warm_basic_z_saved), put back when it does."""
    for i in range(size_from.shape[0]):
        size_to[i] = size_from[i]
        for c in range(basic_z_from.shape[1]):
            basic_z_to[i, c] = basic_z_from[i, c]


@njit(cache=True, inline='always')
def save_warm_start(w, opt):
    """Keep the memories a step reads and writes (the dense warm start's bases with opt.warm_start, the sparse
    solver's modes per pair for islands it takes), for a step that is handed back to be run again."""
    _copy_memories(opt, w.warm_size, w.warm_basic_z, w.sparse_pair_mode,
                   w.warm_size_saved, w.warm_basic_z_saved, w.sparse_pair_saved)


@njit(cache=True, inline='always')
def restore_warm_start(w, opt):
    _copy_memories(opt, w.warm_size_saved, w.warm_basic_z_saved, w.sparse_pair_saved,
                   w.warm_size, w.warm_basic_z, w.sparse_pair_mode)


@njit(cache=True, inline='always')
def _copy_memories(opt, size_from, basic_z_from, modes_from, size_to, basic_z_to, modes_to):
    if opt.warm_start:
        copy_warm_start(size_from, basic_z_from, size_to, basic_z_to)
    if opt.sparse_min > 0:
        copy_pair_modes(modes_from, modes_to)


@njit(cache=True, inline='always')
def copy_pair_modes(src, dst):
    for p in range(src.shape[0]):
        dst[p, 0] = src[p, 0]
        dst[p, 1] = src[p, 1]


@njit(cache=True, inline='always')
def step_pipeline(solve, fallback, project, m, state, h, opt, w, out, stats):
    """THE step: advance (q, v, qk) by one step of size h with kinematic velocities vk.

    Parameters
    ----------
    solve : island solver
        Solves each island first (signature below).
    fallback : island solver or None
        Solves an island `solve` gave no certified answer for (the step then reports STEP_LCP_FAILED). None: the step
        returns STEP_NEEDS_FALLBACK at once instead, with the warm-start memory as it was before the step.
    project : `project_positions` or None
        The velocity form's last stage. None: a velocity-form step returns STEP_NEEDS_FALLBACK at once.
    m : model struct;  w : work struct (engine/layout.py);  opt : StepOptions;  h : float, s
    state : (q, v, qk, vk), a tuple
        q, v: (ndyn, 3) float64, COM poses (m, rad) and velocities (m/s, rad/s) of the dynamic bodies; qk, vk:
        (nkin, 3) float64, kinematic poses and (prescribed) velocities.
    out : (q_out, v_out, qk_out), a tuple of arrays like q, v, qk
        The state after the step (must not alias the inputs).
    stats : (NSTAT,) float64
        The step's diagnostics, by `Stat`.

    Returns
    -------
    int
        A STEP_* code. The step's contacts stay in w.con_* (their count is stats[Stat.N_CONTACTS]).

    Notes
    -----
    Island solver signature: ``solve(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats) -> lemke STATUS_*``
    for island isl whose nci contacts and nsi support points are w.island_con[:nci], w.island_sup[:nsi], contact
    geometry at the linearization pose w.body_pose. It adds the island's impulses to w.v_new and records them
    (w.con_cn, con_ft, con_vt, con_mode), or, failing, leaves w.v_new as it was. Implementations in
    engine/solvers/: `solve_island_lemke` (certified), `solve_island_pgs`, `solve_island_osqp` (Python).

    solve, fallback and project select a variant at compile time: numba inlines this function into each `@njit`
    variant below with its own constant arguments, prunes the branches of the arguments that are None, and compiles
    only the stages the variant calls. The same Python function (`step_pipeline.py_func`) is the osqp solver's
    step, whose island solver is Python. A step handed back (STEP_NEEDS_FALLBACK) is run again by a variant with a
    fallback: every variant computes the same thing up to the failure, so the stitched result is that variant's
    bit for bit. A step whose island needs larger dense buffers returns STEP_NEEDS_SPACE the same way (nothing
    written, the warm-start memory as before the step; `Simulator` grows them and runs it again).
    """
    q, v, qk, vk = state
    q_out, v_out, qk_out = out
    velocity_form = opt.formulation == FORM_VELOCITY
    if project is None:
        if velocity_form:
            return STEP_NEEDS_FALLBACK
    # kept in case the step is handed back (STEP_NEEDS_FALLBACK, STEP_NEEDS_SPACE): its re-run starts from it
    save_warm_start(w, opt)
    begin_step(m, q, v, qk, vk, h, opt, w, qk_out, stats)
    # the velocity form evaluates contacts at the current configuration, the position forms at the end of the step
    qk_lin = kinematic_linearization(w, qk, velocity_form)
    fp_iter = 0
    # a step fails if any of its solves had an island without a certified answer: a fixed-point iterate or an
    # active-set re-solve that starts from an uncertified answer is not trusted either, even if its own LCP solves
    worst = STATUS_SOLVED
    while True:
        ncon, nisl = prepare_contacts(m, w, opt, qk_lin, stats)
        for isl in range(nisl):
            nci, nsi = island_members(m, w, isl, ncon)
            if nci == 0 and nsi == 0:
                continue
            st = solve(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats)
            if st == STATUS_NEEDS_SPACE:
                restore_warm_start(w, opt)
                return STEP_NEEDS_SPACE
            if st != STATUS_SOLVED:
                if fallback is None:
                    restore_warm_start(w, opt)
                    return STEP_NEEDS_FALLBACK
                stats[Stat.PGS_UNCERTIFIED] += 1
                if fallback(m, w, opt, vk, isl, nci, nsi, h, velocity_form, stats) == STATUS_NEEDS_SPACE:
                    restore_warm_start(w, opt)
                    return STEP_NEEDS_SPACE
                worst = st
        integrate_positions(q, h, w)
        integrate_servos(m, qk, vk, h, w, qk_out)
        again, it = needs_another_solve(m, w, opt, q, h, qk_out, fp_iter, stats)
        if it >= 0:
            fp_iter = it
        if not again:
            break
    if project is not None:
        if velocity_form:
            if not project(m, w, opt, qk_out, stats):
                restore_warm_start(w, opt)
                return STEP_NEEDS_SPACE
    return write_outputs(w, ncon, q_out, v_out, stats, fp_iter, worst)


# The two step functions: every Lemke run, whatever its scene, formulation or options, takes `lemke_step` (one
# compilation serves every scene: the options and the model's sizes are run-time values, never compile-time
# variants), and solver = "pgs" takes `pgs_step`. Each is inlined into its rollout kernel (engine/rollout.py), which
# is also what `Simulator.step` runs, one step a call: a cold cache compiles each step once.

@njit(cache=True, inline='always')
def lemke_step(m, state, h, opt, w, out, stats):
    """Lemke's certified chain (the warm start with opt.warm_start; large islands by the sparse solver and block Lemke
    first, opt.sparse_min), PGS's uncertified answer for an island none of them certifies (the step is then reported
    as failed), and the velocity form's projection."""
    return step_pipeline(solve_island_lemke, solve_island_pgs, project_positions, m, state, h, opt, w, out, stats)


@njit(cache=True, inline='always')
def pgs_step(m, state, h, opt, w, out, stats):
    """PGS (never fails, so no fallback) with the velocity form's projection."""
    return step_pipeline(solve_island_pgs, None, project_positions, m, state, h, opt, w, out, stats)
