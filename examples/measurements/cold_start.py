"""Wall clock of a planar-lcp command on an empty numba cache, each run in a child process with a cache of its own,
in alternating rounds over the variants given, and the time until a background compilation it started has ended
(planar_lcp/compilation/background.py: simulate() on a cold cache): this tree with the second compiling process,
without it (PLANAR_LCP_PRECOMPILE=0), and other source trees (--tree, e.g. a git worktree of an earlier commit).
Used for docs/performance.md ("Compile time"):

    python examples/measurements/cold_start.py [--rounds 2] [--tree /path/to/worktree] [--no-helper] -- simulate falling_rod
    python examples/measurements/cold_start.py --rounds 1 --tree /work/before -- plan push_box --seed 5 --iterations 15000
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from planar_lcp.compilation.background import Background, lock_file

HERE = Path(__file__).resolve().parents[2]
_MAIN = "import sys; from planar_lcp.cli import main; sys.argv[0] = 'planar-lcp'; sys.exit(main())"


def cold_run(tree, args, helper=True, env_extra=None, path_first=None):
    """(seconds of wall clock for `planar-lcp ARGS` run from `tree`'s sources on an empty numba cache, seconds until
    a background compilation it started has ended too: the same when there is none). env_extra: more environment
    variables for the run (a value None removes one); path_first: a directory put on PYTHONPATH before `tree`
    (examples/measurements/compile_events.py's sitecustomize)."""
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as cwd:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache,
                   PYTHONPATH=os.pathsep.join(str(p) for p in (path_first, tree) if p is not None),
                   PLANAR_LCP_PRECOMPILE="1" if helper else "0")
        for name, value in (env_extra or {}).items():
            if value is None:
                env.pop(name, None)
            else:
                env[name] = value
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", _MAIN, *args], cwd=cwd, env=env, capture_output=True, text=True)
        dt = time.perf_counter() - t0
        # a background compilation it started (planar_lcp/compilation/background.py; trees before it have none): the cache is
        # removed only after it, and no load is left over for the next run
        Background(None, lock_file(cache), 0.0).wait()
        compiled = time.perf_counter() - t0
    if out.returncode != 0:
        raise SystemExit(f"planar-lcp {' '.join(args)} from {tree} failed:\n{out.stderr}")
    return dt, compiled


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--tree", action="append", default=[], help="another source tree to time (repeatable)")
    ap.add_argument("--no-helper", action="store_true", help="also time this tree with PLANAR_LCP_PRECOMPILE=0")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then the planar-lcp command")
    a = ap.parse_args()
    args = a.command[1:] if a.command[:1] == ["--"] else a.command
    if not args:
        ap.error("give the command after --, e.g. -- simulate falling_rod")
    variants = [(f"{t}", Path(t), True) for t in a.tree] + [("this tree", HERE, True)]
    if a.no_helper:
        variants.append(("this tree, PLANAR_LCP_PRECOMPILE=0", HERE, False))
    times = {name: [] for name, _, _ in variants}
    compiled = {name: [] for name, _, _ in variants}
    for r in range(a.rounds):
        for name, tree, helper in variants:
            dt, ct = cold_run(tree, args, helper)
            times[name].append(dt)
            compiled[name].append(ct)
            print(f"round {r + 1}: {name}: {dt:.1f} s (kernels compiled by {ct:.1f} s)", file=sys.stderr, flush=True)
    print(f"planar-lcp {' '.join(args)}, empty numba cache, wall clock, {a.rounds} alternating rounds:")
    for name, ts in times.items():
        cs = compiled[name]
        print(f"  {name}: median {statistics.median(ts):.1f} s [{min(ts):.1f}-{max(ts):.1f}]; the kernels compiled "
              f"(a background compilation ended) by {statistics.median(cs):.1f} s [{min(cs):.1f}-{max(cs):.1f}]")


if __name__ == "__main__":
    main()
