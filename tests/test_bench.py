"""The benchmark commands measure what they promise: alternating rounds of thread CPU time, ratios as the median of
the per-round ratios with their spread, and the JSON fields the docs and examples/plot_performance.py read.

Functional checks only, never timing assertions: speed targets live in the benchmarks (docs/performance.md). The
statistics are checked with a fake clock whose readings are known; the real runs are checked for completeness."""

import functools
import json
import math

import numpy as np
import pytest

from planar_lcp.experiments import bench
from planar_lcp.experiments.bench import (alternate_rounds, ratio_stats, bench_lcp, bench_scaling, bench_step,
                                          format_lcp_table, format_scaling_table, format_step_table)

# the real runs time compiled code; without the JIT QuantEcon's Lemke alone runs for hours on the cycling instances
needs_jit = pytest.mark.needs_jit


class FakeClock:
    """A clock that moves only when a fake runner says it worked for `dt` seconds."""

    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def fake_runner(name, clock, log, costs):
    """A runner that logs its name and advances the clock by the next of `costs` (seconds) per call."""
    it = iter(costs)

    def run():
        log.append(name)
        clock.t += next(it)
    return run


# --- the alternation and its statistics, with a fake clock ------------------------------------------------------


def test_alternate_runs_each_round_of_every_runner_in_turn():
    clock, log, prepared = FakeClock(), [], []
    # per call: a 0.5 s, b 0.25 s, c 1 s; with min_round_s = 1 a round is 2 a's, 4 b's, 1 c
    runners = dict(a=fake_runner("a", clock, log, [0.5] * 100), b=fake_runner("b", clock, log, [0.25] * 100),
                   c=fake_runner("c", clock, log, [1.0] * 100))
    runners["c"].prepare = prepared.append        # set-up hook, called before each of c's rounds
    m = alternate_rounds(runners, rounds=3, min_round_s=1.0, clock=clock)
    assert m["reps"] == dict(a=2, b=4, c=1)
    calibration, rounds = log[:6], log[6:]
    assert calibration == ["a", "a", "b", "b", "c", "c"]       # one untimed call, one timed call each
    assert rounds == (["a"] * 2 + ["b"] * 4 + ["c"]) * 3        # a, b, c, a, b, c, ...: never two rounds of one
    assert prepared == [2, 1, 1, 1]                              # calibration, then each round's k before its clock
    for name, cost in (("a", 0.5), ("b", 0.25), ("c", 1.0)):
        np.testing.assert_array_equal(m["per_unit"][name], [cost] * 3)


def test_ratio_is_the_median_of_the_per_round_ratios_with_their_spread():
    clock, log = FakeClock(), []
    # after the two calibration calls, ours costs 2, 4, 6, 8, 20 and the peer 1, 1, 2, 2, 4 in rounds 1..5
    ours = fake_runner("ours", clock, log, [1.0, 1.0, 2.0, 4.0, 6.0, 8.0, 20.0])
    peer = fake_runner("peer", clock, log, [1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 4.0])
    m = alternate_rounds(dict(ours=ours, peer=peer), rounds=5, min_round_s=1e-9, clock=clock)
    assert m["reps"] == dict(ours=1, peer=1)
    np.testing.assert_array_equal(m["per_unit"]["ours"], [2, 4, 6, 8, 20])
    np.testing.assert_array_equal(m["per_unit"]["peer"], [1, 1, 2, 2, 4])
    st = ratio_stats(m["per_unit"]["ours"], m["per_unit"]["peer"])   # per round 2, 4, 3, 4, 5
    assert st == dict(median=4.0, min=2.0, q1=3.0, q3=4.0, max=5.0)
    # not the ratio of the medians (6 / 2 = 3): a slow round of one side is compared with its own round of the other
    assert st["median"] != np.median([2, 4, 6, 8, 20]) / np.median([1, 1, 2, 2, 4])


def busy(n):
    """A runner whose work is proportional to n (a Python loop: no caches or vector units to make it nonlinear)."""
    def run():
        s = 0
        for i in range(n):
            s += i * i
        return s
    return run


