"""`planar-lcp study falling-rod` and `planar-lcp study four-disks` (--quick), checked against physics."""

import csv
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.optimize import brentq

from planar_lcp.cli import main
from planar_lcp.spec.scene import load_scene
from planar_lcp.sim import simulate

pytestmark = pytest.mark.slow

ROD_FILES = {"strobe.png", "vy.png", "omega.png", "vx.png", "seed_arm.png", "events.csv", "events.md",
             "convergence.csv", "convergence.md", "convergence_phase.csv"}
DISK_FILES = {"trajectories.png", "impulses.png", "velocity.png", "events.csv", "events.md", "cascade.csv",
              "cascade.md", "convergence.csv", "convergence.md", "convergence_phase.csv"}
CONVERGENCE_COLUMNS = ["h", "vel_err", "pos_err", "vel_var", "order_vel", "order_pos"]
PHASE_COLUMNS = ["h", "phases", "vel_err_mean", "vel_err_max", "pos_err_mean", "pos_err_max", "order_vel",
                 "order_pos", "failed_steps"]
ROD_EVENT_COLUMNS = ["h", "friction_arm", "t_impact", "t_tip_stops_right", "t_slap_down", "t_rest", "slide_left_s",
                     "contact_losses", "x_final", "theta_final"]
DISK_EVENT_COLUMNS = ["h", "t_ground", "t_first_disk_contact", "cascade_step", "active_contacts", "active_disk_disk",
                      "active_table"]
CASCADE_COLUMNS = ["h", "step", "t_start", "t_end", "body_a", "body_b", "cn", "ft", "mode", "point_x", "point_y",
                   "normal_x", "normal_y"]


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], [dict(zip(rows[0], r)) for r in rows[1:]]


def num(s):
    return float(s) if s != "" else math.nan


@pytest.fixture(scope="module")
def rod_dir(tmp_path_factory, monkeypatch_module):
    out = tmp_path_factory.mktemp("falling_rod")
    assert main(["study", "falling-rod", "--out", str(out), "--quick"]) == 0
    return out


@pytest.fixture(scope="module")
def disk_dir(tmp_path_factory, monkeypatch_module):
    out = tmp_path_factory.mktemp("four_disks")
    assert main(["study", "four-disks", "--out", str(out), "--quick"]) == 0
    return out


@pytest.fixture(scope="module")
def monkeypatch_module():
    mp = pytest.MonkeyPatch()
    mp.setenv("MPLBACKEND", "Agg")
    yield mp
    mp.undo()


def exact_rod_impact():
    """Free flight of the scene's rod until its lower cap touches y = 0 (independent of the study's code)."""
    sc = load_scene("falling_rod")
    rod = sc.bodies[0]
    cap = rod.shapes[0]
    g = -sc.world.gravity[1]
    y0, th0, w0 = rod.position[1], rod.angle, rod.angular_velocity

    def gap(t):
        return y0 - 0.5 * g * t * t - 0.5 * cap.length * math.sin(th0 + w0 * t) - cap.radius

    return brentq(gap, 0.0, 0.6, xtol=1e-14)   # sin > 0 on [0, 0.6]: theta goes from 30 to 168 degrees


def test_exact_rod_impact_time():
    assert exact_rod_impact() == pytest.approx(0.385818, abs=1e-6)


def test_rod_files_and_columns(rod_dir):
    assert ROD_FILES <= {p.name for p in rod_dir.iterdir()}
    for name in ROD_FILES:
        if name.endswith(".png"):
            assert 1000 < (rod_dir / name).stat().st_size < 300_000, name
    assert read_csv(rod_dir / "events.csv")[0] == ROD_EVENT_COLUMNS
    assert read_csv(rod_dir / "convergence.csv")[0] == CONVERGENCE_COLUMNS
    assert read_csv(rod_dir / "convergence_phase.csv")[0] == PHASE_COLUMNS
    _, rows = read_csv(rod_dir / "convergence.csv")
    assert [num(r["h"]) for r in rows] == [0.0025, 0.00125, 0.000625]


def test_rod_first_contact_within_two_steps_before_the_exact_time(rod_dir):
    t_exact = exact_rod_impact()
    _, rows = read_csv(rod_dir / "events.csv")
    assert len(rows) == 4          # three step sizes and Stewart & Trinkle's friction arm
    for r in rows:
        h, t_end_of_step = num(r["h"]), num(r["t_impact"])
        assert t_end_of_step >= t_exact - 2 * h - 1e-12, r      # at most two steps early
        assert t_end_of_step - h <= t_exact + 1e-12, r           # never after the step containing t_exact


def test_rod_ends_at_rest_and_horizontal(rod_dir):
    _, rows = read_csv(rod_dir / "events.csv")
    for r in rows:
        th = num(r["theta_final"])
        assert min(abs(th - math.pi), abs(th), abs(th - 2 * math.pi)) < 1e-6, r
        assert math.isfinite(num(r["t_rest"])) and num(r["t_rest"]) < 0.7, r
        # Stewart & Trinkle's sequence: impact, slap-down, then rest
        assert num(r["t_impact"]) < num(r["t_slap_down"]) < num(r["t_rest"]), r
    tr = simulate("falling_rod", h=0.0025)
    x, y, th = tr.q[-1, 0]
    assert min(abs(th - math.pi), abs(th)) < 1e-6
    assert np.abs(tr.v[-1]).max() < 1e-6
    assert y == pytest.approx(0.05, abs=1e-6)          # lying on its side: centre at the cap radius


