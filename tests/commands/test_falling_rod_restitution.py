"""`planar-lcp study falling-rod --restitution E`: the flag reaches every run of the study, bad values are
refused before any work, and without it the study is unchanged.

The study runs in-process on a short run: T_END cut to 0.45 s (the first impact is at 0.3858 s), --quick."""

import csv
import math

import numpy as np
import pytest
from cli_helpers import run_cli

import planar_lcp.sim as sim_module
from planar_lcp.cli import main
from planar_lcp.studies import common
from planar_lcp.studies import falling_rod as fr

SHORT_T_END = 0.45


def first_contact_step(tr):
    return next((k for k in range(len(tr.t) - 1) if common.active_contacts(tr, k)), None)


def rises_after_first_contact(tr):
    """True if the rod's centre of mass moves up (vy > 0) at some time after its first contact step."""
    k0 = first_contact_step(tr)
    assert k0 is not None, "the run never touches the table"
    return bool((tr.v_com[k0 + 1:, 0, 1] > 0).any())


def run_short_study(out, monkeypatch, *flags):
    """Run the study (--quick, t = 0 to 0.45 s) through the CLI entry point in-process; returns (every Trajectory
    simulate() returned during it, every figure title saved)."""
    runs, titles = [], []
    real_simulate, real_save = sim_module.simulate, common.save_png

    def recording_simulate(*args, **kwargs):
        tr = real_simulate(*args, **kwargs)
        runs.append(tr)
        return tr

    def recording_save(fig, path, *args, **kwargs):
        sup = getattr(fig, "_suptitle", None)
        titles.extend(t for t in [sup.get_text() if sup else ""] + [ax.get_title() for ax in fig.axes] if t)
        return real_save(fig, path, *args, **kwargs)

    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setattr(sim_module, "simulate", recording_simulate)
    monkeypatch.setattr(common, "save_png", recording_save)
    monkeypatch.setattr(fr, "T_END", SHORT_T_END)
    assert main(["study", "falling-rod", "--out", str(out), "--quick", *flags]) == 0
    return runs, titles


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    """The short study without the flag, with --restitution 0.5 and with --restitution 0."""
    out = {}
    for key, flags in (("default", ()), ("e05", ("--restitution", "0.5")), ("e0", ("--restitution", "0"))):
        d = tmp_path_factory.mktemp(f"rod_{key}")
        mp = pytest.MonkeyPatch()          # one per study: the recording wrappers must not stack
        try:
            runs, titles = run_short_study(d, mp, *flags)
        finally:
            mp.undo()
        out[key] = dict(dir=d, runs=runs, titles=titles)
    return out


def test_restitution_reaches_every_run_and_the_rod_rebounds(studies):
    runs = studies["e05"]["runs"]
    # the study's step sizes, the run with Stewart & Trinkle's friction arm and the grid-phase runs: all of them
    assert len(runs) >= 4 + 16
    for tr in runs:
        assert tr.scene.world.restitution == 0.5
        assert rises_after_first_contact(tr), (tr.options.h, tr.scene.bodies[0].position)


def test_without_the_flag_the_rod_does_not_rebound(studies):
    runs = studies["default"]["runs"]
    assert len(runs) >= 4 + 16
    assert all(tr.scene.world.restitution == 0.0 for tr in runs)
    # the first three runs are the study's step sizes, friction at the contact point (Stewart & Trinkle's friction arm, run
    # next, lifts the tip off the table after the impact: docs/falling-rod.md; not checked here)
    main_runs = runs[:3]
    assert [tr.options.h for tr in main_runs] == [0.0025, 0.00125, 0.000625]
    for tr in main_runs:
        assert not rises_after_first_contact(tr), tr.options.h


def test_restitution_is_recorded_in_the_tables_and_titles(studies):
    d = studies["e05"]["dir"]
    for name in ("events.md", "convergence.md"):
        assert "Coefficient of restitution (`--restitution`): e = 0.5 in every run." in (d / name).read_text()
    titles = studies["e05"]["titles"]
    for start in ("Falling rod, e = 0.5, h = 0.0025", "vy [m/s] of the rod, e = 0.5",
                  "omega [rad/s] of the rod, e = 0.5", "vx [m/s] of the rod, e = 0.5", "Friction moment arm, e = 0.5"):
        assert any(t.startswith(start) for t in titles), (start, titles)
    # without the flag: no such line, no e in the titles
    d0 = studies["default"]["dir"]
    for name in ("events.md", "convergence.md"):
        assert "restitution" not in (d0 / name).read_text()
    assert not any("e = " in t for t in studies["default"]["titles"]), studies["default"]["titles"]


def test_restitution_zero_is_the_default_study(studies):
    """--restitution 0 runs Stewart & Trinkle's inelastic model: the same numbers as no flag, bit for bit; only the note."""
    d0, dz = studies["default"]["dir"], studies["e0"]["dir"]
    for name in ("events.csv", "convergence.csv", "convergence_phase.csv"):
        assert (dz / name).read_text() == (d0 / name).read_text(), name
    assert not any("e = " in t for t in studies["e0"]["titles"])       # titles name e only when e > 0
    for a, b in zip(studies["default"]["runs"], studies["e0"]["runs"]):
        assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v)
    events_05 = read_rows(studies["e05"]["dir"] / "events.csv")
    events_0 = read_rows(d0 / "events.csv")
    # contact-point rows: the e = 0.5 rod loses contact after its impact, the e = 0 rod does not
    assert all(int(r["contact_losses"]) >= 1 for r in events_05[:3])
    assert all(int(r["contact_losses"]) == 0 for r in events_0[:3])
    assert all(math.isfinite(float(r["t_impact"])) for r in events_05 + events_0)


@pytest.mark.parametrize("value", ["-0.1", "1.5", "abc", "nan", "inf", "-inf", "1e400"])
def test_bad_restitution_is_one_line_exit_2(tmp_path, value):
    out = tmp_path / "out"
    r = run_cli("study", "falling-rod", "--out", out, "--quick", f"--restitution={value}")
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    assert r.stderr == (f"planar-lcp study falling-rod: error: argument --restitution: must be a number in [0, 1], "
                        f"got {value!r}\n")
    assert r.stdout == ""
    assert not out.exists()            # checked before any work: not even the output directory


def test_bad_restitution_with_a_space_before_a_negative_value(tmp_path):
    r = run_cli("study", "falling-rod", "--out", tmp_path / "out", "--restitution", "-2")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == ("planar-lcp study falling-rod: error: argument --restitution: must be a number in [0, 1], "
                        "got '-2'\n")
