"""What each process of a planar-lcp command compiles on an empty numba cache, and when: numba's compile events in
every process the command starts (the command itself, the second compiling process compilation/precompile.py, the
background compilation planar_lcp/compilation/kernel_sets.py), each function's exclusive compile time (thread CPU time, less the
functions compiled on the way), the kernels each process loaded from the cache instead, and each process's start,
wall clock and CPU time. Used for docs/performance.md ("Compile time"):

    python examples/measurements/compile_events.py [--top N] [--tree TREE] [--json OUT] -- COMMAND
    python examples/measurements/compile_events.py --top 8 -- plan push_box --seed 5 --iterations 15000 --no-gif

The command runs in a child process with a cache and a working directory of its own; a `sitecustomize` module put
first on its PYTHONPATH (inherited by the processes it starts) registers the event listener once numba is imported
and writes each process's events when it exits. The report waits for a background compilation the command started,
as examples/measurements/cold_start.py does. Another `sitecustomize` the interpreter would have imported is shadowed for the run.
"""

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from cold_start import HERE, cold_run  # examples/measurements/cold_start.py, beside this script

# The listener, as the child processes' sitecustomize: imported at interpreter start-up, it waits for numba's own
# import (a meta-path finder) so that it neither imports numba earlier nor slows a process that never compiles.
_SITECUSTOMIZE = r'''
import os
if os.environ.get("PLANAR_LCP_COMPILE_EVENTS"):
    import atexit, json, signal, sys, time
    _t_start, _events, _loads, _stack = time.time(), [], [], []

    def _install():
        from numba.core import caching, event

        class _Listener(event.Listener):
            def on_start(self, ev):
                d = ev.data.get("dispatcher")
                name = f"{d.py_func.__module__}.{d.py_func.__qualname__}" if d is not None else "?"
                _stack.append([name, time.time(), time.thread_time(), 0.0])

            def on_end(self, ev):
                name, t0, c0, children = _stack.pop()
                cpu = time.thread_time() - c0
                _events.append({"name": name, "start": t0, "end": time.time(), "cpu": cpu - children})
                if _stack:
                    _stack[-1][3] += cpu

        event.register("numba:compile", _Listener())
        load = caching.Cache.load_overload

        def load_overload(self, sig, target_context):
            t0 = time.time()
            found = load(self, sig, target_context)
            if found is not None:
                _loads.append({"name": self._name, "at": t0})
            return found
        caching.Cache.load_overload = load_overload

    class _AfterNumba:
        def find_spec(self, name, path=None, target=None):
            if name != "numba":
                return None
            sys.meta_path.remove(self)
            from importlib.machinery import PathFinder
            spec = PathFinder.find_spec(name, path)
            run = spec.loader.exec_module

            def exec_module(module):
                run(module)
                _install()
            spec.loader.exec_module = exec_module
            return spec
    sys.meta_path.insert(0, _AfterNumba())

    def _write():
        t = os.times()
        path = os.path.join(os.environ["PLANAR_LCP_COMPILE_EVENTS"], f"{os.getpid()}.json")
        with open(path, "w") as f:
            json.dump({"argv": sys.argv, "pid": os.getpid(), "start": _t_start, "end": time.time(),
                       "cpu": t.user + t.system, "events": _events, "loads": _loads}, f)
    atexit.register(_write)
    # a helper stopped by its parent (SIGTERM) still writes what it did
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
'''


def role(argv):
    """Which of the command's processes wrote a log, by its argv[0]."""
    first = Path(argv[0]).name if argv else "?"
    return {"precompile.py": "second compiling process (compilation/precompile.py)",
            "kernel_sets.py": "background compilation (planar_lcp/compilation/kernel_sets.py)",
            "background.py": "background compilation (background.py)"}.get(first, "the command")


def run_logged(tree, args):
    """Run `planar-lcp ARGS` from `tree`'s sources on an empty cache with the listener in every process
    (examples/measurements/cold_start.py `cold_run`). Returns (wall clock of the command, seconds until a background compilation
    it started ended, the processes' logs sorted by start)."""
    with tempfile.TemporaryDirectory() as site, tempfile.TemporaryDirectory() as logs:
        Path(site, "sitecustomize.py").write_text(_SITECUSTOMIZE)
        wall, ended = cold_run(tree, args, env_extra={"PLANAR_LCP_COMPILE_EVENTS": logs, "NUMBA_DISABLE_JIT": None},
                               path_first=site)
        time.sleep(0.2)                 # a stopped helper's log is written as it exits
        procs = sorted((json.loads(p.read_text()) for p in Path(logs).glob("*.json")), key=lambda r: r["start"])
    return wall, ended, procs


def report(procs, top):
    """Lines: per process, its start and end (from the first process's start), CPU, compilations (when the first began
    and the last ended, their exclusive CPU) and loads; then its `top`
    functions by exclusive compile CPU, with the time each was first compiled."""
    t00 = procs[0]["start"]
    lines = []
    for r in procs:
        ev = r["events"]
        span = (f" from +{min(e['start'] for e in ev) - t00:.1f} to +{max(e['end'] for e in ev) - t00:.1f} s"
                if ev else "")
        lines.append(f"{role(r['argv'])}, pid {r['pid']}: start +{r['start'] - t00:.1f} s, "
                     f"end +{r['end'] - t00:.1f} s, "
                     f"CPU {r['cpu']:.1f} s; {len(ev)} compilations{span}, {sum(e['cpu'] for e in ev):.1f} s CPU; "
                     f"{len(r['loads'])} kernels loaded from the cache"
                     + (f" (the last at +{max(x['at'] for x in r['loads']) - t00:.1f} s)" if r["loads"] else ""))
        by_name = {}
        for e in ev:
            n, cpu, first = by_name.get(e["name"], (0, 0.0, e["start"]))
            by_name[e["name"]] = (n + 1, cpu + e["cpu"], min(first, e["start"]))
        for name, (n, cpu, first) in sorted(by_name.items(), key=lambda kv: -kv[1][1])[:top]:
            lines.append(f"  {cpu:6.2f} s CPU  at +{first - t00:5.1f} s  {name}" + (f"  (x{n})" if n > 1 else ""))
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=15, help="functions listed per process (default 15)")
    ap.add_argument("--tree", default=str(HERE), help="the source tree to run (default this one)")
    ap.add_argument("--json", help="also write the processes' raw logs to this file")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then the planar-lcp command")
    a = ap.parse_args()
    args = a.command[1:] if a.command[:1] == ["--"] else a.command
    if not args:
        ap.error("give the command after --, e.g. -- simulate falling_rod")
    if a.top < 0:
        ap.error(f"--top must be >= 0, got {a.top}")
    if a.json and not Path(a.json).resolve().parent.is_dir():
        ap.error(f"--json: the directory of {a.json} does not exist")
    wall, ended, procs = run_logged(Path(a.tree), args)
    if not procs:
        sys.exit("no process wrote a compile log (was the sitecustomize shadowed?)")
    print(f"planar-lcp {' '.join(args)}, empty numba cache: {wall:.1f} s wall clock"
          + (f", a background compilation ended by {ended:.1f} s" if ended - wall > 0.5 else ""))
    print("\n".join(report(procs, a.top)))
    if a.json:
        Path(a.json).write_text(json.dumps(procs))


if __name__ == "__main__":
    main()
