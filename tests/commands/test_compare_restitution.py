"""Restitution in the pymunk comparison: the scene's per-pair coefficient on pymunk's arbiters, a
bounce in pymunk that shows it acts, and `planar-lcp compare --restitution`.

Oracles: Scene.restitution_between (the contract: per pair from the scene, not pymunk's product of elasticities);
Newton's law for a point mass dropped from H (apex e^2 H); the bad-input conventions of tests/commands/test_bad_input.py.
"""

import csv

import numpy as np
import pytest
from cli_helpers import run_cli

pymunk = pytest.importorskip("pymunk")

from planar_lcp.bridges.pymunk import build_space, contact_pairs, simulate_pymunk  # noqa: E402
from planar_lcp.spec.scene import load_scene, parse_scene, restitution_setting, scenes_dir  # noqa: E402

DISK = str(scenes_dir() / "bouncing_disk.toml")


def _two_disks(world):
    """Two disks falling at 1 m/s onto a table from 1 mm above it (contact within two 1 ms steps)."""
    disk = [{"type": "disk", "radius": 0.1}]
    return parse_scene({
        "name": "two_disks", "world": world,
        "bodies": [
            {"name": "ball", "type": "dynamic", "mass": 1.0, "position": [-1.0, 0.101], "velocity": [0.0, -1.0],
             "shapes": disk},
            {"name": "puck", "type": "dynamic", "mass": 1.0, "position": [1.0, 0.101], "velocity": [0.0, -1.0],
             "shapes": disk},
            {"name": "table", "type": "static", "shapes": [{"type": "halfplane", "point": [0.0, 0.0],
                                                            "normal": [0.0, 1.0]}]},
        ]})


def _arbiter_restitutions(scene, steps=5, h=1e-3):
    """{body name: restitution of its arbiter with the table} after `steps` steps of h."""
    space, hd = build_space(scene, h=h)
    seen = {}
    for _ in range(steps):
        space.step(h)
        for name in hd.dynamic_names:
            def visit(arb, name=name):
                names = {hd.shape_body[s] for s in arb.shapes}
                if names == {name, "table"}:
                    seen[name] = arb.restitution
            hd.bodies[name].each_arbiter(visit)
    return hd, seen


def test_pymunks_arbiter_restitution_is_the_scenes_pair_value():
    scene = _two_disks({"restitution": 0.3, "restitution_pairs": [{"a": "table", "b": "ball", "e": 0.8}]})
    assert scene.restitution_between("ball", "table") == 0.8 and scene.restitution_between("puck", "table") == 0.3
    pairs = contact_pairs(scene, "restitution")
    assert pairs == {("ball", "puck"): 0.3, ("ball", "table"): 0.8, ("puck", "table"): 0.3}
    hd, seen = _arbiter_restitutions(scene)
    assert hd.restitution_mode == "pre_solve" and hd.pair_e == pairs
    # shapes keep elasticity 0 (pymunk's product rule alone would give 0): the values are the callback's, exactly
    assert all(sh.elasticity == 0.0 for shapes in hd.shapes.values() for sh in shapes)
    assert seen == {"ball": 0.8, "puck": 0.3}
    # restitution 0 everywhere: no callback, and the product of the elasticities is 0
    hd, seen = _arbiter_restitutions(_two_disks({}))
    assert hd.restitution_mode == "zero" and seen == {"ball": 0.0, "puck": 0.0}
    # the override of `compare --restitution` (world.restitution) leaves the pair entry alone
    hd, seen = _arbiter_restitutions(restitution_setting(scene, 0.1))
    assert seen == {"ball": 0.8, "puck": 0.1}


def _apex_after_first_bounce(tr, r):
    """The highest point of the disk's bottom after its first impact (the first step its velocity turns upward)."""
    vy = tr.v_com[:, 0, 1]
    k = int(np.flatnonzero((vy[:-1] < 0) & (vy[1:] > 0))[0]) + 1
    return float(np.max(tr.q_com[k:, 0, 1]) - r), k