def test_rod_convergence_order(rod_dir):
    _, rows = read_csv(rod_dir / "convergence_phase.csv")
    assert [num(r["h"]) for r in rows] == [0.0025, 0.00125]
    finest = rows[-1]
    assert num(finest["order_vel"]) >= 0.7, rows
    assert num(finest["order_pos"]) >= 0.7, rows
    for r in rows:        # errors of order h: well below 1 m/s * 1 s at these steps
        assert num(r["vel_err_mean"]) < 20 * num(r["h"]), r


def test_disk_files_and_columns(disk_dir):
    assert DISK_FILES <= {p.name for p in disk_dir.iterdir()}
    for name in DISK_FILES:
        if name.endswith(".png"):
            assert 1000 < (disk_dir / name).stat().st_size < 300_000, name
    assert read_csv(disk_dir / "events.csv")[0] == DISK_EVENT_COLUMNS
    assert read_csv(disk_dir / "cascade.csv")[0] == CASCADE_COLUMNS
    assert read_csv(disk_dir / "convergence.csv")[0] == CONVERGENCE_COLUMNS
    assert read_csv(disk_dir / "convergence_phase.csv")[0] == PHASE_COLUMNS


def test_disk_impulse_reaches_the_last_disk_in_one_step(disk_dir):
    _, rows = read_csv(disk_dir / "cascade.csv")
    by_h = {}
    for r in rows:
        by_h.setdefault(num(r["h"]), []).append(r)
    assert set(by_h) == {0.0025, 0.00125, 0.000625}
    for h, rs in by_h.items():
        assert len({r["step"] for r in rs}) == 1
        cn = {(r["body_a"], r["body_b"]): num(r["cn"]) for r in rs}
        chain = [cn[("thrown", "d1")], cn[("d1", "d2")], cn[("d2", "d3")]]
        assert min(chain) > 0, (h, cn)
        # each disk passes on less than it receives (part goes into its own motion): decreasing along the row
        assert chain[0] > chain[1] > chain[2], (h, chain)
        # d1 is pushed down by the thrown disk's friction (seed 4.2): the table holds it
        assert cn[("d1", "table")] > 0, (h, cn)
    # at Stewart & Trinkle's figure step every contact, disk-disk and disk-table, carries an impulse in that one step
    assert all(num(r["cn"]) > 0 for r in by_h[0.0025]) and len(by_h[0.0025]) == 7


def test_disk_table_impulses_balance_gravity_and_disk_friction(disk_dir):
    """For the resting disks d1..d3 (vy = 0 before the step, on the table): Signorini + vertical momentum give
    table c_n = max(0, m g h - V), V the upward impulse from the other disks in that step."""
    sc = load_scene("four_disks")
    g = -sc.world.gravity[1]
    mass = {b.name: b.mass for b in sc.bodies if b.type == "dynamic"}
    _, rows = read_csv(disk_dir / "cascade.csv")
    for h in {num(r["h"]) for r in rows}:
        rs = [r for r in rows if num(r["h"]) == h]
        up = dict.fromkeys(mass, 0.0)
        table = dict.fromkeys(mass, 0.0)
        for r in rs:
            a, b = r["body_a"], r["body_b"]
            nx, ny, cn, ft = num(r["normal_x"]), num(r["normal_y"]), num(r["cn"]), num(r["ft"])
            vert = cn * ny + ft * nx           # tangent t = (-n_y, n_x)
            if b == "table":
                table[a] = cn
            else:
                up[a] += vert
                up[b] -= vert
        for d in ("d1", "d2", "d3"):
            expect = max(0.0, mass[d] * g * h - up[d])
            assert table[d] == pytest.approx(expect, abs=1e-9 + 1e-6 * expect), (h, d, table[d], up[d])


def test_disk_events_match_the_2d_rigid_body_times(disk_dir):
    _, rows = read_csv(disk_dir / "events.csv")
    sc = load_scene("four_disks")
    thrown = sc.bodies[0]
    r = thrown.shapes[0].radius
    g = -sc.world.gravity[1]
    t_land = math.sqrt(2 * (thrown.position[1] - r) / g)
    v_roll = thrown.velocity[0] / (1 + thrown.inertia / (thrown.mass * r * r))
    t_hit = t_land + (sc.bodies[1].position[0] - 2 * r - thrown.velocity[0] * t_land) / v_roll
    for row in rows:
        h = num(row["h"])
        assert abs(num(row["t_ground"]) - t_land) <= 2 * h, row
        assert abs(num(row["t_first_disk_contact"]) - t_hit) <= 3 * h, row
        assert int(row["active_disk_disk"]) == 3


def test_study_cli_does_not_import_matplotlib():
    code = ("import sys, planar_lcp.cli as c; c.build_parser(); "
            "bad = [m for m in ('matplotlib', 'tqdm') if m in sys.modules]; print(bad); "
            "sys.exit(1 if bad else 0)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_study_out_must_be_a_directory(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["study", "falling-rod", "--out", str(f), "--quick"]) == 2
    assert capsys.readouterr().err == f"planar-lcp study: error: --out {f}: must be a directory, got an existing file\n"
