"""The kernels run as plain Python (NUMBA_DISABLE_JIT=1) give the compiled run's results bit for bit.

Arithmetic (+ - * /, sqrt) is IEEE in both; what can differ is a function whose Python evaluation is not the C
library's that numba's compiled code calls: NumPy's own SIMD loops (np.arcsinh, np.log2, np.exp on an AVX-512
machine), CPython's own math.hypot, and x ** 2 (the C pow in Python, x * x compiled). The kernels call math.asinh,
math.log2, math.cos, math.sin (the C library's in both: numba compiles np.arcsinh, np.cos, ... to the same calls) and
np.hypot (the C library's hypot in both), and square by multiplying.
"""

import math
import os
import pickle
import subprocess
import sys

import numpy as np
import pytest
from numba import njit

from planar_lcp import simulate

pytestmark = pytest.mark.needs_jit


def _bits(a):
    a = np.ascontiguousarray(a)
    return a.view(np.uint64) if a.dtype == np.float64 else a


@njit
def _compiled_math(x, y, out):
    for i in range(x.shape[0]):
        out[i, 0] = math.asinh(x[i])
        out[i, 1] = math.log2(abs(x[i]) + 1e-300)
        out[i, 2] = np.hypot(x[i], y[i])
        out[i, 3] = math.cos(x[i])
        out[i, 4] = math.sin(x[i])


def test_kernel_math_functions_compiled_equal_python():
    rng = np.random.default_rng(3)
    n = 20000
    x = rng.uniform(-1.0, 1.0, n) * 10.0 ** rng.integers(-8, 4, n)
    y = rng.uniform(-1.0, 1.0, n) * 10.0 ** rng.integers(-8, 4, n)
    out = np.empty((n, 5))
    _compiled_math(x, y, out)
    py = _compiled_math.py_func
    ref = np.empty((n, 5))
    py(x, y, ref)
    assert np.array_equal(_bits(out), _bits(ref))


_RUN = """
import pickle, sys
from planar_lcp import simulate
tr = simulate(sys.argv[1])
pickle.dump({"q": tr.q_com, "v": tr.v_com, "qk": tr.qk, "stats": tr.stats, "contacts": tr.contacts},
            sys.stdout.buffer)
"""


# box_push: its limit surface's closed form (asinh) from step 2, a contact's distance (hypot) at step 164 differed
@pytest.mark.parametrize("scene", ["box_push", "push_table"])
def test_interpreted_run_equals_compiled(scene):
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    p = subprocess.run([sys.executable, "-c", _RUN, scene], env=env, capture_output=True, timeout=600)
    assert p.returncode == 0, p.stderr.decode()
    py = pickle.loads(p.stdout)
    tr = simulate(scene)
    compiled = {"q": tr.q_com, "v": tr.v_com, "qk": tr.qk, "stats": tr.stats, "contacts": tr.contacts}
    for key in ("q", "v", "qk"):
        assert np.array_equal(_bits(py[key]), _bits(compiled[key])), key
    for group in ("stats", "contacts"):
        for key, a in compiled[group].items():
            if isinstance(a, np.ndarray):
                assert np.array_equal(_bits(py[group][key]), _bits(a)), (group, key)
            else:
                assert py[group][key] == a, (group, key)
