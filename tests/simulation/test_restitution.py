"""Restitution: Newton's impact law at the velocity level, checked against analytic mechanics.

The model (docs/method.md, "Restitution"): a contact that free motion would close within the step (its row's constant
b < 0) and that was approaching at the start of the step (v_n- < 0, start-of-step velocities) leaves with
n.v+ >= -e v_n-, in the same LCP as the gap and friction rows.

A disk dropped on the table, step by step (semi-implicit Euler: v' = v - g h, y' = y + h v'): free flight keeps
I = v^2/2 + g y - g h v / 2 exactly, so the apex height of a flight is I/g up to g h^2 (the sampled apex). A bounce
starts a step at height phi >= 0 above the table with speed V and ends it at height phi + h e V with speed e V, so

    H_{k+1} - e^2 H_k = (1 - e^2) phi + e (1 - e) h V / 2,   0 <= phi < h (V + g h)

up to the two apexes' sampling (2 g h^2): every bounce is at least e^2 of the previous one and at most that plus
h V ((1 - e^2) + e (1 - e) / 2) + 2 g h^2 higher. That is the expected O(h) excess, with its constant derived.
"""

import dataclasses

import numpy as np
import pytest

from cli_helpers import run_cli
from planar_lcp.model import compile_scene
from planar_lcp.sim import simulate
from planar_lcp.spec.scene import load_scene, parse_scene

G = 9.81
FORMULATIONS = ("position", "fixed_point", "velocity")
TABLE = {"name": "table", "type": "static", "shapes": [{"type": "halfplane", "point": [0, 0], "normal": [0, 1]}]}
RADIUS = 0.1


def drop_scene(e, h, t_end, formulation="position", mu=0.5, height=1.0):
    """A 1 kg disk of radius 0.1 m whose bottom is `height` above the table, at rest."""
    return parse_scene({
        "name": "drop", "world": {"plane": "vertical", "friction": mu, "restitution": e},
        "sim": {"h": h, "t_end": t_end, "formulation": formulation},
        "bodies": [{"name": "ball", "type": "dynamic", "mass": 1.0, "position": [0.0, height + RADIUS],
                    "shapes": [{"type": "disk", "radius": RADIUS}]}, TABLE]})


def bounces(traj):
    """(impact steps k: v_y(k) < 0 < v_y(k+1); the apex height before each impact and after the last one)."""
    y = traj.q[:, 0, 1] - RADIUS
    vy = traj.v[:, 0, 1]
    impacts = [k for k in range(len(vy) - 1) if vy[k] < 0.0 and vy[k + 1] > 1e-9]
    ends = [0] + impacts + [len(y) - 1]
    apex = [float(y[a:b + 1].max()) for a, b in zip(ends[:-1], ends[1:])]
    return impacts, apex


def kinetic(model, v_com):
    a = model.arrays
    return 0.5 * (a.dyn_mass * (v_com[..., 0] ** 2 + v_com[..., 1] ** 2) + a.dyn_inertia * v_com[..., 2] ** 2)


@pytest.mark.parametrize("formulation", FORMULATIONS)
@pytest.mark.parametrize("e", [0.5, 0.8])
def test_a_dropped_disk_bounces_to_e_squared_of_the_previous_height_bounce_after_bounce(e, formulation):
    h = 1e-3
    tr = simulate(drop_scene(e, h, 3.0, formulation))
    impacts, apex = bounces(tr)
    speed = -tr.v[impacts, 0, 1]
    assert len(impacts) >= 6                 # e = 0.8: six impacts in 3 s; every one of them is checked
    for k in range(len(impacts)):
        excess = apex[k + 1] - e ** 2 * apex[k]
        bound = h * speed[k] * ((1 - e ** 2) + e * (1 - e) / 2) + 2 * G * h ** 2
        assert -2 * G * h ** 2 <= excess <= bound, (k, apex[k], apex[k + 1], excess, bound)
    # the first bounce: within 1 % of e^2 at this step
    assert abs(apex[1] / apex[0] - e ** 2) < 0.01 * e ** 2


