"""The step's checked differences (step_derivatives(method="differences"), planar_lcp/derivatives/differences.py)
against the dual numbers, the exact oracle: on the states of the shipped scenes in every formulation and of seeded
random scenes, the differences either stand for the derivatives (and then agree with the dual numbers' to
AGREE_RTOL of the Jacobian's scale) or give way to them with a reason; degenerate states give way; parameters,
rollouts and the simulator's state after them."""

import numpy as np
import pytest

from planar_lcp.derivatives import step_derivatives
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec.scene import load_scene, parse_scene

from derivative_scenes import (SHIPPED, disk_at_wall, options, random_pushing_scene, random_vertical_scene,
                               states_along)

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")

#: the differences' largest difference from the dual numbers' derivatives, relative to the largest entry of its row
#: or column (at least FLOOR): the differences' truncation and round-off (differences.py) with a margin of 5
AGREE_RTOL = 1e-5
FLOOR = 1e-4


def relative_error(d, ref):
    A = np.abs(ref.jacobian)
    scale = np.maximum(np.maximum(A.max(axis=0)[None, :], A.max(axis=1)[:, None]), FLOOR)
    return float(np.max(np.abs(d.jacobian - ref.jacobian) / scale))


def check(sim, states, params=()):
    """(states both methods call exact, states the dual numbers call exact); asserts the agreement there."""
    used = exact = 0
    for q, v, qk, vk in states:
        ref = step_derivatives(sim, q, v, qk, vk, params)
        d = step_derivatives(sim, q, v, qk, vk, params, method="differences")
        # the same cold step, bit for bit
        assert np.array_equal(d.q, ref.q) and np.array_equal(d.v, ref.v) and np.array_equal(d.qk, ref.qk)
        assert d.status == ref.status
        exact += ref.exact
        if d.method == "dual":
            assert d.fallback, "a differences request that took the dual numbers says why"
            assert np.array_equal(d.jacobian, ref.jacobian) and d.exact == ref.exact
            continue
        assert d.method == "differences" and d.fallback == ""
        used += d.exact and ref.exact
        if not d.exact:
            # each input's differences hold and their sum does not: the step is not linear in its inputs here, and
            # the dual numbers find it degenerate too
            assert [g.kind for g in d.degenerate] == ["mixed"]
            assert not ref.exact, "differences not exact where the dual numbers are"
        elif ref.exact:
            assert relative_error(d, ref) <= AGREE_RTOL
    return used, exact


@pytest.mark.parametrize("formulation", ["position", "fixed_point", "velocity"])
def test_shipped_scenes_agree_with_the_dual_numbers(formulation):
    used = exact = 0
    for name in SHIPPED:
        sim = Simulator(compile_scene(load_scene(name)), options(formulation))
        u, e = check(sim, states_along(sim, *sim.initial_state(), 40, 8))
        used, exact = used + u, exact + e
    # the differences serve nearly every exact state (the rest: a kink within their step, which the one-sided
    # check finds; 45, 46 and 19 of 45, 46 and 19 when written)
    assert used >= 0.95 * exact, f"differences exact on {used} states of {exact} exact ones"


@pytest.mark.slow
@pytest.mark.parametrize("formulation", ["position", "fixed_point"])
def test_random_scenes_agree_with_the_dual_numbers(formulation):
    used = exact = 0
    for seed in range(14):
        for scene in (random_vertical_scene(seed), random_pushing_scene(seed)):
            sim = Simulator(compile_scene(scene), options(formulation))
            u, e = check(sim, states_along(sim, *sim.initial_state(), 60, 15))
            used, exact = used + u, exact + e
    # 108 of 109 and 108 of 110 when written
    assert used >= 0.95 * exact, f"differences exact on {used} states of {exact} exact ones"


@pytest.mark.parametrize("name, params", [("block_on_incline", ["world.friction"]),
                                          ("box_push", ["world.friction", "bodies.box.mass"]),
                                          ("bouncing_disk", ["world.restitution"])])
