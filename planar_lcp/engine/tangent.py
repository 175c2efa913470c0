"""The step's derivatives at the cold step's certified bases, in one compiled call: the fast path of the checked
differences (planar_lcp/derivatives/differences.py).

Where every island's LCP answer is strictly complementary, its basis B holds on a neighbourhood of the state, and
there the answer is z_B = -A_BB^-1 b_B: the implicit function theorem gives its derivative along an input as
dz_B = -A_BB^-1 d(A z + b)_B, z held. The step's other stages (contacts, the limit surfaces' re-centred columns, the
assembly of A and b, the impulses' velocity change M^-1 G z and the integration) are smooth functions of the inputs
for the contacts and islands fixed; `step_tangent` takes their derivatives with z held by central differences of
that smooth part alone (no LCP is solved there: two evaluations per input, along the smooth part's own inputs,
SMOOTH_*, the velocities' without contact detection; the velocities' in closed form where the smooth part is linear
in them: the dynamic bodies' without restitution or a limit surface in any island, `_dynamic_velocity_columns`, the
kinematic bodies' without restitution, `_kinematic_velocity_columns`; none for the pose of a body
in no contact and clear of every shape pair, which moves nothing there but its own end pose: `_untouched_bodies`,
`_clear_of_pairs`, nor for the angle of a body whose shapes are disks about its centre of mass, whose geometry a
turn leaves as it is: `_turn_free_bodies`, and one translation's of an island touching only half-planes of one normal,
which it glides along: `_glide_axes`), and adds the LCP's through one solve with A_BB at the state.
Only the rows of A and b that depend on the state enter: the Delassus part G^T M^-1 G z + b over the force unknowns
(computed as G^T (M^-1 (G z)), linear in the unknowns), the friction and slack rows being constant.

It answers for the steps it covers (`_covered`): the position form, every island solved by Lemke's first try from
scratch (no warm start, no retry, no sparse or block solver, no force-limited body in the island), no active-set
re-solve. Everywhere else, and where its checks fail, it returns a code and the checked differences of whole steps
(`step_differences`, engine/rollout.py) answer instead. Its checks:

- each island's basis holds on both sides: every index at the certificate's zero on both sides, z_i and
  w_i = (A z + b)_i (the dual numbers' test of a degenerate index, planar_lcp/derivatives/forward.py), stays there
  along every input (its rate below DEGENERATE_RTOL of the island's: a sticking contact's unloaded friction ray,
  whose w = lambda + t.v has lambda and t.v both held at zero), where a contact touching without load opens or
  closes. Two kinds of contact are exempt, their step smooth where their indices move: one at rest, loaded inside
  its friction cone, with both friction rays at zero (it sticks whichever way it is pushed: its rays are solved as
  one bilateral constraint, the +t ray in the basis with a rate of either sign), and a separating one's friction
  (held at zero; its slack's kink enters no other row). Where either is present, or a sliding element's friction
  may be positive, every segment of the island's LCP answers must leave the velocities where they are (A over the
  basic and degenerate unknowns has no null vector but along normal impulses and sticking friction, whose rows hold
  the velocities, and a sliding contact's own two rays: a sliding element's friction column coinciding with
  another's gives way, as the dual numbers call it non-unique).
  Where the sticking rays added to the basis coincide (a box at rest on the two corners of a flat face), the LCP's
  part solves with the basis's independent rows and columns (elimination with complete pivoting), and the rows left
  out must hold by themselves along every input;
- every evaluation at a moved pose has x's contacts (the same pairs, in the same order, hence the same islands; a
  pair's contacts, whose order can swap between the two sides of a pose, matched to x's by their points) and its
  end-of-step check adds no pair (taken where its end configuration moved far enough from x's that it could:
  `_end_room`, `_end_motion`);
- the one-sided differences of the smooth part agree (a kink of the contact geometry, of max and min in the rows,
  or a body at rest on its limit surface, whose re-centred column jumps);
- the cold steps at x +- d move as J d predicts (d the mixed direction of `step_differences`).

A body touching nothing that rests on its table (`_untouched_bodies`: its free-motion velocity below REST_SPEED in
every component, each support element able to hold it) is held there whichever way the state moves: no evaluation
along its pose or velocity, its island's rows and outputs move with no input, q+ one on its q (`_hold_resting`: the
dual numbers hold its re-centred column fixed there, derivatives/forward.py). Where the cold steps at x +- d do not
move as that predicts, it gives way to the differences of whole steps.
"""

import numpy as np
from numba import njit

from planar_lcp.engine.assemble import (REST_SPEED, apply_impulses, assemble_columns, assemble_lcp, column_dot,
                                        island_is_elastic, island_problem_size, island_servo,
                                        kinematic_velocity_along, recentre_limit_surfaces, support_column_count)
from planar_lcp.engine.constants import (BODY_DYNAMIC, BODY_KINEMATIC, BODY_STATIC, SHAPE_HALFPLANE,
                                        SUPPORT_LIMIT_SURFACE)
from planar_lcp.engine.contacts import body_poses, find_contacts, pair_contacts, world_vertices
from planar_lcp.engine.islands import contact_island, island_members
from planar_lcp.engine.layout import Stat
from planar_lcp.engine.rollout import (DIFF_MOVES, DIFF_OK, _restore_memory, _sides_differ, cold_step_at,
                                       mixed_direction_check, unflatten_inputs)
from planar_lcp.engine.step import (FORM_POSITION, begin_step, check_end_configuration, kinematic_linearization,
                                    prepare_contacts)

#: step_tangent's answers besides the DIFF_* codes it shares with step_differences: the step is not one it covers
#: (`_covered`), an island's basis does not hold on both sides, an evaluation nearby has other contacts or a re-solve,
#: the one-sided differences of the smooth part differ. The checked differences of whole steps answer then.
TANGENT_NOT_COVERED = 10
TANGENT_DEGENERATE = 11
TANGENT_CONTACTS = 12
TANGENT_KINK = 13

#: the smooth part's inputs (`_moved_start`), in the order and layout of the state's (x: q, v, qk, vk): the
#: linearization pose q_hat = q + h v_s, the velocity v_s = v damping^h, the kinematic poses qk_hat = qk + h vk (= qk+)
#: and the kinematic velocities in the rows. The state's inputs reach the smooth part only through them (and q,
#: directly, in q+ = q + h v+): d/dq = d/dq_hat + (q+ = q + ...), d/dv = damping^h (h d/dq_hat + d/dv_s),
#: d/dqk = d/dqk_hat, d/dvk = h d/dqk_hat + d/dkinv. The velocities' columns need neither the contacts (the poses are
#: held) nor the end-of-step check (q+ moves by h times them)
SMOOTH_POSE, SMOOTH_VELOCITY, SMOOTH_KIN_POSE, SMOOTH_KIN_VELOCITY = 0, 1, 2, 3
#: a basis matrix A_BB whose pivot falls below this fraction of its largest entry is singular to working precision:
#: the tangent gives way (a certified basis has a well-conditioned matrix; Lemke's own LU accepted it)
SINGULAR_RTOL = 1e-14
#: a degenerate index (z_i = w_i = 0) keeps its basis on both sides where its w (z, if basic) changes along no
#: input: by less than this fraction of the island's largest rate along that input (the smooth part's differences
#: are good to about 1e-7 of it; a mode that switches moves at the scale of the others)
DEGENERATE_RTOL = 1e-6
#: a pivot of an island's A (over the unknowns that may be positive) below this fraction of its largest entry marks
#: a null vector: a segment of LCP answers (the dual numbers' threshold on singular values, forward._check_unique)
NULL_RTOL = 1e-9
#: a body without contacts keeps its pose columns in closed form where every shape pair of its stays this many times
#: its differences' largest motion of a point beyond the contact margin (`_clear_of_pairs`): the evaluations at
#: +- eps would meet the same pairs, none (the narrow phase's gaps move by at most a point's motion on the features
#: that give them; the factor covers the separating axes' gaps, whose features can lie farther out)
CLEARANCE_FACTOR = 4.0
#: the stats of a cold step a tangent does not cover where nonzero: another try, solver or re-solve than Lemke's
#: first from scratch
_UNCOVERED = np.array([Stat.LEMKE_RETRIES, Stat.WARM_STARTS, Stat.SOLVED_SPARSE, Stat.SOLVED_BLOCK,
                       Stat.PGS_UNCERTIFIED, Stat.SERVO_LIMITED, Stat.RESOLVES, Stat.FP_ITERATIONS],
                      dtype=np.int64)


@njit(cache=True)
def _covered(opt, stats):
    """Whether the cold step just taken (its stats) is one `step_tangent` covers (module docstring)."""
    if opt.formulation != FORM_POSITION:
        return False
    for a in _UNCOVERED:
        if stats[a] != 0.0:
            return False
    return True


@njit(cache=True)
def translation_free(m):
    """Whether no shape pair has a static body's shape: the step's smooth part then moves with every pose moved alike
    (contacts and rows are the same, the table's friction the same everywhere, gravity uniform; qk+ moves along, q+ =
    q + h v+ does not), so along each axis the pose columns sum to the kinematic bodies' qk+ rows, and the last pose
    column follows from the others."""
    for p in range(m.pair_a.shape[0]):
        if (m.body_kind[m.shape_body[m.pair_a[p]]] == BODY_STATIC
                or m.body_kind[m.shape_body[m.pair_b[p]]] == BODY_STATIC):
            return False
    return True