def rest_time(traj, tol=1e-9):
    """The first time from which the disk's vertical speed stays below tol."""
    moving = np.flatnonzero(np.abs(traj.v[:, 0, 1]) > tol)
    return traj.t[moving[-1] + 1]


def test_the_bounces_accumulate_to_t_inf_at_first_order_and_the_disk_rests_without_jitter():
    """t_inf = t_0 (1 + e) / (1 - e) after the first impact at t_0 = sqrt(2 H / g). Every discrete bounce is a
    little higher than e^2 of the one before (module docstring), so the disk comes to rest late, by O(h): a quarter
    of the step gives about a quarter of the delay."""
    e = 0.5
    t_inf = np.sqrt(2 * 1.0 / G) * (1 + e) / (1 - e)
    delays = {}
    for h in (2e-3, 5e-4):
        tr = simulate(drop_scene(e, h, t_inf + 0.8))
        t_rest = rest_time(tr)
        delays[h] = t_rest - t_inf
        after = tr.t >= t_rest
        assert tr.t[-1] - t_rest > 0.5                          # at rest for the last half second at least
        assert np.abs(tr.v[after, 0]).max() <= 1e-9             # no jitter: speed and spin
        assert np.abs(tr.v[tr.t >= tr.t[-1] - 0.25, 0]).max() <= 1e-12    # and it settles to round-off
        assert np.abs(tr.q[after, 0, 1] - RADIUS).max() <= 1e-9   # on the table, not above it or in it
    assert 0.0 < delays[2e-3]
    assert 0.1 < delays[5e-4] / delays[2e-3] < 0.4, delays


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_elastic_frictionless_impacts_keep_kinetic_energy_to_round_off(formulation):
    """e = 1, mu = 0: every contact with an impulse obeys v_n+ = -v_n-, so dKE = sum c (v_n- + v_n+) / 2 = 0."""
    # the disk on the table: kinetic energy after each impact step = before it
    tr = simulate(drop_scene(1.0, 1e-3, 2.0, formulation, mu=0.0))
    impacts, _ = bounces(tr)
    assert len(impacts) == 2
    vy = tr.v[:, 0, 1]
    for k in impacts:
        assert vy[k + 1] ** 2 == pytest.approx(vy[k] ** 2, rel=1e-13)
    # rods at random angles and spins, a box landing flat (two contacts at once), two disks colliding obliquely, a disk
    # struck by a kinematic pusher: no gravity, one step through each impact
    tr, model = run_one_step(impact_bodies(np.random.default_rng(4), 20), 1.0, 0.0, formulation)
    ke = kinetic(model, tr.v_com)
    names = list(tr.body_names)
    left, right, struck = (names.index(n) for n in ("left", "right", "struck"))
    alone = [d for d in range(len(names)) if d not in (left, right, struck)]   # the rods and the box
    assert np.abs(ke[1, alone] - ke[0, alone]).max() <= 1e-12 * ke[0].max()
    pair = ke[:, left] + ke[:, right]                                           # the two disks exchange energy
    assert pair[1] == pytest.approx(pair[0], rel=1e-12) and abs(ke[1, left] - ke[0, left]) > 0.1
    assert tr.stats["n_contacts"][0] >= 20 + 2 + 2 + 1 + 1                      # every body was in an impact
    # the pusher does work: elastic in its frame, the struck disk leaves at twice its speed
    assert tr.v[1, struck, 0] == pytest.approx(2 * PUSHER_SPEED, rel=1e-12)


PUSHER_SPEED = 0.7


