"""Every shipped scene with every formulation and solver; rollout equals a loop of step bit for bit."""

import numpy as np
import pytest

from planar_lcp.model import compile_scene
from planar_lcp.spec.scene import FORMULATIONS, list_scenes, load_scene
from planar_lcp.sim import SimOptions, Simulator, simulate

SCENES = [name for name, _ in list_scenes()]


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("formulation", FORMULATIONS)
@pytest.mark.parametrize("solver", ["lemke", "pgs", "osqp"])
def test_every_scene_runs_with_every_formulation_and_solver(name, formulation, solver):
    tr = simulate(name, formulation=formulation, solver=solver)  # on_failure="raise": any failed step fails here
    assert np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v))
    assert np.all(tr.stats["status"] == 0)
    assert len(tr.t) == round(tr.scene.sim.t_end / tr.scene.sim.h) + 1
    if solver == "lemke" and (name, formulation) not in LINEARIZATION_LIMITED:
        # Lemke's answers are certified: penetration at the end of a step stays below the active-set tolerance
        # (position/velocity forms: linearization error; fixed point: converged)
        assert tr.stats["penetration"].max() <= 1e-6


#: scenes whose position form's linearization error exceeds 1e-6 m at their own h, with the test that shows it is
#: that error (it shrinks at least as h^2) and not a solver failure
LINEARIZATION_LIMITED = {("push_clutter", "position"), ("push_table", "position"), ("bin", "position"),
                         ("bin", "velocity")}


def _check_linearization_error(name):
    pen = [simulate(name, formulation="position", h=h).stats["penetration"].max() for h in (0.02, 0.01, 0.005)]
    assert pen[0] > 1e-6                       # the exemption above is needed, else drop it
    assert pen[0] / pen[1] >= 3.5 and pen[1] / pen[2] >= 3.5, pen
    assert simulate(name, formulation="fixed_point").stats["penetration"].max() <= 1e-12


def test_push_clutter_penetration_is_the_position_forms_linearization_error():
    """push_clutter at h = 0.02 s: the disk, pushed at 0.1 m/s, strikes the crate and spins it (0.043 rad in
    the step): linearized at the step's start pose, the new contact ends 4.2e-5 m deep (r theta^2 / 2 = 3.2e-5 for
    the crate's 35 mm half-diagonal). The error shrinks at least as fast as h^2 (measured: 4.2e-5, 9.9e-6, 1.3e-6 m
    at h = 0.02, 0.01, 0.005 s), and the fixed-point form, which re-linearizes, has none."""
    _check_linearization_error("push_clutter")


def test_push_table_penetration_is_the_position_forms_linearization_error():
    """push_table at h = 0.02 s, the same mechanism: the box, pushed at 0.1 m/s, shoves the disk into the crate at
    t = 1.38 s, which turns by 0.029 rad in the step; the new contact ends 4.7e-6 m deep. The error shrinks at least
    as fast as h^2 (measured: 4.7e-6, 7.7e-7, 6.3e-8 m at h = 0.02, 0.01, 0.005 s), and the fixed-point form has
    none."""
    _check_linearization_error("push_table")


def test_the_bins_penetration_stays_below_a_millimetre_at_its_step():
    """The bound for the bin (penetration <= 1 mm) at the scene's h = 1/240 s, in every formulation, and exact
    once the pile rests. At 1/60 s the position form linearizes at q + h v, where a falling box is 3 cm into the disk
    below it and their contact has another normal than at the step's end: 12.6 mm deep (measured: 0.33 mm at 1/240 s,
    2.1e-5 m in the velocity form, 5.8e-8 m in the fixed-point form; docs/performance.md, "Piles")."""
    for formulation in FORMULATIONS:
        pen = simulate("bin", formulation=formulation).stats["penetration"]
        assert pen.max() <= 1e-3 and pen[-1] <= 1e-6, (formulation, pen.max(), pen[-1])
    assert simulate("bin", h=1 / 60).stats["penetration"].max() > 1e-3      # why the bin steps at 1/240 s


@pytest.mark.parametrize("name", ["falling_rod", "box_push", "four_disks"])
@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_rollout_equals_a_python_loop_of_step_bit_for_bit(name, formulation):
    sc = load_scene(name)
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, formulation=formulation))
    q, v, qk, vk = sim.initial_state()
    n = 150
    # a time-varying control for kinematic bodies, to exercise vk_seq indexing
    vk_seq = np.stack([vk * (1.0 + 0.01 * i) for i in range(n)]) if sim.model.nkin else vk[None]
    out = sim.rollout(q, v, qk, vk_seq, n)
    for i in range(n):
        q, v, qk, st = sim.step(q, v, qk, vk_seq[min(i, len(vk_seq) - 1)])
        assert st == out["status"][i]
        assert np.array_equal(q, out["q"][i + 1]) and np.array_equal(v, out["v"][i + 1]), f"step {i}"
        assert np.array_equal(qk, out["qk"][i + 1])
    assert out["steps_done"] == n