@njit(cache=True)
def _turn_free_bodies(m, turn_free_dyn, turn_free_kin):
    """Which dynamic and kinematic bodies (by slot) a turn moves nothing of but their own angle: every shape a disk
    (a core of one vertex, inflated) centred on the body's origin, and no table support element (its support points
    turn with it). Their contacts' points, normals and gaps, hence the rows and the impulses' arms, follow the
    centre alone, so the smooth part's column along their angle is zero (a kinematic body's, one on its own qk+)."""
    for d in range(turn_free_dyn.shape[0]):
        turn_free_dyn[d] = True
    for kk in range(turn_free_kin.shape[0]):
        turn_free_kin[kk] = True
    for s in range(m.shape_body.shape[0]):
        if m.shape_kind[s] == SHAPE_HALFPLANE:
            continue
        a = m.shape_vert_adr[s]
        disk = m.shape_vert_num[s] == 1 and m.vert_local[a, 0] == 0.0 and m.vert_local[a, 1] == 0.0
        if not disk:
            _unflag(m, m.shape_body[s], turn_free_dyn, turn_free_kin)
    for e in range(m.sup_dyn.shape[0]):
        turn_free_dyn[m.sup_dyn[e]] = False


@njit(cache=True)
def _lu_factor(a, perm):
    """a (n, n) in place into its LU factors by Gaussian elimination with partial pivoting, the row order in perm.
    False where a pivot is below SINGULAR_RTOL of a's largest entry (singular to working precision)."""
    n = a.shape[0]
    big = 0.0
    for i in range(n):
        perm[i] = i
        for j in range(n):
            big = max(big, abs(a[i, j]))
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(a[i, k]) > abs(a[p, k]):
                p = i
        if not abs(a[p, k]) > SINGULAR_RTOL * big:
            return False
        if p != k:
            for j in range(n):
                a[k, j], a[p, j] = a[p, j], a[k, j]
            perm[k], perm[p] = perm[p], perm[k]
        for i in range(k + 1, n):
            a[i, k] /= a[k, k]
            f = a[i, k]
            for j in range(k + 1, n):
                a[i, j] -= f * a[k, j]
    return True


@njit(cache=True)
def _lu_solve(a, perm, b, x):
    """x (n, m) = a^-1 b for a's factors from `_lu_factor` (b is not changed)."""
    n, cols = b.shape
    for c in range(cols):
        for i in range(n):
            s = b[perm[i], c]
            for j in range(i):
                s -= a[i, j] * x[j, c]
            x[i, c] = s
        for i in range(n - 1, -1, -1):
            s = x[i, c]
            for j in range(i + 1, n):
                s -= a[i, j] * x[j, c]
            x[i, c] = s / a[i, i]


@njit(cache=True)
def _pivots(a, tol, rows, cols):
    """The rank of a (r, c) to tol: Gaussian elimination of a (in place) with complete pivoting, which stops where
    every entry left is below tol (rank-revealing on these small, well-scaled matrices; no LAPACK). rows and cols
    (length r and c) come back as the row and column order it chose: the first `rank` of each index a nonsingular
    square part of a (its independent rows and columns)."""
    nr, nc = a.shape
    for i in range(nr):
        rows[i] = i
    for j in range(nc):
        cols[j] = j
    for k in range(min(nr, nc)):
        p, q, best = k, k, 0.0
        for i in range(k, nr):
            for j in range(k, nc):
                if abs(a[i, j]) > best:
                    p, q, best = i, j, abs(a[i, j])
        if best <= tol:
            return k
        for j in range(nc):
            a[k, j], a[p, j] = a[p, j], a[k, j]
        rows[k], rows[p] = rows[p], rows[k]
        for i in range(nr):
            a[i, k], a[i, q] = a[i, q], a[i, k]
        cols[k], cols[q] = cols[q], cols[k]
        for i in range(k + 1, nr):
            f = a[i, k] / a[k, k]
            for j in range(k, nc):
                a[i, j] -= f * a[k, j]
    return min(nr, nc)


@njit(cache=True)
def _nullity(a, tol):
    """The dimension of the null space of a (r, c) to tol (`_pivots`; a is overwritten)."""
    return a.shape[1] - _pivots(a, tol, np.empty(a.shape[0], np.int64), np.empty(a.shape[1], np.int64))


@njit(cache=True, inline='always')
def _indices(mask, o, n):
    """The positions i in 0 .. n - 1 (within an island at o) where mask[o + i] holds, in order."""
    count = 0
    for i in range(n):
        count += mask[o + i]
    idx = np.empty(count, np.int64)
    c = 0
    for i in range(n):
        if mask[o + i]:
            idx[c] = i
            c += 1
    return idx


@njit(cache=True)
def _unpinned(z, o, n, nci, nf, nsi, k):
    """Per unknown of an island, whether a segment of LCP answers along it moves the velocities: the friction of a
    sliding contact or support element (its lambda positive), whose split between coinciding columns changes how it
    opposes the slip. A normal impulse's row holds its gap's velocity and a sticking element's rows hold its slip
    at zero, whatever the split (the dual numbers' `forward._pinned`)."""
    out = np.zeros(n, np.bool_)
    o_lc = nci + 2 * nf + k * nsi
    for f in range(nf):
        if z[o + o_lc + f] > 0.0:
            out[nci + 2 * f] = out[nci + 2 * f + 1] = True
    for a in range(nsi):
        if z[o + o_lc + nf + a] > 0.0:
            for i in range(k):
                out[nci + 2 * nf + k * a + i] = True
    return out


@njit(cache=True)
def _segments_leave_velocities(afull, basic, degenerate, unpinned, o, n, nci, nf):
    """Whether every segment of the island's LCP answers gives the same velocities: each null vector of A over the
    unknowns that may be positive (the basic and the degenerate) lies in the span of the pinned unknowns
    (`_unpinned`: a box's two sticking corners, whose friction columns coincide) and of the sums e_+t + e_-t of a
    sliding contact's two rays (whose force columns cancel at every pose). Any other null vector (a sliding element's
    friction column coinciding with another's: a limit surface's re-centred column with a contact's) is a segment
    that a change of the inputs breaks: the dual numbers' test (`forward._check_unique`) calls it non-unique, and
    the tangent gives way. By dimensions: the null space is the pinned columns' null space plus those ray sums."""
    pos = np.full(n, -1, np.int64)
    ns = 0
    npin = 0
    for i in range(n):
        if basic[o + i] or degenerate[o + i]:
            pos[i] = ns
            ns += 1
            npin += not unpinned[i]
    if ns == 0 or npin == ns:
        # no sliding element's friction among them: A's null space is the pinned columns' own (a box at rest)
        return True
    a = np.empty((ns, ns))
    pinned = np.empty((ns, npin))
    for i in range(n):
        if pos[i] < 0:
            continue
        c2 = 0
        for c in range(n):
            if pos[c] >= 0:
                a[pos[i], pos[c]] = afull[o + i, o + c]
                if not unpinned[c]:
                    pinned[pos[i], c2] = afull[o + i, o + c]
                    c2 += 1
    big = 0.0
    for i in range(ns):
        for c in range(ns):
            big = max(big, abs(a[i, c]))
    if not big > 0.0:
        return True
    null = _nullity(a.copy(), NULL_RTOL * big)
    null_pinned = _nullity(pinned, NULL_RTOL * big) if npin > 0 else 0
    rays = 0
    for f in range(nf):
        pa, pb = pos[nci + 2 * f], pos[nci + 2 * f + 1]
        if pa < 0 or pb < 0 or not unpinned[nci + 2 * f]:
            continue
        gap = 0.0
        for r in range(ns):
            gap = max(gap, abs(a[r, pa] + a[r, pb]))
        if gap <= NULL_RTOL * big:
            rays += 1
    return null <= null_pinned + rays


@njit(cache=True)
def _match_contacts(w, ncon, pts, order, phi, nrm, pnt):
    """At a moved pose with x's pairs in x's order, each contact put in the slot of x's contact of its pair nearest
    to it: a pair's contacts come in an order that can swap between the two sides of a pose (a box flush on a
    plane, its corners in order of depth), the same contacts in the step's answer, a jump where z is held. False
    where the nearest are not one to one."""
    for i in range(ncon):
        order[i] = -1
    for j in range(ncon):
        best, slot = np.inf, -1
        for i in range(ncon):
            if w.con_pair[i] != w.con_pair[j]:
                continue
            d = (w.con_p[j, 0] - pts[i, 0]) ** 2 + (w.con_p[j, 1] - pts[i, 1]) ** 2
            if d < best:
                best, slot = d, i
        if slot < 0 or order[slot] >= 0:
            return False
        order[slot] = j
    for i in range(ncon):
        if order[i] != i:
            break
    else:
        return True
    for i in range(ncon):
        j = order[i]
        phi[i] = w.con_phi[j]
        for c in range(2):
            nrm[i, c] = w.con_n[j, c]
            pnt[i, c] = w.con_p[j, c]
    for i in range(ncon):
        w.con_phi[i] = phi[i]
        for c in range(2):
            w.con_n[i, c] = nrm[i, c]
            w.con_p[i, c] = pnt[i, c]
    return True


