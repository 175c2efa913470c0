"""Numba kernels. Importing this package first points numba's on-disk cache at a directory keyed by a hash of every
kernel source file.

Why: numba's cache (`cache=True`) is invalidated only when the file defining a function changes, not when a callee in
another file changes. After an edit or an upgrade, `rollout_lemke` (rollout.py unchanged) would silently keep an
old inlined `step_pipeline` (step.py changed). Keying the cache directory on all kernel sources makes any change start
a fresh cache. A user-set NUMBA_CACHE_DIR is respected as is. numba's cache setting is process-wide: other numba
libraries imported after planar_lcp (QuantEcon in the benchmarks) cache into the same directory.
"""

import hashlib
import os
from pathlib import Path

import numba


def kernel_source_hash():
    h = hashlib.sha256()
    here = Path(__file__).resolve().parent
    for p in sorted(here.rglob("*.py")):
        h.update(str(p.relative_to(here)).encode())
        h.update(p.read_bytes())
    h.update(numba.__version__.encode())
    return h.hexdigest()[:16]


def _cache_dir():
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "planar_lcp", "numba", kernel_source_hash())


if not os.environ.get("NUMBA_CACHE_DIR"):
    try:
        d = _cache_dir()
        os.makedirs(d, exist_ok=True)
        numba.config.CACHE_DIR = d
    except OSError:
        pass  # an unwritable home: numba falls back to its own locators (next to the sources, or a temp dir)