def impact_bodies(rng, nrods, h=1e-3):
    """Bodies that each meet the table (or each other, or the pusher) within the first step, spread along x so that
    each impact is its own island: nrods capsules with random angle, velocity and spin; a flat rod; a box falling flat;
    two disks colliding obliquely; a disk struck by a kinematic pusher."""
    bodies = []
    for i in range(nrods):
        th = rng.uniform(-np.pi / 2, np.pi / 2)
        vy = -rng.uniform(0.5, 3.0)
        low = abs(0.25 * np.sin(th)) + 0.02
        bodies.append({"name": f"rod{i}", "type": "dynamic", "mass": 1.0, "position": [3.0 * i, low + 0.3 * h * -vy],
                       "angle": th, "velocity": [rng.uniform(-2, 2), vy], "angular_velocity": rng.uniform(-10, 10),
                       "shapes": [{"type": "capsule", "length": 0.5, "radius": 0.02}]})
    x = 3.0 * nrods
    # a nearly flat rod spinning as it lands: the impact at its near end drives its far end into the table within the
    # step (a contact that takes an impulse without being an impact)
    bodies.append({"name": "flat_rod", "type": "dynamic", "mass": 1.0, "position": [x, 0.022194986346144488],
                   "angle": -0.006699135990373639, "velocity": [0.0009047573949834131, -1.734049584890287],
                   "angular_velocity": 9.171645722184945,
                   "shapes": [{"type": "capsule", "length": 0.5, "radius": 0.02}]})
    x += 3.0
    bodies.append({"name": "box", "type": "dynamic", "mass": 2.0, "position": [x, 0.1 + 0.5 * h],
                   "velocity": [0.3, -1.0], "shapes": [{"type": "box", "width": 0.4, "height": 0.2}]})
    # centres 0.2 + 0.3 h apart along 30 degrees, closing at 1.5 cos(30 deg) along it
    sep = (0.2 + 0.3 * h) * np.array([np.cos(np.pi / 6), np.sin(np.pi / 6)])
    bodies += [{"name": "left", "type": "dynamic", "mass": 1.0, "position": [x + 3.0, 1.0], "velocity": [1.0, 0.0],
                "shapes": [{"type": "disk", "radius": 0.1}]},
               {"name": "right", "type": "dynamic", "mass": 3.0, "position": [x + 3.0 + sep[0], 1.0 + sep[1]],
                "velocity": [-0.5, 0.0], "shapes": [{"type": "disk", "radius": 0.1}]}]
    bodies += [{"name": "struck", "type": "dynamic", "mass": 1.0, "position": [x + 6.0, 1.0],
                "shapes": [{"type": "disk", "radius": 0.1}]},
               {"name": "pusher", "type": "kinematic", "position": [x + 6.0 - 0.2 - 0.5 * h * PUSHER_SPEED, 1.0],
                "velocity": [PUSHER_SPEED, 0.0], "shapes": [{"type": "disk", "radius": 0.1}]}]
    return bodies


def run_one_step(bodies, e, mu, formulation, h=1e-3):
    scene = parse_scene({"name": "impacts", "world": {"plane": "vertical", "gravity": [0.0, 0.0], "friction": mu,
                                                      "restitution": e},
                         "sim": {"h": h, "t_end": 2 * h, "formulation": formulation}, "bodies": bodies + [TABLE]})
    tr = simulate(scene)
    return tr, compile_scene(scene)


def contact_velocities(tr, model, k, v_com, formulation):
    """Normal and tangential relative velocities (A minus B) at the contacts of step k for body velocities v_com
    (ndyn, 3), with the step's contact geometry: at the linearization pose q + h v (position form) or at q
    (velocity form). Returns (body slot of A, u_n, u_t, c_n, f_t) per contact; B is the static table here."""
    a = model.arrays
    c = tr.contacts
    out = []
    for j in range(c["count"][k]):
        p = c["pair"][k, j]
        body = a.shape_body[a.pair_a[p]]
        d = a.body_slot[body]
        com = tr.q_com[k, d, :2] + (tr.options.h * tr.v_com[k, d, :2] if formulation == "position" else 0.0)
        r = c["point"][k, j] - com
        vel = v_com[d, :2] + v_com[d, 2] * np.array([-r[1], r[0]])
        n = c["normal"][k, j]
        out.append((d, vel @ n, vel @ np.array([-n[1], n[0]]), c["cn"][k, j], c["ft"][k, j]))
    return out


