"""Derivatives of the step (planar_lcp.derivatives) against three oracles: central finite differences of the compiled
`Simulator.step` (shipped scenes and seeded random scenes, every formulation), mechanics in closed form (a block on
an incline), and states built to be degenerate (a contact at the switch between two modes).

The finite-difference oracle takes, per input, the central differences at the steps 1e-8 ... 1e-3 (times
max(1, |x|)) and uses the pair of consecutive steps nearest 1e-5 that agree with each other (a plateau). Much below
1e-6 the certified solves' tolerance (a residual of 1e-9 of the LCP's scale) shows: a friction impulse the exact
LCP needs for a change of 1e-8 is within the tolerance of zero, and the differences see a body that does not stick.
Above 1e-5 a contact a few micrometres away can switch (a gap of 1e-7 m is a kink 1e-7 away: then only the smallest
steps form a plateau). An input with no plateau is not compared (it is counted, and the tests require most inputs
to be compared).
"""

import math

import numpy as np
import pytest

from planar_lcp.derivatives import scene_param, scene_with_param, step_derivatives
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec.scene import load_scene, parse_scene

from derivative_scenes import (SHIPPED, disk_at_wall, options, random_pushing_scene, random_vertical_scene,
                               states_along)

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")

STEPS = (1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3)
#: the pairs of consecutive steps tried, nearest 1e-5 first: (1e-6, 1e-5), (1e-5, 1e-4), (1e-7, 1e-6), ...
PAIR_ORDER = (2, 3, 1, 4, 0)
PLATEAU_RTOL = 1e-6
AGREE_RTOL = 1e-5


def _flat(*arrays):
    return np.concatenate([np.asarray(a, float).ravel() for a in arrays])


def _step_flat(sim, x, shapes):
    parts, o = [], 0
    for shp in shapes:
        n = int(np.prod(shp))
        parts.append(x[o:o + n].reshape(shp))
        o += n
    sim.reset_warm_start()
    q, v, qk, st = sim.step(*parts)
    return _flat(q, v, qk)


def fd_plateau(sim, q, v, qk, vk):
    """(J, tested): the finite-difference Jacobian of the step over (q, v, qk, vk), column by column at its first
    plateau (module docstring), and which columns had one."""
    shapes = [a.shape for a in (q, v, qk, vk)]
    x = _flat(q, v, qk, vk)
    f0 = _step_flat(sim, x, shapes)
    J = np.zeros((len(f0), len(x)))
    tested = np.zeros(len(x), bool)
    for k in range(len(x)):
        cols = []
        for rel in STEPS:
            e = rel * max(1.0, abs(x[k]))
            xp, xm = x.copy(), x.copy()
            xp[k] += e
            xm[k] -= e
            cols.append((_step_flat(sim, xp, shapes) - _step_flat(sim, xm, shapes)) / (2 * e))
        for i in PAIR_ORDER:
            a, b = cols[i], cols[i + 1]
            # 1e-4: derivatives of a step are h (dq/dv) or larger; a column of zeros agrees to 1e-10 once the steps
            # are above the solves' noise
            scale = max(np.max(np.abs(a)), np.max(np.abs(b)), 1e-4)
            if np.max(np.abs(a - b)) <= PLATEAU_RTOL * scale:
                J[:, k] = b
                tested[k] = True
                break
    return J, tested


def compare(d, J, tested):
    """Largest relative difference over the tested columns (relative to the column's largest entry, at least 1e-4 as
    in the plateau: a column of round-off zeros is not a scale)."""
    ours = d.jacobian[:, :J.shape[1]]
    floor = 1e-4
    worst = 0.0
    for k in np.flatnonzero(tested):
        scale = max(np.max(np.abs(J[:, k])), np.max(np.abs(ours[:, k])), floor)
        worst = max(worst, np.max(np.abs(ours[:, k] - J[:, k])) / scale)
    return worst


def _check_states(sim, states, min_exact):
    exact = compared = total = 0
    worst = 0.0
    for q, v, qk, vk in states:
        d = step_derivatives(sim, q, v, qk, vk)
        q1, v1, qk1, st = sim.step(q, v, qk, vk)
        assert np.array_equal(d.q, q1) and np.array_equal(d.v, v1) and d.status == st
        if not d.exact:
            assert d.degenerate, "a step not exact names why"
            continue
        exact += 1
        J, tested = fd_plateau(sim, q, v, qk, vk)
        compared += int(tested.sum())
        total += len(tested)
        worst = max(worst, compare(d, J, tested))
    assert exact >= min_exact, f"only {exact} of {len(states)} states exact"
    assert compared >= 0.9 * total, f"only {compared} of {total} inputs had a finite-difference plateau"
    assert worst <= AGREE_RTOL, f"largest relative difference from finite differences {worst:.3g}"
    return exact


