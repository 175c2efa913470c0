"""The time-stepper against analytic mechanics (oracles, not smoke).

Each test states the exact result, and the expected discretization error of the semi-implicit scheme
(M (v+ - v) = h f + impulses, q+ = q + h v+) where there is one.
"""

import math

import numpy as np
import pytest

from planar_lcp.engine.layout import Stat
from planar_lcp.spec.scene import FORMULATIONS, parse_scene
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, SimulationError, Simulator, simulate

G = 9.81


def table():
    return {"name": "table", "type": "static",
            "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]}


def scene(bodies, *, friction=0.5, h=0.001, t_end=1.0, plane="vertical", **sim):
    world = {"plane": plane, "friction": friction}
    if plane == "vertical":
        world["gravity"] = [0.0, -G]
    return parse_scene({"name": "test", "world": world, "sim": {"h": h, "t_end": t_end, **sim}, "bodies": bodies})


# --- free flight -------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("h", [0.01, 0.005])
def test_free_flight_is_the_discrete_parabola_and_O_h_from_the_exact_one(h):
    x0, y0, vx0, vy0, w0 = 0.1, 2.0, 1.5, 3.0, 2.0
    sc = scene([{"name": "disk", "type": "dynamic", "mass": 2.0, "position": [x0, y0], "velocity": [vx0, vy0],
                 "angular_velocity": w0, "shapes": [{"type": "disk", "radius": 0.1}]}], h=h, t_end=0.5)
    tr = simulate(sc)
    t = tr.t
    n = np.arange(len(t))
    # semi-implicit Euler exactly: y_n = y0 + vy0 t_n - g h^2 n (n + 1) / 2
    np.testing.assert_allclose(tr.q[:, 0, 1], y0 + vy0 * t - G * h * h * n * (n + 1) / 2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.q[:, 0, 0], x0 + vx0 * t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.q[:, 0, 2], w0 * t, rtol=0, atol=1e-12)
    # against the exact parabola: the error is exactly g h t / 2 (first order)
    err = (y0 + vy0 * t - 0.5 * G * t ** 2) - tr.q[:, 0, 1]
    np.testing.assert_allclose(err, 0.5 * G * h * t, rtol=1e-9, atol=1e-12)
    assert tr.stats["lcp_size"].max() == 0  # a body touching nothing never builds an LCP


# --- sliding to a stop -----------------------------------------------------------------------------------------

def _slide_distance(h, v0=2.0, mu=0.4):
    sc = scene([{"name": "box", "type": "dynamic", "mass": 1.5, "position": [0.0, 0.05], "velocity": [v0, 0.0],
                 "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}, table()], friction=mu, h=h,
               t_end=v0 / (mu * G) + 0.1)
    tr = simulate(sc)
    return tr, tr.q[-1, 0, 0] - tr.q[0, 0, 0]


def test_box_sliding_stops_after_v0_squared_over_2_mu_g():
    v0, mu = 2.0, 0.4
    exact = v0 ** 2 / (2 * mu * G)
    errs = []
    for h in (0.002, 0.001):
        tr, d = _slide_distance(h, v0, mu)
        errs.append(abs(d - exact))
        # at rest at the end, flat on the table, never lifted or sunk
        assert abs(tr.v[-1, 0, 0]) < 1e-12 and abs(tr.v[-1, 0, 1]) < 1e-12 and abs(tr.v[-1, 0, 2]) < 1e-12
        np.testing.assert_allclose(tr.q[:, 0, 1], 0.05, atol=1e-12)
        # the discrete deceleration is exactly mu g while sliding
        vx = tr.v[:, 0, 0]
        sliding = vx[1:] > 1e-9  # (the stopped box keeps a round-off velocity of ~1e-16)
        np.testing.assert_allclose(np.diff(vx)[sliding], -mu * G * h, rtol=1e-9)
        assert errs[-1] <= v0 * h  # O(h): the scheme's error is about v0 h / 2
    assert 1.7 < errs[0] / errs[1] < 2.3  # first order


# --- incline ---------------------------------------------------------------------------------------------------

def incline_scene(angle_deg, mu, h, t_end):
    a = math.radians(angle_deg)
    nrm = [-math.sin(a), math.cos(a)]
    return scene([{"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.05 * nrm[0], 0.05 * nrm[1]],
                   "angle_deg": angle_deg, "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]},
                  {"name": "incline", "type": "static",
                   "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": nrm}]}],
                 friction=mu, h=h, t_end=t_end)


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_box_on_incline_sticks_exactly_when_tan_a_below_mu(formulation):
    tr = simulate(incline_scene(20.0, 0.5, 0.01, 10.0), formulation=formulation)
    drift = np.linalg.norm(tr.q[:, 0, :2] - tr.q[0, 0, :2], axis=1).max()
    assert drift <= 1e-9, f"creep of {drift:.3e} m over 10 s"
    assert np.abs(tr.q[:, 0, 2] - tr.q[0, 0, 2]).max() <= 1e-9
    modes = tr.contacts["mode"][tr.contacts["count"] > 0]
    assert np.all(tr.contacts["mode"][:, :2] != 2), "a sticking box reported sliding"
    assert modes.size > 0


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_box_on_incline_slides_with_g_sin_minus_mu_cos(formulation):
    a, mu, h = math.radians(30.0), 0.3, 0.005
    tr = simulate("block_on_incline", formulation=formulation)
    t_dir = np.array([math.cos(a), math.sin(a)])
    v_along = tr.v[:, 0, :2] @ t_dir  # positive up the slope
    acc = -np.diff(v_along) / h
    np.testing.assert_allclose(acc, G * (math.sin(a) - mu * math.cos(a)), rtol=1e-9)
    assert np.abs(tr.v[:, 0, 2]).max() < 1e-9  # slides without rotating
    # the slide is reported as such
    assert np.all(tr.contacts["mode"][5:, :2] == 2)


# --- rolling ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("formulation", ["position", "velocity"])
def test_spinning_disk_ends_rolling_at_omega0_r_over_3(formulation):
    r, m, w0 = 0.1, 1.0, 20.0
    J = 0.5 * m * r * r
    sc = scene([{"name": "disk", "type": "dynamic", "mass": m, "inertia": J, "position": [0.0, r],
                 "angular_velocity": w0, "shapes": [{"type": "disk", "radius": r}]}, table()],
               friction=0.3, h=0.001, t_end=1.5)
    tr = simulate(sc, formulation=formulation)
    vx, w = tr.v[-1, 0, 0], tr.v[-1, 0, 2]
    # CCW spin drives the contact point forward, so friction pushes the disk towards -x
    assert vx == pytest.approx(-w0 * r / 3, rel=1e-9)
    assert vx + w * r == pytest.approx(0.0, abs=1e-12)  # rolling without slipping
    np.testing.assert_allclose(tr.q[:, 0, 1], r, atol=1e-12)


# --- energy ----------------------------------------------------------------------------------------------------

NO_EXTERNAL_WORK = ["falling_rod", "four_disks", "block_on_incline", "box_stack", "painleve_rod"]


@pytest.mark.parametrize("name", NO_EXTERNAL_WORK)
def test_velocity_form_never_gains_energy(name):
    tr = simulate(name, formulation="velocity")
    e = tr.stats["energy"]
    assert np.diff(e).max() <= 1e-12 * max(1.0, np.abs(e).max())


@pytest.mark.parametrize("name", NO_EXTERNAL_WORK)
@pytest.mark.parametrize("formulation", ["position", "fixed_point"])
def test_position_forms_never_lose_more_than_they_dissipate(name, formulation):
    """Position forms: energy never rises above its starting value (net), and any per-step rise is O(h^2):
    the linearized position constraint of a rotating pivot (measured in test_position_form_gain_is_O_h2)."""
    tr = simulate(name, formulation=formulation)
    e = tr.stats["energy"]
    assert e[1:].max() <= e[0] + 1e-12 * abs(e[0])
    h = tr.options.h
    assert np.diff(e).max() <= 10.0 * G * h * h * max(1.0, np.abs(e).max())


def test_position_form_gain_is_O_h2():
    """On the Painleve rod pivoting on its end, the largest per-step energy rise of the position form scales as
    h^2 (quarters when h halves) - a discretization effect, not a modelling error. See docs/method.md."""
    gains = [np.diff(simulate("painleve_rod", h=h, t_end=0.3).stats["energy"]).max() for h in (0.002, 0.001)]
    assert gains[0] > 0
    assert 3.5 < gains[0] / gains[1] < 4.5


# --- resting contact -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("formulation", ["position", "velocity"])
def test_box_resting_on_table_holds_its_height_for_1e4_steps(formulation):
    sc = scene([{"name": "box", "type": "dynamic", "mass": 2.0, "position": [0.3, 0.05],
                 "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}, table()], h=0.005, t_end=50.0)
    tr = simulate(sc, formulation=formulation)
    assert len(tr.t) == 10001
    assert np.abs(tr.q[:, 0, 1] - 0.05).max() <= 1e-9
    assert np.abs(tr.q[:, 0, 0] - 0.3).max() <= 1e-9
    # two contacts (the bottom corners), each carrying half the weight
    cn = tr.contacts["cn"][-1, :2]
    np.testing.assert_allclose(cn, 0.5 * 2.0 * G * 0.005, rtol=1e-9)


# --- model only what the scene requires ------------------------------------------------------------------------

def test_frictionless_contacts_carry_only_the_normal_unknown():
    sc = scene([{"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.05],
                 "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}, table()], friction=0.0, t_end=0.01)
    tr = simulate(sc)
    assert np.all(tr.stats["lcp_size"] == tr.stats["n_contacts"])


def test_vertical_plane_friction_uses_exactly_two_rays():
    tr = simulate(incline_scene(20.0, 0.5, 0.01, 0.05))
    # per contact: c_n, beta(+t), beta(-t), lambda
    assert np.all(tr.stats["lcp_size"] == 4 * tr.stats["n_contacts"])


def test_separate_piles_are_separate_islands():
    boxes = [{"name": f"b{i}", "type": "dynamic", "mass": 1.0, "position": [float(i), 0.05],
              "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]} for i in range(3)]
    flyer = {"name": "flyer", "type": "dynamic", "mass": 1.0, "position": [0.0, 5.0],
             "shapes": [{"type": "disk", "radius": 0.1}]}
    tr = simulate(scene(boxes + [flyer, table()], t_end=0.01))
    # three boxes each on the table: three islands, and the flyer's own (empty) one
    assert np.all(tr.stats["n_islands"] == 4)
    assert np.all(tr.stats["lcp_max"] == 8)        # one box: 2 contacts x 4 unknowns
    assert np.all(tr.stats["lcp_size"] == 24)


# --- failures are reported, never hidden -----------------------------------------------------------------------

def test_lcp_failure_raises_with_step_and_cause_or_is_recorded():
    # res_tol = 0 demands an exact residual, which round-off denies on some step: a controlled LCP "failure"
    with pytest.raises(SimulationError, match=r"step \d+ \(t = .* s, h = 0\.0025\): no method gave a certified "
                                              r"solution .* Lemke ended with 'inaccurate'.*; the run stopped at this "
                                              r"step\."):
        simulate("falling_rod", res_tol=0.0)
    tr = simulate("falling_rod", res_tol=0.0, on_failure="record")
    assert tr.failures and len(tr.t) == 401
    i, t, cause = tr.failures[0]
    assert tr.stats["status"][i] == 1 and cause.endswith("that island took PGS's uncertified answer")
    assert tr.stats["pgs_uncertified"][i] >= 1
    assert np.all(np.isfinite(tr.q))


def test_bad_simulate_arguments():
    with pytest.raises(ValueError, match="solver must be one of 'lemke', 'pgs', 'osqp', got 'magic'"):
        simulate("falling_rod", solver="magic", t_end=0.01)
    with pytest.raises(ValueError,
                       match="formulation must be one of 'position', 'fixed_point', 'velocity', got 'implicit'"):
        simulate("falling_rod", formulation="implicit", t_end=0.01)
    with pytest.raises(ValueError, match="h must be > 0, got -0.1"):
        simulate("falling_rod", h=-0.1)
    with pytest.raises(ValueError, match="on_failure must be 'raise' or 'record'"):
        simulate("falling_rod", on_failure="ignore")


# --- the osqp relaxation ---------------------------------------------------------------------------------------

def test_osqp_relaxation_separates_while_sliding_and_lemke_does_not():
    """Anitescu's convex relaxation replaces n.v+ + phi/h = 0 by = mu lambda while sliding: a box sliding on the
    table lifts off at mu |v_t| per unit time (documented artefact). Lemke's complementarity keeps it on the table."""
    mu, v0, h = 0.4, 2.0, 0.001
    sc = scene([{"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.05], "velocity": [v0, 0.0],
                 "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}, table()], friction=mu, h=h, t_end=0.05)
    lem = simulate(sc, solver="lemke")
    qp = simulate(sc, solver="osqp")
    np.testing.assert_allclose(lem.q[:, 0, 1], 0.05, atol=1e-12)
    # first step: the relaxation's normal velocity is mu times the sliding speed (to OSQP's tolerance)
    vt = qp.v[1, 0, 0]
    assert qp.v[1, 0, 1] == pytest.approx(mu * vt, rel=1e-4)
    assert qp.q[:, 0, 1].max() > 0.05 + 0.5 * mu * vt * h


def test_osqp_matches_lemke_without_sliding():
    """A box resting on a table (no sliding, no impact): both solve the same problem exactly."""
    sc = scene([{"name": "box", "type": "dynamic", "mass": 2.0, "position": [0.3, 0.05],
                 "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}, table()], h=0.005, t_end=0.1)
    lem, qp = simulate(sc, solver="lemke"), simulate(sc, solver="osqp")
    np.testing.assert_allclose(qp.q, lem.q, atol=1e-9)
    np.testing.assert_allclose(qp.contacts["cn"], lem.contacts["cn"], atol=1e-8)


# --- scenes that cannot start --------------------------------------------------------------------------------------

def test_bodies_interpenetrating_at_the_start_are_rejected():
    from planar_lcp.spec.scene import SceneError
    sc = scene([{"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.04],
                 "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}, table()])
    with pytest.raises(SceneError, match=r"<dict>: bodies\[0\]\.shapes\[0\] \('box'\) and bodies\[1\]\.shapes\[0\] "
                                         r"\('table'\) must not overlap at the start by more than 1e-06 m, got an "
                                         r"overlap of 0\.01 m"):
        simulate(sc)
    # touching (gap 0) and a sub-tolerance overlap are accepted
    simulate(scene([{"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.05 - 5e-7],
                     "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]}, table()], t_end=0.01))
    two = [{"name": f"d{i}", "type": "dynamic", "mass": 1.0, "position": [0.15 * i, 0.5],
            "shapes": [{"type": "disk", "radius": 0.1}]} for i in range(2)]
    with pytest.raises(SceneError, match=r"bodies\[0\]\.shapes\[0\] \('d0'\) and bodies\[1\]\.shapes\[0\] \('d1'\) "
                                         r".*got an overlap of 0\.05 m"):
        simulate(scene(two))


def test_seed_friction_arm_puts_the_friction_moment_arm_at_the_end_cap_centre():
    """Stewart & Trinkle's rod: d = [+-1, 0, +-(l/2) sin theta], i.e. friction applied at the end-cap centre. Our default
    applies it at the contact point (r lower still); seed_friction_arm reproduces Stewart & Trinkle's for comparison."""
    from planar_lcp.model import compile_scene
    from planar_lcp.spec.scene import load_scene
    from planar_lcp.sim import SimOptions, Simulator
    sc = load_scene("falling_rod")
    for seed_arm, extra in ((True, 0.0), (False, 0.05)):
        sim = Simulator(compile_scene(sc, seed_friction_arm=seed_arm), SimOptions(h=sc.sim.h))
        q, v, qk, vk = sim.initial_state()
        out = sim.rollout(q, v, qk, vk[None], 153)       # the step of first contact is the 154th
        q, v = out["q"][153], out["v"][153]
        sim.step(q, v, qk, vk)
        w = sim.work
        assert sim.stats[Stat.N_CONTACTS] == 1            # one contact: the lower cap
        theta = q[0, 2] + sim.h * v[0, 2]                 # linearization pose q + h v
        nci = 1
        # friction column +t = (1, 0) on the table (n = (0, 1) gives t = (-1, 0); the first ray is -x): torque
        # about the COM of a horizontal unit impulse at height y below the COM is +y for d = -x
        # the contact point is the midpoint of the witness points: phi/2 above the cap's lowest point
        arm_y = 0.25 * abs(np.sin(theta)) + (extra + 0.5 * w.con_phi[0] if extra else 0.0)
        assert w.column_g[nci, 0, 0] == pytest.approx(-1.0)
        assert w.column_g[nci, 0, 2] == pytest.approx(-arm_y, rel=1e-9, abs=1e-12)


def test_nearly_degenerate_flat_rod_lcp_false_ray_and_its_certified_solutions():
    """Regression: the rod lying flat has two contacts whose friction columns differ only by round-off-sized lever
    arms. In this phase-shifted run Lemke as assembled (piv_tol 1e-9, the time-stepper's first try) pivots on a 3e-7
    entry of step 108's LCP and ends on a false ray (residual 0.36); Lemke on the equilibrated problem (the chain's
    second method) solves it, as does the stricter pivot tolerance of its third. The LCP is the kernel's own assembly
    of that step. With the (optional) warm start, the previous step's basis solves it without Lemke."""
    from planar_lcp import lemke
    from planar_lcp.spec.scene import load_scene
    from planar_lcp.studies.common import shift_scene
    sc = shift_scene(load_scene("falling_rod"), 0.017148085531751386)
    tr = simulate(sc, h=0.005)   # raises on failure
    assert tr.stats["solved_equilibrated"][108] == 1 and tr.stats["lemke_retries"][108] == 1
    assert tr.stats["residual"][108] <= 1e-9 * 40
    sim = Simulator(compile_scene(sc), SimOptions(h=0.005))
    q, v, qk, vk = sim.initial_state()
    out = sim.rollout(q, v, qk, vk[None], 108)
    sim.step(out["q"][108], out["v"][108], out["qk"][108], vk)
    n = int(sim.stats[Stat.LCP_SIZE])
    A, b = sim.work.lcp_matrix[:n * n].reshape(n, n).copy(), sim.work.lcp_vector[:n].copy()
    assert lemke(A, b).status == "ray_termination"
    for r in (lemke(A, b, equilibrate=True), lemke(A, b, piv_tol=1e-6)):
        assert r.status == "solved"
        w = A @ r.z + b
        assert r.z.min() >= 0 and w.min() >= -1e-12 and np.abs(r.z * w).max() <= 1e-12
    tr = simulate(sc, h=0.005, warm_start=True)
    assert tr.stats["warm_starts"][108] >= 1 and tr.stats["lemke_retries"][108] == 0
    assert tr.stats["residual"][108] <= 1e-9 * 40


def test_contact_mode_agrees_with_the_lcp_at_impact():
    """The rod's impact step: the LCP's friction is inside the cone (|f_t| < mu c_n), so the contact sticks; the
    reported slip is measured with the LCP's own geometry and is zero to round-off."""
    tr = simulate("falling_rod")
    c = tr.contacts
    k = int(np.argmax(c["count"] > 0))
    assert c["cn"][k, 0] > 0 and abs(c["ft"][k, 0]) < 0.6 * c["cn"][k, 0]
    assert c["mode"][k, 0] == 1 and abs(c["vt"][k, 0]) < 1e-12
    assert set(c) >= {"count", "pair", "phi", "normal", "point", "cn", "ft", "vt", "mode", "shape_pairs"}
    # sliding contacts do slide: the box sliding down the incline
    inc = simulate("block_on_incline")
    sliding = inc.contacts["mode"][10:, :2]
    assert np.all(sliding == 2) and np.all(np.abs(inc.contacts["vt"][10:, :2]) > 1e-3)
