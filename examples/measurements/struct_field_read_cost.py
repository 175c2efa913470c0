"""Does reading a struct field inside a loop cost more than reading a local? (It does not: LLVM hoists the load and
the reference counting out of the loop.) Used for docs/performance.md:

    python examples/measurements/struct_field_read_cost.py
"""
import time
from numba import njit
from planar_lcp import load_scene
from planar_lcp.model import compile_scene
from planar_lcp.engine.layout import model_struct
m = model_struct(compile_scene(load_scene("push_t")).arrays)
@njit
def field_in_loop(m, n):
    s = 0.0
    for i in range(n):
        s += m.dyn_mass[0] + m.pair_mu[0]
    return s
@njit
def hoisted(m, n):
    dm = m.dyn_mass; pm = m.pair_mu
    s = 0.0
    for i in range(n):
        s += dm[0] + pm[0]
    return s
for f in (field_in_loop, hoisted):
    f(m, 10)
    t=time.perf_counter(); f(m, 10_000_000); print(f.__name__, (time.perf_counter()-t)/1e7*1e9/2, "ns per read")