#: states of the 5 along each shipped run that must be exact (the others name why they are not): the velocity form's
#: resting contacts sit on the kink of max(phi, 0) / h, and push_t's T slides straight along a fixed twist of its
#: limit surface (the re-centred column coincides with it: "non-unique")
MIN_EXACT = {"velocity": 0, "push_t": 1}


@pytest.mark.parametrize("formulation", ["position", "fixed_point", "velocity"])
@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenes_agree_with_finite_differences(name, formulation):
    sim = Simulator(compile_scene(load_scene(name)), options(formulation))
    q, v, qk, vk = sim.initial_state()
    states = states_along(sim, q, v, qk, vk, 40, 8)
    _check_states(sim, states, MIN_EXACT.get(formulation, MIN_EXACT.get(name, 2)))


N_RANDOM = 14


@pytest.mark.slow
@pytest.mark.parametrize("formulation", ["position", "fixed_point"])
@pytest.mark.parametrize("seed", range(N_RANDOM))
def test_random_scenes_agree_with_finite_differences(seed, formulation):
    """Seeded random scenes: falling, bouncing, sliding and tumbling bodies of every shape on a tilted ground, and a
    random object pushed on a table (limit surface or support points); 4 states of each along its run."""
    for scene in (random_vertical_scene(seed), random_pushing_scene(seed)):
        sim = Simulator(compile_scene(scene), options(formulation))
        q, v, qk, vk = sim.initial_state()
        _check_states(sim, states_along(sim, q, v, qk, vk, 60, 15), 1)


@pytest.mark.parametrize("max_force", [4.0])
@pytest.mark.parametrize("formulation", ["position", "fixed_point"])
def test_a_force_limited_pusher_agrees_with_finite_differences(max_force, formulation):
    """A disk pusher with a force limit of 4 N against a 1 kg box on a table (mu 0.3: 2.94 N to slide it): it pushes
    at its limit, lagging, while the box speeds up, then at the box's pace."""
    pusher = {"name": "pusher", "type": "kinematic", "position": [-0.15, 0.01], "velocity": [0.2, 0.0],
              "max_force": max_force, "shapes": [{"type": "disk", "radius": 0.05}]}
    box = {"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.0], "support_friction": 0.3,
           "shapes": [{"type": "box", "width": 0.2, "height": 0.2}]}
    scene = parse_scene({"name": "servo", "world": {"plane": "horizontal", "friction": 0.5},
                         "sim": {"h": 0.01, "t_end": 0.5}, "bodies": [box, pusher]})
    sim = Simulator(compile_scene(scene), options(formulation))
    q, v, qk, vk = sim.initial_state()
    states = states_along(sim, q, v, qk, vk, 30, 5)
    lag = [sim.step_derivatives(*s).dqk_dvk[0, 0] for s in states]
    assert min(lag) < 0.01 * sim.h and max(lag) == pytest.approx(sim.h), "the pusher lags, then keeps its pace"
    _check_states(sim, states, 2)


def test_the_oracles_cover_at_least_200_states():
    """The two tests above compare this many states (every one of them asserted): >= 200."""
    shipped = len(SHIPPED) * 3 * len(range(0, 40, 8))
    random = N_RANDOM * 2 * 2 * len(range(0, 60, 15))
    assert shipped + random >= 200


# --- closed forms -------------------------------------------------------------------------------------------------

def _incline(mu, v_along=0.0):
    """block_on_incline with friction mu, the block moving down the slope at v_along (m/s)."""
    scene = scene_with_param(load_scene("block_on_incline"), "world.friction", mu)
    sim = Simulator(compile_scene(scene), SimOptions())
    q, v, qk, vk = sim.initial_state()
    down = np.array([-math.cos(math.radians(30)), -math.sin(math.radians(30))])
    v = v.copy()
    v[0, :2] = v_along * down
    return sim, q, v, qk, vk, down


