"""Bad input: every hole gets one line naming the file or flag, the field, the
expected and the actual value; exit status 2 from the CLI without a traceback; a ValueError from the Python API.

The CLI cases run `planar-lcp` in a subprocess (cli_helpers.run_cli), as a user would."""

import os
import re
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import run_cli

import planar_lcp.sim as sim_module
from planar_lcp.model import compile_scene
from planar_lcp.spec.scene import (MAX_FIXED_POINT_ITERATIONS, MAX_FRICTION_DIRECTIONS, MAX_PGS_ITERATIONS, MAX_STEPS,
                                   SceneError, load_scene, parse_scene, scenes_dir)
from planar_lcp.sim import SimulationError, Simulator, check_run_size, estimate_run_bytes, simulate

ROD = str(scenes_dir() / "falling_rod.toml")
PUSH = str(scenes_dir() / "box_push.toml")


def assert_scene_refused(path, msg):
    """A bad scene file: load_scene raises SceneError with exactly `msg`, and `planar-lcp simulate` exits 2 with that
    one line and prints nothing else."""
    with pytest.raises(SceneError) as e:
        load_scene(path)
    assert str(e.value) == msg
    r = run_cli("simulate", path)
    assert error_line(r) == msg and r.stdout == ""


def error_line(r, prog="planar-lcp simulate"):
    """The one line of a bad-input error of the finished CLI run r: exit status 2, no traceback, a single line on
    stderr."""
    err = r.stderr
    assert r.returncode == 2, err
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"{prog}: error: "), lines[0]
    return lines[0][len(f"{prog}: error: "):]


# --- 1. encoding ------------------------------------------------------------------------------------------------


def test_utf16_scene_file_is_named_not_utf8(tmp_path):
    path = tmp_path / "rod16.toml"
    path.write_text(Path(ROD).read_text(), encoding="utf-16")
    msg = (f"{path}: the scene file must be UTF-8 text, got a UTF-16 (little-endian) byte-order mark at byte "
           "offset 0 (save the file as UTF-8)")
    assert_scene_refused(path, msg)


def test_latin1_byte_is_named_with_its_offset_and_line(tmp_path):
    path = tmp_path / "rod1.toml"
    text = Path(ROD).read_text()
    text = text.replace('description = "', '# caf\u00e9\ndescription = "', 1)
    path.write_bytes(text.encode("latin-1"))
    offset = text.index("\u00e9")
    line = text[:offset].count("\n") + 1
    msg = (f"{path}: the scene file must be UTF-8 text, got byte 0xe9 at byte offset {offset} (line {line}: invalid "
           "continuation byte; save the file as UTF-8)")
    assert_scene_refused(path, msg)


def test_utf8_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + Path(ROD).read_bytes())
    assert load_scene(path).sim == load_scene(ROD).sim


# --- 2. sizes and run time, checked before allocating -----------------------------------------------------------


@pytest.mark.parametrize("argv, msg", [
    (["--t-end", "1e9"], f"{ROD}: the number of steps --t-end / sim.h must be <= {MAX_STEPS}, got 1e+09 s / "
                         "0.0025 s = 4e+11 (reduce --t-end or increase --h)"),
    (["--h", "1e-12"], f"{ROD}: the number of steps sim.t_end / --h must be <= {MAX_STEPS}, got 1 s / 1e-12 s = "
                       "1e+12 (reduce --t-end or increase --h)"),
    (["--h", "5e-9"], f"{ROD}: the number of steps sim.t_end / --h must be <= {MAX_STEPS}, got 1 s / 5e-09 s = "
                      "2e+08 (reduce --t-end or increase --h)"),
    (["--fixed-point-iterations", "5000"],
     f"{ROD}: --fixed-point-iterations must be <= {MAX_FIXED_POINT_ITERATIONS}, got 5000"),
])
def test_cli_run_limits(argv, msg):
    r = run_cli("simulate", "falling_rod", *argv)
    assert error_line(r) == msg and r.stdout == ""


