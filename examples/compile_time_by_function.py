"""Where the first-call compile time goes: numba's compile events, timed per function (exclusive of the functions it
compiles on the way), for the first `simulate()` with a fresh cache. Used for docs/performance.md:

    NUMBA_CACHE_DIR=$(mktemp -d) python examples/compile_time_by_function.py [N]     (the N largest; default 20)
"""

import sys
import time

from numba.core import event

stack, exclusive = [], {}


class _Timer(event.Listener):
    def on_start(self, ev):
        name = ev.data["dispatcher"].py_func.__qualname__ if "dispatcher" in ev.data else "?"
        stack.append([name, time.perf_counter(), 0.0])

    def on_end(self, ev):
        name, t0, children = stack.pop()
        dt = time.perf_counter() - t0
        exclusive[name] = exclusive.get(name, 0.0) + dt - children
        if stack:
            stack[-1][2] += dt


event.register("numba:compile", _Timer())
t0 = time.perf_counter()
from planar_lcp import simulate  # noqa: E402

simulate("falling_rod", t_end=0.01)
total = time.perf_counter() - t0
top = int(sys.argv[1]) if len(sys.argv) > 1 else 20
print("| function | s |\n|---|---:|")
for name, s in sorted(exclusive.items(), key=lambda kv: -kv[1])[:top]:
    print(f"| `{name}` | {s:.2f} |")
print(f"\n{len(exclusive)} functions compiled, {sum(exclusive.values()):.1f} s of compiling; import + first simulate() "
      f"{total:.1f} s")