def test_parameter_columns_agree_with_the_dual_numbers(name, params):
    sim = Simulator(compile_scene(load_scene(name)), SimOptions())
    used, _ = check(sim, states_along(sim, *sim.initial_state(), 40, 8), params)
    assert used >= 3


def test_a_change_within_the_simulators_tolerance_is_differentiated():
    """push_t's T at rest with the pusher touching it: the simulator's step (res_tol 1e-9) does not move for a
    pusher's turn of 1e-6 rad/s (Lemke accepts the answer at the state: its artificial variable is within res_tol of
    zero), while the exact step turns the T at d(omega+)/d(omega_pusher) = -0.1425 (the dual numbers, and the step at
    1e-5 rad/s). The differences certify their steps to DIFF_RES_TOL and see the turn."""
    from planar_lcp.derivatives.differences import DIFF_RES_TOL, DIFF_STEP
    sim = Simulator(compile_scene(load_scene("push_t")), options("position"))
    assert sim.options.res_tol > 1e3 * DIFF_RES_TOL
    q, v, qk, vk = states_along(sim, *sim.initial_state(), 40, 8)[0]
    assert np.all(v == 0.0)

    def turned(eps):
        sim.reset_warm_start()
        v0 = sim.step(q, v, qk, vk)[1]
        turn = vk.copy()
        turn[0, 2] += eps
        sim.reset_warm_start()
        return (sim.step(q, v, qk, turn)[1][0, 2] - v0[0, 2]) / eps

    ref = step_derivatives(sim, q, v, qk, vk)
    assert ref.exact and abs(ref.dv_dvk[2, 2] - (-0.1425)) < 1e-3
    assert abs(turned(1e-5) - ref.dv_dvk[2, 2]) < 1e-6
    assert abs(turned(DIFF_STEP)) < 1e-12             # the simulator's dead zone at the differences' step
    d = step_derivatives(sim, q, v, qk, vk, method="differences")
    assert d.method == "differences" and d.exact
    assert relative_error(d, ref) <= AGREE_RTOL


def test_a_switch_near_the_state_but_not_at_it_is_differentiated_over_a_smaller_step(monkeypatch):
    """box_push in the velocity form: states where the dual numbers find a switch of the engine's discrete choices
    within 1e-6 of the state (their one-sided derivatives equal) and the differences over DIFF_STEP see it (they
    give way); taken again over DIFF_STEP / DIFF_RETRY_SHRINK they stand on the state's smooth piece and agree with
    the dual numbers' derivatives."""
    import planar_lcp.derivatives.differences as differences
    sim = Simulator(compile_scene(load_scene("box_push")), options("velocity"))
    near = []
    for q, v, qk, vk in states_along(sim, *sim.initial_state(), 40, 8):
        ref = step_derivatives(sim, q, v, qk, vk)
        sides = np.max(np.abs(ref.jacobian_right - ref.jacobian_left))
        if [g.kind for g in ref.degenerate] == ["switch"] and sides <= 1e-12 * max(1.0, np.max(np.abs(ref.jacobian))):
            near.append(((q, v, qk, vk), ref))
    assert near, "no state with a switch nearby: the scene or the states changed"
    for state, ref in near:
        d = step_derivatives(sim, *state, method="differences")
        assert d.method == "differences" and d.exact
        assert relative_error(d, ref) <= AGREE_RTOL
    monkeypatch.setattr(differences, "DIFF_RETRY_SHRINK", 1.0)
    monkeypatch.setattr(differences, "_settings", {})
    gave_way = [step_derivatives(sim, *state, method="differences").method == "dual" for state, _ in near]
    assert any(gave_way), "the switches nearby are not within DIFF_STEP: the retry is not what answers here"


