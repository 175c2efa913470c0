import os

import pytest
from cli_helpers import TIP_PLAN_ARGS, run_cli

from planar_lcp.benchmarks.lcp_corpus import find_corpus_dir, load_corpus

JIT_DISABLED = os.environ.get("NUMBA_DISABLE_JIT", "0") == "1"


@pytest.fixture(scope="session")
def corpus_dir():
    d = find_corpus_dir()
    if d is None:
        pytest.skip("LCP corpus ../shared/data/lcp not found (set PLANAR_LCP_CORPUS to its path)")
    return d


@pytest.fixture(scope="session")
def corpus(corpus_dir):
    return {inst.id: inst for inst in load_corpus(corpus_dir)}


@pytest.fixture(scope="session")
def tip_plan(tmp_path_factory):
    """A small plan made once for the whole test run by `planar-lcp plan` (TIP_PLAN_ARGS): (the finished process, its --out
    directory). Tests that replay or read a plan share it; the tests of `plan` itself check it."""
    pytest.importorskip("ompl")
    pytest.importorskip("shapely")
    out = tmp_path_factory.mktemp("tip_plan")
    return run_cli(*TIP_PLAN_ARGS, "--out", out), out


@pytest.fixture(scope="session")
def cold_demo(tmp_path_factory):
    """`planar-lcp demo` run once for the whole test run on an EMPTY numba cache, as on a user's fresh machine, and the
    background compilation it started waited for: (the finished process, its --out directory, the cache). Tests
    that need what a user's first command leaves share it (and one xdist process: xdist_group "cold_demo"); one that
    writes to the cache copies it first."""
    pytest.importorskip("ompl")
    from planar_lcp.compilation import background
    base = tmp_path_factory.mktemp("cold_demo")
    out, cache = base / "demo", base / "numba_cache"
    cache.mkdir()
    r = run_cli("demo", "--out", out, cwd=base, timeout=1800, env=dict(NUMBA_CACHE_DIR=str(cache)))
    assert background.Background(None, background.lock_file(str(cache)), 0.0).wait(timeout=900)
    return r, out, cache


def pytest_collection_modifyitems(config, items):
    # `slow` tests (deselected by default, pyproject.toml) are long with the JIT too: skip both kinds without it
    if JIT_DISABLED:
        skip = pytest.mark.skip(reason="minutes to hours without the JIT (NUMBA_DISABLE_JIT=1)")
        for item in items:
            if "needs_jit" in item.keywords or "slow" in item.keywords:
                item.add_marker(skip)