@pytest.mark.parametrize("formulation", ("position", "velocity"))
def test_no_frictionless_impact_gains_energy_and_frictional_ones_obey_the_stated_bound(formulation):
    """The impulse identity dKE = sum [c_n (v_n- + v_n+) + f_t (v_t- + v_t+)] / 2 over a step's contacts, with

    - an impact (free motion closes the contact, v_n- < 0): Newton's law v_n+ = -e v_n-, so c_n (v_n- + v_n+) =
      -(1 - e) c_n |v_n-|;
    - any other contact of an elastic pair that takes an impulse (open, the step's impacts drive it in): the weaker of
      the gap's row and the same law, v_n+ <= -e v_n-, so c_n (v_n- + v_n+) <= (1 - e) c_n v_n-;
    - friction: maximal dissipation, f_t v_t+ <= 0;

    gives   dKE <= sum [f_t v_t- + (1 - e) c_n v_n-] / 2 <= sum c_n (mu |v_t-| + (1 - e) v_n-) / 2.

    Without friction, Moreau's argument (c_n (v_n+ + e v_n-) = 0 at every contact, v+ - v- = W c) gives
    dKE = -(1 - e) / (1 + e) c.W c / 2 <= 0 when the law binds everywhere; measured here: no step gains. With friction
    a step gains only where the friction impulse points along the slip before the impact: the slip reverses during
    the impact, the contact's normal and tangent being coupled through the body's effective mass (a rod striking at an
    angle). That happens here, and is measured. e = 0 (Stewart & Trinkle's gap rows, v_n+ <= 0 where c_n > 0) never gains:
    dKE = c.v+ - c.W c / 2 <= 0."""
    rng = np.random.default_rng(11)
    gains = {}
    counts = {"impacts": 0, "others": 0}
    for e in (0.0, 0.5, 1.0):
        for mu in (0.0, 0.3, 1.0):
            # the rods and the box: contacts with the table only
            bodies = [b for b in impact_bodies(rng, 30) if b["name"].startswith(("rod", "flat_rod", "box"))]
            tr, model = run_one_step(bodies, e, mu, formulation)
            ke0, ke1 = kinetic(model, tr.v_com[0]), kinetic(model, tr.v_com[1])
            before = contact_velocities(tr, model, 0, tr.v_com[0], formulation)
            after = contact_velocities(tr, model, 0, tr.v_com[1], formulation)
            tight, loose, identity = (np.zeros(len(ke0)) for _ in range(3))
            for (d, un0, ut0, cn, ft), (_, un1, ut1, _, _) in zip(before, after):
                identity[d] += 0.5 * (cn * (un0 + un1) + ft * (ut0 + ut1))
                if cn <= 0.0:
                    continue
                assert ft * ut1 <= 1e-12                                     # maximal dissipation
                if e == 0.0:
                    assert un1 <= 1e-12                                      # the gap row closes the contact
                    continue
                if un0 < 0.0 and un1 == pytest.approx(-e * un0, abs=1e-12):   # Newton's law
                    counts["impacts"] += 1
                    tight[d] += 0.5 * (ft * ut0 - (1 - e) * cn * abs(un0))
                    loose[d] += 0.5 * cn * (mu * abs(ut0) - (1 - e) * abs(un0))
                else:                                                        # driven in: the law or the gap
                    assert un1 <= -e * un0 + 1e-12, (un0, un1)
                    counts["others"] += 1
                    tight[d] += 0.5 * (ft * ut0 + (1 - e) * cn * un0)
                    loose[d] += 0.5 * cn * (mu * abs(ut0) + (1 - e) * un0)
            dke = ke1 - ke0
            tol = 1e-12 * ke0.max()
            np.testing.assert_allclose(dke, identity, atol=tol, rtol=0)     # the geometry is the LCP's
            if e == 0.0 or mu == 0.0:
                assert np.all(dke <= tol)
            else:
                assert np.all(dke <= tight + tol) and np.all(tight <= loose + tol)
            gains[e, mu] = float((dke / ke0).max())
    assert counts["impacts"] > 100 and counts["others"] > 0, counts
    # elastic and frictional: rods do gain, by up to a third of their kinetic energy (the bound is needed)
    assert gains[1.0, 0.3] > 0.05 and gains[1.0, 1.0] > 0.05, gains