@pytest.mark.parametrize("v_along", [0.0, 0.3])
def test_sliding_block_on_an_incline_dv_dmu_is_minus_g_cos_a_h(v_along):
    sim, q, v, qk, vk, down = _incline(0.3, v_along)
    d = step_derivatives(sim, q, v, qk, vk, params=["world.friction"])
    assert d.exact, d.degenerate
    g, h, a = 9.81, sim.h, math.radians(30)
    dv = d.dv_dp[:, 0]
    assert dv[:2] @ down == pytest.approx(-g * math.cos(a) * h, rel=1e-9)
    assert abs(dv[:2] @ np.array([-down[1], down[0]])) < 1e-12       # no change across the slope
    assert abs(dv[2]) < 1e-12
    # and the position by h times that (q+ = q + h v+)
    assert d.dq_dp[:2, 0] @ down == pytest.approx(-g * math.cos(a) * h * h, rel=1e-9)


def test_sticking_block_has_zero_derivatives():
    """mu = 0.8 > tan 30 deg: the block stays put, whatever mu and its small velocity."""
    sim, q, v, qk, vk, down = _incline(0.8)
    d = step_derivatives(sim, q, v, qk, vk, params=["world.friction"])
    assert d.exact, d.degenerate
    assert np.max(np.abs(d.dv_dp)) < 1e-12
    assert np.max(np.abs(d.dv_dv)) < 1e-9
    assert np.max(np.abs(d.v)) < 1e-12


def test_stick_slip_boundary_is_degenerate_with_its_one_sided_derivatives():
    """mu = tan 30 deg: the friction the block needs to stay is exactly the most the contact gives. More friction
    (right): it sticks, dv/dmu = 0; less (left): it slides, dv/dmu = -g cos a h along the slope."""
    a = math.radians(30)
    sim, q, v, qk, vk, down = _incline(math.tan(a))
    d = step_derivatives(sim, q, v, qk, vk, params=["world.friction"])
    assert not d.exact
    assert any(g.kind == "complementarity" for g in d.degenerate)
    n = 6 * sim.model.ndyn + 6 * sim.model.nkin
    right, left = d.jacobian_right[3:6, n], d.jacobian_left[3:6, n]
    assert np.max(np.abs(right)) < 1e-9
    assert left[:2] @ down == pytest.approx(-9.81 * math.cos(a) * sim.h, rel=1e-6)


def test_touching_without_force_is_degenerate():
    """A disk resting on the floor against a wall, pressing nothing: moving into the wall it stops (right side of
    dv/dv_x: 0), moving away it keeps its velocity (left: 1)."""
    sim = disk_at_wall()
    q, v, qk, vk = sim.initial_state()
    d = step_derivatives(sim, q, v, qk, vk)
    assert not d.exact
    assert any("wall" in g.where for g in d.degenerate)
    assert d.jacobian_right[3, 3] == pytest.approx(0.0, abs=1e-9)
    assert d.jacobian_left[3, 3] == pytest.approx(1.0, abs=1e-9)
    assert d.dv_dv[0, 0] == pytest.approx(0.5, abs=1e-9)             # the mean: what central differences give


def test_equal_faces_in_contact_are_a_geometry_switch():
    """Three boxes of one width stacked: which face gives each contact's normal switches with the boxes' angles."""
    sim = Simulator(compile_scene(load_scene("box_stack")), SimOptions())
    d = step_derivatives(sim, *sim.initial_state())
    assert not d.exact
    assert any(g.kind == "geometry" and "box" in g.where for g in d.degenerate)


def test_a_box_flat_on_a_larger_face_is_smooth():
    """tip_box's pusher face against the box's side, shorter than it: the longer face gives the normal on both sides
    of the pose, so the step is differentiable (and the finite-difference test above checks its derivatives)."""
    sim = Simulator(compile_scene(load_scene("tip_box")), SimOptions())
    q, v, qk, vk = sim.initial_state()
    d = step_derivatives(sim, *states_along(sim, q, v, qk, vk, 20, 10)[1])
    assert d.exact, d.degenerate


