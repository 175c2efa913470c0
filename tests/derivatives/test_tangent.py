"""The derivatives at the cold step's certified bases (engine/tangent.py `step_tangent`, the first try of
step_derivatives(method="differences")) against the dual numbers, the exact oracle: where it answers, the dual numbers
call the step exact and their Jacobians agree far inside the checked differences' tolerance (the LCP's part is a
solve, not a difference); states it does not cover, or where an island is degenerate, are left to the differences of
whole steps."""

import numpy as np
import pytest

from planar_lcp.derivatives import step_derivatives
from planar_lcp.derivatives.differences import tangent_at_bases
from planar_lcp.engine.rollout import DIFF_OK
from planar_lcp.engine.tangent import (TANGENT_DEGENERATE, TANGENT_NOT_COVERED, _lu_factor, _lu_solve, _nullity,
                                       _pivots, translation_free)
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec.scene import load_scene

from derivative_scenes import SHIPPED, options, random_pushing_scene, random_vertical_scene, states_along
from test_differences import relative_error

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")

#: the tangent's largest difference from the dual numbers, relative to its row's or column's largest entry: the
#: smooth part's central differences alone (5e-8 on derivative_methods.py's states; whole steps' differences: 1e-5)
TANGENT_RTOL = 1e-7


def tangent(sim, q, v, qk, vk):
    return tangent_at_bases(sim, *(np.ascontiguousarray(a, dtype=float) for a in (q, v, qk, vk)))


def check(sim, states):
    """(states the tangent answers, states the dual numbers call exact); asserts the agreement where it answers."""
    answered = exact = 0
    for q, v, qk, vk in states:
        ref = step_derivatives(sim, q, v, qk, vk)
        code, jac = tangent(sim, q, v, qk, vk)
        exact += ref.exact
        if code != DIFF_OK:
            continue
        answered += 1
        assert ref.exact, f"the tangent answers where the dual numbers find {ref.degenerate}"
        assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL
    return answered, exact


def test_shipped_position_form_states_agree_with_the_dual_numbers():
    answered = exact = 0
    for name in SHIPPED:
        sim = Simulator(compile_scene(load_scene(name)), options("position"))
        a, e = check(sim, states_along(sim, *sim.initial_state(), 40, 8))
        answered, exact = answered + a, exact + e
    # it answers on most exact states (the others: a body at rest on its limit surface, a contact touching without
    # load, a restitution's or the fixed-point form's step; 23 of 45 when written)
    assert answered >= 0.4 * exact, f"the tangent answers on {answered} of {exact} exact states"


def test_random_scenes_agree_with_the_dual_numbers():
    answered = exact = 0
    for seed in range(6):
        for scene in (random_vertical_scene(seed), random_pushing_scene(seed)):
            sim = Simulator(compile_scene(scene), options("position"))
            a, e = check(sim, states_along(sim, *sim.initial_state(), 60, 15))
            answered, exact = answered + a, exact + e
    assert answered >= 0.3 * exact, f"the tangent answers on {answered} of {exact} exact states"


def test_a_sticking_contact_is_answered_and_a_contact_without_load_is_not():
    """box_push's pusher sticks on the box: one friction ray carries the load and the other has z = 0 and w = 0 (its
    slip rate and the contact's are zero), a degenerate index that stays at zero along every input, so the basis
    holds on both sides. A contact that touches without load is degenerate in the mode that matters: the tangent
    gives way (to the differences of whole steps)."""
    sim = Simulator(compile_scene(load_scene("box_push")), SimOptions())
    q, v, qk, vk = sim.initial_state()
    r = sim.rollout(q, v, qk, vk[None], 100)
    state = (r["q"][100], r["v"][100], r["qk"][100], vk)
    code, jac = tangent(sim, *state)
    ref = step_derivatives(sim, *state)
    assert code == DIFF_OK and ref.exact
    assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL
    # the scene's start with the pusher still: it touches the box's face (gap 0) with no load, on a box at rest on
    # its limit surface
    q, v, qk, _ = sim.initial_state()
    still = np.zeros_like(vk)
    assert tangent(sim, q, v, qk, still)[0] != DIFF_OK
    assert not step_derivatives(sim, q, v, qk, still).exact


