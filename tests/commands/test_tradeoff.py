"""planar-lcp tradeoff: the sweep's measurements and the Pareto front."""

import csv
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planar_lcp.cli import main
from planar_lcp.sim import simulate
from planar_lcp.studies.accuracy import grid_ratio, table1_errors
from planar_lcp.benchmarks.tradeoff import (COLUMNS, QUICK_SUPPORT_SWEEP, REFERENCE_SUPPORT, _settings,
                                             pareto_front, plot_pareto, support_series)

#: the CSV columns as docs/tradeoff.md documents them (the contract: readers find the columns by these names)
DOCUMENTED_COLUMNS = ["scene", "h", "solver", "pgs_iterations", "formulation", "support_model",
                      "limit_surface_twists", "friction_directions", "velocity_error", "position_error",
                      "max_penetration", "energy_drift", "cpu_s_per_sim_s", "failed_steps", "reference"]


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(0.001, 10), st.floats(1e-9, 10)), min_size=1, max_size=30))
def test_pareto_front_is_exactly_the_non_dominated_set(points):
    front = set(pareto_front(points))
    for i, (c, e) in enumerate(points):
        dominated = any((c2 <= c and e2 < e) or (c2 < c and e2 <= e) for c2, e2 in points)
        duplicate_earlier = any(points[j] == (c, e) for j in range(i))
        assert (i in front) == (not dominated and not duplicate_earlier)


def test_errors_vanish_against_itself_and_shrink_with_h():
    """Against a fine reference, the rest position converges monotonically (about first order). The velocity error
    integral converges too, but not monotonically: each velocity jump (impact, slap-down) lands on a step-aligned
    time whose phase depends on h, and a jump one step off costs |dv| h whatever h is."""
    ref = simulate("falling_rod", h=0.0003125, formulation="fixed_point", record_contacts=False)
    assert table1_errors(ref, ref, 1.0) == (0.0, 0.0)
    runs = [simulate("falling_rod", h=h, record_contacts=False) for h in (0.01, 0.005, 0.0025, 0.00125, 0.000625)]
    x_err = [abs(tr.q[-1, 0, 0] - ref.q[-1, 0, 0]) for tr in runs]
    assert all(a > b for a, b in zip(x_err, x_err[1:])), x_err
    v_err = [table1_errors(tr, ref, 1.0)[0] for tr in runs]
    assert v_err[-1] < 0.05 * v_err[0]


def _run(h, v, q=None):
    """A stand-in Trajectory: velocities v (T, 1, 3) at t = k h."""
    v = np.asarray(v, float)
    return SimpleNamespace(t=np.arange(len(v)) * h, v=v, q=np.zeros_like(v) if q is None else q,
                           options=SimpleNamespace(h=h))


def test_velocity_error_integrates_the_step_function_of_the_time_stepping():
    """Stewart & Trinkle's integral of ||v_h(t) - v_ref(t)||_inf with v_h(t) = v_(k+1) over the step (t_k, t_k+1]: a run
    whose velocity is off by c from its first step on has the error c t_end exactly (a trapezoidal rule gives
    c (t_end - h / 2)), and an offset in the last step alone costs c h."""
    h, n, c = 0.01, 50, 0.3
    ref = _run(h / 4, np.zeros((4 * n + 1, 1, 3)))
    v = np.zeros((n + 1, 1, 3))
    v[1:, 0, 2] = -c
    assert table1_errors(_run(h, v), ref, n * h)[0] == pytest.approx(c * n * h, rel=1e-14)
    v = np.zeros((n + 1, 1, 3))
    v[-1, 0, 0] = c
    assert table1_errors(_run(h, v), ref, n * h)[0] == pytest.approx(c * h, rel=1e-14)
    q = np.zeros((n + 1, 1, 3))
    q[7, 0, 1] = -2 * c
    assert table1_errors(_run(h, np.zeros((n + 1, 1, 3)), q), ref, n * h) == (0.0, 2 * c)


def test_the_reference_step_must_divide_h():
    assert grid_ratio(0.01, 0.0025) == 4
    with pytest.raises(ValueError, match="not a multiple"):
        grid_ratio(0.01, 0.003)


def test_the_columns_are_the_documented_ones():
    assert COLUMNS == DOCUMENTED_COLUMNS
    docs = Path(__file__).resolve().parents[2] / "docs"
    doc = " ".join((docs / "tradeoff.md").read_text().split())
    assert "`" + "`, `".join(DOCUMENTED_COLUMNS) + "`." in doc
    header = (docs / "figures" / "tradeoff" / "tradeoff.csv").read_text().splitlines()[0]
    assert header.strip().split(",") == DOCUMENTED_COLUMNS  # the committed sweep is of this version