# --- scene parameters ----------------------------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("name, params, start, nsteps", [
    # pushed at constant speed, a box's motion does not depend on its mass (friction and inertia scale alike); the
    # pusher reaches the box at step 270
    ("box_push", ["world.friction", "bodies.box.support_friction"], 250, 400),
    ("random_push_6", ["bodies.object.support_friction", "world.friction"], 0, 100),     # limit surface
    ("random_push_1", ["bodies.object.support_friction"], 0, 100),                       # support points
    ("bouncing_disk", ["world.restitution"], 0, 1000),                                    # its two impacts
    ("four_disks", ["bodies.thrown.mass", "bodies.d1.mass", "world.friction"], 150, 400),  # impacts from 170
])
def test_parameter_derivatives_agree_with_finite_differences_of_the_scene(name, params, start, nsteps):
    scene = random_pushing_scene(int(name.split('_')[-1])) if name.startswith("random_push") else load_scene(name)
    sim = Simulator(compile_scene(scene), SimOptions())
    q, v, qk, vk = sim.initial_state()
    checked = np.zeros(len(params), int)
    for n, (q, v, qk, vk) in enumerate(states_along(sim, q, v, qk, vk, nsteps, 1)[start:]):
        d = step_derivatives(sim, q, v, qk, vk, params=params)
        # every state whose derivatives are not zero (an impact, a push), and a few where they are
        if not d.exact or (n % 25 and not np.any(np.abs(d.jacobian[:, -len(params):]) > 1e-9)):
            continue
        for i, name_p in enumerate(params):
            p0 = scene_param(scene, name_p)
            e = 1e-5 * max(abs(p0), 1e-3)
            outs = []
            for p in (p0 + e, p0 - e):
                s2 = Simulator(compile_scene(scene_with_param(scene, name_p, p)), SimOptions())
                outs.append(_flat(*s2.step(q, v, qk, vk)[:3]))
            fd = (outs[0] - outs[1]) / (2 * e)
            ours = np.concatenate([d.dq_dp[:, i], d.dv_dp[:, i], d.dqk_dp[:, i]])
            # 1e-9: the differences' round-off (1e-16 of the state over a step of 1e-5 of the parameter)
            assert np.max(np.abs(ours - fd)) <= 1e-5 * np.max(np.abs(fd)) + 1e-9, (name_p, ours, fd)
            checked[i] += np.max(np.abs(fd)) > 1e-6
        if np.all(checked >= 3):
            break
    assert np.all(checked >= 1), f"each parameter compared where the step depends on it: {dict(zip(params, checked))}"


# --- a rollout ----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name, nsteps, start", [("falling_rod", 30, 180), ("box_push", 20, 280),
                                                 ("tip_box", 20, 10)])