def test_cli_friction_directions_limit():
    r = run_cli("simulate", "box_push", "--friction-directions", "100000")
    assert error_line(r) == f"{PUSH}: --friction-directions must be <= {MAX_FRICTION_DIRECTIONS}, got 100000"


@pytest.mark.parametrize("kw, msg", [
    (dict(t_end=1e9), f"{ROD}: the number of steps t_end / sim.h must be <= {MAX_STEPS}, got 1e+09 s / 0.0025 s = "
                      "4e+11 (reduce t_end or increase h)"),
    (dict(h=5e-9), f"{ROD}: the number of steps sim.t_end / h must be <= {MAX_STEPS}, got 1 s / 5e-09 s = 2e+08 "
                   "(reduce t_end or increase h)"),
    (dict(pgs_iterations=10 ** 8), f"{ROD}: pgs_iterations must be <= {MAX_PGS_ITERATIONS}, got 100000000"),
    (dict(pgs_iterations=1e8), f"{ROD}: pgs_iterations must be an integer, got 100000000.0"),
    (dict(fixed_point_iterations=0), f"{ROD}: fixed_point_iterations must be >= 1, got 0"),
    (dict(h="0.01"), f"{ROD}: h must be a number, got '0.01'"),
    (dict(t_end=float("nan")), f"{ROD}: t_end must be a finite number, got nan"),
    (dict(h=-1.0), f"{ROD}: h must be > 0, got -1.0"),
    (dict(solver="dantzig"), f"{ROD}: solver must be one of 'lemke', 'pgs', 'osqp', got 'dantzig'"),
])
def test_simulate_keywords_follow_the_scene_rules(kw, msg):
    with pytest.raises(ValueError) as e:
        simulate("falling_rod", **kw)
    assert str(e.value) == msg


@pytest.mark.parametrize("key, value, msg", [
    ("pgs_iterations", 100_000_000, f"sim.pgs_iterations must be <= {MAX_PGS_ITERATIONS}, got 100000000"),
    ("friction_directions", 100_000, f"sim.friction_directions must be <= {MAX_FRICTION_DIRECTIONS}, got 100000"),
    ("fixed_point_iterations", 10 ** 6,
     f"sim.fixed_point_iterations must be <= {MAX_FIXED_POINT_ITERATIONS}, got 1000000"),
    ("h", 5e-9, f"the number of steps sim.t_end / sim.h must be <= {MAX_STEPS}, got 1 s / 5e-09 s = 2e+08 (reduce "
                "sim.t_end or increase sim.h)"),
])
def test_scene_file_limits(tmp_path, key, value, msg):
    path = tmp_path / "x.toml"
    text = Path(ROD).read_text()
    assert "\nh = 0.0025\n" in text
    path.write_text(text.replace("\nh = 0.0025\n", f"\nh = 0.0025\n{key} = {value!r}\n" if key != "h" else
                                 f"\nh = {value!r}\n", 1))
    assert_scene_refused(path, f"{path}: {msg}")


def _many_disks(n):
    """n disks in a row above a table, none touching: n (n - 1) / 2 + n shape pairs."""
    bodies = [{"name": f"d{i}", "type": "dynamic", "mass": 1.0, "position": [0.3 * i, 0.5],
               "shapes": [{"type": "disk", "radius": 0.1}]} for i in range(n)]
    bodies.append({"name": "table", "type": "static",
                   "shapes": [{"type": "halfplane", "point": [0, 0], "normal": [0, 1]}]})
    return {"name": "many", "sim": {"h": 1e-4, "t_end": 999.0}, "bodies": bodies}


