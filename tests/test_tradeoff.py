"""planar-lcp tradeoff: the sweep's measurements and the Pareto front."""

import csv
from types import SimpleNamespace

import numpy as np

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planar_lcp.cli import main
from planar_lcp.sim import simulate
from planar_lcp.experiments.accuracy import grid_ratio, table1_errors
from planar_lcp.experiments.tradeoff import COLUMNS, pareto_front


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
    """The seed's integral of ||v_h(t) - v_ref(t)||_inf with v_h(t) = v_(k+1) over the step (t_k, t_k+1]: a run
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


@pytest.mark.slow  # minutes without the JIT (NUMBA_DISABLE_JIT=1)
def test_quick_sweep_writes_csv_and_plots(tmp_path, capsys):
    assert main(["tradeoff", "--quick", "--no-progress", "--scenes", "falling_rod", "box_push",
                 "--out", str(tmp_path)]) == 0
    rows = list(csv.DictReader(open(tmp_path / "tradeoff.csv")))
    assert list(rows[0].keys()) == COLUMNS
    assert {r["scene"] for r in rows} == {"falling_rod", "box_push"}
    assert all(float(r["cpu_s_per_sim_s"]) > 0 and int(r["failed_steps"]) == 0 for r in rows)
    lem = [r for r in rows if r["scene"] == "falling_rod" and r["solver"] == "lemke"]
    assert all(float(r["energy_drift"]) < 1e-3 for r in lem)
    assert (tmp_path / "pareto_falling_rod.png").stat().st_size > 10000
    assert "Pareto front" in capsys.readouterr().out


def test_unknown_scene_is_an_error(capsys):
    assert main(["tradeoff", "--quick", "--scenes", "nosuch"]) == 2
    assert "unknown scene 'nosuch'" in capsys.readouterr().err