@njit(cache=True, inline='always')
def _give_way(msize, mbasic, mmodes, w, code):
    """The warm-start memory as the cold step left it, and the code."""
    _restore_memory(msize, mbasic, mmodes, w)
    return code


@njit(cache=True, inline='always')
def _contacts_at(m, h, opt, w, x, nd, nk, q, v, qk, vk, qk_out, scratch):
    """The step's first stages at the flattened state x: its inputs into q, v, qk, vk, the free motion, the
    linearization pose, the contacts and islands (w.con_*, w.body_island), w.v_new = v_tilde. Returns (contacts,
    islands)."""
    unflatten_inputs(x, nd, nk, q, v, qk, vk)
    begin_step(m, q, v, qk, vk, h, opt, w, qk_out, scratch)
    return prepare_contacts(m, w, opt, kinematic_linearization(w, qk, False), scratch)


@njit(cache=True, inline='always')
def _moved_start(m, h, opt, w, q, v, qk, vk, kinv, qk_out, scratch, kind, i, c, delta):
    """The step's first stage at the state (begin_step), then one input of the smooth part moved by delta (kind:
    SMOOTH_*, body i, coordinate c): the linearization pose q_hat, the velocity v_s the free motion starts from
    (v_start, v_tilde = v_s + h g and the position form's v_hat = v_s move together, q_hat held), a kinematic body's
    pose (qk_hat = qk+) or its velocity in the rows (kinv, a copy of vk)."""
    begin_step(m, q, v, qk, vk, h, opt, w, qk_out, scratch)
    for j in range(vk.shape[0]):
        for a in range(3):
            kinv[j, a] = vk[j, a]
    if kind == SMOOTH_POSE:
        w.q_hat[i, c] += delta
    elif kind == SMOOTH_VELOCITY:
        w.v_start[i, c] += delta
        w.v_tilde[i, c] += delta
        w.v_hat[i, c] += delta
    elif kind == SMOOTH_KIN_POSE:
        w.qk_hat[i, c] += delta
        qk_out[i, c] += delta
    elif kind == SMOOTH_KIN_VELOCITY:
        kinv[i, c] += delta
        w.kin_velocity[i, c] += delta


@njit(cache=True, inline='always')
def _smooth_part(m, h, w, vk, nisl, ncon, z, zoff, q, qk_out, r, out, dv, active, r0, f0):
    """With the contacts and islands of `_contacts_at` and the answers z held (island i's at zoff[i] ...
    zoff[i + 1]): the rows r = (A z + b) of every island over its force unknowns (G^T (M^-1 G z) + b; b alone on the
    constant rows), and the step's outputs out = (q + h v+, v+, qk+) with v+ = v_tilde + M^-1 G z. dv: (ndyn, 3)
    scratch. Leaves q+ in w.q_new (for the end-of-step check). An island not `active` (an evaluation that moves
    nothing of it: `_active_islands`) keeps x's rows r0 and its bodies x's outputs f0, bit for bit what computing
    them again would give."""
    k = support_column_count(m)
    nd = q.shape[0]
    for isl in range(nisl):
        o = zoff[isl]
        if not active[isl]:
            for u in range(o, zoff[isl + 1]):
                r[u] = r0[u]
            continue
        nci, nsi = island_members(m, w, isl, ncon)
        if nci == 0 and nsi == 0:
            continue
        n, nf = assemble_columns(m, w, vk, nci, nsi, h, False, r[o:zoff[isl + 1]], np.bool_(True))
        nforce = nci + 2 * nf + k * nsi
        for d in range(nd):
            for c in range(3):
                dv[d, c] = 0.0
        apply_impulses(nforce, w.column_slot, w.column_g, z[o:o + n], m, dv)
        for u in range(nforce):
            r[o + u] += column_dot(w.column_slot, w.column_g, u, dv)
        for d in range(nd):
            for c in range(3):
                w.v_new[d, c] += dv[d, c]
    for d in range(nd):
        if not active[w.body_island[d]]:
            for c in range(3):
                w.q_new[d, c] = f0[3 * d + c]
                w.v_new[d, c] = f0[3 * nd + 3 * d + c]
                out[3 * d + c] = f0[3 * d + c]
                out[3 * nd + 3 * d + c] = f0[3 * nd + 3 * d + c]
            continue
        for c in range(3):
            w.q_new[d, c] = q[d, c] + h * w.v_new[d, c]
            out[3 * d + c] = w.q_new[d, c]
            out[3 * nd + 3 * d + c] = w.v_new[d, c]
    for j in range(qk_out.shape[0]):
        for c in range(3):
            out[6 * nd + 3 * j + c] = qk_out[j, c]


@njit(cache=True)
def _active_islands(m, w, ncon, kind, i, active):
    """The islands an evaluation along one input of the smooth part (kind: SMOOTH_*, body slot i) moves: a dynamic
    body's own island (its contacts and support elements are there, and only its rows and outputs move), a kinematic
    body's the islands of its contacts (its pose and velocity enter the rows through them alone)."""
    for isl in range(active.shape[0]):
        active[isl] = False
    if kind == SMOOTH_POSE or kind == SMOOTH_VELOCITY:
        active[w.body_island[i]] = True
        return
    for j in range(ncon):
        b = m.shape_body[m.pair_b[w.con_pair[j]]]
        if m.body_kind[b] == BODY_KINEMATIC and m.body_slot[b] == i:
            active[contact_island(m, w.body_island, w.con_pair, j)] = True


@njit(cache=True)
def _dynamic_velocity_columns(m, h, w, nd, nk, nisl, ncon, zoff, rows, dr, jy):
    """The smooth part's dynamic velocity columns where it is linear in them (`step_tangent`: the position form, no
    restitution, no limit surface), at x's contacts and poses, into dr and jy (the SMOOTH_VELOCITY columns, in the
    state's layout): a body's velocity v_s moves v_tilde and the position form's v_hat alike, so a normal row
    (phi/h + n.(v_tilde - v_hat)) stays and a friction or support row moves by its column's entry (g_u . e);
    v+ = v_tilde + M^-1 G z moves by e and q+ by h e. rows: scratch, an entry per LCP unknown."""
    k_sup = support_column_count(m)
    unit = np.zeros((nd, 3))
    unit_k = np.zeros((nk, 3))
    for isl in range(nisl):
        o = zoff[isl]
        nci, nsi = island_members(m, w, isl, ncon)
        if nci == 0 and nsi == 0:
            continue
        n, nf = assemble_columns(m, w, unit_k, nci, nsi, h, False, rows[o:zoff[isl + 1]], np.bool_(True))
        first, last = nci, nci + 2 * nf + k_sup * nsi           # the friction rays' and support elements' rows
        for d in range(nd):
            for c in range(3):
                unit[d, c] = 1.0
                for u in range(first, last):
                    dr[o + u, 3 * nd + 3 * d + c] = column_dot(w.column_slot, w.column_g, u, unit)
                unit[d, c] = 0.0
    for d in range(nd):
        for c in range(3):
            jy[3 * d + c, 3 * nd + 3 * d + c] = h
            jy[3 * nd + 3 * d + c, 3 * nd + 3 * d + c] = 1.0


@njit(cache=True)
def _kinematic_velocity_columns(m, w, nd, nk, nisl, ncon, zoff, dr):
    """The smooth part's kinematic velocity columns in the rows where it is linear in them (`step_tangent`: the
    position form, no restitution), at x's contacts and poses (w.body_pose), into dr (the SMOOTH_KIN_VELOCITY
    columns): a kinematic body's velocity moves a friction row by its point velocity along the ray
    (`kinematic_velocity_along`, linear in vk: taken at unit velocities) and no other row; the outputs not at all
    (its end pose qk+ = qk + h vk is SMOOTH_KIN_POSE's column, `_state_columns`)."""
    unit_k = np.zeros((nk, 3))
    for isl in range(nisl):
        o = zoff[isl]
        nci, nsi = island_members(m, w, isl, ncon)
        f = 0
        for a in range(nci):
            j = w.island_con[a]
            if not m.pair_mu[w.con_pair[j]] > 0.0:
                continue
            u = o + nci + 2 * f
            f += 1
            for kk in range(nk):
                for c in range(3):
                    unit_k[kk, c] = 1.0
                    vt = kinematic_velocity_along(m, w.body_pose, unit_k, w.con_pair, w.con_p, j, -w.con_n[j, 1],
                                                  w.con_n[j, 0])
                    unit_k[kk, c] = 0.0
                    dr[u, 6 * nd + 3 * nk + 3 * kk + c] = vt
                    dr[u + 1, 6 * nd + 3 * nk + 3 * kk + c] = -vt