def test_estimate_covers_what_a_run_allocates():
    """The estimate is an upper bound of the rollout's arrays plus the work buffers, and not a loose one."""
    model = compile_scene(parse_scene(_many_disks(5), "many.toml"))
    simr = Simulator(model, sim_module.SimOptions(h=1e-3))
    nsteps = 200
    q0, v0, qk0, vk0 = simr.initial_state()
    out = simr.rollout(q0, v0, qk0, vk0[None], nsteps, record_contacts=True, trajectory_rows=True)  # simulate's
    rollout_bytes = sum(a.nbytes for a in out.values() if isinstance(a, np.ndarray))
    work_bytes = sum(a.nbytes for a in simr.work if isinstance(a, np.ndarray))
    traj, work = estimate_run_bytes(model, nsteps, record_contacts=True)
    assert rollout_bytes <= traj <= 2 * rollout_bytes
    assert work_bytes <= work <= 1.5 * work_bytes


def test_memory_limit_message_and_nothing_allocated(monkeypatch):
    scene = parse_scene(_many_disks(40), "many.toml")
    model = compile_scene(scene)
    traj, work = estimate_run_bytes(model, 9_990_000)
    assert traj > 1e12          # > 1 TB: refused on any machine with less than 4 TB of memory
    with pytest.raises(SceneError) as e:
        check_run_size(model, 9_990_000, {"t_end": "--t-end", "h": "--h"}, limit=2 ** 30)
    msg = str(e.value)
    assert msg.startswith("many.toml: the run must fit in 1 GiB (0.25 of this machine's ")
    assert ("got an estimated " in msg and "(9990000 steps x 40 dynamic bodies, 1640 contact slots)" in msg
            and f"(up to {model.max_unknowns()} unknowns); reduce --t-end or increase --h" in msg)
    # simulate() refuses before its Simulator allocates anything
    made = []
    monkeypatch.setattr(sim_module, "Simulator", lambda *a, **k: made.append(1))
    with pytest.raises(SceneError, match=r"^many.toml: the run must fit in .*; reduce t_end or increase h$"):
        simulate(scene)
    assert made == []


@pytest.mark.parametrize("cache", ["warm", "cold"])
def test_cli_memory_limit(tmp_path, cache):
    """A run too large is refused with one line and nothing else: on stdout nothing, and on a cold numba cache no
    background compilation started (its notice would be a second line on stderr, its process work for nothing)."""
    path = tmp_path / "many.toml"
    lines = ['name = "many"', "[sim]", "h = 1e-4", "t_end = 999.0"]
    for b in _many_disks(40)["bodies"][:-1]:
        lines += ["[[bodies]]", f'name = "{b["name"]}"', 'type = "dynamic"', "mass = 1.0",
                  f"position = [{b['position'][0]!r}, 0.5]", 'shapes = [ { type = "disk", radius = 0.1 } ]']
    lines += ["[[bodies]]", 'name = "table"', 'type = "static"',
              'shapes = [ { type = "halfplane", point = [0.0, 0.0], normal = [0.0, 1.0] } ]']
    path.write_text("\n".join(lines) + "\n")
    numba_cache = tmp_path / "numba"
    env = {} if cache == "warm" else dict(NUMBA_CACHE_DIR=str(numba_cache), PLANAR_LCP_PRECOMPILE="1")
    r = run_cli("simulate", path, env=env)
    line = error_line(r)
    assert line.startswith(f"{path}: the run must fit in ") and "(9990000 steps x 40 dynamic bodies" in line
    assert line.endswith("; reduce --t-end or increase --h")
    assert r.stdout == ""
    if cache == "cold":
        from planar_lcp.compilation.background import lock_file
        assert not os.path.exists(lock_file(str(numba_cache))), "a background compilation started"


# --- 3. output paths, before any simulation -----------------------------------------------------------------------