def bench_state(name):
    """A shipped scene's simulator (its own options) and the state `bench derivatives` differentiates it at."""
    from planar_lcp.benchmarks.bench import derivative_state
    sc = load_scene(name)
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, solver=sc.sim.solver, formulation=sc.sim.formulation))
    q, v, qk, vk, _ = derivative_state(sim, sc)
    return sim, (q, v, qk, vk)


@pytest.mark.parametrize("name, why", [
    ("four_disks", "disks at rest on each other and on the ground, loaded inside their friction cones: each contact's "
                   "two friction rays at z = w = 0 move along the inputs, and it sticks whichever way it is pushed"),
    ("bouncing_disk", "a disk near the ground, its contact without load: its friction held at zero, its slack's rate "
                      "kinked, nothing the step returns moves"),
    ("block_on_incline", "a block flush on the incline: its two corner contacts come in the other order on the other "
                         "side of its angle"),
    ("tip_box", "a box at rest on the two corners of its flat face: their friction rows coincide (the split of the "
                "friction between them is a segment of answers, the same velocities), solved on the basis's "
                "independent rows"),
])
def test_degenerate_indices_that_move_without_a_switch_are_answered(name, why):
    sim, state = bench_state(name)
    code, jac = tangent(sim, *state)
    ref = step_derivatives(sim, *state)
    assert ref.exact and code == DIFF_OK, why
    assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL


def test_coinciding_friction_columns_give_way():
    """push_t at 1.5 s: the pusher's two friction rays coincide with two of the T's limit-surface columns, a segment
    of LCP answers that a change of the inputs breaks (the dual numbers call it non-unique): the tangent gives way,
    though the pusher's contact sticks at rest."""
    sim, state = bench_state("push_t")
    assert tangent(sim, *state)[0] == TANGENT_DEGENERATE
    assert any(d.kind == "non-unique" for d in step_derivatives(sim, *state).degenerate)


def test_a_scene_without_static_shapes_takes_its_last_pose_columns_from_the_others():
    """Without a pair of a static shape the step's smooth part moves with every pose moved alike: box_push (a pusher
    and a box on a table) has its pusher's x and y columns from the box's (the agreement with the dual numbers above
    holds them), falling_rod (a rod over the ground) has every pose column evaluated."""
    box = Simulator(compile_scene(load_scene("box_push")), SimOptions())
    rod = Simulator(compile_scene(load_scene("falling_rod")), SimOptions())
    assert translation_free(box.kmodel) and not translation_free(rod.kmodel)


def test_the_velocity_form_is_not_covered():
    sim = Simulator(compile_scene(load_scene("box_push")), SimOptions(formulation="velocity"))
    assert tangent(sim, *sim.initial_state())[0] == TANGENT_NOT_COVERED


def test_the_basis_solve_agrees_with_numpy_and_refuses_a_singular_basis():
    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 12):
        A = rng.standard_normal((n, n))
        B = rng.standard_normal((n, 4))
        lu, perm, x = A.copy(), np.zeros(n, np.int64), np.empty((n, 4))
        assert _lu_factor(lu, perm)
        _lu_solve(lu, perm, B, x)
        np.testing.assert_allclose(x, np.linalg.solve(A, B), rtol=1e-10, atol=1e-12)
    singular = np.array([[1.0, 2.0], [2.0, 4.0]])
    assert not _lu_factor(singular.copy(), np.zeros(2, np.int64))