def test_trajectory_reports_body_frame_poses_of_a_compound_body():
    """push_t's T has its centre of mass below the bar's centre (the body frame origin): q is the frame, q_com the
    centre of mass, and they differ by R(theta) com_local."""
    tr = simulate("push_t", t_end=0.2)
    m = compile_scene(load_scene("push_t"))
    com = m.com_local[0]
    assert com[1] < -1e-3 and abs(com[0]) < 1e-12
    c, s = np.cos(tr.q[:, 0, 2]), np.sin(tr.q[:, 0, 2])
    np.testing.assert_allclose(tr.q_com[:, 0, 0], tr.q[:, 0, 0] + c * com[0] - s * com[1], atol=1e-14)
    np.testing.assert_allclose(tr.q_com[:, 0, 1], tr.q[:, 0, 1] + s * com[0] + c * com[1], atol=1e-14)
    np.testing.assert_allclose(tr.q[0, 0], [0.0, 0.0, 0.0], atol=1e-15)


def test_csv_layout(tmp_path):
    tr = simulate("four_disks", t_end=0.05)
    path = tmp_path / "out.csv"
    tr.to_csv(path)
    lines = path.read_text().splitlines()
    cols = ["t"] + [f"{b}.{c}" for b in ("thrown", "d1", "d2", "d3")
                    for c in ("x", "y", "theta", "vx", "vy", "omega")]
    assert lines[0] == ",".join(cols)
    assert len(lines) == len(tr.t) + 1
    row = np.array(lines[1].split(","), dtype=float)
    assert row[0] == 0.0 and row[1] == 0.0 and row[2] == 1.0 and row[4] == 1.5
    last = np.array(lines[-1].split(","), dtype=float)
    np.testing.assert_array_equal(last[1:7], np.concatenate([tr.q[-1, 0], tr.v[-1, 0]]))


def test_every_lemke_run_takes_the_one_rollout_kernel():
    """No kernel depends on the scene or the options: every Lemke run (both planes, a pile, the velocity form, the warm
    start) takes `rollout_lemke`, solver pgs `rollout_pgs` (the compiled kernels' signatures: tests/compilation/test_compile_once.py)."""
    from planar_lcp.engine.rollout import rollout_lemke, rollout_pgs

    def kernel(name, **options):
        sc = load_scene(name)
        return Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, **options))._kernel
    assert kernel("falling_rod") is kernel("tower") is kernel("box_push", formulation="velocity") is rollout_lemke
    assert kernel("push_t", warm_start=True) is kernel("bin", sparse_min_unknowns=0) is rollout_lemke
    assert kernel("box_push", solver="pgs") is rollout_pgs


def test_simulate_compiles_a_scene_once_for_the_same_settings():
    """Set-up: `simulate` takes its model from `compiled_scene`, which remembers compile_scene's answer for a
    scene and its settings (a Model never changes after compile) and compiles again for other settings."""
    from planar_lcp.sim import compiled_scene
    sc = load_scene("box_push")
    m = compiled_scene(sc)
    assert compiled_scene(load_scene("box_push")) is m                 # an equal scene, read again
    assert compiled_scene(sc, support_model="points") is not m
    assert compiled_scene(sc, friction_directions=8) is not m
    tr = simulate(sc, t_end=0.05)
    assert np.array_equal(tr.q_com[0], m.q0)



@pytest.mark.parametrize("scene, options", [("box_push", {}), ("falling_rod", {"res_tol": 0.0}),
                                            ("box_tip", {"formulation": "fixed_point"}),
                                            ("push_t", {"warm_start": True})])