@njit(cache=True)
def _exempt_friction(m, w, o, nci, nsi, nf, k_sup, basic, degenerate, solve, exempt):
    """Two kinds of frictional contact whose degenerate friction indices may move without a switch of the step
    (island at o, its contacts in w.island_con):
    - at rest, loaded, its load inside the friction cone (c_n basic and positive, both friction rays at the
      certificate's zero, its slack lambda nonbasic with a positive row): it sticks whichever way a change of the
      inputs pushes it, its two rays one bilateral constraint t.v+ = 0 with beta = beta(+t) - beta(-t) of either
      sign. The LCP's part solves with the +t ray in the basis (`solve`; a negative rate is the -t ray's);
    - separating (c_n nonbasic, its row positive; its rays nonbasic): its friction is held at zero
      (sum beta <= mu c_n = 0) and its slack lambda = |t.v+|, kinked at t.v+ = 0, enters no other row: nothing the
      step returns moves.
    Their indices' rates need not stay at zero (`exempt`), provided the island's LCP answers form no segment that
    moves the velocities (`_segments_leave_velocities`). Returns (a ray was added to the basis, an index was
    exempted)."""
    f = 0
    added = False
    exempted = False
    for a in range(nci):
        if not m.pair_mu[w.con_pair[w.island_con[a]]] > 0.0:
            continue
        ray = o + nci + 2 * f
        slack = o + nci + 2 * nf + k_sup * nsi + f
        f += 1
        if not (degenerate[ray] or degenerate[ray + 1] or degenerate[slack]):
            continue
        if not basic[o + a] and not degenerate[o + a]:
            # its rays nonbasic (a basic ray at zero would be held to t.v+ = 0 by the basis solve)
            if not (basic[ray] or basic[ray + 1]):
                exempt[ray] = exempt[ray + 1] = exempt[slack] = True
                exempted = True
            continue
        if (not (degenerate[ray] and degenerate[ray + 1]) or degenerate[o + a] or not basic[o + a]
                or degenerate[slack] or basic[slack]):
            continue
        exempt[ray] = exempt[ray + 1] = True
        exempted = True
        if not (solve[ray] or solve[ray + 1]):
            solve[ray] = True
            added = True
    return added, exempted


@njit(cache=True)
def _factor_solve_part(A, o, n, lu, perm, solve, solve_row, held):
    """The factors of the basis the island's LCP part solves with (island at o, size n, its matrix A), the sticking
    rays added to it (`_exempt_friction`). Those rays can coincide (a box on two corners of a flat face: its two
    contacts' tangential rows are one): the part solves with a nonsingular square part of the basis's matrix, its
    independent rows and columns (`_pivots`); the other unknowns' rates are zero (any answer on the segment gives
    the same velocities: `_segments_leave_velocities`) and the other rows must hold by themselves (`held`, checked
    with the degenerate indices' rates). False where the part is singular to working precision."""
    idx = _indices(solve, o, n)
    nb = idx.shape[0]
    sub = np.empty((nb, nb))
    big = 0.0
    for a in range(nb):
        for c in range(nb):
            sub[a, c] = A[idx[a], idx[c]]
            big = max(big, abs(sub[a, c]))
    prow, pcol = np.empty(nb, np.int64), np.empty(nb, np.int64)
    rank = _pivots(sub, NULL_RTOL * big, prow, pcol)
    for a in range(rank, nb):
        solve[o + idx[pcol[a]]] = False
        solve_row[o + idx[prow[a]]] = False
        held[o + idx[prow[a]]] = True
    rsel, csel = np.sort(prow[:rank]), np.sort(pcol[:rank])
    fac = lu[o:o + rank, o:o + rank]
    for a in range(rank):
        for c in range(rank):
            fac[a, c] = A[idx[rsel[a]], idx[csel[c]]]
    return _lu_factor(fac, perm[o:o + rank])


@njit(cache=True)
def _island_bases(m, h, w, vk, nisl, ncon, zoff, mbasic, res_tol, z, lu, perm, afull, basic, degenerate, solve,
                  solve_row, held, exempt):
    """Each island's LCP at x (its contacts in w) at the cold step's bases mbasic: its answer z, its matrix A
    (afull's diagonal block at zoff), the indices at the certificate's zero on both sides (`degenerate`), the
    sticking and separating contacts' friction (`exempt`) and the factors the LCP's part solves with (lu, perm over
    the columns `solve` and the rows `solve_row`; `held`, the basis's rows left out). False where the bases do not
    hold: an index beyond the certificate's zero, a singular basis matrix, a segment of answers that moves the
    velocities."""
    k_sup = support_column_count(m)
    for isl in range(nisl):
        o, n = zoff[isl], zoff[isl + 1] - zoff[isl]
        if n == 0:
            continue
        nci, nsi = island_members(m, w, isl, ncon)
        A = np.empty((n, n))
        b = np.empty(n)
        assemble_lcp(m, w, vk, nci, nsi, h, False, A, b, np.bool_(True))
        for i in range(n):
            basic[o + i] = mbasic[isl, i]
        idx = _indices(basic, o, n)
        nb = idx.shape[0]
        if nb > 0:
            fac = lu[o:o + nb, o:o + nb]
            rhs = np.empty((nb, 1))
            for a in range(nb):
                rhs[a, 0] = -b[idx[a]]
                for c in range(nb):
                    fac[a, c] = A[idx[a], idx[c]]
            if not _lu_factor(fac, perm[o:o + nb]):
                return False
            zb = np.empty((nb, 1))
            _lu_solve(fac, perm[o:o + nb], rhs, zb)
            for a in range(nb):
                z[o + idx[a]] = zb[a, 0]
        # the indices at the certificate's zero on both sides (forward.py `degenerate_indices`): z_i = w_i = 0
        scale = 1.0
        zmax = 1.0
        for i in range(n):
            scale = max(scale, abs(b[i]))
            zmax = max(zmax, abs(z[o + i]))
            for c in range(n):
                scale = max(scale, abs(A[i, c]))
                afull[o + i, o + c] = A[i, c]
        for i in range(n):
            wi = b[i]
            for c in range(n):
                wi += A[i, c] * z[o + c]
            if basic[o + i]:
                if z[o + i] < -res_tol * zmax:
                    return False
                degenerate[o + i] = z[o + i] <= res_tol * zmax
            else:
                if wi < -res_tol * scale:
                    return False
                degenerate[o + i] = wi <= res_tol * scale
        for i in range(n):
            solve[o + i] = basic[o + i]
        nf = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)[1]
        added, exempted = _exempt_friction(m, w, o, nci, nsi, nf, k_sup, basic, degenerate, solve, exempt)
        # a segment of answers can move the velocities only along a sliding element's friction (`_unpinned`): where
        # one may be positive, or sticking rays were added to the basis, every segment must leave them
        unpinned = _unpinned(z, o, n, nci, nf, nsi, k_sup)
        sliding = False
        for i in range(n):
            sliding = sliding or (unpinned[i] and (basic[o + i] or degenerate[o + i]))
        if (exempted or sliding) and not _segments_leave_velocities(afull, basic, degenerate, unpinned, o, n, nci,
                                                                    nf):
            return False
        for i in range(n):
            solve_row[o + i] = solve[o + i]
        if added and not _factor_solve_part(A, o, n, lu, perm, solve, solve_row, held):
            return False
    return True


@njit(cache=True)
def _linear_in_velocities(m, w, nisl, ncon):
    """Whether the smooth part is linear in the dynamic bodies' velocities (`_dynamic_velocity_columns`): no island
    with restitution (its rows' max and min) or on a limit surface (its re-centred columns turn with the velocity);
    and in the kinematic ones' (`_kinematic_velocity_columns`): no island with restitution (a kinematic body's
    velocity enters only the friction rows otherwise, the limit surfaces holding dynamic bodies alone)."""
    dynamic, kinematic = True, True
    for isl in range(nisl):
        nci, nsi = island_members(m, w, isl, ncon)
        if island_is_elastic(m, w.island_con, nci, w.con_pair):
            dynamic, kinematic = False, False
        elif nsi > 0 and m.support_model == SUPPORT_LIMIT_SURFACE:
            dynamic = False
    return dynamic, kinematic


@njit(cache=True)
def _untouched_bodies(m, w, ncon, untouched_dyn, untouched_kin, resting_dyn):
    """Which dynamic and kinematic bodies (by slot) are in no contact at x (w.con_*), have no half-plane shape and
    no forced pair: their poses reach the smooth part only through contacts they do not have. A dynamic body on a
    table (support elements) is untouched only where it rests there (resting_dyn): its free-motion velocity below
    REST_SPEED in every component and every support element able to hold it (friction and load positive), so that
    the table holds it at rest whichever way its state moves: its q+ is its q, its v+ zero, and nothing else
    depends on it. resting_dyn is the table's verdict alone: a resting body is one also left untouched here and by
    `_clear_of_pairs` (step_tangent joins the two after both)."""
    for d in range(untouched_dyn.shape[0]):
        untouched_dyn[d] = True
        resting_dyn[d] = False
    for s in range(m.sup_dyn.shape[0]):
        d = m.sup_dyn[s]
        resting_dyn[d] = True
    for s in range(m.sup_dyn.shape[0]):
        d = m.sup_dyn[s]
        held = m.sup_mu[s] * m.sup_load[s] > 0.0
        for c in range(3):
            held = held and abs(w.v_tilde[d, c]) < REST_SPEED
        if not held:
            untouched_dyn[d] = False
            resting_dyn[d] = False
    for kk in range(untouched_kin.shape[0]):
        untouched_kin[kk] = True
    for s in range(m.shape_body.shape[0]):
        if m.shape_kind[s] == SHAPE_HALFPLANE:
            _unflag(m, m.shape_body[s], untouched_dyn, untouched_kin)
    for p in range(m.pair_a.shape[0]):
        if w.pair_forced[p]:
            _unflag(m, m.shape_body[m.pair_a[p]], untouched_dyn, untouched_kin)
            _unflag(m, m.shape_body[m.pair_b[p]], untouched_dyn, untouched_kin)
    for j in range(ncon):
        p = w.con_pair[j]
        _unflag(m, m.shape_body[m.pair_a[p]], untouched_dyn, untouched_kin)
        _unflag(m, m.shape_body[m.pair_b[p]], untouched_dyn, untouched_kin)


