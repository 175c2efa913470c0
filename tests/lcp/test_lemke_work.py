"""Lemke's work structs (engine/layout.py LEMKE_LAYOUT, BLOCK_LAYOUT): the allocators agree with the tables, and the
kernels answer the same in a step's work struct as in a LemkeWork of their own."""

import numpy as np

from planar_lcp.engine.layout import (BLOCK_LAYOUT, LEMKE_LAYOUT, WORK_LAYOUT, BlockLemkeWork, LemkeSettings,
                                      LemkeWork, lemke_work_struct, make_lemke_work, numba_type)
from planar_lcp.engine.solvers.lemke import _make_work, default_max_pivots, lemke_kernel, lemke_solve
from planar_lcp.lcp import DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL


def test_the_kernel_allocator_gives_the_layouts_fields():
    """`_make_work` (the public solver's allocation, in a kernel) makes LEMKE_LAYOUT's fields in order, with the
    shapes and dtypes `make_lemke_work` gives them."""
    for n in (0, 1, 5):
        got, want = _make_work(n), make_lemke_work(n)
        assert len(got) == len(want) == len(LEMKE_LAYOUT)
        for f, a, b in zip(LEMKE_LAYOUT, got, want):
            assert a.shape == b.shape and a.dtype == b.dtype, f.name


def test_the_step_work_holds_lemkes_fields_as_declared():
    """A step's work has every Lemke and block Lemke field, with the same type: the kernels take either struct."""
    step = {f.name: f for f in WORK_LAYOUT}
    for f in LEMKE_LAYOUT + BLOCK_LAYOUT:
        assert numba_type(step[f.name]) == numba_type(f)
    assert LemkeWork._fields == tuple(f.name for f in LEMKE_LAYOUT)
    assert BlockLemkeWork._fields == tuple(f.name for f in LEMKE_LAYOUT + BLOCK_LAYOUT)
    assert isinstance(make_lemke_work(3, block=True), BlockLemkeWork)


def test_the_kernel_in_a_larger_work_answers_as_lemke_solve():
    """lemke_kernel in work for a larger problem (the step's case: the tableau is the buffer's first n (2n + 2)
    entries) gives lemke_solve's answer bit for bit."""
    rng = np.random.default_rng(7)
    n = 9
    G = rng.standard_normal((n, n))
    M, q = G @ G.T + 0.1 * np.eye(n), rng.standard_normal(n)
    for equilibrate in (False, True):
        z, w, status, pivots, res = lemke_solve(M, q, default_max_pivots(n), DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL,
                                                DEFAULT_RES_TOL, equilibrate)
        work = make_lemke_work(2 * n)
        settings = LemkeSettings(default_max_pivots(n), DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL,
                                 equilibrate)
        assert lemke_kernel(M, q, settings, lemke_work_struct(work)) == (status, pivots, res)
        assert np.array_equal(work.lemke_z[:n], z) and np.array_equal(work.lemke_w[:n], w)