def test_real_rounds_measure_a_known_workload_ratio():
    """With the real clock a runner doing twice the work measures about twice the cost, one doing the same work
    about the same, whatever the order they run in."""
    m = alternate_rounds(dict(one=busy(20000), two=busy(40000), again=busy(20000)), rounds=7, min_round_s=0.02)
    assert m["rounds"] == 7 and all(len(m["per_unit"][k]) == 7 for k in ("one", "two", "again"))
    assert m["reps"]["one"] > m["reps"]["two"] >= 1
    two = ratio_stats(m["per_unit"]["two"], m["per_unit"]["one"])
    same = ratio_stats(m["per_unit"]["again"], m["per_unit"]["one"])
    assert 1.7 < two["median"] < 2.3, two
    assert 0.85 < same["median"] < 1.15, same
    assert two["min"] <= two["q1"] <= two["median"] <= two["q3"] <= two["max"]


def test_default_clock_counts_this_threads_cpu_not_waiting():
    """Thread CPU time: a runner that sleeps 20 ms costs almost nothing, so other processes on a shared machine (which
    make a thread wait, not work) do not move the ratios."""
    import time
    # max_reps: the sleeper's calibration sees almost no CPU time and would ask for thousands of sleeps per round
    m = alternate_rounds(dict(sleeper=lambda: time.sleep(0.02), worker=busy(20000)), rounds=3, min_round_s=0.01,
                         max_reps=3)
    assert np.median(m["per_unit"]["sleeper"]) < 0.002
    assert np.median(m["per_unit"]["worker"]) > 0


def spy_alternate(monkeypatch, costs):
    """Replace bench.alternate_rounds by one that runs the real runners (in the real order) but times them with a fake
    clock advanced by costs[name] per call. Returns the call log."""
    real, clock, log = bench.alternate_rounds, FakeClock(), []

    def wrap(name, fn):
        def run():
            log.append(name)
            fn()
            clock.t += costs[name]
        if hasattr(fn, "prepare"):
            run.prepare = fn.prepare
        return run

    def spy(runners, **kw):
        return real({k: wrap(k, f) for k, f in runners.items()}, clock=clock, **kw)
    monkeypatch.setattr(bench, "alternate_rounds", spy)
    return log


@needs_jit
def test_bench_step_alternates_ours_warm_and_pymunk_and_reports_their_ratios(monkeypatch):
    log = spy_alternate(monkeypatch, dict(ours=0.012, ours_warm=0.008, pymunk=0.004))
    rows = bench_step(scenes=("falling_rod",), rounds=4, min_round_s=0.01)
    r = rows[0]
    assert r["runs_per_round"] == dict(ours=1, ours_warm=2, pymunk=3)
    assert log[6:] == (["ours"] + ["ours_warm"] * 2 + ["pymunk"] * 3) * 4
    n = r["steps"]
    assert r["us_per_step"] == pytest.approx(0.012 / n * 1e6)
    assert r["warm_us_per_step"] == pytest.approx(0.008 / n * 1e6)
    assert r["pymunk_us_per_step"] == pytest.approx(0.004 / n * 1e6)
    for k in ("ratio", "ratio_min", "ratio_q1", "ratio_q3", "ratio_max"):
        assert r[k] == pytest.approx(3.0)
    for k in ("warm_ratio", "warm_ratio_min", "warm_ratio_max"):
        assert r[k] == pytest.approx(2.0)


# --- real runs: complete, finite, the fields present ------------------------------------------------------------


def check_spread(r, prefix):
    vals = [r[prefix + s] for s in ("_min", "_q1", "", "_q3", "_max")]
    assert all(math.isfinite(x) and x > 0 for x in vals), (prefix, vals)
    assert vals == sorted(vals), (prefix, vals)