def test_disks_never_gain_energy_even_elastic_with_friction():
    """A disk's normal passes through its centre: normal and tangential impulses are decoupled, so friction cannot
    reverse the slip and f_t v_t- <= 0 at every impact: dKE <= -(1 - e) sum c_n |v_n-| / 2 <= 0."""
    rng = np.random.default_rng(5)
    bodies = [{"name": f"disk{i}", "type": "dynamic", "mass": 1.0, "position": [1.0 * i, 0.1 + 1e-4],
               "velocity": [rng.uniform(-3, 3), -rng.uniform(0.5, 3)], "angular_velocity": rng.uniform(-30, 30),
               "shapes": [{"type": "disk", "radius": 0.1}]} for i in range(40)]
    for e in (0.5, 1.0):
        for mu in (0.2, 1.0):
            tr, model = run_one_step(bodies, e, mu, "position")
            ke0, ke1 = kinetic(model, tr.v_com[0]), kinetic(model, tr.v_com[1])
            assert tr.stats["n_contacts"][0] == 40
            assert np.all(ke1 <= ke0 * (1 + 1e-13))


def row_scene(h, t_end, gap=1e-5, u=1.0):
    """Stewart & Trinkle's four balls on a line (section 4.2) without gravity or friction: a striker at speed u reaches the
    first of three disks 1e-5 apart within the first step; all disks 1 kg, radius 0.1, e = 1."""
    x0 = 0.2 + 0.5 * u * h
    bodies = [{"name": "striker", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.0], "velocity": [u, 0.0],
               "shapes": [{"type": "disk", "radius": 0.1}]}]
    bodies += [{"name": f"d{i + 1}", "type": "dynamic", "mass": 1.0, "position": [x0 + i * (0.2 + gap), 0.0],
                "shapes": [{"type": "disk", "radius": 0.1}]} for i in range(3)]
    return parse_scene({"name": "row", "world": {"plane": "vertical", "gravity": [0.0, 0.0], "friction": 0.0,
                                                 "restitution": 1.0},
                        "sim": {"h": h, "t_end": t_end}, "bodies": bodies})


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_a_struck_row_of_disks_takes_the_momentum_in_one_step(formulation):
    """h much longer than gap / u: the four impacts fall in one step and are simultaneous. The striker's contact is
    an impact (v_1 - v_0 = u, e = 1); the row's contacts were not approaching at the step's start, so they only close
    their gaps (v_{i+1} - v_i = -gap / h); with momentum u that is one linear system, solved here by numpy. The whole
    row moves after the one step, at about u / 2, and the striker rebounds at about -u / 2 (not Newton's cradle)."""
    h, gap, u = 0.0025, 1e-5, 1.0
    tr = simulate(row_scene(h, 2 * h), formulation=formulation)
    A = np.array([[-1, 1, 0, 0], [0, -1, 1, 0], [0, 0, -1, 1], [1, 1, 1, 1]], float)
    expected = np.linalg.solve(A, [u, -gap / h, -gap / h, u])
    np.testing.assert_allclose(tr.v[1, :, 0], expected, atol=1e-12)
    assert tr.v[1, 3, 0] > 0.49                                  # the last disk moves after the first step
    assert tr.v[1, :, 0].sum() == pytest.approx(u, abs=1e-13)    # momentum
    # kinetic energy: the row's plastic closing of its gaps costs (3/4) u gap / h, to first order in gap / h
    loss = 0.5 * u ** 2 - 0.5 * (tr.v[1, :, 0] ** 2).sum()
    assert loss == pytest.approx(0.75 * u * gap / h, rel=0.01)