@pytest.mark.parametrize("option, name, msg", [
    ("--plot", "x.txt", "--plot x.txt: the file name must end in .png, got '.txt'"),
    ("--animate", "x.mp4", "--animate x.mp4: the file name must end in .gif, got '.mp4'"),
    ("--csv", "x.json", "--csv x.json: the file name must end in .csv or .txt, got '.json'"),
    ("--plot", "plot", "--plot plot: the file name must end in .png, got 'no extension'"),
])
def test_output_extension_refused_before_the_run(tmp_path, option, name, msg):
    # 400000 steps would take tens of seconds: the refusal comes first
    r = run_cli("simulate", "falling_rod", "--t-end", "1000", "--csv", "run.csv", option, name, cwd=tmp_path)
    assert error_line(r) == msg and r.stdout == ""
    assert r.seconds < 15.0
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_output_checks_run_before_simulate(tmp_path, monkeypatch, capsys):
    from planar_lcp.cli import main
    calls = []
    monkeypatch.setattr(sim_module, "simulate", lambda *a, **k: calls.append(1))
    unwritable = tmp_path / "ro"
    unwritable.mkdir()
    for argv, msg in [
        (["--animate", tmp_path / "x.mp4"], f"--animate {tmp_path / 'x.mp4'}: the file name must end in .gif, "
                                            "got '.mp4'"),
        (["--csv", tmp_path / "no" / "x.csv"], f"--csv {tmp_path / 'no' / 'x.csv'}: the directory "
                                               f"{tmp_path / 'no'} does not exist"),
        (["--plot", unwritable], None),
        (["--csv", "/proc/x.csv"], "--csv /proc/x.csv: must be a writable file, got: No such file or directory"),
    ]:
        if argv[1] == unwritable:
            target = unwritable / "d.png"
            target.mkdir()
            argv, msg = ["--plot", target], f"--plot {target}: must be a file name, got a directory"
        rc = main(["simulate", "falling_rod", *map(str, argv)])
        err = capsys.readouterr().err
        assert rc == 2 and err == f"planar-lcp simulate: error: {msg}\n"
    assert calls == []


@pytest.mark.parametrize("argv, prog", [
    (["compare", "falling_rod", "--out", "afile"], "planar-lcp compare"),
    (["study", "falling-rod", "--out", "afile"], "planar-lcp study"),
    (["tradeoff", "--quick", "--out", "afile"], "planar-lcp tradeoff"),
])
def test_out_directory_that_is_a_file(tmp_path, argv, prog):
    (tmp_path / "afile").write_text("keep")
    r = run_cli(*argv, cwd=tmp_path)
    if "pymunk is not installed" in r.stderr:
        pytest.skip("pymunk missing")
    assert error_line(r, prog) == "--out afile: must be a directory, got an existing file"
    assert (tmp_path / "afile").read_text() == "keep"


def test_out_directory_that_cannot_be_created(tmp_path):
    (tmp_path / "afile").write_text("keep")
    r = run_cli("tradeoff", "--quick", "--out", "afile/sub", cwd=tmp_path)
    assert error_line(r, "planar-lcp tradeoff") == ("--out afile/sub: cannot create the directory: Not a "
                                                          "directory")


def test_compare_settings_checked_before_the_run(tmp_path):
    r = run_cli("compare", "falling_rod", "--out", tmp_path / "c", "--h", "2")
    if "pymunk is not installed" in r.stderr:
        pytest.skip("pymunk missing")
    assert error_line(r, "planar-lcp compare") == f"{ROD}: --h must be < sim.t_end = 1.0 s (at least one " \
                                                         "step), got 2.0"
    assert not (tmp_path / "c").exists()


# --- 4. accepted silently before ----------------------------------------------------------------------------------