def test_simulate_keeps_its_simulators_and_a_kept_one_runs_as_a_new_one(scene, options):
    """Set-up: `simulate` gives its Simulator back for the next call with the same model and options.
    Whatever the kept one ran before (another length, failed steps handed to the fallback kernel with res_tol = 0,
    the warm start's memory), its next run equals a new Simulator's bit for bit, every output."""
    from planar_lcp import sim as S
    fails = {"on_failure": "record"} if options.get("res_tol") == 0.0 else {}
    S._idle_simulators.clear()
    fresh = simulate(scene, **options, **fails)                      # a new Simulator, kept afterwards
    assert len(S._idle_simulators) == 1
    kept, = S._idle_simulators.values()
    assert kept._chunk > 0
    simulate(scene, t_end=0.3 * float(fresh.t[-1]), **options, **fails)     # takes it, runs, gives it back
    assert list(S._idle_simulators.values()) == [kept]
    again = simulate(scene, **options, **fails)
    assert list(S._idle_simulators.values()) == [kept]
    for k in ("q", "v", "q_com", "v_com", "qk"):
        assert np.array_equal(getattr(fresh, k), getattr(again, k)), k
    for k, a in fresh.stats.items():
        assert np.array_equal(a, again.stats[k]), k
    for k in ("pair", "phi", "normal", "point", "cn", "ft", "vt", "mode"):
        assert np.array_equal(fresh.contacts[k], again.contacts[k]), k
    assert fresh.failures == again.failures and (not fails or fresh.failures)


def test_simulate_keeps_no_simulator_with_large_buffers_and_a_bounded_number():
    from planar_lcp import sim as S
    S._idle_simulators.clear()
    simulate("tower", t_end=0.05)
    assert not S._idle_simulators                                    # a tower's buffers: over IDLE_SIMULATOR_BYTES
    for i in range(S.IDLE_SIMULATORS + 3):
        simulate("falling_rod", t_end=0.01, contact_margin=1e-3 * (1 + i))   # another SimOptions each
    assert len(S._idle_simulators) == S.IDLE_SIMULATORS

def _same_run(tr, sc, nsteps, **options):
    """tr (a simulate() Trajectory) equals a fresh Simulator's rollout of sc with those options, bit for bit."""
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, **options))
    q, v, qk, vk = sim.initial_state()
    out = sim.rollout(q, v, qk, vk[None], nsteps, record_contacts=True)
    return (len(tr.t) == nsteps + 1 and np.array_equal(tr.q_com, out["q"]) and np.array_equal(tr.v_com, out["v"])
            and np.array_equal(tr.stats["status"], out["status"]) and np.array_equal(tr.contacts["cn"], out["con_cn"]))


def test_simulate_keeps_its_run_setup_for_the_same_scene_object_and_arguments():
    """Set-up: `simulate` keeps what it makes of its arguments (the validated settings, the options, the
    model, the run-size check) for the next call with the same Scene object and the same arguments; any other
    argument, option or Scene makes (and checks) its own, and every run equals a fresh Simulator's bit for bit. A
    Scene that does not hash (lists: it can change) is never kept, and a bad argument fails on every call."""
    import dataclasses
    from planar_lcp import sim as S
    from planar_lcp.spec.scene import SceneError
    S._run_setups.clear()
    sc = load_scene("box_push")
    first = simulate(sc, t_end=0.2)
    assert len(S._run_setups) == 1
    kept, = S._run_setups.values()
    again = simulate(sc, t_end=0.2)
    assert list(S._run_setups.values()) == [kept] and again.options is first.options
    assert _same_run(again, sc, 20)
    assert _same_run(simulate(sc, t_end=0.1), sc, 10) and len(S._run_setups) == 2
    shifted = simulate(sc, t_end=0.2, contact_margin=1e-3)
    assert shifted.options.contact_margin == 1e-3 and _same_run(shifted, sc, 20, contact_margin=1e-3)
    assert len(S._run_setups) == 3
    other = load_scene("box_push")                                   # equal, another object: its own entry
    simulate(other, t_end=0.2)
    assert len(S._run_setups) == 4
    for _ in range(2):
        with pytest.raises(SceneError, match="h"):
            simulate(sc, t_end=0.2, h=-1.0)
    assert len(S._run_setups) == 4
    # a Scene with a list of bodies does not hash: made again each call, so a change to the list is run
    listed = dataclasses.replace(sc, bodies=list(sc.bodies))
    light = simulate(listed, t_end=0.2)
    assert len(S._run_setups) == 4 and _same_run(light, sc, 20)
    box = next(i for i, b in enumerate(listed.bodies) if b.type == "dynamic")
    x, y = listed.bodies[box].position
    listed.bodies[box] = dataclasses.replace(listed.bodies[box], position=(x, y + 1e-3))
    moved = simulate(listed, t_end=0.2)
    assert len(S._run_setups) == 4 and np.isclose(moved.q[0, 0, 1], light.q[0, 0, 1] + 1e-3)
    for i in range(S.RUN_SETUPS + 3):
        simulate(sc, t_end=0.02 + 0.01 * i)
    assert len(S._run_setups) == S.RUN_SETUPS