def test_the_nullity_is_numpys_rank_deficit():
    """The null-space test of `_segments_leave_velocities`: elimination with complete pivoting against numpy's SVD
    rank, on seeded random matrices of every rank, and a contact's two friction columns (exact negatives)."""
    rng = np.random.default_rng(3)
    for n in range(1, 9):
        for rank in range(n + 1):
            a = rng.standard_normal((n, rank)) @ rng.standard_normal((rank, n))
            big = np.max(np.abs(a), initial=0.0)
            want = n - np.linalg.matrix_rank(a, tol=1e-9 * np.linalg.norm(a, 2)) if big > 0 else n
            assert _nullity(a.copy(), 1e-9 * big) == want, (n, rank)
    g = rng.standard_normal(3)
    a = np.outer([1.0, -1.0, 0.5], g)[:, [0, 1, 2]]
    a[:, 1] = -a[:, 0]
    assert _nullity(a.copy(), 1e-9 * np.max(np.abs(a))) == 2


def test_the_pivots_pick_a_nonsingular_part_of_the_rank():
    """The basis's independent rows and columns (`_pivots`, the solve where sticking rays coincide): on seeded random
    square and rectangular matrices of every rank, the rows and columns it puts first form a square part of full rank
    (numpy's SVD rank) and the rank is numpy's."""
    rng = np.random.default_rng(5)
    for nr, nc in ((1, 1), (3, 3), (6, 6), (4, 7), (7, 4)):
        for rank in range(min(nr, nc) + 1):
            a = rng.standard_normal((nr, rank)) @ rng.standard_normal((rank, nc))
            big = np.max(np.abs(a), initial=0.0)
            rows, cols = np.empty(nr, np.int64), np.empty(nc, np.int64)
            got = _pivots(a.copy(), 1e-9 * big, rows, cols)
            want = np.linalg.matrix_rank(a, tol=1e-9 * np.linalg.norm(a, 2)) if big > 0 else 0
            assert got == want, (nr, nc, rank)
            assert sorted(rows) == list(range(nr)) and sorted(cols) == list(range(nc))
            part = a[np.ix_(rows[:got], cols[:got])]
            assert np.linalg.matrix_rank(part, tol=1e-9 * big) == got


@pytest.mark.parametrize("name", ["falling_rod", "four_disks", "box_tip", "bouncing_disk", "box_push"])
def test_the_velocity_columns_agree_with_the_dual_numbers_to_round_off(name):
    """The velocities' columns (d/dv, d/dvk): in closed form where the smooth part is linear in the velocities
    (`_dynamic_velocity_columns`, `_kinematic_velocity_columns`: falling_rod, four_disks, box_tip; box_push's
    pusher), by the smooth part's differences with restitution (bouncing_disk) or a limit surface (box_push's box);
    within 1e-9 of the dual numbers' either way (the whole Jacobian's tolerance is TANGENT_RTOL, the pose columns'
    differences)."""
    sim, state = bench_state(name)
    nd, nk = len(state[0]), len(state[2])
    code, jac = tangent(sim, *state)
    ref = step_derivatives(sim, *state)
    assert code == DIFF_OK and ref.exact
    cols = list(range(3 * nd, 6 * nd)) + list(range(6 * nd + 3 * nk, 6 * nd + 6 * nk))
    assert np.max(np.abs(jac[:, cols] - ref.jacobian[:, cols])) <= 1e-9 * np.max(np.abs(ref.jacobian[:, cols]))


