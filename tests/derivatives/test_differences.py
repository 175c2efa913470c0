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
from planar_lcp.spec.scene import load_scene

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
    with pytest.raises(ValueError, match="method must be one of dual, differences, got 'fd'"):
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
    worst = float(lines[-1].split(": ")[1].split(" ")[0])
    assert worst <= AGREE_RTOL


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