def test_simulate_reads_a_named_scene_file_once_per_version(tmp_path):
    """Set-up: `simulate("box_push")` reads and validates the file once (then its run set-up is kept as a
    Scene object's); an edited file (another modification time or size) is read again and run as edited; an unknown
    name still fails with load_scene's error."""
    import os
    from planar_lcp import sim as S
    from planar_lcp.spec.scene import SceneError
    S._loaded_scenes.clear()
    S._run_setups.clear()
    first = simulate("box_push", t_end=0.2)
    assert len(S._loaded_scenes) == 1
    sc, = S._loaded_scenes.values()
    assert sc == load_scene("box_push")
    again = simulate("box_push", t_end=0.2)
    assert len(S._loaded_scenes) == 1 and len(S._run_setups) == 1 and again.options is first.options
    assert _same_run(again, sc, 20)
    # a scene file of one's own, edited between two calls
    path = tmp_path / "drop.toml"
    text = (S.scene_path("falling_rod")).read_text()
    path.write_text(text)
    before = simulate(str(path), t_end=0.05)
    assert len(S._loaded_scenes) == 2 and before.t[-1] == pytest.approx(0.05)
    edited = text.replace("t_end = 1.0\n", "t_end = 0.0375\n", 1)
    assert edited != text
    path.write_text(edited)
    os.utime(path, ns=(os.stat(path).st_atime_ns, os.stat(path).st_mtime_ns + 10**9))
    after = simulate(str(path))                      # the file's own t_end, as edited
    assert len(S._loaded_scenes) == 3 and after.t[-1] == pytest.approx(0.0375) and len(after.t) == 16
    with pytest.raises(SceneError, match="unknown scene"):
        simulate("no_such_scene")


def test_a_model_pickles_after_its_kernel_struct_was_made():
    """Model.struct is made once and kept on the model; numba's memory does not pickle, so a pickled model leaves it
    out and makes it again (a Model sent to a Dask worker, or saved)."""
    import pickle
    sc = load_scene("box_push")
    model = compile_scene(sc)
    sim = Simulator(model, SimOptions(h=sc.sim.h))
    q, v, qk, vk = sim.initial_state()
    before = sim.rollout(q, v, qk, vk[None], 50)
    again = pickle.loads(pickle.dumps(model))
    after = Simulator(again, SimOptions(h=sc.sim.h)).rollout(q, v, qk, vk[None], 50)
    assert np.array_equal(before["q"], after["q"]) and np.array_equal(before["v"], after["v"])


def _reference_rows(sim, scene, nsteps, on_failure="raise"):
    """Trajectory.stats and energy as simulate made them before the kernel wrote its rows: numpy over the rollout's
    (nsteps, NSTAT) stats and its COM states."""
    from planar_lcp.engine.layout import STATS
    from planar_lcp.trajectory import energy
    m = sim.model
    out = sim.rollout(m.q0, m.v0, m.qk0, m.vk0[None], nsteps, stop_on_failure=on_failure == "raise")
    done = out["steps_done"]
    st = out["stats"][:done]
    rows = {name: (st[:, i].astype(int) if integer else st[:, i].copy()) for i, (name, integer, _) in enumerate(STATS)
            if name != "lemke_status"}
    rows["energy"] = energy(m, out["q"][:done + 1], out["v"][:done + 1])
    return rows


@pytest.mark.parametrize("scene, options", [("falling_rod", {}), ("box_tip", {}), ("four_disks", {}),
                                            ("box_stack", {"warm_start": True}),
                                            # res_tol = 0: every solve 'fails', so steps are handed back to the
                                            # variant with the PGS fallback and stitched
                                            ("falling_rod", {"res_tol": 0.0, "on_failure": "record"})])
@pytest.mark.parametrize("chunked", [False, True])
def test_the_kernels_trajectory_rows_equal_numpys_bit_for_bit(scene, options, chunked, monkeypatch):
    """simulate's Trajectory.stats rows and energy are written by the rollout kernel (engine/rollout.py
    `record_rows`): each equals, dtype and bits, what numpy makes of the rollout's stats and states, also when the
    run is made of chunks (each kernel call writes at the run's step indices) and of handed-back steps."""
    if chunked:
        monkeypatch.setattr(Simulator, "CHUNK_SECONDS", 1e-9)   # chunks of 16 steps
    sc = load_scene(scene)
    tr = simulate(sc, **options)
    keep = {k: v for k, v in options.items() if k != "on_failure"}
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, **keep))
    ref = _reference_rows(sim, sc, len(tr.t) - 1, options.get("on_failure", "raise"))
    for name, want in ref.items():
        got = tr.stats[name]
        assert got.dtype == want.dtype and got.flags.c_contiguous, name
        assert got.tobytes() == want.tobytes(), name
    if options.get("res_tol") == 0.0:
        assert tr.stats["pgs_uncertified"].sum() > 0          # the stitched steps happened