def contacts_at_linearization(sim, q, v, qk, vk):
    """`step_tangent`'s first stage, the state's contacts and islands at the linearization pose, into the simulator's
    work (its warm-start memory reset before): (ncon, nisl, x flattened, the differences' steps)."""
    from planar_lcp.derivatives.differences import DIFF_STEP
    from planar_lcp.engine.layout import NSTAT
    from planar_lcp.engine.rollout import difference_steps
    from planar_lcp.engine.tangent import _contacts_at
    nd, nk = len(q), len(qk)
    x = np.concatenate([np.ravel(a) for a in (q, v, qk, vk)]).astype(float)
    parts = [np.empty((nd, 3)), np.empty((nd, 3)), np.empty((nk, 3)), np.empty((nk, 3))]
    sim.reset_warm_start()
    ncon, nisl = _contacts_at(sim.kmodel, sim.h, sim.kopt, sim.kwork, x, nd, nk, *parts, np.empty((nk, 3)),
                              np.zeros(NSTAT))
    return ncon, nisl, x, difference_steps(x, DIFF_STEP)


def untouched_flags(sim, q, v, qk, vk):
    """The tangent's verdict at the linearization pose: (dynamic bodies, kinematic bodies) in no contact and clear
    of every pair there, and the dynamic ones among them held at rest by their table, as `step_tangent` reaches it
    before its check at the end configuration (where the kinematic bodies of tip_box and push_box, at rest, stand
    as at the linearization pose)."""
    from planar_lcp.engine.tangent import _clear_of_pairs, _untouched_bodies
    m, w, opt = sim.kmodel, sim.kwork, sim.kopt
    nd, nk = len(q), len(qk)
    ncon, _, _, steps = contacts_at_linearization(sim, q, v, qk, vk)
    dyn, kin, resting = np.empty(nd, np.bool_), np.empty(nk, np.bool_), np.empty(nd, np.bool_)
    _untouched_bodies(m, w, ncon, dyn, kin, resting)
    _clear_of_pairs(m, w, nd, steps, opt.margin, False, dyn, kin)
    sim.reset_warm_start()
    return dyn, kin, resting & dyn


def finger_gap(sim, q, v, qk, vk):
    """tip_box's gap between the box and the finger at the step's linearization pose."""
    from planar_lcp.engine.constants import BODY_KINEMATIC
    from planar_lcp.engine.contacts import contacts_at
    a = sim.model.arrays
    pair, phi, _, _ = contacts_at(a, q + sim.h * v, qk + sim.h * vk, 0.0, all_pairs=True)
    finger = sim.model.kin_names.index("finger")
    rows = [i for i, p in enumerate(pair) if a.body_kind[a.shape_body[a.pair_b[p]]] == BODY_KINEMATIC
            and a.body_slot[a.shape_body[a.pair_b[p]]] == finger]
    return min(phi[i] for i in rows)


def test_an_untouched_body_has_its_pose_columns_in_closed_form():
    """tip_box half-way: the finger 3 cm from the box touches nothing, so its pose moves nothing in the step but its
    own end pose: its columns are zero but qk+'s, without an evaluation of the smooth part; the same as the dual
    numbers' to the bit, and the whole Jacobian within the tangent's tolerance."""
    sim, state = bench_state("tip_box")
    q, v, qk, vk = state
    dyn, kin, _ = untouched_flags(sim, *state)
    assert kin.tolist() == [True] and dyn.tolist() == [False]
    nd, nk = len(q), len(qk)
    code, jac = tangent(sim, *state)
    ref = step_derivatives(sim, *state)
    assert code == DIFF_OK and ref.exact
    cols = slice(6 * nd, 6 * nd + 3 * nk)
    expected = np.zeros((6 * nd + 3 * nk, 3 * nk))
    expected[6 * nd:, :] = np.eye(3 * nk)
    assert np.array_equal(jac[:, cols], expected) and np.array_equal(ref.jacobian[:, cols], expected)
    assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL


@pytest.mark.parametrize("room, untouched", [(1e-3, True), (1e-7, False), (-1e-4, False)])
def test_a_body_near_a_pair_has_its_pose_columns_evaluated(room, untouched):
    """The finger moved to a gap of the contact margin plus `room` from the box: beyond its differences' reach (1e-3
    m) it stays in closed form; within it (1e-7 m: the evaluations at +- eps could meet the pair) or inside the
    margin (a contact) its columns are evaluated, and the Jacobian still agrees with the dual numbers."""
    sim, (q, v, qk, vk) = bench_state("tip_box")
    qk = qk.copy()
    qk[0, 0] -= finger_gap(sim, q, v, qk, vk) - (sim.kopt.margin + room)
    assert abs(finger_gap(sim, q, v, qk, vk) - (sim.kopt.margin + room)) < 1e-12
    dyn, kin, _ = untouched_flags(sim, q, v, qk, vk)
    assert kin.tolist() == [untouched] and dyn.tolist() == [False]
    code, jac = tangent(sim, q, v, qk, vk)
    ref = step_derivatives(sim, q, v, qk, vk)
    if code == DIFF_OK:
        assert ref.exact
        assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL
    assert untouched is False or code == DIFF_OK


@pytest.mark.parametrize("speed, resting", [(0.0, True), (1e-13, True), (0.2, False)])
def test_a_body_at_rest_on_its_table_is_held_there(speed, resting):
    """push_box's start: the box at rest on its table, the pusher away. Below REST_SPEED in every component the
    first try takes the box as held by its table (its support able to hold it: friction and load positive), whichever
    way its state moves: its v+ rows are zero and its q+ rows one on its q, without an evaluation (the dual numbers,
    which hold its re-centred column as fixed there, give the same); sliding at 0.2 m/s it is not held, and its
    columns are evaluated (where they answer, they agree with the dual numbers)."""
    sc = load_scene("push_box")
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, solver=sc.sim.solver, formulation=sc.sim.formulation))
    q, v, qk = (np.array(a, dtype=float) for a in sim.initial_state()[:3])
    v[0, 0] = speed
    vk = np.zeros_like(qk)
    dyn, kin, rest = untouched_flags(sim, q, v, qk, vk)
    assert rest.tolist() == [resting] and dyn.tolist() == [resting] and kin.tolist() == [True]
    code, jac = tangent(sim, q, v, qk, vk)
    ref = step_derivatives(sim, q, v, qk, vk)
    assert code == DIFF_OK or not resting
    if code == DIFF_OK:
        assert ref.exact
        assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL
    if resting:
        expected = np.zeros((6, jac.shape[1]))
        expected[:3, :3] = np.eye(3)
        assert np.array_equal(jac[:6], expected)


def test_a_box_sliding_straight_along_a_fixed_twist_gives_way():
    """push_box's box sliding straight along x at 0.2 m/s: its limit surface's re-centred column coincides with the
    fixed twist along x, a segment of answers along a sliding element's friction that a turn of its velocity breaks
    (the dual numbers call it non-unique): the first try gives way; sliding at an angle it answers."""
    sc = load_scene("push_box")
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, solver=sc.sim.solver, formulation=sc.sim.formulation))
    q, v, qk = (np.array(a, dtype=float) for a in sim.initial_state()[:3])
    vk = np.zeros_like(qk)
    v[0] = (0.2, 0.0, 0.0)
    assert tangent(sim, q, v, qk, vk)[0] == TANGENT_DEGENERATE
    assert any(d.kind == "non-unique" for d in step_derivatives(sim, q, v, qk, vk).degenerate)
    v[0] = (0.2, 0.05, 0.0)
    code, jac = tangent(sim, q, v, qk, vk)
    ref = step_derivatives(sim, q, v, qk, vk)
    assert code == DIFF_OK and ref.exact
    assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL


def pose_shortcuts(sim, q, v, qk, vk):
    """The tangent's two verdicts on the pose columns at the linearization pose: (turn-free dynamic bodies, turn-free
    kinematic bodies, each dynamic body's glide direction t (zero where its island does not glide), its island where
    it glides (else -1), the derived axis of each gliding island's last body (else -1)), as `step_tangent` reaches
    them."""
    from planar_lcp.engine.tangent import _glide_axes, _turn_free_bodies
    m, w, opt = sim.kmodel, sim.kwork, sim.kopt
    nd, nk = len(q), len(qk)
    ncon, nisl, _, steps = contacts_at_linearization(sim, q, v, qk, vk)
    turn_dyn, turn_kin = np.empty(nd, np.bool_), np.empty(nk, np.bool_)
    _turn_free_bodies(m, turn_dyn, turn_kin)
    t, group, axis = np.empty((nd, 2)), np.empty(nd, np.int64), np.empty(nd, np.int64)
    _glide_axes(m, w, nd, nisl, ncon, steps, opt.margin, t, group, axis)
    sim.reset_warm_start()
    return turn_dyn, turn_kin, t, group, axis


@pytest.mark.parametrize("name, turn_dyn, turn_kin", [
    ("four_disks", [True] * 4, []), ("bouncing_disk", [True], []), ("box_push", [False], [True]),
    ("falling_rod", [False], []), ("tip_box", [False], [True]),
])
def test_a_disk_turns_without_moving_the_step(name, turn_dyn, turn_kin):
    """A body whose shapes are disks about its centre of mass (four_disks' and bouncing_disk's disks, box_push's and
    tip_box's round fingers; not a box, a rod or a capsule's ends) has no evaluation along its angle: its contacts'
    points, normals and gaps follow its centre alone, so its angle's column is one on its own angle (a dynamic body's
    q+, a kinematic one's qk+) and zero elsewhere, as the dual numbers' is, and the Jacobian agrees with theirs."""
    sim, state = bench_state(name)
    got_dyn, got_kin, _, _, _ = pose_shortcuts(sim, *state)
    assert got_dyn.tolist() == turn_dyn and got_kin.tolist() == turn_kin
    nd, nk = len(state[0]), len(state[2])
    code, jac = tangent(sim, *state)
    ref = step_derivatives(sim, *state)
    assert code == DIFF_OK and ref.exact
    assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL
    cols = [3 * d + 2 for d in range(nd) if turn_dyn[d]] + [6 * nd + 3 * j + 2 for j in range(nk) if turn_kin[j]]
    unit = np.eye(6 * nd + 3 * nk, 6 * nd + 6 * nk)[:, cols]
    assert np.array_equal(jac[:, cols], unit)
    assert np.max(np.abs(ref.jacobian[:, cols] - unit), initial=0.0) <= 1e-12


@pytest.mark.parametrize("name, groups", [
    ("falling_rod", [0]), ("bouncing_disk", [0]), ("block_on_incline", [0]), ("box_tip", [0]),
    ("four_disks", [0, 1, 1, 1]), ("box_stack", [0, 0, 0]), ("tip_box", [-1]), ("box_push", [-1]),
])
def test_an_island_on_one_plane_glides_along_it(name, groups):
    """An island whose contacts are all between its bodies or with half-planes of one normal n, clear of every other
    pair (four_disks' thrown disk rolling on the ground, and its row of disks pressed together on it; box_stack's
    boxes; box_tip's box on its corner, the finger clear of it; not tip_box's box or box_push's, which a finger
    pushes): moving the whole island along the plane, t = (-n_y, n_x), moves none of its contacts, so the sum over
    its bodies of J_x t_x + J_y t_y is zero for the pose columns (less q+'s identity). The tangent evaluates every
    translation but one, its last body's along the axis where t is the larger, and writes that one from the others
    (on the 30 degree incline, x's from y's at -tan 30 deg; on level ground, one body's x column from the others'
    x columns). The dual numbers' columns hold the same relation, and the Jacobian agrees with theirs."""
    sim, state = bench_state(name)
    _, _, t, group, axis = pose_shortcuts(sim, *state)
    # the islands as found, numbered in the order of their first body
    seen = {}
    assert [-1 if g < 0 else seen.setdefault(g, len(seen)) for g in group] == groups
    code, jac = tangent(sim, *state)
    ref = step_derivatives(sim, *state)
    assert code == DIFF_OK
    if ref.exact:
        assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL
    eye = np.eye(jac.shape[0], jac.shape[1])
    for g in set(group) - {-1}:
        members = np.flatnonzero(group == g)
        assert sum(axis[d] >= 0 for d in members) == 1 and axis[members[-1]] >= 0
        for J in (jac, ref.jacobian):
            smooth = J - eye
            along = sum(smooth[:, 3 * d] * t[d, 0] + smooth[:, 3 * d + 1] * t[d, 1] for d in members)
            scale = max(np.max(np.abs(smooth[:, [3 * d + c for d in members for c in (0, 1)]])), 1.0)
            assert np.max(np.abs(along)) <= 1e-9 * scale
    if name == "block_on_incline":
        assert axis[0] == 0 and abs(t[0, 1] / t[0, 0] - np.tan(np.radians(30.0))) < 1e-12