def test_the_kernels_entry_point_answers_as_numbas_dispatcher():
    """After its first call, through numba's dispatcher, a simulator calls the derivatives' kernel by the entry point
    of the overload that call chose (engine/entry.py; not where the kernels are not compiled): the same answers, bit
    for bit, as the dispatcher's at other states, on a state whose arrays are not aligned too."""
    from numba import config

    from planar_lcp.derivatives.differences import tangent_at_bases
    from planar_lcp.engine.tangent import step_tangent
    sim = Simulator(compile_scene(load_scene("box_push")), SimOptions())
    states = states_along(sim, *sim.initial_state(), 40, 10)
    sim.step_derivatives(*states[0], method="differences")
    assert (step_tangent in sim.kernel_calls) == (not config.DISABLE_JIT)
    for state in states[1:]:
        got = sim.step_derivatives(*state, method="differences")
        code, want = tangent_at_bases(sim, *state)
        if got.fallback == "":
            assert code == 0 and np.array_equal(got.jacobian, want)
    q = states[1][0]
    buf = np.zeros(q.size * 8 + 1, np.uint8)
    odd = np.frombuffer(buf.data, dtype=np.float64, count=q.size, offset=1).reshape(q.shape)
    odd[...] = q
    assert not odd.flags.aligned
    got = sim.step_derivatives(odd, *states[1][1:], method="differences")
    assert np.array_equal(got.jacobian, sim.step_derivatives(*states[1], method="differences").jacobian)


@pytest.mark.parametrize("formulation", ["position", "fixed_point"])
def test_the_bound_first_try_answers_as_the_general_way(formulation):
    """Once its entry point is known, a simulator's first try is bound to it (differences.py `FirstTry`) and states
    whose arrays it takes go straight to it: the same answer, bit for bit (Jacobians, state, stats, verdict), as the
    general way that arrays it does not take (read-only, strided views, lists) go, where the first try answers
    (the position form) and where it gives way and the differences of whole steps answer (the fixed-point form, which
    it does not cover). The bound object keeps no reference to the simulator."""
    import gc
    import weakref

    from numba import config

    from planar_lcp.derivatives.differences import first_try
    sim = Simulator(compile_scene(load_scene("box_push")), options(formulation))
    states = states_along(sim, *sim.initial_state(), 40, 10)
    assert first_try(sim) is None
    sim.step_derivatives(*states[0], method="differences")
    first = first_try(sim)
    assert (first is not None) == (not config.DISABLE_JIT)

    def answer(state):
        d = sim.step_derivatives(*state, method="differences")
        return (d.jacobian, d.jacobian_right, d.jacobian_left, d.q, d.v, d.qk, sim.stats.copy(),
                (d.status, d.exact, d.method, d.fallback, [str(g) for g in d.degenerate]))

    for state in states[1:]:
        if first is not None:
            assert first.takes(*state)
        frozen = [a.copy() for a in state]
        for a in frozen:
            a.flags.writeable = False
        strided = [np.repeat(a, 2, axis=1)[:, ::2] for a in state]      # every other column: not contiguous
        others = (frozen, strided, [a.tolist() for a in state])
        assert not any(first.takes(*o) for o in others[:2]) if first is not None else True
        want = answer(state)
        assert want[-1][2] == ("differences" if formulation == "position" else want[-1][2])
        for other in others:
            got = answer(other)
            assert all(np.array_equal(g, w) for g, w in zip(got[:-1], want[:-1])) and got[-1] == want[-1]
    gone = weakref.ref(sim)
    del sim, first
    gc.collect()
    assert gone() is None


