"""Benchmarks (not tests): speed reported as ratios against a peer measured in the same run."""

import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from planar_lcp.compilation.notice import COLD_START_SECONDS
from planar_lcp.engine.layout import LemkeSettings, lemke_work_struct, make_lemke_work
from planar_lcp.engine.solvers.certificate import STATUS_NAMES
from planar_lcp.engine.solvers.lemke import lemke_kernel
from planar_lcp.lcp import DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL, default_max_pivots, lemke
from planar_lcp.benchmarks.lcp_corpus import load_corpus


#: The clock of every timed round: CPU time of the calling thread. Wall clock on a shared machine counts the time
#: other processes hold the core (docs/performance.md); thread CPU time does not. Every peer timed
#: here runs its work on the calling thread (numba kernels without parallel=True, QuantEcon's njit lcp_lemke,
#: pymunk.Space() unthreaded: Chipmunk's cpSpaceStep in C through cffi), so thread CPU time counts all of it; each
#: round also records the process's CPU time, and `other_threads_cpu_share` reports what other threads used.
_clock = time.thread_time

#: Default number of alternating rounds and the least thread CPU time of one runner's round (s).
ROUNDS = 15
MIN_ROUND_S = 0.005


def _spread(x):
    """Median and spread (min, first and third quartile, max) of the values x."""
    x = np.asarray(x, dtype=float)
    q1, med, q3 = np.percentile(x, [25, 50, 75])
    return dict(median=float(med), min=float(x.min()), q1=float(q1), q3=float(q3), max=float(x.max()))


def alternate_rounds(runners, rounds=ROUNDS, min_round_s=MIN_ROUND_S, max_reps=100000, clock=None):
    """Time the callables of `runners` (name -> callable doing one unit of work: a solve, a whole rollout) in
    alternating rounds: round r runs every runner in turn (a, b, c, a, b, c, ...), each its fixed number of units.

    Each runner is first called once untimed (JIT, caches), then once timed to fix its units per round so that a
    round lasts at least `min_round_s` of thread CPU time. A runner with a `prepare(k)` method gets it called before
    each of its rounds' clock starts (set-up for k units that must not be timed).

    Returns a dict with `per_unit`: per name, (rounds,) seconds of thread CPU time per unit in each round; `reps`:
    units per round; `other_threads_cpu_share`: the process CPU time beyond this thread's over the timed rounds, as
    a fraction of this thread's (0 when nothing else ran).
    """
    clock = clock or _clock
    names = list(runners)
    reps = {}
    for name in names:
        fn = runners[name]
        prepare = getattr(fn, "prepare", None)
        if prepare is not None:
            prepare(2)
        fn()
        t0 = clock()
        fn()
        one = clock() - t0
        reps[name] = int(min(max_reps, max(1, math.ceil(min_round_s / one)))) if one > 0 else max_reps
    per = {name: np.empty(rounds) for name in names}
    thread_total = process_total = 0.0
    for r in range(rounds):
        for name in names:
            fn, k = runners[name], reps[name]
            prepare = getattr(fn, "prepare", None)
            if prepare is not None:
                prepare(k)
            p0 = time.process_time()
            t0 = clock()
            for _ in range(k):
                fn()
            dt = clock() - t0
            process_total += time.process_time() - p0
            thread_total += dt
            per[name][r] = dt / k
    share = max(0.0, process_total - thread_total) / thread_total if thread_total > 0 else 0.0
    return dict(per_unit=per, reps=reps, rounds=rounds, other_threads_cpu_share=share)


def ratio_stats(num, den):
    """The per-round ratios num[r] / den[r] (each round's two times were measured back to back) summarized by
    `_spread`: median, min, q1, q3, max."""
    return _spread(np.asarray(num, dtype=float) / np.asarray(den, dtype=float))


def _ratio_fields(prefix, st):
    """Flat JSON fields for a ratio summary: `prefix` is the median, then its spread."""
    return {prefix: st["median"], f"{prefix}_min": st["min"], f"{prefix}_q1": st["q1"], f"{prefix}_q3": st["q3"],
            f"{prefix}_max": st["max"]}


def _fmt_ratio(r, prefix, digits=1):
    """'median [min-max]' of a ratio's fields."""
    return f"{r[prefix]:.{digits}f} [{r[prefix + '_min']:.{digits}f}-{r[prefix + '_max']:.{digits}f}]"


class _OurKernel:
    """Our numba kernel with preallocated work arrays, as the time-stepper calls it."""

    def __init__(self, M, q):
        n = q.shape[0]
        self.M, self.q = np.ascontiguousarray(M), np.ascontiguousarray(q)
        self.work = lemke_work_struct(make_lemke_work(n))
        # not equilibrated: the first try of the step's chain (LEMKE_CHAIN) and the public lemke()'s default
        self.settings = LemkeSettings(default_max_pivots(n), DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL,
                                      False)

    def __call__(self):
        return lemke_kernel(self.M, self.q, self.settings, self.work)


class _QuantEcon:
    """QuantEcon's numba lcp_lemke with its documented work arrays (tableau, basis, z), default options."""

    def __init__(self, M, q):
        from quantecon.optimize import lcp_lemke
        n = q.shape[0]
        self.f = lcp_lemke
        self.M, self.q = np.ascontiguousarray(M), np.ascontiguousarray(q)
        self.tab, self.basis, self.z = np.empty((n, 2 * n + 2)), np.empty(n, np.int64), np.empty(n)

    def __call__(self):
        return self.f(self.M, self.q, tableau=self.tab, basis=self.basis, z=self.z)


def _residual(M, q, z):
    w = M @ z + q
    return float(np.max(np.abs(np.minimum(z, w))) + max(0.0, -z.min()) + max(0.0, -w.min())) if len(q) else 0.0


def bench_lcp(corpus_dir=None, slow_cap_s=1.0, rounds=ROUNDS, min_round_s=MIN_ROUND_S):
    """Ours vs QuantEcon's lcp_lemke on every corpus instance. Returns a list of row dicts.

    Per instance, our kernel, QuantEcon's and our public lemke() are timed in `rounds` alternating rounds of thread
    CPU time (`alternate_rounds`); `ratio` is the median over rounds of ours / QuantEcon measured back to back, with its
    spread in ratio_min, ratio_q1, ratio_q3, ratio_max; us, qe_us, public_us are the medians per solve. Where one
    QuantEcon solve takes more than `slow_cap_s` (it cycles to its iteration cap) it is timed once, and the ratio
    is our median over that one time (`qe_rounds` 1, no spread)."""
    try:
        import quantecon  # noqa: F401
    except ImportError as e:
        raise SystemExit("bench lcp needs quantecon (pip install -e '.[dev]'): " + str(e)) from None
    rows = []
    warm = np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0])
    _QuantEcon(*warm)()  # compile QuantEcon before the first timed call
    _OurKernel(*warm)()
    for inst in load_corpus(corpus_dir):
        ours, qe = _OurKernel(inst.M, inst.q), _QuantEcon(inst.M, inst.q)
        status, pivots, res = ours()
        t0 = _clock()
        qres = qe()
        qe_once = _clock() - t0
        qe_status = {0: "solved", 1: "max_iter", 2: "ray_termination"}[int(qres.status)]
        if qe_status == "solved":
            # QuantEcon does not check its answer; we do, with the same residual as ours
            scale = max(1.0, np.abs(inst.M).max(), np.abs(inst.q).max())
            if _residual(inst.M, inst.q, qres.z) > DEFAULT_RES_TOL * scale:
                qe_status = "wrong_z"
        public = (lambda M=inst.M, q=inst.q: lemke(M, q))
        slow = qe_once > slow_cap_s
        runners = dict(ours=ours, public=public) if slow else dict(ours=ours, qe=qe, public=public)
        m = alternate_rounds(runners, rounds=rounds, min_round_s=min_round_s)
        per = m["per_unit"]
        if slow:
            ratio = _spread(per["ours"] / qe_once)
            qe_s, qe_rounds = qe_once, 1
        else:
            ratio = ratio_stats(per["ours"], per["qe"])
            qe_s, qe_rounds = float(np.median(per["qe"])), rounds
        rows.append(dict(id=inst.id, n=inst.n, status=STATUS_NAMES[status], pivots=int(pivots), residual=float(res),
                         us=float(np.median(per["ours"])) * 1e6, public_us=float(np.median(per["public"])) * 1e6,
                         qe_status=qe_status, qe_pivots=int(qres.num_iter), qe_us=qe_s * 1e6,
                         **_ratio_fields("ratio", ratio), rounds=rounds, qe_rounds=qe_rounds, min_round_s=min_round_s,
                         solves_per_round=m["reps"]["ours"], qe_solves_per_round=m["reps"].get("qe", 1),
                         other_threads_cpu_share=m["other_threads_cpu_share"]))
    return rows


_COMPILE_SNIPPET = (
    "import time; t0, c0 = time.perf_counter(), time.process_time()\n"
    "import numpy as np\n"
    "import planar_lcp\n"
    "t1, c1 = time.perf_counter(), time.process_time()\n"
    "planar_lcp.lemke(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0]))\n"
    "t2, c2 = time.perf_counter(), time.process_time()\n"
    "print(t1 - t0, t2 - t1, c1 - c0, c2 - c1)\n"
)


