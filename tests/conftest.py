import os

import pytest

from planar_lcp.experiments.lcp_corpus import find_corpus_dir, load_corpus

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


def pytest_collection_modifyitems(config, items):
    if JIT_DISABLED:
        skip = pytest.mark.skip(reason="slow without the JIT (NUMBA_DISABLE_JIT=1)")
        for item in items:
            if "slow" in item.keywords:
                item.add_marker(skip)