@njit(cache=True, inline='always')
def _unflag(m, b, flags_dyn, flags_kin):
    """Body b's flag (by slot, among the dynamic or the kinematic bodies) set False; a static body has none."""
    if m.body_kind[b] == BODY_DYNAMIC:
        flags_dyn[m.body_slot[b]] = False
    elif m.body_kind[b] == BODY_KINEMATIC:
        flags_kin[m.body_slot[b]] = False


@njit(cache=True, inline='always')
def _reach(m, w, s, b):
    """The farthest point of shape s (its core vertices in w.vert_world, plus its radius) from body b's origin."""
    far = 0.0
    a0 = m.shape_vert_adr[s]
    for k in range(a0, a0 + m.shape_vert_num[s]):
        far = max(far, np.hypot(w.vert_world[k, 0] - w.body_pose[b, 0], w.vert_world[k, 1] - w.body_pose[b, 1]))
    return far + m.shape_radius[s]


@njit(cache=True, inline='always')
def _pose_motion(m, w, steps, nd, b, sa, sb):
    """The largest motion of a point of shape pair (sa, sb) when one pose coordinate of body b (an untouched
    candidate) moves by its difference step: eps along x or y, eps_angle times the pair's reach from b's origin."""
    k0 = 3 * m.body_slot[b] if m.body_kind[b] == BODY_DYNAMIC else 6 * nd + 3 * m.body_slot[b]
    reach = max(_reach(m, w, sa, b), _reach(m, w, sb, b))
    return max(steps[0, k0], steps[0, k0 + 1], steps[0, k0 + 2] * reach)


@njit(cache=True, inline='always')
def _is_untouched(m, b, untouched_dyn, untouched_kin):
    k = m.body_kind[b]
    if k == BODY_DYNAMIC:
        return untouched_dyn[m.body_slot[b]]
    if k == BODY_KINEMATIC:
        return untouched_kin[m.body_slot[b]]
    return False


@njit(cache=True)
def _clear_of_pairs(m, w, nd, steps, margin, kinematic_only, untouched_dyn, untouched_kin):
    """Keeps a body untouched (`_untouched_bodies`) only where none of its shape pairs has a contact within margin
    plus CLEARANCE_FACTOR times its differences' largest point motion (`_pose_motion`) at the poses in
    w.body_pose and w.vert_world; kinematic_only: the dynamic bodies' flags stay as they are."""
    for p in range(m.pair_a.shape[0]):
        sa, sb = m.pair_a[p], m.pair_b[p]
        ba, bb = m.shape_body[sa], m.shape_body[sb]
        ua = _is_untouched(m, ba, untouched_dyn, untouched_kin) and not (
            kinematic_only and m.body_kind[ba] == BODY_DYNAMIC)
        ub = _is_untouched(m, bb, untouched_dyn, untouched_kin) and not (
            kinematic_only and m.body_kind[bb] == BODY_DYNAMIC)
        if not ua and not ub:
            continue
        room = margin
        if ua:
            room += CLEARANCE_FACTOR * _pose_motion(m, w, steps, nd, ba, sa, sb)
        if ub:
            room += CLEARANCE_FACTOR * _pose_motion(m, w, steps, nd, bb, sa, sb)
        if pair_contacts(m, w.vert_world, p, room, False, w.pair_phi, w.pair_n, w.pair_p) > 0:
            if ua:
                _unflag(m, ba, untouched_dyn, untouched_kin)
            if ub:
                _unflag(m, bb, untouched_dyn, untouched_kin)


@njit(cache=True)
def _glide_axes(m, w, nd, nisl, ncon, steps, margin, glide_t, glide_group, glide_axis):
    """The islands that glide: every contact of their bodies at x (w.con_*, w.body_island) between two of them or
    with a half-plane, the half-planes all of one normal n, no forced pair, and every pair of a body of theirs with a
    shape of another island, a kinematic body or a static body but such a half-plane clear (no contact within margin
    plus CLEARANCE_FACTOR times the body's translations' difference step, at the poses in w.vert_world). Moving the
    whole island along the planes, t = (-n_y, n_x), moves none of its contacts' gaps, normals or arms, so the smooth
    part's rows and outputs stay as they are: the sum over its bodies of J_x t_x + J_y t_y is zero. glide_t[d]: t
    for a body of such an island (else zero), glide_group[d] its island (else -1); glide_axis[d]: for the island's
    last body, the axis b whose column follows from the others' (|t_b| the larger: `_glide_columns`), else -1."""
    normal = np.zeros((nisl, 2))
    touches = np.zeros(nisl, np.bool_)
    glides = np.ones(nisl, np.bool_)
    for j in range(ncon):
        p = w.con_pair[j]
        sa, sb = m.pair_a[p], m.pair_b[p]          # shape A is a dynamic body's
        isl = w.body_island[m.body_slot[m.shape_body[sa]]]
        if m.shape_kind[sb] == SHAPE_HALFPLANE:
            nx, ny = m.hp_normal_w[sb, 0], m.hp_normal_w[sb, 1]
            if not touches[isl]:
                touches[isl] = True
                normal[isl, 0], normal[isl, 1] = nx, ny
            elif normal[isl, 0] != nx or normal[isl, 1] != ny:
                glides[isl] = False
        elif m.body_kind[m.shape_body[sb]] != BODY_DYNAMIC:
            glides[isl] = False                      # a kinematic or static shape other than a half-plane
    for isl in range(nisl):
        glides[isl] = glides[isl] and touches[isl]
    for p in range(m.pair_a.shape[0]):
        sa, sb = m.pair_a[p], m.pair_b[p]
        for side in range(2):
            s_own, s_other = (sa, sb) if side == 0 else (sb, sa)
            b_own, b_other = m.shape_body[s_own], m.shape_body[s_other]
            if m.body_kind[b_own] != BODY_DYNAMIC:
                continue
            d = m.body_slot[b_own]
            isl = w.body_island[d]
            if not glides[isl]:
                continue
            if w.pair_forced[p]:
                glides[isl] = False
            elif m.body_kind[b_other] == BODY_DYNAMIC and w.body_island[m.body_slot[b_other]] == isl:
                continue                                 # it moves along
            elif m.shape_kind[s_other] == SHAPE_HALFPLANE and (
                    m.hp_normal_w[s_other, 0] == normal[isl, 0] and m.hp_normal_w[s_other, 1] == normal[isl, 1]):
                continue                                 # its gaps to a plane of the same normal stay as they are
            else:
                room = margin + CLEARANCE_FACTOR * max(steps[0, 3 * d], steps[0, 3 * d + 1])
                if pair_contacts(m, w.vert_world, p, room, False, w.pair_phi, w.pair_n, w.pair_p) > 0:
                    glides[isl] = False
    last = np.full(nisl, -1, np.int64)
    for d in range(nd):
        isl = w.body_island[d]
        glide_axis[d] = -1
        glide_group[d] = isl if glides[isl] else -1
        glide_t[d, 0] = -normal[isl, 1] if glides[isl] else 0.0
        glide_t[d, 1] = normal[isl, 0] if glides[isl] else 0.0
        last[isl] = d
    for isl in range(nisl):
        if glides[isl]:
            d = last[isl]
            glide_axis[d] = 0 if abs(glide_t[d, 0]) >= abs(glide_t[d, 1]) else 1


@njit(cache=True)
def _glide_columns(nd, glide_t, glide_group, glide_axis, dr, jy):
    """A gliding island's derived pose column (`_glide_axes`), its last body's along axis b, from the others':
    J_b = -(sum over the island's other bodies of J_b) - (t_a / t_b) (sum over all its bodies of J_a)."""
    for last in range(nd):
        b = glide_axis[last]
        if b < 0:
            continue
        ratio = glide_t[last, 1 - b] / glide_t[last, b]
        kb = 3 * last + b
        for part in range(2):
            cols = dr if part == 0 else jy
            for r in range(cols.shape[0]):
                acc = 0.0
                for d in range(nd):
                    if glide_group[d] != glide_group[last]:
                        continue
                    acc += ratio * cols[r, 3 * d + 1 - b]
                    if d != last:
                        acc += cols[r, 3 * d + b]
                cols[r, kb] = -acc


@njit(cache=True)
def _turn_reach(m):
    """Three times the farthest shape point of any body from its origin (core vertices plus radius): a body's turn by
    dtheta moves a pair's gap by at most that times |dtheta| while the pair is near contact (its own points move by
    its reach times |dtheta|; a face normal of its turns, and the other shape's points, within twice the largest
    reach of its origin, move along it by as much)."""
    far = 0.0
    for s in range(m.shape_body.shape[0]):
        if m.shape_kind[s] == SHAPE_HALFPLANE:
            continue
        a0 = m.shape_vert_adr[s]
        for k in range(a0, a0 + m.shape_vert_num[s]):
            far = max(far, np.hypot(m.vert_local[k, 0], m.vert_local[k, 1]) + m.shape_radius[s])
    return 3.0 * far


