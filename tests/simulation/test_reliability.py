"""Reliability on scenes nobody wrote by hand: seeded random scenes (planar_lcp.spec.random_scenes), each run with the
three formulations under the defaults (on_failure="raise"). Required: no aborted run, no non-finite state, a bounded
final penetration, and every island answer certified (no uncertified PGS fallback). A failing seed prints its scene
as TOML, to be saved as a regression case.

And what cannot be solved is reported as such: a kinematic pusher driving a box into a wall has no rigid-body
solution (the pusher has no force limit), and the run stops with that cause, certified (planar_lcp.infeasibility).
The jam set (`jam_scene`: a pusher, one or two objects, a block in the path) is the generator's scenes where
that happens: each run is solved or certified to have no rigid solution, none is left unclassified.
"""

import numpy as np
import pytest

from planar_lcp.spec.random_scenes import jam_scene, random_scene, scene_to_toml
from planar_lcp.spec.scene import FORMULATIONS, load_scene, parse_scene
from planar_lcp.model import compile_scene
from planar_lcp.sim import NoRigidSolution, SimulationError, simulate
from planar_lcp.trajectory import energy_changes

N_SCENES = 200
# Deepest overlap at the end of a run, m: every body has settled or is in flight by then, and each formulation
# corrects penetration (the position forms through phi/h in the LCP, the velocity form by its projection). The
# largest measured on this set is 2.4 mm (position form, a 12-body pile still moving at t_end).
FINAL_PENETRATION_BOUND = 5e-3
# Largest one-step energy gain on the vertical-plane scenes, relative to the run's initial energy E0 (ground as the
# datum): the bounds docs/method.md states, each above the largest measured (python examples/measurements/random_scene_scan.py).
# position 4.17 and fixed_point 0.51 (seeds 36 and 42: a body that moves more than its own size in one step is
# linearized at a pose it never reaches); velocity 2.5e-3, all of it the projection's potential energy: its contact
# impulses never add kinetic energy.
ENERGY_GAIN_BOUND = {"position": 5.0, "fixed_point": 1.0, "velocity": 5e-3}
IMPULSE_KE_GAIN_BOUND_VELOCITY = 1e-12
# The same with e = 0.5 on every pair (python examples/measurements/restitution_measures.py, part 5): position 0.41 (seed 133),
# fixed_point 0.10 (seed 135), velocity 0.052 (seed 127). The velocity form's is friction's: a Newton impact with
# friction can gain kinetic energy (docs/method.md, "Restitution"); with the friction set to 0 that seed gains
# nothing. Its energy never rises above E0.
ENERGY_GAIN_BOUND_RESTITUTION = {"position": 5.0, "fixed_point": 1.0, "velocity": 0.1}


@pytest.mark.parametrize("seed", range(N_SCENES))
def test_random_scene_runs_to_the_end_certified(seed):
    data = random_scene(seed)
    sc = parse_scene(data, f"<random scene {data['name']}>")
    model = compile_scene(sc)
    for formulation in FORMULATIONS:
        try:
            tr = simulate(sc, formulation=formulation)
        except SimulationError as e:
            pytest.fail(f"formulation {formulation!r}: {e}\nscene (save as a .toml regression case):\n"
                        f"{scene_to_toml(data)}")
        where = f"seed {seed}, formulation {formulation!r}\n{scene_to_toml(data)}"
        assert np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v)), where
        assert tr.stats["pgs_uncertified"].sum() == 0 and not tr.failures, where
        assert tr.stats["penetration"][-1] <= FINAL_PENETRATION_BOUND, where
        # every step that had an LCP was solved by certified methods (none uncertified: checked above)
        solved = sum(tr.stats[k] for k in ("warm_starts", "solved_lemke", "solved_equilibrated", "solved_strict",
                                           "solved_velocity", "solved_inelastic"))
        assert np.all((solved > 0) == (tr.stats["lcp_size"] > 0)), where
        if data["world"]["plane"] == "vertical":
            e0 = tr.stats["energy"][0]
            assert e0 > 0, where
            total, impulses, projection = (x / e0 for x in energy_changes(model, tr.q_com, tr.v_com, sc.sim.h))
            assert total.max() <= ENERGY_GAIN_BOUND[formulation], where
            if formulation == "velocity":
                assert impulses.max() <= IMPULSE_KE_GAIN_BOUND_VELOCITY, where
            else:
                assert np.abs(projection).max() <= 1e-9, where      # q+ = q + h v+: no position change beyond it