def test_the_incline_block_slides_with_dv_dmu_minus_g_cos_a_h():
    """A block sliding down a 30 degree incline: d(v+ along the slope)/d(mu) = g cos(a) h, against the slide."""
    sim = Simulator(compile_scene(load_scene("block_on_incline")), SimOptions())
    q, v, qk, vk = sim.initial_state()
    down = np.array([-np.cos(np.radians(30)), -np.sin(np.radians(30))])
    v = v.copy()
    v[0, :2] = 0.3 * down
    d = step_derivatives(sim, q, v, qk, vk, ["world.friction"], method="differences")
    assert d.method == "differences"
    g = 9.81
    assert d.dv_dp[:2, 0] @ down == pytest.approx(-g * np.cos(np.radians(30)) * sim.h, rel=1e-6)


def test_a_switch_of_modes_gives_way_to_the_dual_numbers():
    """A disk touching a wall without pressing it (z = 0 and w = 0): v+_x = min(vx, -dx/h) has a kink there; the
    differences see it and give way, and the dual numbers name the degenerate contact."""
    sim = disk_at_wall()
    q, v, qk, vk = sim.initial_state()
    d = step_derivatives(sim, q, v, qk, vk, method="differences")
    assert d.method == "dual" and d.fallback
    assert not d.exact and d.degenerate


def test_one_sided_differences_give_the_one_sided_derivatives_at_a_switch():
    """The disk touching the wall (v+_x = min(vx, -dx / h)): method "one_sided" answers by the compiled step's
    one-sided differences where the checked differences give way, not exact, naming the inputs whose sides differ:
    along its x, d(v+_x)/dx is -1/h from the right (into the wall) and 0 from the left, d(q+_x)/dx 0 and 1; along its
    vx, d(v+_x)/dvx is 0 and 1; as the dual numbers' one-sided derivatives. A rollout lists the step."""
    sim = disk_at_wall()
    q, v, qk, vk = sim.initial_state()
    d = step_derivatives(sim, q, v, qk, vk, method="one_sided")
    ref = step_derivatives(sim, q, v, qk, vk)
    assert d.method == "one_sided" and d.fallback and not d.exact
    assert np.array_equal(d.q, ref.q) and np.array_equal(d.v, ref.v) and d.status == ref.status
    kinds = {g.kind: g.where for g in d.degenerate}
    assert set(kinds) == {"sides"} and "q[0, 0]" in kinds["sides"] and "v[0, 0]" in kinds["sides"]
    h = sim.h
    x, vx = 0, 3                                   # columns: the disk's x and vx; rows: q+_x and v+_x alike
    assert d.jacobian_right[3 + x, x] == pytest.approx(-1.0 / h, rel=1e-6)
    assert d.jacobian_left[3 + x, x] == pytest.approx(0.0, abs=1e-6 / h)
    assert d.jacobian_right[x, x] == pytest.approx(0.0, abs=1e-6) and d.jacobian_left[x, x] == pytest.approx(1.0)
    assert d.jacobian_right[3 + x, vx] == pytest.approx(0.0, abs=1e-6)
    assert d.jacobian_left[3 + x, vx] == pytest.approx(1.0, rel=1e-6)
    for got, want in ((d.jacobian_right, ref.jacobian_right), (d.jacobian_left, ref.jacobian_left)):
        assert np.max(np.abs(got - want)) <= 1e-6 * np.max(np.abs(want))
    assert np.array_equal(d.jacobian, 0.5 * (d.jacobian_right + d.jacobian_left))
    r = sim.rollout_derivatives(q, v, qk, vk[None], 1, method="one_sided")
    assert [i for i, _ in r.one_sided] == [0] and r.fallbacks == () and not r.exact