@njit(cache=True)
def _end_room(m, w, opt, qk_new):
    """How far the end configuration (w.q_new, qk_new: x's, after its end-of-step check added no pair) may move
    before that check could add one: the penetration tolerance less the deepest penetration of a pair it may add (a
    pair with fewer than two contacts in the set, not forced); pairs apart there (no contact at gap 0) have the whole
    tolerance."""
    body_poses(m, w.q_new, qk_new, w.body_pose)
    world_vertices(m, w.body_pose, w.vert_world)
    nchk = find_contacts(m, w.vert_world, 0.0, w.pair_forced, w.check_pair, w.check_phi, w.check_n, w.check_p,
                         w.pair_phi, w.pair_n, w.pair_p)
    room = opt.pen_tol
    for j in range(nchk):
        p = w.check_pair[j]
        if w.pair_set_count[p] < 2 and not w.pair_forced[p]:
            room = min(room, w.check_phi[j] + opt.pen_tol)
    return room


@njit(cache=True, inline='always')
def _end_motion(nd, nk, f, f0, turn_reach):
    """The most a body moves a gap of its pairs near contact between the end configurations f and f0 (the smooth
    part's outputs: q+ and qk+ poses): its translation's components plus its turn times `_turn_reach`."""
    far = 0.0
    for b in range(nd + nk):
        o = 3 * b if b < nd else 6 * nd + 3 * (b - nd)
        far = max(far, abs(f[o] - f0[o]) + abs(f[o + 1] - f0[o + 1]) + abs(f[o + 2] - f0[o + 2]) * turn_reach)
    return far


@njit(cache=True, inline='always')
def _is_moved(m, b, kinematic, i):
    """Whether body b is the one an evaluation moves: slot i, kinematic or dynamic."""
    return m.body_slot[b] == i and m.body_kind[b] == (BODY_KINEMATIC if kinematic else BODY_DYNAMIC)


@njit(cache=True)
def _watched_pairs(m, w, opt, nd, steps, pairs, ncon, first, count, watch):
    """x's contacts by pair (first[p]: pair p's first in `pairs`, count[p]: how many; a pair's contacts are
    consecutive), and the pairs an evaluation at a moved pose recomputes where one of their bodies moves (watch):
    those with contacts at x, forced, or not clear of the contact margin by CLEARANCE_FACTOR times their bodies'
    difference steps' largest point motion (`_pose_motion`) at x's linearization pose (w.body_pose; the others
    cannot meet the margin there: their contacts stay none)."""
    for p in range(first.shape[0]):
        first[p] = -1
        count[p] = 0
    for j in range(ncon):
        p = pairs[j]
        if first[p] < 0:
            first[p] = j
        count[p] += 1
    world_vertices(m, w.body_pose, w.vert_world)
    for p in range(first.shape[0]):
        if count[p] > 0 or w.pair_forced[p]:
            watch[p] = True
            continue
        sa, sb = m.pair_a[p], m.pair_b[p]
        room = opt.margin
        for side in range(2):
            b = m.shape_body[sa if side == 0 else sb]
            if m.body_kind[b] != BODY_STATIC:
                room += CLEARANCE_FACTOR * _pose_motion(m, w, steps, nd, b, sa, sb)
        watch[p] = pair_contacts(m, w.vert_world, p, room, False, w.pair_phi, w.pair_n, w.pair_p) > 0


@njit(cache=True)
def _moved_pose_contacts(m, w, opt, stats, recentre, kinematic, i, ncon, nisl, pairs, phi_x, n_x, p_x, first, count,
                         watch):
    """`prepare_contacts` at a pose where one body (slot i, kinematic or dynamic) moved from x's: the contacts of its
    watched pairs (`_watched_pairs`) found again, every other pair's x's (phi_x, n_x, p_x: the same bodies' poses
    give them), x's islands (the same pairs join the same bodies). False where a pair of the moved body has another
    number of contacts than at x. Slot -1 moves no body (no dynamic or kinematic body has it): x's contacts put
    back as found, none found again."""
    body_poses(m, w.q_hat, w.qk_hat, w.body_pose)
    if recentre and m.support_model == SUPPORT_LIMIT_SURFACE:
        recentre_limit_surfaces(m, w)
    world_vertices(m, w.body_pose, w.vert_world)
    for j in range(ncon):
        w.con_pair[j] = pairs[j]
        w.con_phi[j] = phi_x[j]
        for c in range(2):
            w.con_n[j, c] = n_x[j, c]
            w.con_p[j, c] = p_x[j, c]
    for p in range(first.shape[0]):
        if not watch[p] or not (_is_moved(m, m.shape_body[m.pair_a[p]], kinematic, i)
                                or _is_moved(m, m.shape_body[m.pair_b[p]], kinematic, i)):
            continue
        cnt = pair_contacts(m, w.vert_world, p, opt.margin, w.pair_forced[p], w.pair_phi, w.pair_n, w.pair_p)
        if cnt != count[p]:
            return False
        for c in range(cnt):
            j = first[p] + c
            w.con_phi[j] = w.pair_phi[c]
            for a in range(2):
                w.con_n[j, a] = w.pair_n[c, a]
                w.con_p[j, a] = w.pair_p[c, a]
    # the rest of prepare_contacts' work but the islands'
    for p in range(first.shape[0]):
        w.pair_set_count[p] = count[p]
    for kk in range(w.kin_lag.shape[0]):
        for c in range(3):
            w.kin_lag[kk, c] = 0.0
    for j in range(ncon):
        w.con_cn[j] = 0.0
        w.con_ft[j] = 0.0
    stats[Stat.N_ISLANDS] = nisl
    for d in range(w.v_new.shape[0]):
        for c in range(3):
            w.v_new[d, c] = w.v_tilde[d, c]
    return True