def test_rollout_derivatives_are_the_chain_of_the_steps(name, nsteps, start):
    """The final state's Jacobians of an nsteps rollout against central differences of the whole rollout: the
    initial state's, each step's kinematic velocities' and a parameter's."""
    scene = load_scene(name)
    sim = Simulator(compile_scene(scene), SimOptions())
    q, v, qk, vk = sim.initial_state()
    q, v, qk, _ = states_along(sim, q, v, qk, vk, start + 1, start)[1]
    vk_seq = np.repeat(vk[None], nsteps, axis=0)
    par = "world.friction"
    r = sim.rollout_derivatives(q, v, qk, vk_seq, nsteps, params=[par])
    assert r.exact, r.degenerate
    assert len(r.q) == nsteps + 1

    def final(q0, v0, qk0, vks, s=sim):
        s.reset_warm_start()
        rec = s.rollout(q0, v0, qk0, vks, nsteps)
        return _flat(rec["q"][-1], rec["v"][-1], rec["qk"][-1])

    assert np.array_equal(final(q, v, qk, vk_seq), _flat(r.q[-1], r.v[-1], r.qk[-1]))
    x0 = _flat(q, v, qk)
    nd, nk = sim.model.ndyn, sim.model.nkin
    e = 1e-6
    for k in range(len(x0)):
        xp, xm = x0.copy(), x0.copy()
        xp[k] += e
        xm[k] -= e
        split = lambda x: (x[:3 * nd].reshape(nd, 3), x[3 * nd:6 * nd].reshape(nd, 3), x[6 * nd:].reshape(nk, 3))
        fd = (final(*split(xp), vk_seq) - final(*split(xm), vk_seq)) / (2 * e)
        assert np.max(np.abs(r.dx_dx0[:, k] - fd)) <= 1e-5 * max(np.max(np.abs(fd)), 1.0)
    for i in (0, nsteps // 2, nsteps - 1):
        for c in range(3 * nk):
            vp, vm = vk_seq.copy(), vk_seq.copy()
            vp[i].flat[c] += e
            vm[i].flat[c] -= e
            fd = (final(q, v, qk, vp) - final(q, v, qk, vm)) / (2 * e)
            assert np.max(np.abs(r.dx_dvk[i][:, c] - fd)) <= 1e-5 * max(np.max(np.abs(fd)), 1.0)
    p0 = scene_param(scene, par)
    outs = [final(q, v, qk, vk_seq, Simulator(compile_scene(scene_with_param(scene, par, p)), SimOptions()))
            for p in (p0 + 1e-6, p0 - 1e-6)]
    fd = (outs[0] - outs[1]) / 2e-6
    assert np.max(np.abs(r.dx_dp[:, 0] - fd)) <= 1e-5 * max(np.max(np.abs(fd)), 1.0)


# --- bad input ----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("method", ["dual", "differences"])
def test_bad_input_is_refused_with_the_field_named(method):
    sim = Simulator(compile_scene(load_scene("box_push")), SimOptions())
    q, v, qk, vk = sim.initial_state()
    with pytest.raises(ValueError, match=r"q must have shape \(1, 3\), got \(3,\)"):
        step_derivatives(sim, q.ravel(), v, qk, vk, method=method)
    for name in ("q", "v", "qk", "vk"):
        for bad in (np.nan, np.inf, -np.inf):
            state = dict(q=q.copy(), v=v.copy(), qk=qk.copy(), vk=vk.copy())
            state[name][0, 1] = bad
            with pytest.raises(ValueError, match=f"^step_derivatives: {name} must be finite$"):
                step_derivatives(sim, **state, method=method)
    # a huge but finite state is no error of the input, and a step the compiled kernel takes (its derivatives on
    # duals overflow on the way: the duals branch on the values, as the kernel does)
    d = step_derivatives(sim, q, v + 1e300, qk, vk, method=method)
    assert d.status == 0 and d.jacobian.shape == (9, 12)
    sim = Simulator(compile_scene(load_scene("falling_rod")), SimOptions())
    q, v, qk, vk = sim.initial_state()
    with pytest.raises(KeyError, match="no body 'nope'"):
        step_derivatives(sim, q, v, qk, vk, params=["bodies.nope.mass"])
    with pytest.raises(KeyError, match="expected world.friction"):
        step_derivatives(sim, q, v, qk, vk, params=["world.colour"])
    osqp = Simulator(sim.model, SimOptions(solver="osqp"))
    with pytest.raises(ValueError, match="osqp"):
        osqp.step_derivatives(q, v, qk, vk)


def test_a_body_at_rest_up_to_round_off_on_a_limit_surface_is_as_at_rest():
    """A box resting on its table with the velocities a resting body decays to (1e-260 m/s: the re-centred column's
    derivative, 1 / |v~|, would overflow): the derivatives are finite and those of the box exactly at rest."""
    doc = {"name": "rest", "world": {"plane": "horizontal", "friction": 0.5}, "sim": {"h": 0.01, "t_end": 0.1},
           "bodies": [{"name": "box", "type": "dynamic", "mass": 1.0, "support_friction": 0.4, "angle": 0.3,
                       "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}]}
    sim = Simulator(compile_scene(parse_scene(doc)), SimOptions())
    q, v, qk, vk = sim.initial_state()
    at_rest = step_derivatives(sim, q, v, qk, vk)
    tiny = step_derivatives(sim, q, np.array([[1e-260, -3e-261, 2e-259]]), qk, vk)
    assert np.all(np.isfinite(tiny.jacobian))
    np.testing.assert_allclose(tiny.jacobian, at_rest.jacobian, rtol=0, atol=1e-12)


def test_the_mixed_direction_finds_a_mode_that_two_inputs_switch_together():
    """max(0, min(x, y)) at 0: along x and along y zero on both sides, along d = (1, 1) 1 on one side; the dual
    numbers' check of the mixed direction (`mixed_agrees`) calls that not differentiable, and a linear step so."""
    from planar_lcp.derivatives import mixed_agrees
    d = np.array([1.0, 1.0])
    assert not mixed_agrees(np.zeros((1, 2)), d, np.array([1.0]), np.array([0.0]))
    J = np.array([[2.0, -1.0], [0.5, 0.25]])
    assert mixed_agrees(J, d, J @ d, J @ d)
    assert not mixed_agrees(J, d, J @ d + [1e-6, 0.0], J @ d)
    assert not mixed_agrees(J, d, np.array([np.inf, 0.75]), J @ d)
