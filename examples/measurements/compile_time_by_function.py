"""Where the first-call compile time goes: numba's compile events, timed per function (exclusive of the functions it
compiles on the way: wall clock and this process's CPU time), for the first `simulate()` of SCENE (default
falling_rod) with a fresh cache. With the second compiling process on (the default), the functions it cached first are
loaded, not compiled, and are not listed; PLANAR_LCP_PRECOMPILE=0 lists all. Used for docs/performance.md:

    NUMBA_CACHE_DIR=$(mktemp -d) python examples/measurements/compile_time_by_function.py [N [SCENE]]   (the N largest; default 20)
"""

import sys
import time

from numba.core import event

stack, exclusive, exclusive_cpu = [], {}, {}


class _Timer(event.Listener):
    def on_start(self, ev):
        name = ev.data["dispatcher"].py_func.__qualname__ if "dispatcher" in ev.data else "?"
        stack.append([name, time.perf_counter(), time.process_time(), 0.0, 0.0])

    def on_end(self, ev):
        name, t0, c0, children, children_cpu = stack.pop()
        dt, dc = time.perf_counter() - t0, time.process_time() - c0
        exclusive[name] = exclusive.get(name, 0.0) + dt - children
        exclusive_cpu[name] = exclusive_cpu.get(name, 0.0) + dc - children_cpu
        if stack:
            stack[-1][3] += dt
            stack[-1][4] += dc


event.register("numba:compile", _Timer())
t0, c0 = time.perf_counter(), time.process_time()
from planar_lcp import simulate  # noqa: E402

simulate(sys.argv[2] if len(sys.argv) > 2 else "falling_rod", t_end=0.05)  # a few steps of either scene
total, total_cpu = time.perf_counter() - t0, time.process_time() - c0
top = int(sys.argv[1]) if len(sys.argv) > 1 else 20
print("| function | s | s CPU |\n|---|---:|---:|")
for name, s in sorted(exclusive.items(), key=lambda kv: -kv[1])[:top]:
    print(f"| `{name}` | {s:.2f} | {exclusive_cpu[name]:.2f} |")
print(f"\n{len(exclusive)} functions compiled, {sum(exclusive.values()):.1f} s of compiling "
      f"({sum(exclusive_cpu.values()):.1f} s CPU); import + first simulate() {total:.1f} s ({total_cpu:.1f} s CPU)")