def test_the_horizontal_plane_sweeps_both_support_models_against_the_limit_surface():
    """box_push: the grid runs the scene's own table friction (the default limit surface, K = 6); the support sweep
    adds both models at every h with lemke/position; the reference is the limit surface with K = 62, and a vertical
    scene has no table (every support key None)."""
    for quick in (True, False):
        sc, settings, ref = _settings("box_push", quick)
        assert sc.world.support_model == "limit_surface" and sc.sim.limit_surface_twists == 6
        grid = [s for s in settings if (s["solver"], s["formulation"]) != ("lemke", "position")]
        assert grid and all((s["support_model"], s["limit_surface_twists"], s["friction_directions"])
                            == ("limit_surface", 6, None) for s in grid)
        hs = sorted({s["h"] for s in settings})
        for h in hs:
            at_h = [s for s in settings if s["h"] == h and (s["solver"], s["formulation"]) == ("lemke", "position")]
            knobs = sorted((s["support_model"], s["limit_surface_twists"] or s["friction_directions"]) for s in at_h)
            expect = QUICK_SUPPORT_SWEEP if quick else [("limit_surface", K) for K in (6, 14, 26)] + [
                ("points", k) for k in (4, 8, 16, 32)]
            assert knobs == sorted(expect), (h, knobs)
        assert (ref["solver"], ref["formulation"], ref["h"]) == ("lemke", "fixed_point", hs[0] / 2)
        assert (ref["support_model"], ref["limit_surface_twists"], ref["friction_directions"]) == (
            "limit_surface", 62, None) == (*REFERENCE_SUPPORT, None)
    _, settings, ref = _settings("falling_rod", False)
    assert all(s[k] is None for s in [*settings, ref] for k in ("support_model", "limit_surface_twists",
                                                                 "friction_directions"))
    assert len(settings) == 5 * 5 * 3


@pytest.mark.needs_jit  # 4 runs of 1600 steps
def test_the_limit_surface_reference_is_converged_in_K_and_the_points_model_is_not_it():
    """The reference of box_push (lemke, fixed_point, h_ref = 0.00125, limit surface K = 62): at h_ref, K = 6 gives
    the same run to round-off (the re-centred twist carries the motion), K = 254 moves it by less than half the
    error of the finest swept default (h = 0.0025, K = 6), and the points model at h_ref, even with k = 32, stays
    more than 20 times farther from it than K = 254: the points rows of the sweep measure a modelling error."""
    kw = dict(h=0.00125, formulation="fixed_point", record_contacts=False)
    ref = simulate("box_push", support_model="limit_surface", limit_surface_twists=62, **kw)
    k6 = simulate("box_push", support_model="limit_surface", limit_surface_twists=6, **kw)
    k254 = simulate("box_push", support_model="limit_surface", limit_surface_twists=254, **kw)
    points = simulate("box_push", support_model="points", friction_directions=32, **kw)
    finest = simulate("box_push", h=0.0025, record_contacts=False)
    assert max(table1_errors(k6, ref, 2.0)) < 1e-12
    shift = table1_errors(k254, ref, 2.0)[0]
    assert 0 < shift < 0.5 * table1_errors(finest, ref, 2.0)[0]
    assert table1_errors(points, ref, 2.0)[0] > 20 * shift


def test_support_series_and_the_plot_read_the_csv_rows(tmp_path):
    """support_series groups the lemke/position rows by model and knob, limit surface first; the plot takes rows
    as csv.DictReader gives them back (strings, "" for a key that does not apply)."""
    def row(h, solver, form, model, K, k, err):
        return dict(scene="box_push", h=str(h), solver=solver, pgs_iterations="20" if solver == "pgs" else "",
                    formulation=form, support_model=model, limit_surface_twists=K, friction_directions=k,
                    velocity_error=str(err), cpu_s_per_sim_s=str(err / 10))
    rows = [row(0.01, "lemke", "position", "points", "", "8", 0.1), row(0.02, "lemke", "position", "points", "", "8",
            0.2), row(0.01, "lemke", "position", "limit_surface", "14", "", 0.01), row(0.01, "pgs", "position",
            "limit_surface", "6", "", 0.03), row(0.01, "lemke", "velocity", "limit_surface", "6", "", 0.02)]
    series = support_series(rows)
    assert list(series) == [("limit_surface", 14), ("points", 8)]
    assert [r["h"] for r in series[("points", 8)]] == ["0.01", "0.02"]
    assert support_series([dict(r, support_model="") for r in rows]) == {}
    plot_pareto(rows, tmp_path / "p.png", "box_push")
    assert (tmp_path / "p.png").stat().st_size > 10000


