"""`planar-lcp simulate` and `planar-lcp scenes`, and the plots and animations of planar_lcp.viz."""

import csv
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planar_lcp import cli
from planar_lcp.cli import main
from planar_lcp.spec.scene import list_scenes, load_scene, scenes_dir
from planar_lcp.sim import SimulationError, simulate

SHIPPED = ["block_on_incline", "box_push", "box_stack", "box_tip", "falling_rod", "four_disks", "painleve_rod",
           "push_t"]


@pytest.fixture(autouse=True)
def _agg(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")


def run(argv, capsys):
    """main(argv) in-process: (exit status, stdout, stderr); argparse's SystemExit becomes the status."""
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:
        rc = e.code
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


def expected_table(traj):
    """The CSV's numbers from a Trajectory: t, then x, y, theta, vx, vy, omega of each dynamic body."""
    cols = [traj.t]
    for b in range(len(traj.body_names)):
        cols += [traj.q[:, b, k] for k in range(3)] + [traj.v[:, b, k] for k in range(3)]
    return np.column_stack(cols)


def summary_field(out, label):
    m = re.search(rf"^{re.escape(label)}\s+(.*)$", out, re.M)
    assert m, f"no {label!r} line in:\n{out}"
    return m.group(1).strip()


# --- scenes -------------------------------------------------------------------------------------------------


def _check_scene_listing(out):
    listed = list_scenes(tasks=True)
    # the eight scenes of SHIPPED are shipped (the planning tasks add scenes of their own)
    assert set(SHIPPED) <= {n for n, _, _ in listed}
    for name, description, has_task in listed:
        mark = r"\[task\]" if has_task else ""
        assert re.search(rf"^\s+{re.escape(name)}\s+{mark}\s*{re.escape(description)}$", out, re.M), (name, out)
    # the scenes that carry a [task] table are marked: the five shipped planning tasks at least
    assert {"push_box", "push_t", "tip_box", "push_clutter", "push_table"} <= {n for n, _, t in listed if t}


def test_scenes_lists_the_eight_shipped_scenes_with_descriptions(capsys):
    rc, out, err = run(["scenes"], capsys)
    assert rc == 0 and err == ""
    _check_scene_listing(out)
    assert str(scenes_dir()) in out


def test_scenes_console_script():
    exe = Path(sys.executable).parent / "planar-lcp"
    if not exe.exists():
        pytest.skip(f"console script {exe} not installed")
    env = dict(os.environ, MPLBACKEND="Agg")
    p = subprocess.run([str(exe), "scenes"], capture_output=True, text=True, timeout=60, env=env)
    assert p.returncode == 0, p.stderr
    _check_scene_listing(p.stdout)


def test_importing_the_package_and_cli_does_not_import_matplotlib():
    code = ("import sys, planar_lcp, planar_lcp.cli, planar_lcp.viz, planar_lcp.sim; "
            "sys.exit(1 if 'matplotlib' in sys.modules else 0)")
    assert subprocess.run([sys.executable, "-c", code], timeout=60).returncode == 0


# --- simulate: outputs ----------------------------------------------------------------------------------------


def test_simulate_falling_rod_csv_plot_and_summary(tmp_path, capsys):
    from matplotlib.colors import to_rgb
    from matplotlib.image import imread

    f, png = tmp_path / "rod.csv", tmp_path / "rod.png"
    rc, out, err = run(["simulate", "falling_rod", "--t-end", "0.2", "--csv", f, "--plot", png], capsys)
    assert rc == 0, err
    assert err == ""

    header, data = read_csv(f)
    assert ",".join(header) == "t,rod.x,rod.y,rod.theta,rod.vx,rod.vy,rod.omega"
    steps = int(round(0.2 / 0.0025))
    assert data.shape == (steps + 1, 7)
    assert data[0, 0] == 0.0
    assert np.array_equal(data[0, 1:4], [0.0, 1.0, math.radians(30.0)])
    assert data[0, 6] == 4.0
    traj = simulate("falling_rod", t_end=0.2)
    assert np.array_equal(data, expected_table(traj))

    # the summary: what ran, and numbers that agree with the run
    assert summary_field(out, "scene").startswith("falling_rod")
    assert summary_field(out, "steps").startswith(f"{steps} (h = 0.0025 s")
    assert summary_field(out, "solver") == "lemke"
    assert summary_field(out, "formulation") == "position"
    assert re.search(r"^wall time\s+\d+\.\d+ s", out, re.M)
    x, y, th = traj.q[-1, 0]
    assert re.search(rf"^\s+rod\s+x = {x: .6f}\s+y = {y: .6f}\s+theta = {th: .6f}$", out, re.M), out
    assert summary_field(out, "max penetration") == f"{traj.stats['penetration'].max():.3e} m"
    assert summary_field(out, "failed steps") == "0"
    assert summary_field(out, "total pivots") == str(int(traj.stats["pivots"].sum()))
    assert re.findall(r"^wrote\s+(.*)$", out, re.M) == [str(f), str(png)]

    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = imread(png)
    assert img.ndim == 3 and img.shape[0] >= 400 and img.shape[1] >= 800
    rgb = img[..., :3]
    assert float(rgb.std()) > 0.05                          # not a single colour
    left = rgb[:, : img.shape[1] // 2]
    # the rod (dynamic bodies are tab:blue first) and the table's grey fill are in the strobe half
    near = lambda c, tol: np.all(np.abs(left - np.array(to_rgb(c))) < tol, axis=-1).sum()  # noqa: E731
    assert near("tab:blue", 0.02) > 200
    assert near("0.82", 0.01) > 5000                        # a band, not antialiasing (a top-down view has < 1000)


def test_simulate_animate_writes_a_gif(tmp_path, capsys):
    from PIL import Image

    gif = tmp_path / "rod.gif"
    rc, out, err = run(["simulate", "falling_rod", "--t-end", "0.1", "--animate", gif], capsys)
    assert rc == 0, err
    assert re.findall(r"^wrote\s+(.*)$", out, re.M) == [str(gif)]
    with Image.open(gif) as im:
        assert im.format == "GIF"
        assert im.n_frames == 41                            # 40 steps + the initial state, all under max_frames
        first = np.asarray(im.convert("RGB"))
        im.seek(im.n_frames - 1)
        last = np.asarray(im.convert("RGB"))
    assert first.shape == last.shape and not np.array_equal(first, last)


def test_animate_subsamples_to_max_frames(tmp_path):
    from PIL import Image

    from planar_lcp.viz import animate_trajectory

    traj = simulate("push_t", t_end=0.5)                    # 51 states
    gif = tmp_path / "t.gif"
    assert animate_trajectory(traj, gif, fps=10, max_frames=7) == gif
    with Image.open(gif) as im:
        assert im.n_frames == 7
    with pytest.raises(ValueError, match="max_frames"):
        animate_trajectory(traj, gif, max_frames=0)


def test_simulate_two_bodies_csv_columns_in_scene_order(tmp_path, capsys):
    f = tmp_path / "disks.csv"
    rc, out, err = run(["simulate", "four_disks", "--t-end", "0.05", "--csv", f], capsys)
    assert rc == 0, err
    header, data = read_csv(f)
    names = [b.name for b in load_scene("four_disks").bodies if b.type == "dynamic"]
    assert names == ["thrown", "d1", "d2", "d3"]
    assert header == ["t"] + [f"{n}.{c}" for n in names for c in ("x", "y", "theta", "vx", "vy", "omega")]
    assert data[0, 1:3].tolist() == [0.0, 1.0] and data[0, 4] == 1.5          # thrown: position, vx
    assert data[0, 1 + 6 * 2] == 1.20001                                       # d2.x
    assert np.array_equal(data, expected_table(simulate("four_disks", t_end=0.05)))
    for n in names:
        assert re.search(rf"^\s+{n}\s+x = ", out, re.M)


def read_contacts(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def test_simulate_contacts_csv_equals_the_trajectory_and_carries_the_stacks_weight(tmp_path, capsys):
    """--contacts-csv: a row per contact per step, every number the Trajectory's (contacts_to_csv); and the impulses
    against an oracle: three 1 kg boxes stacked on a table at rest, the normal impulses of each interface add up per
    step to the weight above it times h (3, 2, 1 m g h), without friction, every contact sticking."""
    f, g = tmp_path / "stack.csv", tmp_path / "stack_contacts.csv"
    rc, out, err = run(["simulate", "box_stack", "--t-end", "0.1", "--csv", f, "--contacts-csv", g], capsys)
    assert rc == 0, err
    assert re.findall(r"^wrote\s+(.*)$", out, re.M) == [str(f), str(g)]
    traj = simulate("box_stack", t_end=0.1)
    c = traj.contacts
    header, rows = read_contacts(g)
    assert header == ["t", "step", "contact", "pair", "cn", "ft", "gap", "mode", "vt", "point.x", "point.y",
                      "normal.x", "normal.y"]
    assert len(rows) == int(c["count"].sum()) == 6 * 20
    h, weight = 0.005, 9.81 * 0.005
    sums = {}
    for r in rows:
        k, i = int(r[1]), int(r[2])
        assert float(r[0]) == traj.t[k + 1] == (k + 1) * h
        assert r[3] == "|".join(c["shape_pairs"][c["pair"][k, i]])
        numbers = [float(x) for x in r[4:7] + r[8:]]
        assert numbers == [c["cn"][k, i], c["ft"][k, i], c["phi"][k, i], c["vt"][k, i], *c["point"][k, i],
                           *c["normal"][k, i]]
        assert r[7] == ("separated", "sticking", "sliding")[c["mode"][k, i]] == "sticking"
        sums[k, r[3]] = sums.get((k, r[3]), 0.0) + float(r[4])
        assert float(r[5]) == 0.0
    for k in range(20):
        assert {p: round(sums[k, p] / weight, 9) for p in ("box1|table", "box1|box2", "box2|box3")} == \
            {"box1|table": 3.0, "box1|box2": 2.0, "box2|box3": 1.0}


def test_contacts_csv_friction_of_a_sliding_block_is_mu_times_its_normal_impulse(tmp_path):
    """The friction column against Coulomb's law: the block sliding down the 30 degree incline (mu = 0.3) takes
    m g cos 30 h of normal impulse per step and mu times that of friction, up the slope, each contact sliding from
    the first step."""
    g = tmp_path / "incline.csv"
    simulate("block_on_incline", t_end=0.2).contacts_to_csv(g)
    header, rows = read_contacts(g)
    per_step = {}
    for r in rows:
        # t = (-n_y, n_x) points down the slope: the block slides along +t, friction pushes it along -t
        assert r[3] == "box|incline" and r[7] == "sliding" and float(r[8]) > 0.0
        cn, ft = per_step.get(int(r[1]), (0.0, 0.0))
        per_step[int(r[1])] = (cn + float(r[4]), ft + float(r[5]))
    assert len(per_step) == 40
    for cn, ft in per_step.values():
        assert cn == pytest.approx(9.81 * 0.005 * math.cos(math.radians(30.0)), rel=1e-9)
        assert ft == pytest.approx(-0.3 * cn, rel=1e-9)


def test_contacts_csv_with_a_bad_file_name_exit_2(tmp_path, capsys):
    rc, out, err = run(["simulate", "falling_rod", "--contacts-csv", tmp_path / "c.png"], capsys)
    assert rc == 2
    line = _one_line(err)
    assert "--contacts-csv" in line and ".csv or .txt" in line and "'.png'" in line
    assert not (tmp_path / "c.png").exists() and out == ""


# --- simulate: overrides ----------------------------------------------------------------------------------------


def test_h_and_t_end_overrides_change_the_steps(tmp_path, capsys):
    f = tmp_path / "rod.csv"
    rc, out, err = run(["simulate", "falling_rod", "--h", "0.005", "--t-end", "0.1", "--csv", f], capsys)
    assert rc == 0, err
    _, data = read_csv(f)
    assert data.shape[0] == 21
    np.testing.assert_allclose(data[:, 0], 0.005 * np.arange(21), rtol=0, atol=1e-15)
    assert summary_field(out, "steps").startswith("20 (h = 0.005 s")
    assert np.array_equal(data, expected_table(simulate("falling_rod", h=0.005, t_end=0.1)))


@pytest.mark.parametrize("scene, argv, kwargs, field, value", [
    ("box_stack", ["--solver", "pgs"], dict(solver="pgs"), "solver", "pgs"),
    ("box_tip", ["--formulation", "velocity"], dict(formulation="velocity"), "formulation", "velocity"),
    ("falling_rod", ["--t-end", "0.5", "--formulation", "fixed_point", "--fixed-point-iterations", "1"],
     dict(t_end=0.5, formulation="fixed_point", fixed_point_iterations=1), "formulation", "fixed_point"),
    ("box_push", ["--support-model", "points", "--friction-directions", "4"],
     dict(support_model="points", friction_directions=4), "solver", "lemke"),
    ("box_push", ["--limit-surface-twists", "14"], dict(limit_surface_twists=14), "solver", "lemke"),
    ("box_push", ["--support-model", "points"], dict(support_model="points"), "solver", "lemke"),
])
def test_overrides_reach_the_simulation(tmp_path, capsys, scene, argv, kwargs, field, value):
    f = tmp_path / "out.csv"
    kwargs.setdefault("t_end", 0.2)
    base = ["--t-end", "0.2"] if "--t-end" not in argv else []
    rc, out, err = run(["simulate", scene, *base, *argv, "--csv", f], capsys)
    assert rc == 0, err
    assert summary_field(out, field) == value
    _, data = read_csv(f)
    with_override = expected_table(simulate(scene, **kwargs))
    default = expected_table(simulate(scene, t_end=kwargs["t_end"]))
    assert np.array_equal(data, with_override)
    assert not np.array_equal(data, default)        # each case is chosen so that the override matters
    pivots = int(simulate(scene, **kwargs).stats["pivots"].sum())
    assert summary_field(out, "total pivots") == str(pivots)


def test_scene_given_as_a_toml_path(tmp_path, capsys):
    path = tmp_path / "rod.toml"
    path.write_text((scenes_dir() / "falling_rod.toml").read_text().replace('name = "falling_rod"',
                                                                            'name = "my_rod"'))
    rc, out, err = run(["simulate", path, "--t-end", "0.05"], capsys)
    assert rc == 0, err
    assert summary_field(out, "scene") == f"my_rod ({path})"


def test_on_failure_option_is_passed_through(tmp_path, capsys, monkeypatch):
    import planar_lcp.sim as sim

    seen = {}
    real = sim.simulate

    def spy(scene, **kw):
        seen.update(kw)
        return real(scene, **kw)

    monkeypatch.setattr(sim, "simulate", spy)
    rc, out, err = run(["simulate", "falling_rod", "--t-end", "0.05", "--on-failure", "record"], capsys)
    assert rc == 0, err
    assert seen["on_failure"] == "record"
    rc, out, err = run(["simulate", "falling_rod", "--t-end", "0.05"], capsys)
    assert seen["on_failure"] == "raise"


# --- simulate: errors -------------------------------------------------------------------------------------------


def _one_line(err):
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


def test_unknown_scene_exit_2_lists_available(capsys):
    rc, out, err = run(["simulate", "no_such_scene"], capsys)
    assert rc == 2
    line = _one_line(err)
    assert "no_such_scene" in line
    for name in SHIPPED:
        assert name in line


def test_bad_toml_exit_2_names_file_and_field(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text((scenes_dir() / "falling_rod.toml").read_text().replace("mass = 1.0", "mass = -2.0"))
    rc, out, err = run(["simulate", path], capsys)
    assert rc == 2
    line = _one_line(err)
    assert str(path) in line and "bodies[0].mass" in line and "-2.0" in line
    assert out == ""


@pytest.mark.parametrize("argv, option", [
    (["--h", "-1"], "--h"), (["--h", "0"], "--h"), (["--h", "nan"], "--h"), (["--h", "abc"], "--h"),
    (["--t-end", "-0.5"], "--t-end"), (["--fixed-point-iterations", "0"], "--fixed-point-iterations"),
    (["--friction-directions", "2"], "--friction-directions"), (["--friction-directions", "4.5"],
                                                                "--friction-directions"),
    (["--solver", "cplex"], "--solver"), (["--formulation", "acceleration"], "--formulation"),
])
def test_bad_numbers_and_choices_exit_2(capsys, argv, option):
    rc, out, err = run(["simulate", "falling_rod", *argv], capsys)
    assert rc == 2
    line = _one_line(err)
    assert option in line and argv[1] in line


def test_output_in_a_missing_directory_exit_2(tmp_path, capsys):
    rc, out, err = run(["simulate", "falling_rod", "--csv", tmp_path / "nope" / "x.csv"], capsys)
    assert rc == 2
    assert "--csv" in _one_line(err) and "does not exist" in err


def test_simulation_error_exit_1(capsys, monkeypatch):
    import planar_lcp.sim as sim

    def fail(scene, **kw):
        raise SimulationError(f"{scene.source}: step 7 (t = 0.02 s, h = 0.0025): the new state is not finite")

    monkeypatch.setattr(sim, "simulate", fail)
    rc, out, err = run(["simulate", "falling_rod"], capsys)
    assert rc == 1
    line = _one_line(err)
    assert "step 7" in line and "not finite" in line


def test_simulator_value_error_exit_2(capsys, monkeypatch):
    """A solver the scene format accepts but the simulator rejects reaches the user as a clean message."""
    import planar_lcp.sim as sim

    def reject(scene, **kw):
        raise ValueError(f"solver must be one of lemke, pgs, got {kw['solver']!r}")

    monkeypatch.setattr(sim, "simulate", reject)
    rc, out, err = run(["simulate", "falling_rod", "--solver", "osqp"], capsys)
    assert rc == 2
    line = _one_line(err)
    assert "'osqp'" in line and "falling_rod.toml" in line


def test_demo_and_bench_still_parse():
    p = cli.build_parser()
    assert p.parse_args(["bench", "lcp", "--json", "x.json"]).func is cli.cmd_bench
    assert p.parse_args(["demo"]).func is cli.cmd_demo


# --- viz geometry --------------------------------------------------------------------------------------------


def test_draw_scene_puts_shapes_at_the_poses():
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon as MplPolygon

    from planar_lcp.viz import draw_scene

    scene = load_scene("falling_rod")
    pose = np.array([0.3, 0.4, 0.7])
    fig = Figure()
    ax = fig.add_subplot()
    draw_scene(ax, scene, pose[None], np.zeros((0, 3)), labels=True)
    patches = [p for p in ax.patches if isinstance(p, MplPolygon)]
    # the capsule: every outline point is at the radius from the core segment, moved to the pose
    c, s = math.cos(pose[2]), math.sin(pose[2])
    a = pose[:2] + np.array([c, s]) * -0.25
    b = pose[:2] + np.array([c, s]) * 0.25

    def seg_dist(p):
        t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        return np.linalg.norm(p - (a + t * (b - a)))

    rods = [p for p in patches if np.allclose([seg_dist(v) for v in p.get_xy()], 0.05, atol=1e-9)]
    assert len(rods) == 1
    # the table: a region below y = 0 clipped to the view, which contains the rod
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    assert x0 < 0.3 - 0.25 and x1 > 0.3 + 0.25 and y0 < 0.0 < 0.4 < y1
    tables = [p for p in patches if p is not rods[0]]
    assert len(tables) == 1
    xy = tables[0].get_xy()
    assert np.all(xy[:, 1] <= 1e-12) and np.isclose(xy[:, 1].max(), 0.0) and np.isclose(xy[:, 1].min(), y0)
    assert np.isclose(xy[:, 0].min(), x0) and np.isclose(xy[:, 0].max(), x1)
    assert {t.get_text() for t in ax.texts} == {"rod", "table"}


def test_plot_trajectory_horizontal_scene_and_every(tmp_path):
    from matplotlib.colors import to_rgb
    from matplotlib.image import imread

    from planar_lcp.viz import plot_trajectory

    traj = simulate("push_t", t_end=0.3)
    png = tmp_path / "t.png"
    assert plot_trajectory(traj, png, every=5) == png
    rgb = imread(png)[..., :3]
    left = rgb[:, : rgb.shape[1] // 2]
    # the T (first dynamic colour) and the pusher (kinematic red) are drawn; no table in a top-down view
    for colour in ("tab:blue", "tab:red"):
        assert np.all(np.abs(left - np.array(to_rgb(colour))) < 0.02, axis=-1).sum() > 50, colour
    # the table grey: only antialiased edge pixels here, > 5000 where a table band is drawn (the falling-rod test)
    assert np.all(np.abs(left - np.array(to_rgb("0.82"))) < 0.01, axis=-1).sum() < 1000
    with pytest.raises(ValueError, match="every"):
        plot_trajectory(traj, png, every=0)


def test_ctrl_c_stops_a_long_simulation_cleanly(tmp_path):
    """The rollout runs in chunks of about a quarter second, between which Python handles SIGINT: a long run stops
    within about a second with one line and exit status 130, no traceback. 200,000 steps of push_t with the points
    model take tens of seconds in one kernel call (the limit surface's take about one); the signal comes 4 s after
    the start, inside the rollout."""
    from cli_helpers import interrupt_cli
    rc, err, dt = interrupt_cli(["simulate", "push_t", "--t-end", "2000", "--support-model", "points"], "scene",
                                tmp_path, wait=4.0)
    assert rc == 130 and err == "planar-lcp simulate: error: interrupted (Ctrl-C); stopped\n", err
    assert dt < 2.0, dt


def test_ctrl_c_during_a_compile_is_still_an_interrupt(monkeypatch, capsys):
    """Ctrl-C while numba compiles: numba's clean-up raises its own error ("no compiled object yet", from saving the
    unfinished function to its cache) while the KeyboardInterrupt is being handled (seen on replay in the suite).
    The command still ends as interrupted: one line, exit status 130."""
    def compile_interrupted(args):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise RuntimeError("no compiled object yet for <Library 'lemke_kernel'>")
    parser = cli.build_parser
    monkeypatch.setattr(cli, "build_parser", lambda: _with_func(parser(), compile_interrupted))
    assert main(["scenes"]) == 130
    assert capsys.readouterr().err == "planar-lcp scenes: error: interrupted (Ctrl-C); stopped\n"
    # any other error is not taken for an interrupt
    def broken(args):
        raise RuntimeError("a bug")
    monkeypatch.setattr(cli, "build_parser", lambda: _with_func(parser(), broken))
    with pytest.raises(RuntimeError, match="a bug"):
        main(["scenes"])


def _with_func(parser, func):
    """The parser with `func` as the command of every subcommand (planar_lcp.cli parses with parse_known_args)."""
    orig = parser.parse_known_args

    def parse_known_args(argv=None, namespace=None):
        args, extra = orig(argv, namespace)
        args.func = func
        return args, extra
    parser.parse_known_args = parse_known_args
    return parser