@njit(cache=True)
def _smooth_columns(m, h, opt, w, q, v, qk, vk, qk_out, scratch, steps, tols, nisl, ncon, z, zoff, r0, f0, derived,
                    linear_dyn, linear_kin, untouched_dyn, untouched_kin, resting_dyn, turn_free_dyn, turn_free_kin,
                    glide_axis, end_room, turn_reach, dr, jy):
    """The smooth part's columns (z held) into dr (its rows) and jy (its outputs), by central differences along
    each of its inputs, +- eps_k (steps[0]), from x's (q, v, qk, vk; its contacts' pairs and points in w, the rows
    r0 and outputs f0 there): the velocities' first (on x's contacts and poses; none where the smooth part is
    linear in them, `linear_dyn` and `linear_kin`: `_dynamic_velocity_columns` and `_kinematic_velocity_columns`
    give them), the kinematic ones before the dynamic ones' (which move the limit surfaces'
    re-centred columns), then the poses' (each with its contacts and, where its end configuration moved farther than
    end_room allows, the end-of-step check; the re-centred columns where they move); none for the `derived` pose
    columns, nor for an untouched body's pose (no contact, clear of
    every pair: `_untouched_bodies`, `_clear_of_pairs`), which moves none of the rows nor the outputs but a kinematic
    body's own qk+, nor for the angle of a body a turn leaves alike (`_turn_free_bodies`: the same), nor for a
    gliding island's derived translation (`_glide_axes`: `_glide_columns` writes it after), nor for an
    untouched kinematic body's velocity in the rows (in no row: zero), nor for a resting
    body's velocity (`_hold_resting` writes its columns). Where it answers it leaves x's stage in w as
    `_contacts_at` left it (x's contacts put back, as they were found). Returns DIFF_OK, TANGENT_CONTACTS (an
    evaluation with other contacts, or whose end-of-step check adds a pair) or TANGENT_KINK (one-sided differences
    that differ by more than tols[1] of their scale, at least tols[3]: the checked differences' kink test,
    `_sides_differ`)."""
    nd, nk = q.shape[0], qk.shape[0]
    K = steps.shape[1]
    N = zoff[nisl]
    nout = f0.shape[0]
    pairs = w.con_pair[:ncon].copy()
    points = w.con_p[:ncon].copy()
    phi_x, normals = w.con_phi[:ncon].copy(), w.con_n[:ncon].copy()
    npair = m.pair_a.shape[0]
    first, count, watch = np.empty(npair, np.int64), np.empty(npair, np.int64), np.empty(npair, np.bool_)
    _watched_pairs(m, w, opt, nd, steps, pairs, ncon, first, count, watch)
    order = np.empty(ncon, np.int64)
    phi_m, n_m, p_m = np.empty(ncon), np.empty((ncon, 2)), np.empty((ncon, 2))
    rp, rm = np.empty(N), np.empty(N)
    fp, fm = np.empty(nout), np.empty(nout)
    kinv = np.empty((nk, 3))
    dv = np.empty((nd, 3))
    active = np.empty(nisl, np.bool_)  # the islands an evaluation moves (`_active_islands`)
    at_x = True                        # w.sup_recentred holds x's re-centred columns
    for t in range(K):
        if (linear_kin and t < 3 * nk) or (linear_dyn and 3 * nk <= t < 3 * nk + 3 * nd):
            continue
        if t < 3 * nk:
            k = 6 * nd + 3 * nk + t                                      # kinematic velocities
        elif t < 3 * nk + 3 * nd:
            k = 3 * nd + (t - 3 * nk)                                    # dynamic velocities
        elif t < 3 * nk + 6 * nd:
            k = t - 3 * nk - 3 * nd                                      # dynamic poses
        else:
            k = t - 3 * nk                                               # kinematic poses
        kind = SMOOTH_POSE if k < 3 * nd else (SMOOTH_VELOCITY if k < 6 * nd else (
            SMOOTH_KIN_POSE if k < 6 * nd + 3 * nk else SMOOTH_KIN_VELOCITY))
        i = (k % (3 * nd)) // 3 if k < 6 * nd else ((k - 6 * nd) % (3 * nk)) // 3
        c = k % 3
        if derived >= 0 and (k == derived or k == derived + 1):
            continue
        if kind == SMOOTH_POSE and c == glide_axis[i]:
            continue
        turn_free = c == 2 and ((kind == SMOOTH_POSE and turn_free_dyn[i]) or (
            kind == SMOOTH_KIN_POSE and turn_free_kin[i]))
        if ((kind == SMOOTH_POSE and untouched_dyn[i]) or (kind == SMOOTH_VELOCITY and resting_dyn[i]) or (
                (kind == SMOOTH_KIN_POSE or kind == SMOOTH_KIN_VELOCITY) and untouched_kin[i]) or turn_free):
            if kind == SMOOTH_KIN_POSE:
                jy[6 * nd + 3 * i + c, k] = 1.0
            continue
        e = steps[0, k]
        _active_islands(m, w, ncon, kind, i, active)
        for sgn in range(2):
            _moved_start(m, h, opt, w, q, v, qk, vk, kinv, qk_out, scratch, kind, i, c, e if sgn == 0 else -e)
            pose = kind == SMOOTH_POSE or kind == SMOOTH_KIN_POSE
            if pose:
                # the re-centred columns depend on a dynamic body's angle and velocity only: an evaluation that
                # moves neither keeps them, once they are x's again (at_x)
                turns = kind == SMOOTH_POSE and c == 2
                same = _moved_pose_contacts(m, w, opt, scratch, turns or not at_x, kind == SMOOTH_KIN_POSE, i, ncon,
                                            nisl, pairs, phi_x, normals, points, first, count, watch)
                at_x = not turns
                if not same or not _match_contacts(w, ncon, points, order, phi_m, n_m, p_m):
                    return TANGENT_CONTACTS
            else:
                if kind == SMOOTH_VELOCITY and m.support_model == SUPPORT_LIMIT_SURFACE:
                    recentre_limit_surfaces(m, w)
                    at_x = False
                for d in range(nd):
                    for a in range(3):
                        w.v_new[d, a] = w.v_tilde[d, a]
            _smooth_part(m, h, w, kinv, nisl, ncon, z, zoff, q, qk_out, rp if sgn == 0 else rm,
                         fp if sgn == 0 else fm, dv, active, r0, f0)
            # the end-of-step check, where the end configuration moved far enough from x's that it could add a
            # pair (a pair's gap moves by at most both its bodies' `_end_motion`; CLEARANCE_FACTOR to spare): else
            # it adds none, as at x
            if pose and CLEARANCE_FACTOR * 2.0 * _end_motion(nd, nk, fp if sgn == 0 else fm, f0,
                                                             turn_reach) >= end_room:
                if check_end_configuration(m, w, opt, qk_out, scratch) != 0:
                    return TANGENT_CONTACTS
        for r in range(N):
            dr[r, k] = (rp[r] - rm[r]) / (2.0 * e)
        for r in range(nout):
            jy[r, k] = (fp[r] - fm[r]) / (2.0 * e)
        # the kink test on the smooth part's one-sided differences, its rows and its outputs each against their own
        # scale
        code = TANGENT_KINK if _sides_differ(rp, rm, r0, e, tols) or _sides_differ(fp, fm, f0, e, tols) else DIFF_OK
        if code != DIFF_OK:
            return code
    # x's stage again for the LCP's part: its contacts put back as found there (slot -1: no body moved, no pair found
    # again), not found again, and its islands, which no evaluation changed
    begin_step(m, q, v, qk, vk, h, opt, w, qk_out, scratch)
    _moved_pose_contacts(m, w, opt, scratch, True, False, -1, ncon, nisl, pairs, phi_x, normals, points, first, count,
                         watch)
    return DIFF_OK


@njit(cache=True)
def _hold_resting(m, w, nd, zoff, resting_dyn, dr, jy):
    """A resting body's part of the columns (`_untouched_bodies`): its table holds it at rest whichever way the
    state moves, and it touches nothing, so its island's rows and its outputs q+, v+ move with no input (the
    smooth part's rates there are cancelled by its table's impulses: `_state_columns` adds q+'s one on q) and its
    inputs move nothing else."""
    N, K = dr.shape
    nout = jy.shape[0]
    for d in range(nd):
        if not resting_dyn[d]:
            continue
        isl = w.body_island[d]
        for r in range(zoff[isl], zoff[isl + 1]):
            for k in range(K):
                dr[r, k] = 0.0
        for c in range(3):
            for k in range(K):
                jy[3 * d + c, k] = 0.0
                jy[3 * nd + 3 * d + c, k] = 0.0
            for r in range(nout):
                jy[r, 3 * d + c] = 0.0
                jy[r, 3 * nd + 3 * d + c] = 0.0
            for r in range(N):
                dr[r, 3 * d + c] = 0.0
                dr[r, 3 * nd + 3 * d + c] = 0.0


@njit(cache=True)
def _derived_columns(derived, nd, nk, dr, jy):
    """The last body's x and y pose columns (from `derived`), where they follow from the others' (`translation_free`):
    moving every pose alike moves nothing but the kinematic bodies' qk+, so each is that less the other pose
    columns along its axis."""
    N, nout = dr.shape[0], jy.shape[0]
    for a in range(2):
        kd = derived + a
        for r in range(N):
            dr[r, kd] = 0.0
        for r in range(nout):
            jy[r, kd] = 0.0
        for j in range(nk):
            jy[6 * nd + 3 * j + a, kd] = 1.0
        for k in range(6 * nd + 3 * nk):
            if k % 3 != a or (k >= 3 * nd and k < 6 * nd) or k == kd:
                continue
            for r in range(N):
                dr[r, kd] -= dr[r, k]
            for r in range(nout):
                jy[r, kd] -= jy[r, k]


@njit(cache=True)
def _lcp_columns(m, h, w, vk, nd, nisl, ncon, zoff, lu, perm, solve, solve_row, held, basic, degenerate, exempt,
                 afull, dr, jy):
    """The LCP's part, at x's contacts (in w): dz_B = -A_BB^-1 dr_B per island (`_island_bases`' factors), the
    degenerate indices' and the held rows' rates checked, and its velocity change M^-1 G dz (q+ moves by h times it)
    added to jy. False where a degenerate index or a held row moves."""
    N, K = dr.shape
    k_sup = support_column_count(m)
    dz = np.zeros((N, K))
    for isl in range(nisl):
        o, n = zoff[isl], zoff[isl + 1] - zoff[isl]
        idx, ridx = _indices(solve, o, n), _indices(solve_row, o, n)
        nb = idx.shape[0]
        if nb == 0:
            continue
        rhs = np.empty((nb, K))
        for a in range(nb):
            for k in range(K):
                rhs[a, k] = -dr[o + ridx[a], k]
        sol = np.empty((nb, K))
        _lu_solve(lu[o:o + nb, o:o + nb], perm[o:o + nb], rhs, sol)
        for a in range(nb):
            for k in range(K):
                dz[o + idx[a], k] = sol[a, k]
    # any other degenerate index holds its basis on both sides only where its w (z, if basic) stays at zero along
    # every input: a sticking contact's unloaded friction ray, w = lambda + t.v = 0 with lambda and t.v both held at
    # 0; the basis's rows left out of its solve (`held`) only where their w stays at zero
    for isl in range(nisl):
        o, n = zoff[isl], zoff[isl + 1] - zoff[isl]
        for k in range(K):
            size = 0.0
            for i in range(o, o + n):
                size = max(size, abs(dr[i, k]), abs(dz[i, k]))
            for i in range(o, o + n):
                if held[i]:
                    rate = dr[i, k]
                    for c in range(o, o + n):
                        rate += afull[i, c] * dz[c, k]
                    if abs(rate) > DEGENERATE_RTOL * size:
                        return False
                if not degenerate[i] or exempt[i]:
                    continue
                if basic[i]:
                    rate = dz[i, k]
                else:
                    rate = dr[i, k]
                    for c in range(o, o + n):
                        rate += afull[i, c] * dz[c, k]
                if abs(rate) > DEGENERATE_RTOL * size:
                    return False
    zk = np.empty(N)
    rows = np.empty(N)
    dv = np.empty((nd, 3))
    for isl in range(nisl):
        o, n = zoff[isl], zoff[isl + 1] - zoff[isl]
        if n == 0:
            continue
        nci, nsi = island_members(m, w, isl, ncon)
        n, nf = assemble_columns(m, w, vk, nci, nsi, h, False, rows[o:zoff[isl + 1]], np.bool_(True))
        nforce = nci + 2 * nf + k_sup * nsi
        for k in range(K):
            for d in range(nd):
                for c in range(3):
                    dv[d, c] = 0.0
            for i in range(n):
                zk[o + i] = dz[o + i, k]
            apply_impulses(nforce, w.column_slot, w.column_g, zk[o:o + n], m, dv)
            for d in range(nd):
                for c in range(3):
                    jy[3 * d + c, k] += h * dv[d, c]
                    jy[3 * nd + 3 * d + c, k] += dv[d, c]
    return True