def test_h_not_below_t_end_is_an_error(tmp_path):
    r = run_cli("simulate", "falling_rod", "--h", "2", "--t-end", "1")
    assert error_line(r) == f"{ROD}: --h must be < --t-end = 1.0 s (at least one step), got 2.0"
    r = run_cli("simulate", "falling_rod", "--h", "1")
    assert error_line(r) == f"{ROD}: --h must be < sim.t_end = 1.0 s (at least one step), got 1.0"
    with pytest.raises(SceneError) as e:
        simulate("falling_rod", h=0.5, t_end=0.5)
    assert str(e.value) == f"{ROD}: h must be < t_end = 0.5 s (at least one step), got 0.5"
    path = tmp_path / "x.toml"
    path.write_text(Path(ROD).read_text().replace("t_end = 1.0", "t_end = 0.001", 1))
    with pytest.raises(SceneError) as e:
        load_scene(path)
    assert str(e.value) == f"{path}: sim.h must be < sim.t_end = 0.001 s (at least one step), got 0.0025"


def test_friction_directions_in_the_vertical_plane():
    r = run_cli("simulate", "falling_rod", "--friction-directions", "5")
    assert error_line(r) == (f"{ROD}: --friction-directions applies only in the horizontal plane (the "
                                   "table friction), got 5 for a scene with world.plane = 'vertical'")
    with pytest.raises(SceneError, match=r"friction_directions applies only in the horizontal plane .* got 5 for"):
        simulate("falling_rod", friction_directions=5)
    assert simulate("box_push", friction_directions=5, t_end=0.02).t.shape == (3,)


def _push_with_support(points):
    return {"name": "sp", "world": {"plane": "horizontal"},
            "bodies": [{"name": "box", "type": "dynamic", "mass": 1.0, "support_points": points,
                        "shapes": [{"type": "box", "width": 0.2, "height": 0.1, "radius": 0.01, "offset": [0.1, 0]}]},
                       {"name": "post", "type": "static", "position": [3.0, 3.0],
                        "shapes": [{"type": "disk", "radius": 0.01}]}]}


def test_support_point_outside_its_body():
    with pytest.raises(SceneError) as e:
        parse_scene(_push_with_support([[0.0, 0.0], [5.0, 0.0]]), "x.toml")
    assert str(e.value) == ("x.toml: bodies[0].support_points[1] must lie within the body's extent x in [-0.01, 0.21], "
                            "y in [-0.06, 0.06] (the bounding box of its shapes, body frame, m), got [5.0, 0.0]")
    with pytest.raises(SceneError, match=r"support_points\[0\] must lie within .* got \[0.1, 0.0601\]$"):
        parse_scene(_push_with_support([[0.1, 0.0601]]), "x.toml")
    # on the boundary (rounding included) is inside
    parse_scene(_push_with_support([[-0.01, -0.06], [0.21, 0.06], [0.1, 0.0]]), "x.toml")


# --- 5. the failure message ---------------------------------------------------------------------------------------


# res_tol = 0 demands an exact residual, which round-off denies on some step: a real, controlled LCP failure
# (tests/simulation/test_sim_physics.py uses the same one).


def test_failure_message_python_keeps_the_keyword_and_says_the_run_stopped():
    with pytest.raises(SimulationError) as e:
        simulate("falling_rod", res_tol=0.0)
    msg = str(e.value)
    assert re.match(rf"{re.escape(ROD)}: step \d+ \(t = .* s, h = 0\.0025\): no method gave a certified solution "
                    r"of an island's contact LCP \(size up to \d+; Lemke ended with 'inaccurate', residual .*, after "
                    r"every fallback: docs/method\.md, 'Certified solves'\); the contact LCP has a solution to within a "
                    r"residual of .* \(found by branch and bound in \d+ branches; the step's tolerance is 0\.000e\+00\) "
                    r"that no method certified: a solver failure; the run stopped at this step\. "
                    r"Pass on_failure='record' to continue \(a failed island then takes PGS's answer\) and list the "
                    r"failures\.$", msg), msg
    assert "PGS's uncertified answer" not in msg and "--on-failure" not in msg