def test_the_kernels_energy_is_numpys_sum_for_any_number_of_bodies():
    """`state_energy` adds the bodies' terms as numpy's pairwise summation does (sequential below 8, eight partial
    sums to 128, halves above): compiled and as Python, equal to planar_lcp.trajectory.mechanical_energy bit for bit,
    on random states with masses and magnitudes over many decades, signed zeros included."""
    from collections import namedtuple
    from numba import njit
    from planar_lcp.engine.interpreted import python_version
    from planar_lcp.engine.rollout import state_energy
    from planar_lcp.trajectory import mechanical_energy

    @njit
    def rows(m, q, v, out):
        terms = np.empty(q.shape[1])
        for t in range(q.shape[0]):
            out[t] = state_energy(m, q[t], v[t], terms)

    Bodies = namedtuple("Bodies", "dyn_mass dyn_inertia gravity")
    rng = np.random.default_rng(7)
    for nb in [1, 2, 3, 7, 8, 9, 15, 16, 17, 31, 64, 127, 128, 129, 136, 257, 513]:
        for g in ([0.0, -9.81], [0.0, 0.0], [1.5, -3.0]):
            m = Bodies(rng.uniform(1e-3, 1e3, nb), rng.uniform(1e-6, 10.0, nb), np.array(g))
            q = rng.standard_normal((12, nb, 3)) * 10.0 ** rng.integers(-6, 4, (12, nb, 3))
            v = rng.standard_normal((12, nb, 3)) * 10.0 ** rng.integers(-6, 4, (12, nb, 3))
            q[0], v[0], q[1], v[1] = 0.0, 0.0, -0.0, -0.0
            want = mechanical_energy(m.dyn_mass, m.dyn_inertia, m.gravity, q, v)
            got = np.empty(len(q))
            rows(m, q, v, got)
            as_python = np.array([python_version(state_energy)(m, q[t], v[t], np.empty(nb)) for t in range(len(q))])
            assert got.tobytes() == want.tobytes() and as_python.tobytes() == want.tobytes(), (nb, g)


def test_simulate_takes_a_scene_dict_as_it_takes_the_scene():
    """simulate() takes the dict `planar_lcp.spec.piles` returns (a TOML document as a dict), and runs it as the
    Scene parse_scene makes of it; a bad dict is refused naming the field, another type naming what it takes."""
    from planar_lcp.spec import piles
    from planar_lcp.spec.scene import SceneError, parse_scene
    d = piles.tower(3)
    a, b = simulate(d, t_end=0.1), simulate(parse_scene(d), t_end=0.1)
    assert a.scene == b.scene and a.body_names == b.body_names
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v) and a.stats["lcp_size"].sum() > 0
    bad = dict(d, sim={"h": -1.0})
    with pytest.raises(SceneError, match=r"sim\.h"):
        simulate(bad)
    with pytest.raises(TypeError, match="a Scene, a scene dict, a shipped scene's name or a .toml path, got int"):
        simulate(3)


def test_simoptions_without_h_take_the_scenes_h():
    """SimOptions(warm_start=True) as the README shows it: h None, taken from the model's scene by Simulator; the
    run is the one with the scene's h given explicitly, bit for bit. Without a model to take it from, the options
    refuse to make the kernels' options, saying what to give."""
    sc = load_scene("box_push")
    model = compile_scene(sc)
    sim = Simulator(model, SimOptions(warm_start=True))
    assert sim.h == sim.options.h == sc.sim.h == 0.01
    given = Simulator(model, SimOptions(h=sc.sim.h, warm_start=True))
    assert sim.options == given.options
    runs = [s.rollout(*s.initial_state()[:3], model.vk0[None], 50) for s in (sim, given)]
    assert np.array_equal(runs[0]["q"], runs[1]["q"]) and np.array_equal(runs[0]["v"], runs[1]["v"])
    assert Simulator(model, SimOptions(h=0.005)).h == 0.005
    with pytest.raises(ValueError, match=r"h is None; give SimOptions\(h=\.\.\.\) in seconds"):
        SimOptions().kernel_options()
    with pytest.raises(ValueError, match="no scene"):
        SimOptions().for_model(object())