def test_one_sided_differences_take_the_side_that_keeps_the_steps_structure():
    """A frictionless disk rising past the contact margin (its gap at the linearization pose q + h v exactly the
    margin): the floor's contact enters the step on one side of its height and of its vertical velocity, the step
    is free flight on both (the contact pushes nothing), and the checked differences give way (the structure
    changes within their smaller step). The one-sided differences take the side that keeps the cold step's
    contacts: free flight's Jacobian (dq+/dq = I, dq+/dv = h I, dv+/dv = I, dv+/dq = 0), the inputs named."""
    doc = {"name": "rising", "world": {"plane": "vertical", "friction": 0.0}, "sim": {"h": 0.01, "t_end": 0.1},
           "bodies": [
               {"name": "floor", "type": "static",
                "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]},
               {"name": "disk", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.5],
                "shapes": [{"type": "disk", "radius": 0.05}]}]}
    sim = Simulator(compile_scene(parse_scene(doc)), SimOptions())
    q, v, qk, vk = sim.initial_state()
    v = np.array([[0.0, 1.0, 0.0]])
    q = np.array([[0.0, 0.05 + sim.options.contact_margin - sim.h * 1.0, 0.0]])
    assert step_derivatives(sim, q, v, qk, vk, method="differences").method == "dual"
    d = step_derivatives(sim, q, v, qk, vk, method="one_sided")
    assert d.method == "one_sided" and not d.exact
    kinds = {g.kind: g.where for g in d.degenerate}
    assert "structure" in kinds and "q[0, 1]" in kinds["structure"] and "v[0, 1]" in kinds["structure"]
    free = np.zeros((6, 6))
    free[:3, :3] = np.eye(3)
    free[:3, 3:] = sim.h * np.eye(3)
    free[3:, 3:] = np.eye(3)
    for J in (d.jacobian_right, d.jacobian_left):
        assert np.max(np.abs(J - free)) <= 1e-6


def test_one_sided_is_the_checked_differences_where_they_answer():
    """Where the checked differences stand for the derivatives, method "one_sided" is they, bit for bit."""
    sim = Simulator(compile_scene(load_scene("box_push")), SimOptions())
    for state in states_along(sim, *sim.initial_state(), 40, 10):
        want = step_derivatives(sim, *state, method="differences")
        got = step_derivatives(sim, *state, method="one_sided")
        assert got.method == want.method
        if want.method == "differences":
            assert np.array_equal(got.jacobian, want.jacobian) and got.exact == want.exact


def test_pgs_gives_way_to_the_dual_numbers():
    sim = Simulator(compile_scene(load_scene("falling_rod")), SimOptions(solver="pgs"))
    d = step_derivatives(sim, *sim.initial_state(), method="differences")
    assert d.method == "dual" and "PGS" in d.fallback


def test_rollout_derivatives_by_differences_agree_with_the_dual_numbers():
    sim = Simulator(compile_scene(load_scene("box_push")), SimOptions())
    q, v, qk, vk = sim.initial_state()
    ref = sim.rollout_derivatives(q, v, qk, vk[None], 30, ["world.friction"])
    d = sim.rollout_derivatives(q, v, qk, vk[None], 30, ["world.friction"], method="differences")
    assert np.array_equal(d.q, ref.q) and np.array_equal(d.v, ref.v)
    assert len(d.fallbacks) < 30, "the differences served some of the steps"
    for got, want in ((d.dx_dx0, ref.dx_dx0), (d.dx_dp, ref.dx_dp), (d.dx_dvk, ref.dx_dvk)):
        scale = max(np.max(np.abs(want)), 1.0)
        assert np.max(np.abs(got - want)) <= 1e-5 * scale


def test_the_simulator_steps_on_as_after_a_cold_step():
    """After the differences (their perturbed steps warm-started on the simulator's memory) a `step` from anywhere
    is the cold step, the model's parameter arrays are as compiled, and the stats are the cold step's."""
    sim = Simulator(compile_scene(load_scene("box_push")), SimOptions())
    fresh = Simulator(compile_scene(load_scene("box_push")), SimOptions())
    q, v, qk, vk = states_along(sim, *sim.initial_state(), 40, 20)[1]
    arrays = [a.copy() for a in sim.model.arrays if isinstance(a, np.ndarray)]
    d = sim.step_derivatives(q, v, qk, vk, ["world.friction", "bodies.box.mass"], method="differences")
    assert d.method == "differences"
    assert all(np.array_equal(a, b) for a, b in zip(arrays, (a for a in sim.model.arrays
                                                               if isinstance(a, np.ndarray))))
    got, want = sim.step(q, v, qk, vk), fresh.step(q, v, qk, vk)
    assert all(np.array_equal(a, b) for a, b in zip(got, want))
    assert np.array_equal(sim.stats, fresh.stats)