@pytest.mark.parametrize("seed", range(N_SCENES))
def test_random_scene_with_restitution_runs_to_the_end_certified(seed):
    """The same scenes with e = 0.5 on every pair: no aborted run, every island certified, the same final-penetration
    and energy bounds. Where Newton's law has no solution (a simultaneous impact asking a body to leave two contacts
    it cannot leave at once) the island is solved inelastically and counted (solved_inelastic; docs/method.md)."""
    data = random_scene(seed)
    sc = parse_scene(data, f"<random scene {data['name']}>")
    model = compile_scene(sc)
    for formulation in FORMULATIONS:
        where = f"seed {seed}, formulation {formulation!r}, restitution 0.5\n{scene_to_toml(data)}"
        try:
            tr = simulate(sc, formulation=formulation, restitution=0.5)
        except SimulationError as e:
            pytest.fail(f"{e}\n{where}")
        assert np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v)), where
        assert tr.stats["pgs_uncertified"].sum() == 0 and not tr.failures, where
        assert tr.stats["penetration"][-1] <= FINAL_PENETRATION_BOUND, where
        if data["world"]["plane"] == "vertical":
            e0 = tr.stats["energy"][0]
            total = energy_changes(model, tr.q_com, tr.v_com, sc.sim.h)[0] / e0
            assert total.max() <= ENERGY_GAIN_BOUND_RESTITUTION[formulation], where
            if formulation == "velocity":
                assert tr.stats["energy"].max() <= e0 * (1 + 1e-12), where


def test_restitution_that_cannot_hold_falls_back_to_inelastic_and_counts_it():
    """Seed 4's position-form run at e = 0.5 meets islands whose elastic LCP has no certified answer (Lemke ends on a
    ray in every form): they are solved with e = 0, counted, and the run completes."""
    sc = parse_scene(random_scene(4), "<random scene 4>")
    tr = simulate(sc, formulation="position", restitution=0.5)
    assert tr.stats["solved_inelastic"].sum() > 0 and not tr.failures
    assert simulate(sc, formulation="position").stats["solved_inelastic"].sum() == 0


def test_the_velocity_forms_gain_with_restitution_is_frictions():
    """Seed 127 has the velocity form's largest one-step gain at e = 0.5 (0.052 E0). Without friction the same run's
    impulses add no kinetic energy: the gain is a Newton impact's with friction (docs/method.md, "Restitution")."""
    data = random_scene(127)
    world = dict(data["world"], friction=0.0,
                 friction_pairs=[dict(p, mu=0.0) for p in data["world"].get("friction_pairs", [])])
    for frictionless, bound in ((False, None), (True, 1e-12)):
        sc = parse_scene(dict(data, world=world) if frictionless else data, "<random scene 127>")
        tr = simulate(sc, formulation="velocity", restitution=0.5)
        impulses = energy_changes(compile_scene(sc), tr.q_com, tr.v_com, sc.sim.h)[1] / tr.stats["energy"][0]
        if bound is None:
            assert impulses.max() > 0.04
        else:
            assert impulses.max() <= bound


def test_the_random_scenes_are_reproducible_and_valid_toml(tmp_path):
    for seed in (0, 1, 57):
        a, b = random_scene(seed), random_scene(seed)
        assert a == b
        path = tmp_path / f"s{seed}.toml"
        path.write_text(scene_to_toml(a))
        assert load_scene(path) == parse_scene(a, str(path))
    kinds = {random_scene(s)["world"]["plane"] for s in range(20)}
    assert kinds == {"vertical", "horizontal"}


def test_the_random_set_covers_what_the_issue_asks_for():
    """Both planes, mass ratios up to 1e5 within a scene, friction up to 5, speeds up to 20 m/s, pushers, walls."""
    ratio, mu, speed, pushers, walls, planes = 0.0, 0.0, 0.0, 0, 0, set()
    for s in range(N_SCENES):
        d = random_scene(s)
        planes.add(d["world"]["plane"])
        masses = [b["mass"] for b in d["bodies"] if b["type"] == "dynamic"]
        ratio = max(ratio, max(masses) / min(masses))
        mu = max(mu, d["world"]["friction"], *(b.get("support_friction", 0.0) for b in d["bodies"]))
        speed = max(speed, *(np.hypot(*b.get("velocity", (0.0, 0.0))) for b in d["bodies"]))
        pushers += any(b["type"] == "kinematic" for b in d["bodies"])
        walls += any(b["name"] in ("walls", "rails") for b in d["bodies"])
    assert planes == {"vertical", "horizontal"}
    assert ratio > 1e4 and mu > 4.5 and speed > 18.0 and pushers >= 30 and walls >= 100