def test_a_struck_row_of_disks_is_newtons_cradle_when_the_step_resolves_the_gaps():
    """h = gap / (10 u): each impact has steps of its own, and the momentum passes disk to disk as sequential elastic
    impacts pass it: the striker and the first two disks stop, the last leaves at u, kinetic energy kept."""
    h = 1e-6
    tr = simulate(row_scene(h, 1e-4))
    np.testing.assert_allclose(tr.v[-1, :, 0], [0.0, 0.0, 0.0, 1.0], atol=1e-9)
    assert 0.5 * (tr.v[-1, :, 0] ** 2).sum() == pytest.approx(0.5, rel=1e-12)


def test_the_four_disks_scene_passes_the_momentum_down_the_row_in_one_step():
    """The shipped four_disks scene (seed 4.2 in elevation: gravity, mu = 0.4; the thrown disk lands and rolls into
    the row) with e = 1 between the disks: in the step where the thrown disk first touches d1, the momentum reaches
    d3 at the end of the row."""
    scene = load_scene("four_disks")
    pairs = tuple((a, b, 1.0) for a, b in (("thrown", "d1"), ("d1", "d2"), ("d2", "d3")))
    scene = dataclasses.replace(scene, world=dataclasses.replace(scene.world, restitution_pairs=pairs))
    tr = simulate(scene, t_end=0.7)
    names = list(tr.body_names)
    d1, d3 = names.index("d1"), names.index("d3")
    k = int(np.argmax(tr.v[:, d1, 0] > 1e-6))
    assert k > 0 and tr.v[k - 1, d3, 0] == 0.0
    assert tr.v[k, d3, 0] > 0.4


def test_resting_contacts_stay_at_rest_with_restitution():
    """A stack of boxes resting on the table at e = 0.9: the contacts are closed, not approaching (beyond round-off),
    so nothing bounces: the trajectory is the inelastic one to round-off."""
    elastic = simulate("box_stack", restitution=0.9, t_end=1.0)
    inelastic = simulate("box_stack", t_end=1.0)
    np.testing.assert_allclose(elastic.q, inelastic.q, rtol=0, atol=1e-14)
    assert np.abs(elastic.v).max() < 1e-12


def test_restitution_pairs_override_the_world_value_per_pair():
    scene = parse_scene({
        "name": "pairs", "world": {"plane": "vertical", "friction": 0.5, "restitution": 0.0,
                                   "restitution_pairs": [{"a": "table", "b": "bouncy", "e": 0.8}]},
        "sim": {"h": 1e-3, "t_end": 1.3},
        "bodies": [{"name": "bouncy", "type": "dynamic", "mass": 1.0, "position": [0.0, 1.1],
                    "shapes": [{"type": "disk", "radius": RADIUS}]},
                   {"name": "dull", "type": "dynamic", "mass": 1.0, "position": [1.0, 1.1],
                    "shapes": [{"type": "disk", "radius": RADIUS}]}, TABLE]})
    tr = simulate(scene)
    bouncy, dull = (list(tr.body_names).index(n) for n in ("bouncy", "dull"))
    assert tr.v[:, bouncy, 1].max() > 0.8 * np.sqrt(2 * G * 1.0) * 0.99
    assert tr.v[:, dull, 1].max() < 1e-9
    # simulate(restitution=) replaces the world value and keeps the pair's
    tr = simulate(scene, restitution=0.5)
    assert tr.v[:, dull, 1].max() == pytest.approx(0.5 * tr.v[:, bouncy, 1].max() / 0.8, rel=0.01)