def test_failure_message_cli_names_the_flag(monkeypatch, capsys):
    from planar_lcp.cli import main
    real = sim_module.simulate
    monkeypatch.setattr(sim_module, "simulate", lambda scene, **kw: real(scene, res_tol=0.0, **kw))
    rc = main(["simulate", "falling_rod"])
    err = capsys.readouterr().err
    assert rc == 1 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("planar-lcp simulate: simulation failed: ") and "no method gave a certified solution" in err
    assert err.endswith("; the run stopped at this step. Pass --on-failure record to continue (a failed island then "
                        "takes PGS's answer) and list the failures.\n"), err
    assert "on_failure=" not in err and "PGS's uncertified answer" not in err


def test_a_jam_reads_as_no_rigid_solution_on_the_command_line(tmp_path):
    """A kinematic pusher driving a box into a wall stops the run with one line that says there is no
    rigid solution and names the bodies, not a solver's status; exit status 1."""
    pytest.importorskip("scipy")
    from test_reliability import JAM
    from planar_lcp.spec.random_scenes import scene_to_toml
    f = tmp_path / "jam.toml"
    f.write_text(scene_to_toml(JAM))
    r = run_cli("simulate", f, cwd=tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert r.stderr.startswith(f"planar-lcp simulate: simulation failed: {f}: step ")
    assert "no rigid solution: kinematic body 'pusher' drives 'box' into static body 'wall' (certified" in r.stderr
    assert "ray_termination" not in r.stderr


@pytest.mark.parametrize("argv, message", [
    (["--support-model", "points"], "--support-model applies only in the horizontal plane (the table friction), got "
                                    "'points' for a scene with world.plane = 'vertical'"),
    (["--limit-surface-twists", "8"], "--limit-surface-twists applies only in the horizontal plane (the table "
                                      "friction), got 8 for a scene with world.plane = 'vertical'"),
])
def test_table_friction_flags_in_the_vertical_plane(argv, message):
    r = run_cli("simulate", "falling_rod", *argv)
    assert error_line(r) == f"{ROD}: {message}"


@pytest.mark.parametrize("argv, message", [
    (["--limit-surface-twists", "7"], "--limit-surface-twists must be even (the twists come in opposite pairs), got 7"),
    (["--limit-surface-twists", "258"], "--limit-surface-twists must be <= 256, got 258"),
    (["--limit-surface-resolution", "65"], "--limit-surface-resolution must be <= 64, got 65"),
])
def test_limit_surface_knobs_out_of_range(argv, message):
    r = run_cli("simulate", "box_push", *argv)
    assert error_line(r) == f"{PUSH}: {message}"


def test_unknown_support_model_in_a_scene(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('name = "s"\n[world]\nplane = "horizontal"\nsupport_model = "disk"\n[[bodies]]\nname = "b"\n'
                    'type = "dynamic"\nmass = 1.0\nshapes = [ { type = "disk", radius = 0.1 } ]\n')
    with pytest.raises(SceneError, match=r"world.support_model must be one of 'limit_surface', 'points', got 'disk'"):
        load_scene(path)


@pytest.mark.parametrize("support, knob", [("limit_surface", "limit_surface_twists"),
                                           ("points", "friction_directions")])
def test_run_size_advice_names_the_support_models_knob(support, knob):
    """When the LCP buffers are what does not fit, the message names the knob of the table friction in use."""
    model = compile_scene(load_scene("push_t"), support_model=support)
    with pytest.raises(SceneError, match=rf"; reduce {knob} or the number of shapes in contact$"):
        check_run_size(model, 1, limit=1000)


# --- 6. absurd magnitudes -----------------------------------------------------------------------------------------

ABSURD = (1e308, -1e308, 1e-308, 1e30, -1e30, 1e-30, 0.0, -1.0, 1e6, 1e-9)


def _numeric_leaves(d, path=()):
    """Paths to every number of a TOML-shaped scene dict (lists and tables walked)."""
    if isinstance(d, dict):
        for k, x in d.items():
            yield from _numeric_leaves(x, path + (k,))
    elif isinstance(d, list):
        for i, x in enumerate(d):
            yield from _numeric_leaves(x, path + (i,))
    elif isinstance(d, (int, float)) and not isinstance(d, bool):
        yield path


def _show(path):
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in path).lstrip(".")


def test_absurd_magnitudes_in_shipped_scenes_give_a_clean_result_or_a_one_line_error():
    """300 seeded mutations of the shipped scenes, each one number set to an absurd value (1e308, 1e-308, 0, -1, ...):
    each loads and runs a few steps cleanly, or is refused at load by a SceneError of one line that names the field
    (a physical bound, docs/scene-format.md "Limits"), or stops as a SimulationError; never another exception, a
    non-finite state or a numpy warning (a disk radius of 1e308 once overflowed in spec/massprops.py)."""
    import copy
    import warnings
    from planar_lcp.spec.scene import SceneError, list_scenes, read_document, scenes_dir
    rng = np.random.default_rng(20261204)
    names = sorted(n for n, _ in list_scenes() if n not in ("bin", "tower", "pyramid", "push_table"))
    outcomes = {"refused": 0, "ran": 0, "stopped": 0}
    for trial in range(300):
        name = names[int(rng.integers(len(names)))]
        doc, _ = read_document(scenes_dir() / f"{name}.toml")
        doc.pop("task", None)
        leaves = [p for p in _numeric_leaves(doc) if p[0] in ("bodies", "world")]
        path = leaves[int(rng.integers(len(leaves)))]
        value = float(ABSURD[int(rng.integers(len(ABSURD)))])
        mutated = copy.deepcopy(doc)
        node = mutated
        for p in path[:-1]:
            node = node[p]
        node[path[-1]] = value
        where = f"{name}: {_show(path)} = {value!r}"
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                sc = parse_scene(mutated, "x.toml")
            except SceneError as e:
                msg = str(e)
                assert msg.startswith("x.toml: ") and "\n" not in msg, (where, msg)
                outcomes["refused"] += 1
                continue
            try:
                tr = simulate(sc, t_end=min(sc.sim.t_end, 8 * sc.sim.h) if 8 * sc.sim.h < sc.sim.t_end else None)
            except SceneError as e:                  # a run too large for memory, or its steps: refused before work
                assert "\n" not in str(e), (where, str(e))
                outcomes["refused"] += 1
                continue
            except SimulationError:
                outcomes["stopped"] += 1
                continue
        assert np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v)), where
        outcomes["ran"] += 1
    assert outcomes["refused"] >= 50 and outcomes["ran"] >= 50, outcomes


