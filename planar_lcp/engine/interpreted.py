"""A kernel run as plain Python: the first run on a cold numba cache, while the kernels compile in the background.

numba compiles the default kernel set for about 50 s on a cold cache (docs/performance.md, "Compile time"); the same
source run by CPython takes a small scene's 400 steps in 0.1 to 0.3 s. `python_version(kernel)` is the kernel's
Python function with every numba dispatcher it calls replaced by that dispatcher's Python function, recursively:
exactly what NUMBA_DISABLE_JIT=1 runs, in a process whose other kernels stay compiled. It takes the namedtuples of
the kernels' arrays (`Model.arrays`, `Simulator.work`) where the compiled kernel takes their structs.

Why the answers are the compiled kernel's bit for bit: both evaluate the same IEEE double operations in the same
order (numba compiles without fast-math: no reassociation, no fused multiply-adds), and the kernels call only
functions that are the C library's in both: `math.cos`, `math.sin`, `math.asinh`, `math.log2` and `np.hypot`
(numpy's own `np.arcsinh` and CPython's own `math.hypot` are not, and gave other last bits), and square by
multiplying (`x ** 2` is `pow` in CPython). tests/compilation/test_interpreted.py holds it on the shipped scenes (every array
of the Trajectory and of the model), tests/compilation/test_interpreted_bits.py under NUMBA_DISABLE_JIT=1 and function by
function.
"""

import os
import types

from numba.core.dispatcher import Dispatcher

_python = {}


def python_version(kernel):
    """The Python function of `kernel` (a numba dispatcher, or a Python function) whose calls to numba dispatchers
    call their Python functions instead, down the whole call tree (made once per function)."""
    func = kernel.py_func if isinstance(kernel, Dispatcher) else kernel
    known = _python.get(func)
    if known is not None:
        return known
    module_globals = {}
    copy = types.FunctionType(func.__code__, module_globals, func.__name__, func.__defaults__, func.__closure__)
    copy.__kwdefaults__ = func.__kwdefaults__
    _python[func] = copy  # before its globals: recursion reaches it again
    for name, value in func.__globals__.items():
        module_globals[name] = python_version(value) if isinstance(value, Dispatcher) else value
    return copy


def compiled(kernel):
    """Whether `kernel` (a numba dispatcher) is compiled in this process or has an entry in numba's on-disk cache
    (then a call loads it instead of compiling). True when it cannot tell, and for a Python function (the osqp
    solver's rollout)."""
    if not isinstance(kernel, Dispatcher) or kernel.overloads:
        return True
    try:
        index = kernel._cache._cache_file._index_path
    except AttributeError:
        return True
    return os.path.exists(index)