JAM = {
    "name": "jam", "world": {"plane": "horizontal", "friction": 0.0}, "sim": {"h": 0.01, "t_end": 0.5},
    "bodies": [
        {"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.0], "support_friction": 0.3,
         "shapes": [{"type": "box", "width": 0.2, "height": 0.2}]},
        {"name": "pusher", "type": "kinematic", "position": [-0.15, 0.0], "velocity": [0.2, 0.0],
         "shapes": [{"type": "disk", "radius": 0.05}]},
        {"name": "wall", "type": "static", "shapes": [{"type": "box", "width": 0.1, "height": 1.0,
                                                       "offset": [0.16, 0.0]}]},
    ],
}


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_a_pusher_crushing_a_box_into_a_wall_is_reported_not_solved(formulation):
    """Head-on, frictionless: the pusher's contact needs n.v >= 0.2 m/s into the wall, the wall's n.v <= 0 (opposite
    normals): no velocity satisfies both, so the LCP has no solution and no method can certify one. The run stops
    at the step the box reaches the wall (0.01 m of travel at 0.2 m/s: t = 0.05 s), with the cause."""
    pytest.importorskip("scipy")
    with pytest.raises(NoRigidSolution) as e:
        simulate(parse_scene(JAM, "<jam>"), formulation=formulation)
    msg = str(e.value)
    assert "no rigid solution: kinematic body 'pusher' drives 'box' into static body 'wall' (certified" in msg
    assert set(e.value.diagnosis.bodies) == {"pusher", "box", "wall"} and e.value.diagnosis.impulse_bound > 1e6
    t = float(msg.split("t = ")[1].split(" s")[0])
    assert 0.04 <= t <= 0.07
    tr = simulate(parse_scene(JAM, "<jam>"), formulation=formulation, on_failure="record")
    assert tr.failures
    assert set(np.flatnonzero(tr.stats["pgs_uncertified"] > 0)) == {i for i, _, _ in tr.failures}
    # Trajectory.stats counts the failures by kind: here every one is certified
    assert tr.stats["certified_infeasible"].sum() == len(tr.failures) and tr.stats["unclassified"].sum() == 0


N_JAMS = 60


@pytest.mark.parametrize("seed", range(N_JAMS))
def test_a_jam_scene_is_solved_or_certified_to_have_no_rigid_solution(seed):
    """Each run of the jam set, in every formulation, goes to its end or stops at a step whose contact LCP
    is certified to have no solution (NoRigidSolution, naming the pusher and the block); a SimulationError of any
    other kind (a failure without a certificate) fails the test."""
    pytest.importorskip("scipy")
    data = jam_scene(seed)
    sc = parse_scene(data, f"<jam scene {data['name']}>")
    for formulation in FORMULATIONS:
        try:
            tr = simulate(sc, formulation=formulation)
        except NoRigidSolution as e:
            assert {"pusher", "block"} <= set(e.diagnosis.bodies), (formulation, str(e))
            continue
        except SimulationError as e:
            pytest.fail(f"formulation {formulation!r}: {e}\nscene:\n{scene_to_toml(data)}")
        assert not tr.failures and tr.stats["certified_infeasible"].sum() == 0 and tr.stats["unclassified"].sum() == 0


def test_the_jam_set_has_both_outcomes():
    """The set measures something: some of its runs jam (certified), others are solved (the object slides past)."""
    pytest.importorskip("scipy")
    outcomes = {"solved": 0, "certified infeasible": 0}
    for seed in range(N_JAMS):
        try:
            simulate(parse_scene(jam_scene(seed)))
            outcomes["solved"] += 1
        except NoRigidSolution:
            outcomes["certified infeasible"] += 1
    assert outcomes["solved"] >= 10 and outcomes["certified infeasible"] >= 10, outcomes


@pytest.mark.parametrize("max_force", [0.1, 10.0, 1e4])
def test_every_jam_scene_runs_to_its_end_with_a_force_limited_pusher(max_force):
    """The jam set with its pusher force-limited (a velocity servo): every run of every formulation goes to
    its end, certified (no failed step), and the limit is reached in some of them: the servo's LCP has an answer
    where the prescribed pusher's has none."""
    limited = 0
    for seed in range(N_JAMS):
        data = jam_scene(seed)
        for b in data["bodies"]:
            if b["name"] == "pusher":
                b["max_force"] = max_force
        sc = parse_scene(data, f"<jam scene {data['name']}>")
        for formulation in FORMULATIONS:
            try:
                tr = simulate(sc, formulation=formulation)
            except SimulationError as e:
                pytest.fail(f"max_force {max_force}, formulation {formulation!r}: {e}\n{scene_to_toml(data)}")
            assert tr.stats["pgs_uncertified"].sum() == 0
            limited += tr.stats["servo_limited"].sum() > 0
    assert limited >= 30, limited


def test_a_rollouts_derivatives_stop_at_the_jam_naming_the_step():
    """rollout_derivatives over the jam: the step the box reaches the wall has no certified LCP answer, and the chain
    stops there with a SimulationError (a RuntimeError) naming the step and its time, by either method."""
    from planar_lcp.model import compile_scene
    from planar_lcp.sim import SimOptions, Simulator
    sc = parse_scene(JAM, "<jam>")
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
    q, v, qk, _ = sim.initial_state()
    vk = np.array([[[0.2, 0.0, 0.0]]])
    for method in ("differences", "dual"):
        with pytest.raises(SimulationError, match=r"rollout_derivatives: step 5 \(t = 0\.05 s\) failed: no certified "
                                                  r"LCP answer"):
            sim.rollout_derivatives(q, v, qk, vk, 10, method=method)