def test_an_unknown_method_is_refused():
    sim = Simulator(compile_scene(load_scene("falling_rod")), SimOptions())
    with pytest.raises(ValueError, match="method must be one of dual, differences, one_sided, got 'fd'"):
        step_derivatives(sim, *sim.initial_state(), method="fd")


def test_dense_buffers_that_are_too_small_grow_first():
    """A simulator whose dense buffers start too small for its island (a box on a box, 2 corner contacts and the
    ground's) grows them and answers as one with buffers large enough from the start."""
    from planar_lcp.engine.layout import make_step_work, work_struct
    sim = Simulator(compile_scene(load_scene("box_tip")), SimOptions())
    big = Simulator(compile_scene(load_scene("box_tip")), SimOptions())
    q, v, qk, vk = states_along(big, *big.initial_state(), 40, 20)[1]
    want = big.step_derivatives(q, v, qk, vk, method="differences")
    assert want.method == "differences", want.fallback
    sim.work = make_step_work(sim.model, 2)
    sim.kwork = work_struct(sim.work)
    got = sim.step_derivatives(q, v, qk, vk, method="differences")
    assert sim.work.lemke_lu.shape[0] > 2
    assert got.method == want.method and np.array_equal(got.jacobian, want.jacobian)


@pytest.mark.slow
def test_the_methods_measurement_runs_as_documented():
    """examples/measurements/derivative_methods.py (docs/method.md, "Two methods") end to end, as a user runs it."""
    import os
    import subprocess
    import sys
    root = os.path.join(os.path.dirname(__file__), "..", "..")
    r = subprocess.run([sys.executable, os.path.join(root, "examples", "measurements", "derivative_methods.py")],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].endswith("exact by the dual numbers") and lines[1].startswith("| dual numbers: exact |")
    stood = [ln for ln in lines if ln.startswith("| yes | differences | - |")]
    assert len(stood) == 1 and int(stood[0].split("|")[4]) > 0
    first_try = [ln for ln in lines if ln.startswith("their largest difference from the dual numbers")]
    assert len(first_try) == 1 and float(first_try[0].split(": ")[1].split(" ")[0]) <= AGREE_RTOL
    # the one-sided differences answer every state the checked differences leave to the dual numbers, and are far
    # from the dual numbers' one-sided derivatives only where those name a second switch within their step or an
    # answer that is not unique (docs/method.md)
    sided = [ln for ln in lines if ln.startswith("one-sided differences: answered")]
    assert len(sided) == 1
    answered, total = int(sided[0].split()[3]), int(sided[0].split()[6])
    assert answered == total > 0
    far = [ln for ln in lines if ln.startswith("  farther than 1e-4: ")]
    assert len(far) == 1
    n_far, n_explained = (int(part.split(": ")[-1]) for part in far[0].split(", where"))
    assert n_far == n_explained and n_far < answered


def test_the_compiled_recording_is_the_rollouts_recording():
    """step_differences makes its one-step Recording in compiled code (`_compiled_recording`: no namedtuple of 17
    arrays to type at each call): the same fields, dtypes and dimensions as `make_recording`'s, so the rollout kernel
    it calls is the one every run compiles."""
    from numba import typeof
    from planar_lcp.engine.rollout import _compiled_recording, make_recording
    for nd, nk in ((1, 0), (3, 2)):
        ours, theirs = _compiled_recording(1, nd, nk), make_recording(1, nd, nk)
        assert typeof(ours) == typeof(theirs)
        assert [a.shape for a in ours] == [a.shape for a in theirs]