def test_a_disk_dropped_in_pymunk_with_e_half_bounces_to_about_e_squared_of_its_height():
    """bouncing_disk: H = 1 m, e = 0.5, h = 1 ms. Chipmunk detects the contact only once the disk overlaps the table
    (positions are integrated first), so the bounce starts from up to |v| h = 4.4 mm deep (v = -sqrt(2 g H)): the
    apex above the surface is e^2 H less at most that, plus O(h) timing; 6 mm covers both. The impact itself is
    Newton's law on the step's start velocity: -v+/v- = e to Chipmunk's convergence."""
    scene = load_scene("bouncing_disk")
    r = scene.body("disk").shapes[0].radius
    tr = simulate_pymunk(scene, t_end=0.8)
    apex, k = _apex_after_first_bounce(tr, r)
    e = scene.world.restitution
    assert e == 0.5
    assert abs(apex - e ** 2 * 1.0) <= 6e-3, apex
    assert -tr.v_com[k, 0, 1] / tr.v_com[k - 1, 0, 1] == pytest.approx(e, abs=1e-3)
    # the same drop at e = 0 does not bounce: the coefficient is what made the difference
    tr0 = simulate_pymunk(restitution_setting(scene, 0.0), t_end=0.8)
    assert np.max(tr0.q_com[tr0.t > 0.5, 0, 1]) - r < 1e-3


def _report_rows(out):
    with open(out / "report.csv") as f:
        return list(csv.DictReader(f))


def test_compare_bouncing_disk_end_to_end_and_restitution_reaches_both_simulators(tmp_path):
    out = tmp_path / "b"
    r = run_cli("compare", "bouncing_disk", "--out", out, "--t-end", "0.6", "--no-gif")
    assert r.returncode == 0, r.stderr
    for f in ("report.md", "report.csv", "trajectories.png", "frames.png"):
        assert (out / f).stat().st_size > 500, f
    assert not (out / "side_by_side.gif").exists()
    md = (out / "report.md").read_text()
    assert "restitution (both simulators): e = 0.5" in md and "restitution the scene's e for its pair" in md
    # at 0.6 s the disk is in the air after its first bounce (apex 0.25 m at 0.68 s) in both
    assert all(float(row["final_y_m"]) > 0.2 for row in _report_rows(out))
    # --restitution 0 for both: no bounce, both at rest on the table at 0.6 s; the command line records the flag
    from planar_lcp.cli import main
    out0 = tmp_path / "b0"
    assert main(["compare", "bouncing_disk", "--out", str(out0), "--t-end", "0.6", "--restitution", "0",
                 "--no-gif"]) == 0
    rows = _report_rows(out0)
    assert [row["simulator"] for row in rows] == ["planar_lcp", "pymunk"]
    # (pymunk's disk is still 1.8 mm deep: it stopped up to |v| h = 4.4 mm in the table and the bias pushes it out
    # slowly)
    assert all(abs(float(row["final_y_m"]) - 0.1) < 5e-3 for row in rows)
    md = (out0 / "report.md").read_text()
    assert f"planar-lcp compare bouncing_disk --out {out0} --t-end 0.6 --restitution 0.0 --no-gif" in md
    assert "restitution (both simulators): e = 0 " in md and "elasticity 0" in md


@pytest.mark.parametrize("value", ["1.5", "-0.1"])
def test_compare_rejects_a_restitution_outside_0_1_before_any_work(tmp_path, value):
    r = run_cli("compare", "bouncing_disk", "--out", tmp_path / "c", "--restitution", value)
    if "pymunk is not installed" in r.stderr:
        pytest.skip("pymunk missing")
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert lines == [f"planar-lcp compare: error: {DISK}: --restitution must be in [0, 1], got {float(value)}"]
    assert not (tmp_path / "c").exists()