@pytest.mark.slow  # minutes without the JIT (NUMBA_DISABLE_JIT=1)
def test_quick_sweep_writes_csv_and_plots(tmp_path, capsys):
    assert main(["tradeoff", "--quick", "--no-progress", "--scenes", "falling_rod", "box_push",
                 "--out", str(tmp_path)]) == 0
    rows = list(csv.DictReader(open(tmp_path / "tradeoff.csv")))
    assert list(rows[0].keys()) == COLUMNS == DOCUMENTED_COLUMNS
    assert {r["scene"] for r in rows} == {"falling_rod", "box_push"}
    assert all(float(r["cpu_s_per_sim_s"]) > 0 and int(r["failed_steps"]) == 0 for r in rows)
    lem = [r for r in rows if r["scene"] == "falling_rod" and r["solver"] == "lemke"]
    assert all(float(r["energy_drift"]) < 1e-3 for r in lem)
    rod = [r for r in rows if r["scene"] == "falling_rod"]
    assert all(r["support_model"] == r["limit_surface_twists"] == r["friction_directions"] == "" for r in rod)
    assert {r["reference"] for r in rod} == {"lemke/fixed_point h=0.00125"}
    box = [r for r in rows if r["scene"] == "box_push"]
    assert {r["reference"] for r in box} == {"lemke/fixed_point h=0.005 K=62"}
    # both support models in the horizontal plane, each with its own knob only
    assert {(r["support_model"], r["limit_surface_twists"], r["friction_directions"]) for r in box} == {
        ("limit_surface", "6", ""), ("limit_surface", "14", ""), ("points", "", "8")}
    by = {(r["support_model"], r["limit_surface_twists"] or r["friction_directions"], r["h"]): r for r in box
          if r["solver"] == "lemke"}
    for h in ("0.01", "0.02"):
        # the points model's modelling error against the limit-surface reference dwarfs the step's error
        assert float(by["points", "8", h]["velocity_error"]) > 3 * float(by["limit_surface", "6", h]["velocity_error"])
    assert (tmp_path / "pareto_falling_rod.png").stat().st_size > 10000
    assert (tmp_path / "pareto_box_push.png").stat().st_size > 10000
    out = capsys.readouterr().out
    assert "Pareto front" in out and "K=6" in out


def test_unknown_scene_is_an_error(capsys):
    assert main(["tradeoff", "--quick", "--scenes", "nosuch"]) == 2
    assert "unknown scene 'nosuch'" in capsys.readouterr().err


# --- a sweep that loses nothing (records.jsonl, --resume, Ctrl-C) ------------------------------------------------

#: the CSV columns a setting's seed-free simulation decides (all but the cost, a clock's)
DETERMINISTIC_COLUMNS = [c for c in DOCUMENTED_COLUMNS if c != "cpu_s_per_sim_s"]


def _csv_rows(out):
    with open(out / "tradeoff.csv", newline="") as f:
        return [tuple(r[c] for c in DETERMINISTIC_COLUMNS) for r in csv.DictReader(f)]


def _files(out):
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(out.iterdir())}


@pytest.fixture(scope="module")
def quick_sweep(tmp_path_factory):
    """A finished `tradeoff --quick --scenes falling_rod` (seconds): its --out."""
    pytest.importorskip("distributed")
    from cli_helpers import run_cli
    out = tmp_path_factory.mktemp("quick_sweep") / "out"
    r = run_cli("tradeoff", "--quick", "--scenes", "falling_rod", "--jobs", "2", "--no-progress", "--out", out)
    assert r.returncode == 0, r.stderr
    return out


@pytest.mark.needs_jit  # the fixture's sweep
@pytest.mark.parametrize("argv, was, got", [
    (["--quick", "--scenes", "box_push"], "scenes falling_rod", "scenes box_push"),
    (["--quick", "--scenes", "falling_rod", "box_push"], "scenes falling_rod", "scenes falling_rod box_push"),
    (["--scenes", "falling_rod"], "the --quick sweep", "the full sweep (no --quick)"),
])
def test_resume_of_another_sweep_is_refused_before_any_work(quick_sweep, argv, was, got):
    """--resume with other scenes or without --quick: one line naming the file and the difference
    (the file's and the command's), exit status 2, nothing written."""
    from cli_helpers import run_cli
    before = _files(quick_sweep)
    r = run_cli("tradeoff", *argv, "--resume", "--no-progress", "--out", quick_sweep)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == (f"planar-lcp tradeoff: error: --resume: {quick_sweep / 'records.jsonl'} was written for {was}; "
                        f"got {got} (give the benchmark's own settings to finish it, or another --out for a new "
                        "benchmark)\n"), r.stderr
    assert _files(quick_sweep) == before