@pytest.mark.parametrize("mutation, message", [
    (lambda d: d["bodies"][0]["shapes"][0].update(radius=1e308),
     "bodies[0].shapes[0].radius must be at most 10000 m (a physical bound), got 1e+308"),
    (lambda d: d["bodies"][0].update(mass=1e-9),
     "bodies[0].mass must be at least 1e-06 kg (a physical bound), got 1e-09"),
    (lambda d: d["bodies"][0].update(velocity=[0.0, -5e3]),
     "bodies[0].velocity must be within +-1000 m/s in each component (a physical bound), got [0.0, -5000.0]"),
    (lambda d: d["bodies"][0].update(position=[2e4, 0.0]),
     "bodies[0].position must be within +-10000 m in each coordinate (a physical bound), got [20000.0, 0.0]"),
    (lambda d: d["bodies"][0].update(angular_velocity=-1e5),
     "bodies[0].angular_velocity must be within +- 10000 rad/s (a physical bound), got -100000.0"),
    (lambda d: d["bodies"][0].update(inertia=1e20),
     "bodies[0].inertia must be at most 1e+14 kg m^2 (a physical bound), got 1e+20"),
    (lambda d: d["world"].update(gravity=[0.0, -1e4]),
     "world.gravity must be within +-1000 m/s^2 in each component (a physical bound), got [0.0, -10000.0]"),
])
def test_each_physical_bound_is_named_with_its_value(mutation, message):
    data = {"name": "d", "world": {"plane": "vertical"}, "sim": {"h": 0.01, "t_end": 0.1},
            "bodies": [{"name": "disk", "type": "dynamic", "mass": 1.0, "position": [0.0, 1.0],
                        "shapes": [{"type": "disk", "radius": 0.1}]}]}
    mutation(data)
    from planar_lcp.spec.scene import SceneError
    with pytest.raises(SceneError) as e:
        parse_scene(data, "x.toml")
    assert str(e.value) == "x.toml: " + message


