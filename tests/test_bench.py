"""The benchmark commands run and report what they promise (functional checks, never timing assertions)."""

import numpy as np
import pytest

from planar_lcp.bench import (bench_lcp, bench_scaling, bench_step, format_lcp_table, format_scaling_table,
                              format_step_table)

# they time compiled code; without the JIT QuantEcon's Lemke alone runs for hours on the cycling instances
pytestmark = pytest.mark.slow


def test_bench_step_measures_ours_and_pymunk():
    rows = bench_step(scenes=("falling_rod",), rounds=1)
    r = rows[0]
    assert r["us_per_step"] > 0 and r["pymunk_us_per_step"] > 0
    assert r["ratio"] == r["us_per_step"] / r["pymunk_us_per_step"]
    assert r["warm_us_per_step"] > 0 and 0.0 <= r["warm_start_share"] <= 1.0
    assert r["warm_ratio"] == r["warm_us_per_step"] / r["pymunk_us_per_step"]
    assert r["warm_start_share"] > 0.5   # the rod rests on the table for most of the run: one basis
    assert "ratio ours/pymunk" in format_step_table(rows)


def test_bench_scaling_fits_an_exponent():
    rows, fits = bench_scaling(sizes=(1, 4, 8), steps=2)
    assert {r["kind"] for r in rows} == {"pile", "islands"}
    # n separate boxes are n islands of one 8-unknown LCP each; a tower is one island of 8 n unknowns
    assert all(r["lcp_max"] == 8 for r in rows if r["kind"] == "islands")
    assert [r["lcp_max"] for r in rows if r["kind"] == "pile"] == [8, 32, 64]
    assert np.isfinite(fits["pile"]) and np.isfinite(fits["islands"])
    assert "fitted growth exponent" in format_scaling_table(rows, fits)


def test_bench_lcp_table(corpus_dir):
    rows = bench_lcp(corpus_dir)
    assert len(rows) == 44
    by_id = {r["id"]: r for r in rows}
    assert by_id["dart_12d"]["status"] == "solved" and by_id["dart_12d"]["pivots"] <= 12
    assert "median ratio ours/QuantEcon" in format_lcp_table(rows)