@needs_jit
def test_bench_step_measures_ours_and_pymunk():
    rows = bench_step(scenes=("falling_rod",), rounds=3)
    r = rows[0]
    assert r["rounds"] == 3 and set(r["runs_per_round"]) == {"ours", "ours_warm", "pymunk"}
    assert r["us_per_step"] > 0 and r["pymunk_us_per_step"] > 0 and r["warm_us_per_step"] > 0
    check_spread(r, "ratio")
    check_spread(r, "warm_ratio")
    assert 0.0 <= r["warm_start_share"] <= 1.0
    assert r["warm_start_share"] > 0.5   # the rod rests on the table for most of the run: one basis
    # every runner works on the calling thread, so thread CPU time sees all of it (docs/performance.md)
    assert 0.0 <= r["other_threads_cpu_share"] < 0.2
    table = format_step_table(rows)
    assert "ratio ours/pymunk median [min-max]" in table and "thread CPU time" in table
    assert f"{r['ratio']:.1f} [{r['ratio_min']:.1f}-{r['ratio_max']:.1f}]" in table


@needs_jit
def test_bench_step_json_keeps_the_old_fields_and_adds_the_spread(monkeypatch, tmp_path):
    monkeypatch.setattr(bench, "bench_step", functools.partial(bench_step, scenes=("box_tip",), rounds=3))
    monkeypatch.setattr(bench, "measure_step_compile_time",   # two cold-cache subprocesses: minutes, not tested here
                        lambda: dict(cold_import_s=1.0, cold_first_simulate_s=2.0, warm_import_s=0.1,
                                     warm_first_simulate_s=0.2))
    path = tmp_path / "bench.json"
    bench.run_bench("step", json_path=str(path))
    d = json.loads(path.read_text())
    assert d["step"]["clock"] == "thread_time"
    (r,) = d["step"]["rows"]
    old = {"scene", "steps", "h", "us_per_step", "pymunk_us_per_step", "ratio", "warm_us_per_step", "warm_ratio",
           "mean_lcp_size", "max_lcp_size", "pivots_per_step", "warm_pivots_per_step", "warm_start_share"}
    new = {f"{p}{s}" for p in ("ratio", "warm_ratio") for s in ("_min", "_q1", "_q3", "_max")}
    assert old | new | {"rounds", "runs_per_round", "other_threads_cpu_share"} <= set(r)
    assert r["scene"] == "box_tip"
    check_spread(r, "ratio")


@needs_jit
def test_bench_scaling_fits_an_exponent_per_round(monkeypatch, tmp_path):
    rows, fits, fit_spread = bench_scaling(sizes=(1, 4, 8), steps=2, rounds=3)
    assert {r["kind"] for r in rows} == {"pile", "islands"}
    # n separate boxes are n islands of one 8-unknown LCP each; a tower is one island of 8 n unknowns
    assert all(r["lcp_max"] == 8 for r in rows if r["kind"] == "islands")
    assert [r["lcp_max"] for r in rows if r["kind"] == "pile"] == [8, 32, 64]
    for r in rows:
        assert 0 < r["us_min"] <= r["us_per_step"] <= r["us_max"]
    for kind in ("pile", "islands"):
        s = fit_spread[kind]
        assert all(np.isfinite([s["min"], s["q1"], fits[kind], s["q3"], s["max"]]))
        assert s["min"] <= s["q1"] <= fits[kind] <= s["q3"] <= s["max"]
    assert "fitted growth exponent" in format_scaling_table(rows, fits, fit_spread)


@pytest.mark.slow    # every corpus instance against QuantEcon in rounds: 20 s
def test_bench_lcp_table(corpus_dir):
    rows = bench_lcp(corpus_dir, rounds=3, min_round_s=0.001)
    assert len(rows) == 44
    by_id = {r["id"]: r for r in rows}
    assert by_id["dart_12d"]["status"] == "solved" and by_id["dart_12d"]["pivots"] <= 12
    for r in rows:
        if r["qe_rounds"] > 1:
            check_spread(r, "ratio")
        else:   # QuantEcon timed once (it cycles to its iteration cap): no spread
            assert r["qe_us"] > 1e6 and r["ratio_min"] <= r["ratio"] <= r["ratio_max"]
        assert r["us"] > 0 and r["public_us"] > 0
    table = format_lcp_table(rows)
    assert "median ratio ours/QuantEcon" in table and "thread CPU time" in table