def test_an_absurd_size_on_the_command_line_is_one_line_and_exit_2(tmp_path):
    """The disk radius of 1e308 that once overflowed in spec/massprops.py, in a scene file run as a user runs it."""
    f = tmp_path / "huge.toml"
    f.write_text('name = "huge"\n[sim]\nh = 0.01\nt_end = 0.1\n[[bodies]]\nname = "disk"\ntype = "dynamic"\nmass = 1.0\n'
                 '[[bodies.shapes]]\ntype = "disk"\nradius = 1e308\n')
    r = run_cli("simulate", f, cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert r.stderr.strip() == (f"planar-lcp simulate: error: {f}: bodies[0].shapes[0].radius must be at most 10000 m "
                                "(a physical bound), got 1e+308")


def _every_subcommand():
    """(words, parser) of every subcommand of `planar-lcp`, nested ones too (study falling-rod, pushdata fit, ...)."""
    import argparse

    from planar_lcp.cli import build_parser

    found = []

    def walk(parser, words):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    found.append(((*words, name), sub))
                    walk(sub, (*words, name))

    walk(build_parser(), ())
    return found


@pytest.mark.parametrize("words, parser", _every_subcommand(),
                         ids=lambda v: " ".join(v) if isinstance(v, tuple) else "")
def test_every_subcommand_refuses_an_unknown_option_in_one_line(words, parser, capsys):
    """Arguments a command cannot take: one line on stderr, "planar-lcp COMMAND: error: ...", exit status 2 (no usage
    block, argparse's default)."""
    with pytest.raises(SystemExit) as e:
        parser.parse_args(["--no-such-option"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"planar-lcp {' '.join(words)}: error: "), err


@pytest.mark.parametrize("argv, line", [
    (["simulate", "falling_rod", "--no-such-option"],
     "planar-lcp simulate: error: unrecognized arguments: --no-such-option"),
    (["study", "four-disks", "--out", "x", "--bogus", "1"],
     "planar-lcp study four-disks: error: unrecognized arguments: --bogus 1"),
    (["no-such-command"], "planar-lcp: error: argument command: invalid choice: 'no-such-command'"),
])
def test_an_argument_no_command_takes_is_one_line_naming_the_command(argv, line):
    """What no parser took is reported by the command it was given to, in one line (not argparse's usage block from
    the top-level parser), before anything runs."""
    r = run_cli(*argv)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and r.stderr.startswith(line), r.stderr


def test_an_argument_a_plainly_added_command_does_not_take_is_one_line(monkeypatch, capsys):
    """A command another package adds with argparse's own add_parser (no cli_support.add_command): what its parser
    does not take is still one line, from the top-level parser, exit status 2."""
    from planar_lcp import cli
    build = cli.build_parser

    def with_plain_command():
        parser = build()
        sub = next(a for a in parser._actions if a.dest == "command")
        sub.add_parser("plain").set_defaults(func=lambda args: 0)
        return parser
    monkeypatch.setattr(cli, "build_parser", with_plain_command)
    with pytest.raises(SystemExit) as e:
        cli.main(["plain", "--bogus"])
    assert e.value.code == 2
    assert capsys.readouterr().err == "planar-lcp: error: unrecognized arguments: --bogus\n"