@pytest.mark.parametrize("name", ["falling_rod", "four_disks", "box_push"])
def test_zero_restitution_is_the_seed_model_bit_for_bit(name):
    """An explicit e = 0 (the keyword, the world key, a pair) takes the same path as no restitution at all."""
    scene = load_scene(name)
    base = simulate(scene, t_end=0.5)
    a, b = scene.bodies[0].name, scene.bodies[-1].name
    explicit = dataclasses.replace(scene, world=dataclasses.replace(scene.world, restitution=0.0,
                                                                      restitution_pairs=((a, b, 0.0),)))
    for tr in (simulate(scene, t_end=0.5, restitution=0.0), simulate(explicit, t_end=0.5)):
        np.testing.assert_array_equal(tr.q, base.q)
        np.testing.assert_array_equal(tr.v, base.v)


def test_simulate_command_takes_restitution_and_refuses_bad_values(tmp_path):
    csv = tmp_path / "bounce.csv"
    r = run_cli("simulate", "four_disks", "--restitution", "0.5", "--t-end", "0.7", "--csv", csv)
    assert r.returncode == 0, r.stderr
    assert csv.exists()
    for bad in ("1.5", "-0.1"):
        r = run_cli("simulate", "four_disks", "--restitution", bad)
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "--restitution" in lines[0] and "Traceback" not in r.stderr, r.stderr
    r = run_cli("simulate", "four_disks", "--restitution", "1.5")
    assert "must be in [0, 1], got 1.5" in r.stderr


def test_under_gravity_an_elastic_impact_takes_half_c_n_h_g_n_from_the_free_motion_energy():
    """With gravity the law compares n.v+ with the start-of-step v_n-, while the impulse acts on the free-motion
    velocity v~ = v- + h g: at e = 1 without friction, KE(v+) - KE(v~) = sum c_n (n.v~ + n.v+) / 2 = sum c_n h g.n / 2
    over the step's contacts (a loss, O(h); what energy_changes reports as the impulses' share). The falling rod's
    impacts, each in one step."""
    scene = load_scene("falling_rod")
    scene = dataclasses.replace(scene, world=dataclasses.replace(scene.world, friction=0.0))
    tr = simulate(scene, restitution=1.0, t_end=0.6)
    model = compile_scene(scene)
    h, g = tr.options.h, np.asarray(scene.world.gravity)
    c = tr.contacts
    checked = 0
    for k in range(len(tr.t) - 1):
        cn = c["cn"][k, :c["count"][k]]
        if not np.any(cn > 0.0) or (k > 0 and np.any(c["cn"][k - 1, :c["count"][k - 1]] > 0.0)):
            continue                                  # only a fresh impact: no impulse in the step before
        v_free = tr.v_com[k].copy()
        v_free[:, :2] += h * g
        dke = kinetic(model, tr.v_com[k + 1]).sum() - kinetic(model, v_free).sum()
        expected = 0.5 * h * float(np.sum(cn * (c["normal"][k, :c["count"][k]] @ g)))
        assert dke == pytest.approx(expected, rel=1e-9, abs=1e-12)
        checked += 1
    assert checked >= 3


@pytest.mark.parametrize("solver", ["pgs", "osqp"])
def test_every_solver_reads_the_impact_law(solver):
    """The law lives in the normal rows' constants, which PGS and OSQP assemble with the same code as Lemke: the
    disk's first impact reverses it by exactly e, and its bounces are Lemke's."""
    if solver == "osqp":
        pytest.importorskip("osqp")
    lemke = simulate(drop_scene(0.5, 1e-3, 1.2))
    other = simulate(drop_scene(0.5, 1e-3, 1.2), solver=solver)
    k = bounces(other)[0][0]
    assert other.v[k + 1, 0, 1] == pytest.approx(-0.5 * other.v[k, 0, 1], rel=1e-12)
    np.testing.assert_allclose(bounces(other)[1], bounces(lemke)[1], rtol=1e-9)