@njit(cache=True)
def _state_columns(m, h, nd, nk, jy, jac):
    """The state's columns from the smooth part's (SMOOTH_POSE's comment)."""
    keep = 1.0 if m.damping == 1.0 else m.damping ** h
    for r in range(jy.shape[0]):
        for d in range(nd):
            for c in range(3):
                kq, kv = 3 * d + c, 3 * nd + 3 * d + c
                jac[r, kq] = jy[r, kq] + (1.0 if r == kq else 0.0)
                jac[r, kv] = keep * (h * jy[r, kq] + jy[r, kv])
        for j in range(nk):
            for c in range(3):
                kq, kv = 6 * nd + 3 * j + c, 6 * nd + 3 * nk + 3 * j + c
                jac[r, kq] = jy[r, kq]
                jac[r, kv] = h * jy[r, kq] + jy[r, kv]


@njit(cache=True)
def step_tangent(m, h, cold_opt, warm_opt, w, q, v, qk, vk, tols, jac, q1, v1, qk1, stats):
    """The derivatives of the cold step at the state (q, v, qk, vk) at its certified bases (module docstring) into
    jac (6 nd + 3 nk, K), columns the K inputs (x: q, v, qk, vk flattened row-major), the smooth part's central
    differences over eps_k = tols[0] max(1, |x_k|); the cold step's state into q1, v1, qk1 and its stats into stats.
    Returns DIFF_OK where every check holds, DIFF_MOVES where only the mixed direction's fails (jac written), else a
    DIFF_* or TANGENT_* code. tols as step_differences takes them. The warm-start memory is left as the cold step
    left it."""
    nd, nk = q.shape[0], qk.shape[0]
    # the cold step, and the steps along each input and the mixed direction's, as step_differences takes them
    code, x, steps, base, rec, memory = cold_step_at(m, h, cold_opt, w, q, v, qk, vk, tols[0], stats)
    if code != DIFF_OK:
        return code
    if not _covered(cold_opt, stats):
        return TANGENT_NOT_COVERED
    K, nout = x.shape[0], base.shape[0]
    msize, mbasic, mmodes = memory
    qa, va, qka, vka = np.empty((nd, 3)), np.empty((nd, 3)), np.empty((nk, 3)), np.empty((nk, 3))
    qk_out = np.empty((nk, 3))
    scratch = np.zeros(stats.shape[0])
    # x's contacts, islands and each island's LCP at the cold step's basis; the bodies clear of every pair there
    ncon, nisl = _contacts_at(m, h, cold_opt, w, x, nd, nk, qa, va, qka, vka, qk_out, scratch)
    untouched_dyn, untouched_kin, resting_dyn = np.empty(nd, np.bool_), np.empty(nk, np.bool_), np.empty(nd, np.bool_)
    _untouched_bodies(m, w, ncon, untouched_dyn, untouched_kin, resting_dyn)
    _clear_of_pairs(m, w, nd, steps, cold_opt.margin, False, untouched_dyn, untouched_kin)
    glide_t, glide_group, glide_axis = np.empty((nd, 2)), np.empty(nd, np.int64), np.empty(nd, np.int64)
    _glide_axes(m, w, nd, nisl, ncon, steps, cold_opt.margin, glide_t, glide_group, glide_axis)
    zoff = np.zeros(nisl + 1, np.int64)
    for isl in range(nisl):
        nci, nsi = island_members(m, w, isl, ncon)
        n = 0
        if nci > 0 or nsi > 0:
            n, nf, _ = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)
            nsb, _ = island_servo(m, w, nci, nf)
            if nsb > 0 or msize[isl] != n:
                return _give_way(msize, mbasic, mmodes, w, TANGENT_NOT_COVERED)
        zoff[isl + 1] = zoff[isl] + n
    N = zoff[nisl]
    z = np.zeros(N)
    lu = np.zeros((N, N))            # each island's A_BB's LU factors, on its diagonal block
    perm = np.zeros(N, np.int64)     # and their row order
    afull = np.zeros((N, N))         # each island's A
    basic = np.zeros(N, np.bool_)
    degenerate = np.zeros(N, np.bool_)
    solve = np.zeros(N, np.bool_)      # the basis each island's LCP part solves with: basic, and the sticking rays
    solve_row = np.zeros(N, np.bool_)  # its rows (`solve` where its matrix is nonsingular)
    # the basis's rows left out of the solve: they hold by themselves, or it gives way
    held = np.zeros(N, np.bool_)
    exempt = np.zeros(N, np.bool_)     # degenerate indices that may move: sticking and separating contacts' friction
    if not _island_bases(m, h, w, vka, nisl, ncon, zoff, mbasic, cold_opt.res_tol, z, lu, perm, afull, basic,
                         degenerate, solve, solve_row, held, exempt):
        return _give_way(msize, mbasic, mmodes, w, TANGENT_DEGENERATE)
    # the smooth part at x (its end-of-step check moves the body poses: put back for the velocities' columns)
    r0, f0 = np.empty(N), np.empty(nout)
    _smooth_part(m, h, w, vka, nisl, ncon, z, zoff, qa, qk_out, r0, f0, np.empty((nd, 3)), np.ones(nisl, np.bool_),
                 r0, f0)
    if check_end_configuration(m, w, cold_opt, qk_out, scratch) != 0:
        return _give_way(msize, mbasic, mmodes, w, TANGENT_CONTACTS)
    end_room = _end_room(m, w, cold_opt, qk_out)
    # a kinematic body's pose moves its end pose qk+ (a dynamic one's, q_hat only: q+ = q + h v+ stays): clear of
    # every pair there too, as the end-of-step check would find it
    _clear_of_pairs(m, w, nd, steps, 0.0, True, untouched_dyn, untouched_kin)
    any_resting = False
    for d in range(nd):
        resting_dyn[d] = resting_dyn[d] and untouched_dyn[d]
        any_resting = any_resting or resting_dyn[d]
    body_poses(m, w.q_hat, w.qk_hat, w.body_pose)
    # then its columns along each of its inputs
    dr = np.zeros((N, K))              # d(A z + b) over the force unknowns, z held
    jy = np.zeros((nout, K))           # d(q+, v+, qk+) along the smooth part's inputs
    # the last body's x and y pose columns, where they follow from the others' (`translation_free`); -1: none
    derived = -1
    if translation_free(m):
        derived = 6 * nd + 3 * (nk - 1) if nk > 0 else 3 * (nd - 1)
    linear_dyn, linear_kin = _linear_in_velocities(m, w, nisl, ncon)
    turn_free_dyn, turn_free_kin = np.empty(nd, np.bool_), np.empty(nk, np.bool_)
    _turn_free_bodies(m, turn_free_dyn, turn_free_kin)
    code = _smooth_columns(m, h, cold_opt, w, qa, va, qka, vka, qk_out, scratch, steps, tols, nisl, ncon, z, zoff, r0,
                           f0, derived, linear_dyn, linear_kin, untouched_dyn, untouched_kin, resting_dyn, turn_free_dyn,
                           turn_free_kin, glide_axis, end_room, _turn_reach(m), dr, jy)
    if code != DIFF_OK:
        return _give_way(msize, mbasic, mmodes, w, code)
    _glide_columns(nd, glide_t, glide_group, glide_axis, dr, jy)
    if derived >= 0:
        _derived_columns(derived, nd, nk, dr, jy)
    # the LCP's part at x's contacts (`_smooth_columns` put them back), and the velocities' columns where they are
    # in closed form
    if linear_dyn:
        _dynamic_velocity_columns(m, h, w, nd, nk, nisl, ncon, zoff, np.empty(N), dr, jy)
    if linear_kin:
        _kinematic_velocity_columns(m, w, nd, nk, nisl, ncon, zoff, dr)
    if any_resting:
        _hold_resting(m, w, nd, zoff, resting_dyn, dr, jy)
    if not _lcp_columns(m, h, w, vka, nd, nisl, ncon, zoff, lu, perm, solve, solve_row, held, basic, degenerate, exempt,
                        afull, dr, jy):
        return _give_way(msize, mbasic, mmodes, w, TANGENT_DEGENERATE)
    _state_columns(m, h, nd, nk, jy, jac)
    code = mixed_direction_check(m, h, warm_opt, w, rec, x, steps, jac, base, (msize, mbasic, mmodes), tols,
                                 np.empty(nout), np.empty(nout), q1, v1, qk1)
    # a resting body taken as held by its table that the steps along the mixed direction do not leave at rest: the
    # differences of whole steps say what the step does there
    return TANGENT_KINK if code == DIFF_MOVES and any_resting else code