def _cold_and_warm(snippet):
    """Run `snippet` (which prints the wall-clock seconds of its import and first call, then their CPU seconds) in a
    subprocess twice with one fresh NUMBA_CACHE_DIR: the first run compiles, the second loads the cache. Returns
    [cold, warm], each a tuple (import wall, call wall, import CPU, call CPU)."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        env.pop("NUMBA_DISABLE_JIT", None)
        out = []
        for _ in range(2):
            p = subprocess.run([sys.executable, "-c", snippet], env=env, capture_output=True, text=True, check=True)
            out.append(tuple(map(float, p.stdout.split())))
    return out


def measure_compile_time():
    """First-call JIT compile time of lemke() (fresh cache) and the same call with the cache warm."""
    out = _cold_and_warm(_COMPILE_SNIPPET)
    return dict(cold_import_s=out[0][0], cold_first_call_s=out[0][1], warm_import_s=out[1][0],
                warm_first_call_s=out[1][1], cold_first_call_cpu_s=out[0][3], warm_first_call_cpu_s=out[1][3])


def _cpu_note(compile_times, key, digits):
    """' (CPU time X s)' from compile_times[key] (older JSON files lack it: then '')."""
    return f" (CPU time {compile_times[key]:.{digits}f} s)" if key in compile_times else ""


def format_lcp_table(rows, compile_times=None):
    lines = [
        "| instance | n | ours: status | pivots | µs | QuantEcon: status | pivots | µs | ratio ours/QE median "
        "[min-max] | public lemke() µs |",
        "|---|---:|---|---:|---:|---|---:|---:|---:|---:|",
    ]
    for r in rows:
        rt = (_fmt_ratio(r, "ratio", 3) if r.get("qe_rounds", 2) > 1 else f"{r['ratio']:.2e} (QE timed once)")
        lines.append(f"| {r['id']} | {r['n']} | {r['status']} | {r['pivots']} | {r['us']:.2f} | {r['qe_status']} | "
                     f"{r['qe_pivots']} | {r['qe_us']:.2f} | {rt} | {r['public_us']:.2f} |")
    ratios = [r["ratio"] for r in rows]
    lines.append("")
    if rows:
        rounds, least = rows[0].get("rounds"), 1e3 * rows[0].get("min_round_s", MIN_ROUND_S)
        lines.append(f"times: thread CPU time (time.thread_time) per solve, median over {rounds} alternating rounds "
                     "(ours, QuantEcon, public lemke(), ours, ...) in one process, each round a fixed number of "
                     f"solves lasting >= {least:g} ms; ratio: median of the per-round ratios ours/QuantEcon, "
                     "[min-max] over rounds")
        other = max(r.get("other_threads_cpu_share", 0.0) for r in rows)
        lines.append(f"CPU time of other threads during the rounds: at most {100 * other:.1f} % of the timed "
                     "thread's (not counted in the times)")
    lines.append(f"median ratio ours/QuantEcon over {len(rows)} instances: {statistics.median(ratios):.3f} "
                 f"(target <= 1.0); geometric mean {float(np.exp(np.mean(np.log(ratios)))):.3f}")
    both = [r for r in rows if r["status"] == "solved" and r["qe_status"] == "solved"]
    if both:
        lines.append(f"median ratio where both solve ({len(both)} instances): "
                     f"{statistics.median([r['ratio'] for r in both]):.3f}")
    if compile_times:
        cpu = _cpu_note(compile_times, "cold_first_call_cpu_s", 2)
        lines.append(f"first-call JIT compile (fresh cache, wall clock of a child process): import "
                     f"{compile_times['cold_import_s']:.2f} s, first lemke() {compile_times['cold_first_call_s']:.2f} s"
                     f"{cpu};"
                     f" warm cache: import {compile_times['warm_import_s']:.2f} s, first lemke() "
                     f"{compile_times['warm_first_call_s']:.3f} s")
    return "\n".join(lines)


STEP_SCENES = ("falling_rod", "box_push", "box_tip", "push_t")

# the fifth number: from the import's end until a background compilation this run started has ended (0 if none)
_STEP_COMPILE_SNIPPET = (
    "import time; t0, c0 = time.perf_counter(), time.process_time()\n"
    "import planar_lcp\n"
    "from planar_lcp.compilation import background\n"
    "t1, c1 = time.perf_counter(), time.process_time()\n"
    "planar_lcp.simulate('falling_rod')\n"
    "t2, c2 = time.perf_counter(), time.process_time()\n"
    "b = background.started()\n"
    "print(t1 - t0, t2 - t1, c1 - c0, c2 - c1, b.wait() and time.perf_counter() - t1 if b else 0.0)\n"
)


def measure_step_compile_time():
    """The first simulate() of falling_rod (its own run) with a fresh numba cache (it runs as Python while the
    kernels compile in the background: `cold_first_simulate_s`; the compilation's end, from the same start:
    `cold_compiled_s`), and again with the kernels in the cache."""
    out = _cold_and_warm(_STEP_COMPILE_SNIPPET)
    return dict(cold_import_s=out[0][0], cold_first_simulate_s=out[0][1], warm_import_s=out[1][0],
                warm_first_simulate_s=out[1][1], cold_first_simulate_cpu_s=out[0][3],
                warm_first_simulate_cpu_s=out[1][3], cold_compiled_s=out[0][4])


def bench_step(scenes=STEP_SCENES, rounds=ROUNDS, pymunk=True, min_round_s=MIN_ROUND_S, progress=None):
    """Microseconds per step of our stepper (one jitted rollout over the scene's duration, warm JIT), with its defaults
    and with the LCP warm start the planners use, and, in the same process, of pymunk on the same scene and h through
    planar_lcp.bridges.pymunk (10 iterations, its defaults).

    The three are timed in `rounds` alternating rounds of thread CPU time (`alternate_rounds`): ours, ours warm-started,
    pymunk, ours, ... each round a fixed number of whole runs. `ratio` (`warm_ratio`) is the median over rounds of
    ours (warm-started) / pymunk measured back to back, with its spread in ratio_min, ratio_q1, ratio_q3,
    ratio_max; the µs per step are medians over rounds.

    Also timed in the same rounds, the API a user calls: `simulate(scene)` over the scene's own run with
    the defaults (`simulate_ratio` against pymunk), its set-up (`setup_us`: the per-round difference between that
    run and the rollout it makes, which records the contacts and the Trajectory's stats rows and energy: settings,
    the compiled model, the Simulator and the rest of the Trajectory), and `Simulator(model, options)` alone
    (`simulator_us`). progress: called with a line as each scene
    starts."""
    from planar_lcp.model import compile_scene
    from planar_lcp.spec.scene import load_scene
    from planar_lcp.sim import SimOptions, Simulator, simulate
    from planar_lcp.engine.layout import Stat
    from planar_lcp.bridges.pymunk import PymunkRun
    from planar_lcp.spec.path import kinematic_velocities
    rows = []
    for i, name in enumerate(scenes):
        if progress is not None:
            progress(f"{name} ({i + 1} of {len(scenes)})")
        sc = load_scene(name)
        n = int(round(sc.sim.t_end / sc.sim.h))
        runners, stats, sims = {}, {}, {}
        for warm in (False, True):
            sim = sims[warm] = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, solver=sc.sim.solver,
                                                                       formulation=sc.sim.formulation,
                                                                       warm_start=warm))
            q, v, qk, _ = sim.initial_state()
            # the run's own kinematic velocities (a `path` body's change step by step), as simulate() takes them
            vks = kinematic_velocities(sc, sim.model.kin_names, sim.h, n)
            stats[warm] = sim.rollout(q, v, qk, vks, n)["stats"]  # also compiles
            runners["ours_warm" if warm else "ours"] = (
                lambda sim=sim, q=q, v=v, qk=qk, vks=vks: sim.rollout(q, v, qk, vks, n))
        # the defaults' simulator again: the rollout simulate() makes (contacts and the Trajectory's rows recorded),
        # and its construction
        cold = sims[False]
        q, v, qk, _ = cold.initial_state()
        runners["recorded"] = lambda sim=cold, q=q, v=v, qk=qk, vks=vks: sim.rollout(q, v, qk, vks, n,
                                                                                    record_contacts=True,
                                                                                    trajectory_rows=True)
        runners["simulate"] = lambda sc=sc: simulate(sc)
        runners["simulator"] = lambda model=cold.model, opts=cold.options: Simulator(model, opts)
        if pymunk:
            runners["pymunk"] = PymunkRun(sc, n)
        m = alternate_rounds(runners, rounds=rounds, min_round_s=min_round_s)
        per = m["per_unit"]
        st, stw = stats[False], stats[True]
        with_lcp = stw[:, Stat.LCP_SIZE] > 0
        row = dict(scene=name, steps=n, h=sc.sim.h, us_per_step=float(np.median(per["ours"])) / n * 1e6,
                   warm_us_per_step=float(np.median(per["ours_warm"])) / n * 1e6,
                   mean_lcp_size=float(st[:, Stat.LCP_SIZE].mean()), max_lcp_size=int(st[:, Stat.LCP_MAX].max()),
                   pivots_per_step=float(st[:, Stat.PIVOTS].mean()),
                   warm_pivots_per_step=float(stw[:, Stat.PIVOTS].mean()),
                   warm_start_share=float(stw[with_lcp, Stat.WARM_STARTS].mean()) if with_lcp.any() else 0.0,
                   rounds=rounds, runs_per_round={k: int(v) for k, v in m["reps"].items()},
                   other_threads_cpu_share=m["other_threads_cpu_share"],
                   simulate_us_per_step=float(np.median(per["simulate"])) / n * 1e6,
                   setup_us=float(np.median(np.asarray(per["simulate"]) - np.asarray(per["recorded"]))) * 1e6,
                   simulator_us=float(np.median(per["simulator"])) * 1e6)
        if pymunk:
            row["pymunk_us_per_step"] = float(np.median(per["pymunk"])) / n * 1e6
            row.update(_ratio_fields("ratio", ratio_stats(per["ours"], per["pymunk"])))
            row.update(_ratio_fields("warm_ratio", ratio_stats(per["ours_warm"], per["pymunk"])))
            row.update(_ratio_fields("simulate_ratio", ratio_stats(per["simulate"], per["pymunk"])))
        rows.append(row)
    return rows


def format_step_table(rows, compile_times=None):
    lines = ["| scene | steps | h (s) | ours µs / step | pymunk µs / step | ratio ours/pymunk median [min-max] | "
             "mean LCP size | largest LCP | pivots / step | ours with warm start µs / step | ratio median [min-max] "
             "| warm-started LCPs | pivots / step |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        pm = f"{r['pymunk_us_per_step']:.2f} | {_fmt_ratio(r, 'ratio')}" if "ratio" in r else "- | -"
        wr = _fmt_ratio(r, "warm_ratio") if "warm_ratio" in r else "-"
        lines.append(f"| {r['scene']} | {r['steps']} | {r['h']} | {r['us_per_step']:.2f} | {pm} | "
                     f"{r['mean_lcp_size']:.1f} | {r['max_lcp_size']} | {r['pivots_per_step']:.1f} | "
                     f"{r['warm_us_per_step']:.2f} | {wr} | {100 * r['warm_start_share']:.0f} % | "
                     f"{r['warm_pivots_per_step']:.1f} |")
    if rows and "setup_us" in rows[0]:
        lines += ["", "| scene | simulate() µs / step (its own run, set-up included) | ratio to pymunk median "
                  "[min-max] | simulate() set-up µs | Simulator() µs |", "|---|---:|---:|---:|---:|"]
        for r in rows:
            sr = _fmt_ratio(r, "simulate_ratio") if "simulate_ratio" in r else "-"
            lines.append(f"| {r['scene']} | {r['simulate_us_per_step']:.2f} | {sr} | {r['setup_us']:.0f} | "
                         f"{r['simulator_us']:.0f} |")
        lines.append("simulate(): the API's whole call on the scene with its defaults, timed in the same rounds; its "
                     "set-up: the per-round median of that call less the rollout it makes (contacts and the stats rows "
                     "and energy recorded; "
                     "settings, the compiled model (remembered for a scene already compiled), Simulator, "
                     "Trajectory); Simulator(): construction "
                     "from a compiled model; targets: set-up and Simulator() <= 300 µs, simulate() ratio "
                     "<= 1.5")
    if rows:
        lines.append("")
        peers = "ours, ours warm-started, pymunk" if "ratio" in rows[0] else "ours, ours warm-started"
        lines.append(f"times: thread CPU time (time.thread_time) per step, median over {rows[0]['rounds']} "
                     f"alternating rounds ({peers}, ours, ...) in one process; a round is a fixed number of whole "
                     "runs of the scene from its initial state (ours: one Simulator.rollout call each, including "
                     "its output arrays; pymunk: space.step(h) in a Python loop on a space built before the clock "
                     "starts); ratio: median of the per-round ratios, [min-max] over rounds")
        other = max(r.get("other_threads_cpu_share", 0.0) for r in rows)
        lines.append(f"CPU time of other threads during the rounds: at most {100 * other:.1f} % of the timed "
                     "thread's (not counted in the times)")
    if any("ratio" in r for r in rows):
        lines.append("target: ratio <= 1.0 on each scene (pymunk through planar_lcp.bridges.pymunk, 10 "
                     "iterations); ours with the defaults, then with SimOptions(warm_start=True) as the planners "
                     "run it")
    if compile_times:
        lines.append("")
        cpu = _cpu_note(compile_times, "cold_first_simulate_cpu_s", 1)
        compiled = compile_times.get("cold_compiled_s")
        background = (f"; the kernels compiled in the background by {compiled:.1f} s" if compiled else "")
        lines.append(f"first simulate() of falling_rod with a fresh numba cache (as Python while the kernels compile, "
                     f"wall clock of a child process): {compile_times['cold_first_simulate_s']:.1f} s{cpu} (import "
                     f"{compile_times['cold_import_s']:.2f} s){background}; with the cache warm: "
                     f"{compile_times['warm_first_simulate_s']:.2f} s (import {compile_times['warm_import_s']:.2f} s); "
                     "targets <= 15 s and <= 2 s (wall clock: a loaded machine makes it longer)")
    return "\n".join(lines)


#: `bench scaling`'s two families: the small layouts of one box size at h = 0.005 s on the dense path (the table of
#: record from before the sparse solver) and the large piles of planar_lcp.spec.piles at h = 1/60 s, each timed with
#: the defaults (the sparse solver on large islands) and on the dense path beside it
SCALING_LAYOUTS = ("pile", "islands")
SCALING_PILES = ("tower", "pyramid", "bin")
SCALING_KINDS = SCALING_LAYOUTS + SCALING_PILES
SCALING_SIZES = (1, 2, 4, 8, 16, 32, 64)
#: Fewer rounds than the others: one 20-step rollout of the 64-box tower is about a second of CPU time.
SCALING_ROUNDS = 7
#: The large piles: body counts (pyramids: the row count whose rows (rows + 1) / 2 boxes is nearest), steps per
#: timed run, and the largest size `--sizes` accepts
PILE_SCALING_SIZES = (16, 32, 64, 128, 256)
PILE_SCALING_STEPS = 10
MAX_SCALING_SIZE = 1024
#: A path whose steps from the timed state take more thread CPU time than this (s) each, run once before the rounds
#: and stopped when over, is reported by their mean and not timed in rounds nor fitted, and its larger sizes of the
#: kind are not run: the budget that caps the dense path (a dense tower of 256 boxes is an LCP of 2048 unknowns,
#: 1.7 s per step) and the sparse solver's fallbacks to dense Lemke
STEP_BUDGET_S = 0.5
#: Bins are timed from the state where they have landed: after the top row's free-fall time plus SETTLE_EXTRA_S (s)
#: of simulated time with the defaults; a bin whose settling takes more thread CPU time than SETTLE_BUDGET_S (s) is
#: not timed, nor are the larger bins
SETTLE_EXTRA_S = 1.0
SETTLE_BUDGET_S = 60.0


def scaling_scene(n, kind):
    """n boxes (0.2 x 0.1 m, 1 kg) on a table: a tower (one island: every box touches the next) or a row of
    separate boxes 0.5 m apart (n islands)."""
    from planar_lcp.spec.scene import parse_scene
    bodies = []
    for i in range(n):
        pos = [0.0, 0.05 + 0.1 * i] if kind == "pile" else [0.5 * i, 0.05]
        bodies.append({"name": f"b{i}", "type": "dynamic", "mass": 1.0, "position": pos,
                       "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]})
    bodies.append({"name": "table", "type": "static",
                   "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]})
    return parse_scene({"name": f"{kind}_{n}", "world": {"plane": "vertical", "gravity": [0.0, -9.81],
                                                           "friction": 0.5},
                        "sim": {"h": 0.005, "t_end": 0.1}, "bodies": bodies}, source=f"<{kind} of {n}>")


def fit_exponent(bodies, per_step):
    """The growth exponent p of cost ~ bodies^p, a least-squares line through (log bodies, log cost) in every round.

    bodies: (k,) body counts, at least two distinct; per_step: (k, rounds) seconds per step of each size in each
    round. Returns `_spread` of the per-round exponents (median, min, q1, q3, max), or None with fewer than two
    distinct body counts."""
    bodies = np.asarray(bodies, dtype=float)
    if len(set(bodies.tolist())) < 2:
        return None
    per_step = np.asarray(per_step, dtype=float)
    return _spread([float(np.polyfit(np.log(bodies), np.log(per_step[:, r]), 1)[0]) for r in range(per_step.shape[1])])


def bench_scaling(sizes=SCALING_SIZES, steps=20, rounds=SCALING_ROUNDS, min_round_s=MIN_ROUND_S,
                  kinds=SCALING_LAYOUTS):
    """Cost per step of a tower of n boxes (kind "pile": one island, LCP of 8 n unknowns) and of n separate boxes
    ("islands": n islands of 8 unknowns) on the dense path (SimOptions.sparse_min_unknowns=0: dense Lemke on every
    island, as before the sparse solver; `bench_scaling_piles` times both paths), with the growth exponent fitted on
    log(cost) against log(n) over n >= 4.

    There is no peer: the sizes of one layout are timed in `rounds` alternating rounds of thread CPU time (n = 1, 2,
    4, ..., 1, 2, 4, ...; each round a fixed number of `steps`-step rollouts), the exponent is fitted in every round
    and `fits` is its median over rounds, `fit_spread` its min, q1, q3 and max (None for a layout with fewer than two
    sizes >= 4). Each row's us_per_step is the median over rounds, with us_min and us_max."""
    from planar_lcp.model import compile_scene
    from planar_lcp.engine.layout import Stat
    from planar_lcp.sim import SimOptions, Simulator
    rows, fits, fit_spread = [], {}, {}
    for kind in kinds:
        runners, outs = {}, {}
        for n in sizes:
            sim = Simulator(compile_scene(scaling_scene(n, kind)), SimOptions(h=0.005, sparse_min_unknowns=0))
            q, v, qk, vk = sim.initial_state()
            outs[n] = sim.rollout(q, v, qk, vk[None], steps)
            runners[n] = lambda sim=sim, q=q, v=v, qk=qk, vk=vk: sim.rollout(q, v, qk, vk[None], steps)
        m = alternate_rounds(runners, rounds=rounds, min_round_s=min_round_s)
        per_step = {n: m["per_unit"][n] / steps for n in sizes}
        for n in sizes:
            st = outs[n]["stats"]
            us = per_step[n] * 1e6
            rows.append(dict(kind=kind, bodies=n, us_per_step=float(np.median(us)), us_min=float(us.min()),
                             us_max=float(us.max()), lcp_max=int(st[:, Stat.LCP_MAX].max()),
                             pivots_per_step=float(st[:, Stat.PIVOTS].mean()),
                             solved_sparse=int(st[:, Stat.SOLVED_SPARSE].sum()), rounds=rounds,
                             runs_per_round=int(m["reps"][n])))
        fit_n = [n for n in sizes if n >= 4]
        sp = fit_exponent(fit_n, [per_step[n] for n in fit_n])
        fits[kind] = sp and sp["median"]
        fit_spread[kind] = sp and dict(min=sp["min"], q1=sp["q1"], q3=sp["q3"], max=sp["max"])
    return rows, fits, fit_spread


def _fmt_fit(fits, fit_spread, kind):
    if fits.get(kind) is None:
        return "not fitted (fewer than two sizes >= 4)"
    if not fit_spread:
        return f"{fits[kind]:.2f}"
    return f"{fits[kind]:.2f} [{fit_spread[kind]['min']:.2f}-{fit_spread[kind]['max']:.2f}]"


def format_scaling_table(rows, fits, fit_spread=None):
    lines = ["| layout | bodies | µs / step median [min-max] | largest LCP | pivots / step |",
             "|---|---:|---:|---:|---:|"]
    for r in rows:
        us = f"{r['us_per_step']:.1f}"
        if "us_min" in r:
            us += f" [{r['us_min']:.1f}-{r['us_max']:.1f}]"
        lines.append(f"| {r['kind']} | {r['bodies']} | {us} | {r['lcp_max']} | {r['pivots_per_step']:.1f} |")
    lines.append("")
    if rows and "rounds" in rows[0]:
        lines.append(f"times: thread CPU time (time.thread_time) per step, median over {rows[0]['rounds']} rounds "
                     "alternating over the sizes of a layout in one process, [min-max] over rounds; the dense path "
                     "(sparse_min_unknowns=0)")
    what = {"pile": "one island: Lemke on a dense tableau", "islands": "n islands of 8 unknowns"}
    fitted = ", ".join(f"{k} p = {_fmt_fit(fits, fit_spread, k)} ({what[k]})" for k in SCALING_LAYOUTS if k in fits)
    lines.append(f"fitted growth exponent (cost ~ n^p over n >= 4, fitted per round, median [min-max]): {fitted}")
    return "\n".join(lines)


def pyramid_rows(bodies):
    """The row count of the pyramid whose rows (rows + 1) / 2 boxes is nearest to `bodies` (at least one row)."""
    return max(1, int(round((math.sqrt(1.0 + 8.0 * bodies) - 1.0) / 2.0)))


def scaling_pile_scene(kind, size):
    """The scene dict of a large pile of about `size` bodies and the generator call that made it: a tower of `size`
    boxes, a pyramid of `pyramid_rows(size)` rows, or a bin of `size` mixed shapes (seed 0)."""
    piles = _piles()
    if kind == "tower":
        return piles.tower(size), f"tower({size})"
    if kind == "pyramid":
        rows = pyramid_rows(size)
        return piles.pyramid(rows), f"pyramid({rows})"
    if kind == "bin":
        return piles.bin_scene(size, seed=0), f"bin_scene({size}, seed=0)"
    raise ValueError(f"kind must be one of {', '.join(SCALING_PILES)}, got {kind!r}")


def settle_steps(scene, q0, extra_s=SETTLE_EXTRA_S):
    """Steps until dropped bodies have landed: the free-fall time of the highest centre of mass from its height
    above y = 0 (the floor of the piles), plus `extra_s` of simulated time."""
    g = math.hypot(*scene.world.gravity)
    top = float(max(0.0, q0[:, 1].max())) if len(q0) else 0.0
    return int(math.ceil((math.sqrt(2.0 * top / g) + extra_s) / scene.sim.h))


def _settle(sim, state, steps, budget_s, chunk=5):
    """Run `steps` steps from state (q, v, qk, vk) with `sim`, in chunks of `chunk`, stopping once the run has taken
    more than `budget_s` of thread CPU time. Returns (state after the steps done, steps done, CPU s, failed steps)."""
    q, v, qk, vk = state
    done, failed, t0 = 0, 0, _clock()
    while done < steps and _clock() - t0 <= budget_s:
        k = min(chunk, steps - done)
        out = sim.rollout(q, v, qk, vk[None], k, stop_on_failure=False)
        q, v, qk = out["q"][-1].copy(), out["v"][-1].copy(), out["qk"][-1].copy()
        failed += int(np.count_nonzero(out["status"][:out["steps_done"]]))
        done += k
    return (q, v, qk, vk), done, _clock() - t0, failed


def _probe(sim, state, steps, budget_s):
    """A unit's `steps` steps from `state`, one rollout step at a time, stopped once they have taken more than
    steps * budget_s of thread CPU time (at least one step). Each one-step rollout starts cold (the sparse solver's
    mode memory is not carried from step to step, as it is in one rollout), so the probe can cost more than the unit
    it stands for. Returns (steps done, their thread CPU time (s), their output as a rollout's: stats,
    status, steps_done)."""
    q, v, qk, vk = state
    stats, status, t0 = [], [], _clock()
    while len(status) < steps and (not status or _clock() - t0 <= steps * budget_s):
        out = sim.rollout(q, v, qk, vk[None], 1, stop_on_failure=False)
        q, v, qk = out["q"][-1], out["v"][-1], out["qk"][-1]
        stats.append(out["stats"][0])
        status.append(out["status"][0])
    cpu = _clock() - t0
    return len(status), cpu, dict(stats=np.array(stats), status=np.array(status), steps_done=len(status))


class _PileRun:
    """One unit: a `steps`-step rollout from `state` (failed steps do not stop it: they are counted); the last
    output is kept for its stats."""

    def __init__(self, sim, state, steps):
        self.sim, self.state, self.steps = sim, state, steps
        self.out = None

    def __call__(self):
        q, v, qk, vk = self.state
        self.out = self.sim.rollout(q, v, qk, vk[None], self.steps, stop_on_failure=False)


def _run_fields(out):
    """Stats of a run: pivots per step, sparse solves and fallbacks, the sparse share, block Lemke's solves (of the
    fallbacks), failed steps, largest LCP, islands per step."""
    from planar_lcp.engine.layout import Stat
    n = int(out["steps_done"])
    st = out["stats"][:n]
    sparse, fallbacks = int(st[:, Stat.SOLVED_SPARSE].sum()), int(st[:, Stat.SPARSE_FALLBACKS].sum())
    return dict(pivots_per_step=float(st[:, Stat.PIVOTS].mean()), solved_sparse=sparse, sparse_fallbacks=fallbacks,
                sparse_share=sparse / (sparse + fallbacks) if sparse + fallbacks else None,
                solved_block=int(st[:, Stat.SOLVED_BLOCK].sum()), failed_steps=int(np.count_nonzero(out["status"][:n])), lcp_max=int(st[:, Stat.LCP_MAX].max()),
                islands=float(st[:, Stat.N_ISLANDS].mean()))


_RUN_FIELDS = ("pivots_per_step", "solved_sparse", "sparse_fallbacks", "sparse_share", "solved_block", "failed_steps",
               "lcp_max",
               "islands")
#: the two paths of a large pile: (name, JSON field prefix, sparse_min_unknowns: None for the default)
_PATHS = (("defaults", "", None), ("dense", "dense_", 0))


def bench_scaling_piles(kinds=SCALING_PILES, sizes=PILE_SCALING_SIZES, steps=PILE_SCALING_STEPS,
                        rounds=SCALING_ROUNDS, min_round_s=MIN_ROUND_S, step_budget_s=STEP_BUDGET_S,
                        settle_budget_s=SETTLE_BUDGET_S, settle_extra_s=SETTLE_EXTRA_S, progress=None):
    """Cost per step of towers, pyramids and bins (planar_lcp.spec.piles, h = 1/60 s) against their number of
    bodies, with the defaults (the sparse solver on islands of >= SimOptions.sparse_min_unknowns unknowns, dense
    Lemke where it leaves an island) and on the dense path (sparse_min_unknowns=0), and the growth exponent of each
    path fitted per round.

    What is timed: towers and pyramids from their initial state (every box resting on its neighbours); bins from the
    state after `settle_steps` (the top row's fall plus `settle_extra_s`), run with the defaults, untimed. Each unit
    is one `steps`-step rollout from that state. Per kind every size and both paths are timed in `rounds`
    alternating rounds of thread CPU time (`alternate_rounds`), so `speedup` (dense / defaults) is the median of
    per-round ratios, and the exponent p of cost ~ bodies^p is fitted in every round over the sizes timed in rounds.

    The budgets: each path first runs its unit's steps once, one by one (`_probe`; also the untimed warm-up), and
    stops when they have taken more than `step_budget_s` of thread CPU time per step; such a path has timing "once"
    (the mean of the steps it ran, not fitted: the cost of a step varies where the sparse solver certifies some steps
    and leaves others to dense Lemke) and the kind's larger sizes have timing "skipped" on that path; a bin whose
    settling took more than `settle_budget_s` is "skipped" on both paths, as are the larger bins. Every size has its
    row, with the reason in `note` / `dense_note`.

    Returns (rows, fits, fit_spread, fit_bodies): rows as dicts (one per kind and size, the dense path's fields
    prefixed dense_); fits[kind][path] the median exponent (None: fewer than two sizes timed in rounds),
    fit_spread[kind][path] its min, q1, q3, max, fit_bodies[kind][path] the body counts of the fit. `progress`: a
    callable given one line per size as it is prepared."""
    from planar_lcp.model import compile_scene
    from planar_lcp.sim import SimOptions, Simulator
    from planar_lcp.spec.scene import parse_scene
    say = progress or (lambda line: None)
    rows, fits, fit_spread, fit_bodies = [], {}, {}, {}
    # Compile the kernel before any clock: on a fresh numba cache the first probe would take the compilation for its
    # steps, go over the step budget and skip the kind's larger sizes (both paths run the one kernel)
    warm_scene, _ = scaling_pile_scene("tower", 2)
    warm = Simulator(compile_scene(parse_scene(warm_scene)), SimOptions(h=1.0 / 60.0))
    q0, v0, qk0, vk0 = warm.initial_state()
    warm.rollout(q0, v0, qk0, vk0[None], 1)
    for kind in kinds:
        params, runners, kind_rows = [], {}, []
        for size in sorted(set(sizes)):
            d, call = scaling_pile_scene(kind, size)
            if call not in params:     # pyramids: two sizes can give the same row count
                params.append(call)
                kind_rows.append((d, call))
        over = {path: None for path, _, _ in _PATHS}     # the first size over the budget, per path
        settle_over = None
        for d, call in kind_rows:
            scene = parse_scene(d)
            model = compile_scene(scene)
            h = scene.sim.h
            row = dict(kind=kind, scene=call, bodies=model.ndyn, h=h, steps=steps, rounds=rounds,
                       step_budget_s=step_budget_s, settle_budget_s=settle_budget_s, settle_extra_s=settle_extra_s,
                       settle_steps=0, settle_cpu_s=0.0, settle_failed_steps=0, settle_max_speed=0.0)
            # a path's simulator is made when it runs: a large skipped one would hold its work buffers for nothing
            options = {path: SimOptions(h=h) if smin is None else SimOptions(h=h, sparse_min_unknowns=smin)
                       for path, _, smin in _PATHS}
            defaults = Simulator(model, options["defaults"])
            state = defaults.initial_state()
            settled = True
            if kind == "bin":
                want = settle_steps(scene, state[0], settle_extra_s)
                if settle_over is None:
                    state, done, cpu, failed = _settle(defaults, state, want, settle_budget_s)
                    settled = done == want
                    row.update(settle_steps=done, settle_cpu_s=cpu, settle_failed_steps=failed,
                               settle_max_speed=float(np.hypot(state[1][:, 0], state[1][:, 1]).max()))
                    if not settled:
                        settle_over = model.ndyn
                        reason = (f"skipped: settling took more than the {settle_budget_s:g} s budget ({done} of "
                                  f"{want} steps in {cpu:.0f} s)")
                else:
                    settled = False
                    reason = f"skipped: the bin of {settle_over} did not settle within the budget"
                say(f"{call}: {model.ndyn} bodies, " + (reason if not settled else
                    f"settled in {want} steps ({row['settle_cpu_s']:.1f} s CPU)"))
            else:
                say(f"{call}: {model.ndyn} bodies")
            for path, pre, _ in _PATHS:
                row.update({pre + "timing": "skipped", pre + "us_per_step": None, pre + "us_min": None,
                            pre + "us_max": None, pre + "runs_per_round": 0, pre + "note": ""})
                row.update({pre + k: None for k in _RUN_FIELDS})
                if not settled:
                    row[pre + "note"] = reason
                    continue
                if over[path] is not None:
                    row[pre + "note"] = f"skipped: the {over[path]}-body {kind} was over the step budget"
                    continue
                sim = defaults if path == "defaults" else Simulator(model, options[path])
                done, cpu, out = _probe(sim, state, steps, step_budget_s)
                if cpu > steps * step_budget_s:
                    over[path] = model.ndyn
                    us = cpu / done * 1e6
                    row.update({pre + "timing": "once", pre + "us_per_step": us, pre + "us_min": us,
                                pre + "us_max": us, pre + "note": f"timed once, {done} of {steps} steps: over the "
                                                                  f"{step_budget_s:g} s per step budget"})
                    row.update({pre + k: x for k, x in _run_fields(out).items()})
                    continue
                row[pre + "timing"] = "rounds"
                runners[(model.ndyn, path)] = _PileRun(sim, state, steps)
            rows.append(row)
        if runners:
            names = {key: f"{kind}_{key[0]}_{key[1]}" for key in runners}
            m = alternate_rounds({names[k]: r for k, r in runners.items()}, rounds=rounds, min_round_s=min_round_s)
        per_step = {}
        for row in (r for r in rows if r["kind"] == kind):
            for path, pre, _ in _PATHS:
                key = (row["bodies"], path)
                if key not in runners:
                    continue
                per_step[key] = m["per_unit"][names[key]] / steps
                us = per_step[key] * 1e6
                row.update({pre + "us_per_step": float(np.median(us)), pre + "us_min": float(us.min()),
                            pre + "us_max": float(us.max()), pre + "runs_per_round": int(m["reps"][names[key]])})
                row.update({pre + k: x for k, x in _run_fields(runners[key].out).items()})
            both = [(row["bodies"], p) in per_step for p, _, _ in _PATHS]
            sp = ratio_stats(per_step[(row["bodies"], "dense")], per_step[(row["bodies"], "defaults")]) if all(both) \
                else None
            row.update(speedup=sp and sp["median"], speedup_min=sp and sp["min"], speedup_max=sp and sp["max"])
        fits[kind], fit_spread[kind], fit_bodies[kind] = {}, {}, {}
        for path, _, _ in _PATHS:
            bodies = sorted(n for n, p in per_step if p == path)
            sp = fit_exponent(bodies, [per_step[(n, path)] for n in bodies])
            fits[kind][path] = sp and sp["median"]
            fit_spread[kind][path] = sp and dict(min=sp["min"], q1=sp["q1"], q3=sp["q3"], max=sp["max"])
            fit_bodies[kind][path] = bodies
    return rows, fits, fit_spread, fit_bodies


def _fmt_us(x):
    return f"{x:.1f}" if x < 100 else f"{x:.0f}"


def _fmt_path(r, pre):
    """A path's cell: median [min-max] when timed in rounds, the one step's time when over the budget, or
    'skipped'; failed steps appended."""
    timing = r[pre + "timing"]
    if timing == "skipped":
        return "skipped"
    if timing == "once":
        cell = f"{_fmt_us(r[pre + 'us_per_step'])} (timed once)"
    else:
        cell = f"{_fmt_us(r[pre + 'us_per_step'])} [{_fmt_us(r[pre + 'us_min'])}-{_fmt_us(r[pre + 'us_max'])}]"
    failed = r.get(pre + "failed_steps", 0)
    return cell + (f", {failed} failed" if failed else "")


def _fmt_sparse(r):
    """The defaults' solver cells: sparse solves / fallbacks (share) | block Lemke solves."""
    if r["timing"] == "skipped":
        return "- | -"
    share = r["sparse_share"]
    return (f"{r['solved_sparse']} / {r['sparse_fallbacks']} ({'-' if share is None else f'{100 * share:.0f} %'}) | "
            f"{r['solved_block']}")


def format_scaling_piles_table(rows, fits, fit_spread, fit_bodies):
    from planar_lcp.sim import SimOptions
    smin = SimOptions.sparse_min_unknowns      # the dataclass field's default
    lines = ["| kind | bodies | scene | timed from | largest LCP | islands | defaults µs / step median [min-max] | "
             "sparse solves / fallbacks (share) | block Lemke solves | pivots / step | dense µs / step median [min-max] | "
             "pivots / step | dense / defaults median [min-max] |",
             "|---|---:|---|---|---:|---:|---:|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        ran = [pre for _, pre, _ in _PATHS if r[pre + "timing"] != "skipped"]
        timed = "t = 0" if r["kind"] != "bin" else (f"step {r['settle_steps']} ({r['settle_max_speed']:.2f} m/s)"
                                                     if ran else "-")
        lcp = f"{r[ran[0] + 'lcp_max']}" if ran else "-"
        isl = f"{r[ran[0] + 'islands']:.1f}" if ran else "-"
        piv = {pre: f"{r[pre + 'pivots_per_step']:.0f}" if pre in ran else "-" for _, pre, _ in _PATHS}
        speed = (f"{r['speedup']:.1f} [{r['speedup_min']:.1f}-{r['speedup_max']:.1f}]" if r["speedup"] is not None
                 else "-")
        lines.append(f"| {r['kind']} | {r['bodies']} | {r['scene']} | {timed} | {lcp} | {isl} | {_fmt_path(r, '')} | "
                     f"{_fmt_sparse(r)} | {piv['']} | {_fmt_path(r, 'dense_')} | {piv['dense_']} | {speed} |")
    lines.append("")
    if rows:
        r0 = rows[0]
        lines.append(f"times: thread CPU time (time.thread_time) per step of a {r0['steps']}-step run (h = 1/60 s), "
                     f"median over {r0['rounds']} rounds alternating over the sizes and both paths of a kind in one "
                     f"process, [min-max] over rounds; defaults: the sparse solver on islands of >= {smin} "
                     "unknowns; dense: sparse_min_unknowns=0; dense / defaults: median of the per-round ratios")
        lines.append(f"timed from: towers and pyramids their initial state at rest; bins the state after their top "
                     f"row's fall plus {r0['settle_extra_s']:g} s (the step, and the largest body speed there), run "
                     "with the defaults")
        lines.append(f"budgets: before its rounds each path runs its steps once, one by one, and stops when they pass "
                     f"{r0['step_budget_s']:g} s of thread CPU time per step; then it shows their mean ('timed once'), "
                     "is not fitted, and its larger sizes are skipped; a bin whose settling takes more than "
                     f"{r0['settle_budget_s']:g} s is skipped, as are larger bins; sparse share '-': no island reached "
                     f"{smin} unknowns")
        for r in rows:
            for _, pre, _ in _PATHS:
                if r[pre + "timing"] == "skipped" and r[pre + "note"]:
                    lines.append(f"  {r['scene']} {'dense' if pre else 'defaults'}: {r[pre + 'note']}")
    for kind in fits:
        parts = []
        for path, _, _ in _PATHS:
            p, b = fits[kind][path], fit_bodies[kind][path]
            if p is None:
                parts.append(f"{path} not fitted (fewer than two sizes timed in rounds)")
            else:
                s = fit_spread[kind][path]
                parts.append(f"{path} p = {p:.2f} [{s['min']:.2f}-{s['max']:.2f}] over {b[0]}-{b[-1]} bodies")
        lines.append(f"fitted growth exponent of {kind} (cost ~ bodies^p, fitted per round, median [min-max]): "
                     + "; ".join(parts))
    if fits:
        lines.append("target: p <= 1.3 over 16 to 256 bodies for towers and bins with the defaults")
    return "\n".join(lines)


#: `bench pile`: the scenes (name, generator), steps per run (2 s at h = 1/60 s), Box2D substeps tried for the tower
PILE_SCENES = (("tower_16", lambda: _piles().tower(16)), ("tower_64", lambda: _piles().tower(64)),
               ("bin_40", lambda: _piles().bin_scene(40)))
PILE_STEPS = 120
PILE_SUBSTEPS = (4, 8, 16, 32, 64)
PILE_ROUNDS = 7
#: a tower "stands" when its top box moves less than this over the run (m)
STAND_TOL = 1e-3


def _piles():
    from planar_lcp.spec import piles
    return piles


def _penetration(model, q):
    """Deepest penetration (m, >= 0) of the dynamic bodies at poses q, by our collision detection."""
    from planar_lcp.engine.contacts import contacts_at
    _, phi, _, _ = contacts_at(model.arrays, q, model.qk0, 0.0, all_pairs=True)
    return float(max(0.0, -phi.min())) if phi.size else 0.0


def _box2d_run(model, substeps, steps, h):
    """Box2D's whole run: (top-box drift (m), deepest penetration over the run at the end of every step, as ours is
    measured: Stat.PENETRATION, the deepest at each step's q+)."""
    from planar_lcp.bridges.box2d import box2d_poses, box2d_world
    world, bodies = box2d_world(model)
    q0 = box2d_poses(bodies)
    pen = 0.0
    for i in range(steps):
        world.step(h, substeps)
        pen = max(pen, _penetration(model, box2d_poses(bodies)))
    q = box2d_poses(bodies)
    return float(np.abs(q[-1, :2] - q0[-1, :2]).max()), pen


class _Box2dRunner:
    """One unit: a whole Box2D run of `steps` steps; its worlds are built by `prepare`, outside the clock."""

    def __init__(self, model, substeps, steps, h):
        self.model, self.substeps, self.steps, self.h = model, substeps, steps, h
        self.worlds = []

    def prepare(self, k):
        from planar_lcp.bridges.box2d import box2d_world
        self.worlds = [box2d_world(self.model)[0] for _ in range(k)]

    def __call__(self):
        world = self.worlds.pop()     # alternate_rounds prepares as many as it calls
        for _ in range(self.steps):
            world.step(self.h, self.substeps)


def bench_pile(scenes=PILE_SCENES, steps=PILE_STEPS, rounds=PILE_ROUNDS, min_round_s=MIN_ROUND_S, progress=None):
    """Per step, ours (the defaults: the sparse solver on large islands) against Box2D v3 on the same scenes in the
    same process, alternating rounds of thread CPU time; Box2D at its default 4 substeps and at the fewest of
    PILE_SUBSTEPS that keep the tower of the same scene family standing (towers: their own; the bin: the 64-box
    tower's). Each row: us/step median [min-max], the ratio ours / Box2D per round (median [min-max]), and for each
    simulator whether the tower stood (top box moved < STAND_TOL) and the deepest penetration over the run."""
    from planar_lcp.engine.layout import Stat
    from planar_lcp.model import compile_scene
    from planar_lcp.sim import SimOptions, Simulator
    from planar_lcp.spec.scene import parse_scene
    rows, tuned_for_bin = [], None
    for i, (name, make) in enumerate(scenes):
        if progress is not None:
            progress(f"{name} ({i + 1} of {len(scenes)})")
        scene = parse_scene(make())
        model = compile_scene(scene)
        h = scene.sim.h
        sim = Simulator(model, SimOptions(h=h))
        q, v, qk, vk = sim.initial_state()
        out = sim.rollout(q, v, qk, vk[None], steps)
        ours_drift = float(np.abs(out["q"][-1, -1, :2] - out["q"][0, -1, :2]).max())
        ours_pen = float(out["stats"][:, Stat.PENETRATION].max())
        tower = name.startswith("tower")
        tried = {}
        if tower:
            for sub in PILE_SUBSTEPS:
                tried[sub] = _box2d_run(model, sub, steps, h)
                if tried[sub][0] < STAND_TOL:
                    break
            stood = [sub for sub, (drift, _) in tried.items() if drift < STAND_TOL]
            tuned = stood[0] if stood else max(tried)
            tuned_for_bin = tuned
            label = "fewest that stand" if stood else "most tried: none stands"
        else:
            tuned = tuned_for_bin or 4
            label = "the last tower's"
        for sub in {4, tuned}:
            if sub not in tried:
                tried[sub] = _box2d_run(model, sub, steps, h)
        runners = {"ours": lambda sim=sim, q=q, v=v, qk=qk, vk=vk: sim.rollout(q, v, qk, vk[None], steps)}
        for sub in sorted({4, tuned}):
            runners[f"box2d_{sub}"] = _Box2dRunner(model, sub, steps, h)
        m = alternate_rounds(runners, rounds=rounds, min_round_s=min_round_s)
        ours = m["per_unit"]["ours"] / steps
        for sub in sorted({4, tuned}):
            peer = m["per_unit"][f"box2d_{sub}"] / steps
            ratio = _spread(ours / peer)
            drift, pen = tried[sub]
            rows.append(dict(scene=name, bodies=model.ndyn, box2d_substeps=sub,
                             box2d_setting="defaults" if sub == 4 else label,
                             ours_us=float(np.median(ours)) * 1e6, ours_us_min=float(ours.min()) * 1e6,
                             ours_us_max=float(ours.max()) * 1e6, box2d_us=float(np.median(peer)) * 1e6,
                             box2d_us_min=float(peer.min()) * 1e6, box2d_us_max=float(peer.max()) * 1e6,
                             ratio=ratio["median"], ratio_min=ratio["min"], ratio_max=ratio["max"],
                             ours_top_drift=ours_drift if tower else None, ours_penetration=ours_pen,
                             box2d_top_drift=drift if tower else None, box2d_penetration=pen,
                             solved_sparse=int(out["stats"][:, Stat.SOLVED_SPARSE].sum()),
                             sparse_fallbacks=int(out["stats"][:, Stat.SPARSE_FALLBACKS].sum()),
                             solved_block=int(out["stats"][:, Stat.SOLVED_BLOCK].sum()),
                             rounds=rounds, steps=steps, h=h))
    return rows


def format_pile_table(rows):
    lines = ["| scene | bodies | Box2D substeps | ours µs/step | Box2D µs/step | ratio ours/Box2D | ours: top drift, "
             "penetration (m) | Box2D: top drift, penetration (m) | sparse solves / fallbacks | block Lemke solves |",
             "|---|---:|---|---:|---:|---:|---|---|---|---:|"]

    def state(drift, pen):
        return (f"{drift:.1e} ({'stands' if drift < STAND_TOL else 'falls'}), {pen:.1e}" if drift is not None
                else f"-, {pen:.1e}")
    for r in rows:
        lines.append(f"| {r['scene']} | {r['bodies']} | {r['box2d_substeps']} ({r['box2d_setting']}) | "
                     f"{r['ours_us']:.0f} [{r['ours_us_min']:.0f}-{r['ours_us_max']:.0f}] | "
                     f"{r['box2d_us']:.0f} [{r['box2d_us_min']:.0f}-{r['box2d_us_max']:.0f}] | "
                     f"{r['ratio']:.2f} [{r['ratio_min']:.2f}-{r['ratio_max']:.2f}] | "
                     f"{state(r['ours_top_drift'], r['ours_penetration'])} | "
                     f"{state(r['box2d_top_drift'], r['box2d_penetration'])} | "
                     f"{r['solved_sparse']} / {r['sparse_fallbacks']} | {r['solved_block']} |")
    if rows:
        lines.append("")
        lines.append(f"times: thread CPU time per step of a whole {rows[0]['steps']}-step run (h = 1/60 s) from the "
                     f"scene's initial state, median over {rows[0]['rounds']} alternating rounds in one process "
                     "[min-max]; ratio: median of the per-round ratios [min-max]; Box2D v3 (pyb2d3) with sleeping "
                     "off, its worlds built outside the clock; penetration by our collision detection on each "
                     "simulator's poses at the end of every step; a tower stands when its top box moves < 1 mm")
    return "\n".join(lines)


# --- the step's derivatives -------------------------------------------------------------------------------------

#: the scenes of `bench derivatives`: the falling rod (vertical plane) and the pushed box (horizontal plane)
DERIVATIVE_SCENES = ("falling_rod", "box_push")
#: central differences' step (times max(1, |x|)) of the differences peer
DIFFERENCE_STEP = 1e-6


def derivative_state(sim, scene):
    """The state (q, v, qk, vk) and its time where `bench derivatives` differentiates the step: half-way through the
    scene's run (t_end / 2) when that step meets a contact, else the first state whose step does (None if no step
    does)."""
    from planar_lcp.engine.layout import Stat
    from planar_lcp.spec.path import kinematic_velocities
    n = int(round(scene.sim.t_end / scene.sim.h))
    q, v, qk, _ = sim.initial_state()
    vks = kinematic_velocities(scene, sim.model.kin_names, sim.h, n)
    r = sim.rollout(q, v, qk, vks, n)
    touching = np.flatnonzero(r["stats"][:r["steps_done"], Stat.N_CONTACTS] > 0)
    if len(touching) == 0:
        return None
    k = n // 2 if n // 2 in set(touching.tolist()) else int(touching[0])
    vk = vks[min(k, len(vks) - 1)]
    return r["q"][k].copy(), r["v"][k].copy(), r["qk"][k].copy(), np.array(vk, dtype=float), k * sim.h


def central_differences(sim, q, v, qk, vk, step=DIFFERENCE_STEP):
    """The Jacobian of `sim.step` (cold) at (q, v, qk, vk) by central differences, in `StepDerivatives.jacobian`'s
    layout (rows q+, v+, qk+; columns q, v, qk, vk): 2 n + 1 steps for n inputs (the last at the state itself, which
    a user needs beside the Jacobian)."""
    parts = [np.array(a, dtype=float) for a in (q, v, qk, vk)]
    nq, nqk = parts[0].size, parts[2].size
    J = np.empty((2 * nq + nqk, sum(a.size for a in parts)))

    def step_into(out):
        sim.reset_warm_start()
        q1, v1, qk1, _ = sim.step(*parts)
        out[:nq], out[nq:2 * nq], out[2 * nq:] = q1.ravel(), v1.ravel(), qk1.ravel()

    plus, minus = np.empty(J.shape[0]), np.empty(J.shape[0])
    step_into(plus)                         # the state's own step
    col = 0
    for a in parts:
        flat = a.reshape(-1)                # a view: the step reads the perturbed entry
        for k in range(flat.size):
            x = flat[k]
            e = step * max(1.0, abs(x))
            flat[k] = x + e
            step_into(plus)
            flat[k] = x - e
            step_into(minus)
            flat[k] = x
            J[:, col] = (plus - minus) / (2.0 * e)
            col += 1
    return J


def bench_derivatives(scenes=DERIVATIVE_SCENES, rounds=ROUNDS, min_round_s=MIN_ROUND_S, mujoco=True, progress=None):
    """The cost of all the Jacobians of one step, in the same process and alternating rounds of thread CPU time
    (`alternate_rounds`), at `derivative_state`, all cold (no warm start): `Simulator.step_derivatives` by its checked
    differences ("derivatives": method "differences"; `method` says whether they answered at the state,
    `differences_exact` whether they are exact there) and by the dual
    numbers ("dual"), and central differences of `Simulator.step` in Python ("central": 2 n + 1 steps for n
    inputs), each against one `Simulator.step`; and where MuJoCo installs (`mujoco`), its `mjd_transitionFD`
    (centred, eps 1e-6) against its `mj_step` on the scene's MuJoCo model (planar_lcp.bridges.mujoco) at the same
    poses and velocities. Each ratio is the median over rounds of the two times measured back to back, with its
    spread; `derivatives_steps` is the derivatives' cost in steps. progress: called with a line as each scene
    starts."""
    from planar_lcp.model import compile_scene
    from planar_lcp.sim import SimOptions, Simulator
    from planar_lcp.spec.scene import load_scene
    rows = []
    for i, name in enumerate(scenes):
        if progress is not None:
            progress(f"{name} ({i + 1} of {len(scenes)})")
        sc = load_scene(name)
        options = SimOptions(h=sc.sim.h, solver=sc.sim.solver, formulation=sc.sim.formulation)
        sim = Simulator(compile_scene(sc), options)
        at = derivative_state(sim, sc)
        if at is None:
            rows.append(dict(scene=name, skipped="no step of its run meets a contact"))
            continue
        q, v, qk, vk, t = at
        d = sim.step_derivatives(q, v, qk, vk)
        checked = sim.step_derivatives(q, v, qk, vk, method="differences")

        def one_step(sim=sim, q=q, v=v, qk=qk, vk=vk):
            sim.reset_warm_start()
            sim.step(q, v, qk, vk)

        runners = dict(step=one_step,
                       derivatives=lambda sim=sim, q=q, v=v, qk=qk, vk=vk: sim.step_derivatives(
                           q, v, qk, vk, method="differences"),
                       dual=lambda sim=sim, q=q, v=v, qk=qk, vk=vk: sim.step_derivatives(q, v, qk, vk),
                       central=lambda sim=sim, q=q, v=v, qk=qk, vk=vk: central_differences(sim, q, v, qk, vk))
        peer = _mujoco_runners(sc, options.contact_margin, q, v, qk, vk) if mujoco else None
        if peer is not None and "runners" in peer:
            runners.update(peer["runners"])
        m = alternate_rounds(runners, rounds=rounds, min_round_s=min_round_s)
        per = m["per_unit"]
        row = dict(scene=name, t=float(t), inputs=int(d.jacobian.shape[1]), exact=bool(d.exact),
                   method=checked.method, fallback=checked.fallback, differences_exact=bool(checked.exact),
                   contacts=_contacts_at(sim, q, v, qk, vk),
                   step_us=float(np.median(per["step"])) * 1e6,
                   derivatives_us=float(np.median(per["derivatives"])) * 1e6,
                   dual_us=float(np.median(per["dual"])) * 1e6,
                   central_us=float(np.median(per["central"])) * 1e6,
                   rounds=rounds, runs_per_round={k: int(x) for k, x in m["reps"].items()},
                   other_threads_cpu_share=m["other_threads_cpu_share"])
        row.update(_ratio_fields("derivatives_steps", ratio_stats(per["derivatives"], per["step"])))
        row.update(_ratio_fields("dual_steps", ratio_stats(per["dual"], per["step"])))
        row.update(_ratio_fields("central_steps", ratio_stats(per["central"], per["step"])))
        row.update(_ratio_fields("derivatives_vs_central", ratio_stats(per["derivatives"], per["central"])))
        if peer is not None and "unmapped" in peer:
            row["mujoco_unmapped"] = peer["unmapped"]
        elif peer is not None:
            row.update(mujoco_version=peer["version"], mujoco_inputs=peer["inputs"], mujoco_contacts=peer["contacts"],
                       mujoco_step_us=float(np.median(per["mujoco_step"])) * 1e6,
                       mujoco_fd_us=float(np.median(per["mujoco_fd"])) * 1e6)
            row.update(_ratio_fields("mujoco_fd_steps", ratio_stats(per["mujoco_fd"], per["mujoco_step"])))
            row.update(_ratio_fields("derivatives_vs_mujoco_fd", ratio_stats(per["derivatives"], per["mujoco_fd"])))
        rows.append(row)
    return rows


def _contacts_at(sim, q, v, qk, vk):
    """The contacts in the active set of the (cold) step at the state."""
    from planar_lcp.engine.layout import Stat
    sim.reset_warm_start()
    sim.step(q, v, qk, vk)
    sim.reset_warm_start()
    return int(sim.stats[Stat.N_CONTACTS])


def _mujoco_runners(scene, margin, q, v, qk, vk):
    """MuJoCo's runners at our state (`bench_derivatives`), None where mujoco does not import, or {"unmapped": why}
    for a scene the bridge does not map."""
    try:
        import mujoco
    except ImportError:
        return None
    from planar_lcp.bridges.mujoco import UnsupportedScene, mujoco_scene
    try:
        ms = mujoco_scene(scene, margin=margin)
    except UnsupportedScene as e:
        return dict(unmapped=str(e))
    ms.set_state(q, v, qk, vk)
    model, data = ms.model, ms.data
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    nx = 2 * model.nv + model.na
    A, B = np.zeros((nx, nx)), np.zeros((nx, model.nu))

    def step():
        mujoco.mj_setState(model, data, state, spec)
        mujoco.mj_step(model, data)

    def fd():
        mujoco.mj_setState(model, data, state, spec)
        mujoco.mjd_transitionFD(model, data, 1e-6, True, A, B, None, None)

    return dict(runners=dict(mujoco_step=step, mujoco_fd=fd), version=mujoco.__version__, inputs=nx + model.nu,
                contacts=int(data.ncon))


def _count(n, noun):
    return f"{n} {noun}{'' if n == 1 else 's'}"


def format_derivatives_table(rows):
    """The markdown table of `bench_derivatives`' rows."""
    lines = ["| scene | state | inputs | exact | step µs | derivatives µs | in steps median [min-max] | "
             "dual numbers in steps | central differences in steps | MuJoCo mjd_transitionFD in its steps | "
             "derivatives / mjd_transitionFD |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if "skipped" in r:
            lines.append(f"| {r['scene']} | {r['skipped']} | | | | | | | | | |")
            continue
        mj = "MuJoCo not installed", "-"
        if "mujoco_unmapped" in r:
            mj = f"not mapped: {r['mujoco_unmapped']}", "-"
        elif "mujoco_fd_us" in r:
            mj = (f"{_fmt_ratio(r, 'mujoco_fd_steps')} ({r['mujoco_inputs']} inputs, {_count(r['mujoco_contacts'], 'contact')})",
                  _fmt_ratio(r, "derivatives_vs_mujoco_fd"))
        how = "" if r["method"] == "differences" else f" (dual numbers: {r['fallback']})"
        lines.append(f"| {r['scene']} | t = {r['t']:.3g} s, {_count(r['contacts'], 'contact')} | {r['inputs']} | "
                     f"{'yes' if r['exact'] else 'no'} | {_fmt_us(r['step_us'])} | {_fmt_us(r['derivatives_us'])}{how} | "
                     f"{_fmt_ratio(r, 'derivatives_steps')} | {_fmt_ratio(r, 'dual_steps')} | "
                     f"{_fmt_ratio(r, 'central_steps')} | {mj[0]} | {mj[1]} |")
    return "\n".join(lines)


def run_bench(which, json_path=None, kinds=None, sizes=None, steps=None, rounds=None, scenes=None,
              step_budget_s=STEP_BUDGET_S, settle_budget_s=SETTLE_BUDGET_S):
    """Run the benchmark `which` (step, lcp, scaling, pile, derivatives or all), print its tables and optionally write
    the JSON.

    `all` is step, lcp and scaling's small layouts (pile, islands): the run of record docs/figures/performance/
    bench.json; the large piles and `pile` are runs of their own. kinds, sizes, steps: scaling's kinds (default all
    of SCALING_KINDS), body counts (default SCALING_SIZES for the layouts, PILE_SCALING_SIZES for the piles) and
    steps per timed run; steps and scenes (names of PILE_SCENES) for pile; scenes (shipped scene names) for
    derivatives; rounds for any (default: each
    benchmark's own)."""
    report = {}

    def say(bench_name):
        """A progress line on stderr (the tables go to stdout): each benchmark takes minutes."""
        return lambda line: print(f"bench {bench_name}: {line}", file=sys.stderr, flush=True)
    if which in ("scaling", "all"):
        kinds = kinds or (SCALING_KINDS if which == "scaling" else SCALING_LAYOUTS)
        layouts = [k for k in kinds if k in SCALING_LAYOUTS]
        pile_kinds = [k for k in kinds if k in SCALING_PILES]
        if layouts:
            rows, fits, fit_spread = bench_scaling(sizes=sizes or SCALING_SIZES, steps=steps or 20,
                                                   rounds=rounds or SCALING_ROUNDS, kinds=layouts)
            print(format_scaling_table(rows, fits, fit_spread))
            report["scaling"] = dict(rows=rows, fits=fits, fit_spread=fit_spread, clock="thread_time")
        if pile_kinds:
            if layouts:
                print("")
            rows, fits, fit_spread, fit_bodies = bench_scaling_piles(
                kinds=pile_kinds, sizes=sizes or PILE_SCALING_SIZES, steps=steps or PILE_SCALING_STEPS,
                rounds=rounds or SCALING_ROUNDS, step_budget_s=step_budget_s, settle_budget_s=settle_budget_s,
                progress=say("scaling"))
            print(format_scaling_piles_table(rows, fits, fit_spread, fit_bodies))
            report["scaling_piles"] = dict(rows=rows, fits=fits, fit_spread=fit_spread, fit_bodies=fit_bodies,
                                           clock="thread_time", step_budget_s=step_budget_s,
                                           settle_budget_s=settle_budget_s, settle_extra_s=SETTLE_EXTRA_S)
    if which == "derivatives":
        rows = bench_derivatives(scenes=tuple(scenes) if scenes else DERIVATIVE_SCENES, rounds=rounds or ROUNDS,
                                 progress=say("derivatives"))
        print(format_derivatives_table(rows))
        report["derivatives"] = dict(rows=rows, clock="thread_time")
    if which == "pile":
        chosen = tuple(sc for sc in PILE_SCENES if sc[0] in scenes) if scenes else PILE_SCENES
        rows = bench_pile(scenes=chosen, steps=steps or PILE_STEPS, rounds=rounds or PILE_ROUNDS,
                          progress=say("pile"))
        print(format_pile_table(rows))
        report["pile"] = dict(rows=rows, clock="thread_time")
    if which in ("step", "all"):
        say("step")("the first simulate() on an empty numba cache, in a child process, and its background "
                    f"compilation (about {COLD_START_SECONDS} s)")
        compile_times = measure_step_compile_time()
        rows = bench_step(rounds=rounds or ROUNDS, progress=say("step"))
        print(format_step_table(rows, compile_times))
        report["step"] = dict(rows=rows, compile=compile_times, clock="thread_time")
    if which in ("lcp", "all"):
        say("lcp")("the first lemke() on an empty numba cache, in a child process")
        compile_times = measure_compile_time()
        say("lcp")("the corpus, ours against QuantEcon's lcp_lemke in alternating rounds")
        rows = bench_lcp(rounds=rounds or ROUNDS)
        if not rows:
            raise SystemExit("bench lcp: the LCP corpus ../shared/data/lcp was not found (set PLANAR_LCP_CORPUS)")
        print(format_lcp_table(rows, compile_times))
        report["lcp"] = dict(rows=rows, compile=compile_times, clock="thread_time",
                             median_ratio=statistics.median([r["ratio"] for r in rows]))
    if json_path:
        with open(json_path, "w") as f:
            json.dump(report, f, indent=1)
        print(f"wrote {json_path}")
    return report