def test_a_pairs_gap_moves_no_more_than_its_bodies_end_motion():
    """The end-of-step check runs at an evaluation only where its end configuration moved from x's by more than the
    room the check leaves (`_end_room`): a pair's gap moves by at most its two bodies' `_end_motion` (translation
    components plus the turn times `_turn_reach`). Held on seeded random scenes (boxes, capsules, polygons, disks on
    a tilted ground) and box_stack: every pair within 1 cm of contact, every body moved at random by up to 1e-4 (m
    and rad), its closest gap (`contacts_at`, all pairs) moves by no more than that bound."""
    from planar_lcp.engine.contacts import contacts_at
    from planar_lcp.engine.tangent import _end_motion, _turn_reach
    rng = np.random.default_rng(11)
    checked = 0
    scenes = [random_vertical_scene(seed) for seed in range(8)] + [load_scene("box_stack")]
    for scene in scenes:
        sim = Simulator(compile_scene(scene), options("position"))
        a = sim.model.arrays
        reach = _turn_reach(sim.kmodel)
        for q, v, qk, vk in states_along(sim, *sim.initial_state(), 40, 10):
            nd, nk = len(q), len(qk)
            pair0, phi0, _, _ = contacts_at(a, q, qk, 0.0, all_pairs=True, m=sim.kmodel)
            gap0 = {p: phi0[pair0 == p].min() for p in set(pair0.tolist())}
            for _ in range(5):
                scale = 10.0 ** rng.uniform(-9, -4)
                dq, dqk = rng.uniform(-scale, scale, (nd, 3)), rng.uniform(-scale, scale, (nk, 3))
                pair1, phi1, _, _ = contacts_at(a, q + dq, qk + dqk, 0.0, all_pairs=True, m=sim.kmodel)
                f0 = np.concatenate([q.ravel(), np.zeros(3 * nd), qk.ravel()])
                f1 = np.concatenate([(q + dq).ravel(), np.zeros(3 * nd), (qk + dqk).ravel()])
                motion = _end_motion(nd, nk, f1, f0, reach)
                for p, g in gap0.items():
                    if g > 0.01:
                        continue
                    moved = abs(phi1[pair1 == p].min() - g)
                    assert moved <= 2.0 * motion * (1 + 1e-9) + 1e-15, (scene.name, p, moved, motion)
                    checked += 1
    assert checked > 100