@pytest.mark.needs_jit  # the fixture's sweep
def test_a_sweep_into_an_out_holding_rows_is_refused_and_resume_rewrites_it(quick_sweep, tmp_path):
    """Without --resume an --out that holds a sweep's rows is refused (one line naming --resume and another --out,
    exit status 2, nothing overwritten); with it, a finished sweep runs nothing and writes the same outputs."""
    import shutil

    from cli_helpers import run_cli
    before = _files(quick_sweep)
    argv = ["tradeoff", "--quick", "--scenes", "falling_rod", "--no-progress"]
    r = run_cli(*argv, "--out", quick_sweep)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == (f"planar-lcp tradeoff: error: --out {quick_sweep} holds 4 finished settings of an earlier "
                        f"tradeoff ({quick_sweep / 'records.jsonl'}): add --resume to finish that benchmark, or pick "
                        "another --out (nothing was overwritten)\n"), r.stderr
    assert _files(quick_sweep) == before
    out = tmp_path / "out"
    shutil.copytree(quick_sweep, out)
    r = run_cli(*argv, "--resume", "--out", out)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"resume: {out / 'records.jsonl'}: 4 of 4 settings finished before; nothing left to "
                               "run: writing the outputs\n"), r.stdout
    assert (out / "tradeoff.csv").read_bytes() == (quick_sweep / "tradeoff.csv").read_bytes()
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["planned_settings"], summary["finished_settings"], summary["complete"]) == (4, 4, True)


@pytest.mark.slow  # about 70 s: the full falling_rod sweep interrupted, its --resume and an uninterrupted one
def test_ctrl_c_keeps_the_finished_settings_and_resume_ends_as_an_uninterrupted_sweep(tmp_path):
    """For the trade-off sweep: Ctrl-C (at a terminal: the whole process group) after the first row
    is recorded leaves the finished rows on disk with a partial CSV, summary and plot and prints one line, no worker
    traceback; --resume runs only the others and ends with the rows of an uninterrupted sweep."""
    import re

    pytest.importorskip("distributed")
    from cli_helpers import ctrl_c_cli, run_cli
    argv = ["tradeoff", "--scenes", "falling_rod", "--jobs", "2"]
    out = tmp_path / "out"
    rec = out / "records.jsonl"
    r = ctrl_c_cli([*argv, "--out", out], lambda: rec.exists() and '"run"' in rec.read_text(), tmp_path)
    assert r.returncode == 130, r.stderr
    lines = r.stderr.splitlines()
    m = re.fullmatch(r"planar-lcp tradeoff: error: interrupted \(Ctrl-C\); stopped after (\d+) of 75 settings: (it "
                     rf"is|they are) kept in {re.escape(str(rec))} with tradeoff.csv, summary.json and the plots of "
                     r"their rows; the same command with --resume runs the other \d+", lines[0])
    assert len(lines) == 1 and m, r.stderr
    assert "Traceback" not in r.stdout + r.stderr and "distributed" not in r.stdout + r.stderr
    assert r.seconds < 10.0 and not r.group_left
    n = int(m.group(1))
    assert 1 <= n < 75 and len(_csv_rows(out)) == n
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["planned_settings"], summary["finished_settings"], summary["complete"], summary["stopped"]) == (
        75, n, False, "interrupted by Ctrl-C")
    assert (out / "pareto_falling_rod.png").stat().st_size > 10000
    resumed = run_cli(*argv, "--no-progress", "--resume", "--out", out)
    assert resumed.returncode == 0, resumed.stderr
    assert resumed.stdout.startswith(f"resume: {rec}: {n} of 75 settings finished before; running the other "
                                     f"{75 - n}\n"), resumed.stdout
    whole = run_cli(*argv, "--no-progress", "--out", tmp_path / "whole")
    assert whole.returncode == 0, whole.stderr
    assert _csv_rows(out) == _csv_rows(tmp_path / "whole") and len(_csv_rows(out)) == 75
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in (tmp_path / "whole").iterdir())
    assert json.loads((out / "summary.json").read_text())["complete"] is True