@pytest.mark.parametrize("room, watched", [(1e-3, False), (1e-7, True), (-1e-4, True)])
def test_an_evaluation_finds_again_the_contacts_of_the_pairs_a_move_can_reach(room, watched):
    """An evaluation at a moved pose finds again only the contacts of the moved body's pairs that have contacts at
    x, are forced, or lie within the contact margin plus CLEARANCE_FACTOR times their difference steps' reach
    (`_watched_pairs`; the others keep x's, none). tip_box's finger moved to a gap of the margin plus `room` from
    the box: 1 mm beyond it, the pair is not watched; 1e-7 m beyond (within its difference steps' reach) or inside
    the margin, it is, and the Jacobian agrees with the dual numbers wherever the first try answers."""
    from planar_lcp.engine.constants import BODY_KINEMATIC
    from planar_lcp.engine.contacts import contacts_at
    from planar_lcp.engine.tangent import _watched_pairs
    sim, (q, v, qk, vk) = bench_state("tip_box")
    qk = qk.copy()
    qk[0, 0] -= finger_gap(sim, q, v, qk, vk) - (sim.kopt.margin + room)
    m, w, opt, h = sim.kmodel, sim.kwork, sim.kopt, sim.h
    ncon, _, _, steps = contacts_at_linearization(sim, q, v, qk, vk)
    a = sim.model.arrays
    npair = len(a.pair_a)
    first, count, watch = np.empty(npair, np.int64), np.empty(npair, np.int64), np.empty(npair, np.bool_)
    pairs, _, _, _ = contacts_at(a, q + h * v, qk + h * vk, opt.margin, m=m)
    _watched_pairs(m, w, opt, len(q), steps, pairs.astype(np.int64), ncon, first, count, watch)
    sim.reset_warm_start()
    finger = sim.model.kin_names.index("finger")
    fingers = [p for p in range(npair) if a.body_kind[a.shape_body[a.pair_b[p]]] == BODY_KINEMATIC and
               a.body_slot[a.shape_body[a.pair_b[p]]] == finger]
    assert [bool(watch[p]) for p in fingers] == [watched]
    assert np.array_equal(count, np.bincount(pairs, minlength=npair))
    code, jac = tangent(sim, q, v, qk, vk)
    if code == DIFF_OK:
        ref = step_derivatives(sim, q, v, qk, vk)
        assert ref.exact
        assert relative_error(type(ref)(**{**ref.__dict__, "jacobian": jac}), ref) <= TANGENT_RTOL


def test_an_evaluation_moves_only_the_islands_of_its_body():
    """A wide pusher driving two boxes side by side (apart: two islands, both touched by the pusher) past a third box
    at rest (an island of its own) on a limit-surface table: an evaluation along a box's pose or velocity computes
    its island's rows and outputs alone and along the pusher's both pushed islands (`_active_islands`), the others'
    kept from the state's; where the tangent answers it agrees with the dual numbers. A pusher whose evaluations
    moved one of its islands only would leave the other's columns zero."""
    from planar_lcp.engine.layout import Stat
    from planar_lcp.spec.scene import parse_scene

    def box(name, x, y):
        return {"name": name, "type": "dynamic", "mass": 0.5, "position": [x, y], "support_friction": 0.4,
                "shapes": [{"type": "box", "width": 0.1, "height": 0.1}]}
    pusher = {"name": "pusher", "type": "kinematic", "position": [-0.07, 0.0], "velocity": [0.1, 0.02],
              "shapes": [{"type": "box", "width": 0.02, "height": 0.3}]}
    scene = parse_scene({"name": "two_islands", "world": {"plane": "horizontal", "friction": 0.5,
                                                          "support_model": "limit_surface"},
                         "sim": {"h": 0.01, "t_end": 0.5},
                         "bodies": [box("a", 0.0, 0.08), box("b", 0.0, -0.08), box("c", 0.5, 0.5), pusher]})
    sim = Simulator(compile_scene(scene), options("position"))
    states = states_along(sim, *sim.initial_state(), 40, 4)[3:]
    pushing = []
    for state in states:
        sim.reset_warm_start()
        sim.step(*state)
        if sim.stats[Stat.N_ISLANDS] == 3 and sim.stats[Stat.N_CONTACTS] >= 4:
            pushing.append(state)
    assert pushing, "no state with the pusher on both boxes"
    answered, _ = check(sim, pushing)
    assert answered >= 1, "the tangent answers on none of the states that push both boxes"
