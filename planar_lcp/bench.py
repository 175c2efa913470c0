"""Benchmarks (not tests): speed reported as ratios against a peer measured in the same run."""

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from .kernels.lemke import STATUS_NAMES, lemke_kernel, make_lemke_work
from .lcp import DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL, default_max_pivots, lemke
from .lcp_corpus import load_corpus


def _time_call(fn, min_total=0.02, max_reps=5000, rounds=3):
    """Median seconds per call over `rounds` batches sized to last at least `min_total` seconds each."""
    t0 = time.perf_counter()
    fn()
    one = max(time.perf_counter() - t0, 1e-7)
    reps = int(min(max_reps, max(1, min_total / one)))
    per = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(reps):
            fn()
        per.append((time.perf_counter() - t0) / reps)
    return statistics.median(per)


class _OurKernel:
    """Our numba kernel with preallocated work arrays, as the time-stepper calls it."""

    def __init__(self, M, q):
        n = q.shape[0]
        self.M, self.q = np.ascontiguousarray(M), np.ascontiguousarray(q)
        self.args = make_lemke_work(n)
        self.max_pivots = default_max_pivots(n)

    def __call__(self):
        return lemke_kernel(self.M, self.q, self.max_pivots, DEFAULT_PIV_TOL, DEFAULT_RATIO_TOL, DEFAULT_RES_TOL,
                            True, *self.args)


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


def bench_lcp(corpus_dir=None, slow_cap_s=1.0):
    """Ours vs QuantEcon's lcp_lemke on every corpus instance. Returns a list of row dicts."""
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
        t0 = time.perf_counter()
        qres = qe()
        qe_once = time.perf_counter() - t0
        qe_status = {0: "solved", 1: "max_iter", 2: "ray_termination"}[int(qres.status)]
        if qe_status == "solved":
            # QuantEcon does not check its answer; we do, with the same residual as ours
            scale = max(1.0, np.abs(inst.M).max(), np.abs(inst.q).max())
            if _residual(inst.M, inst.q, qres.z) > DEFAULT_RES_TOL * scale:
                qe_status = "wrong_z"
        t_ours = _time_call(ours)
        t_qe = qe_once if qe_once > slow_cap_s else _time_call(qe)
        t_pub = _time_call(lambda: lemke(inst.M, inst.q))
        rows.append(dict(id=inst.id, n=inst.n, status=STATUS_NAMES[status], pivots=int(pivots), residual=float(res),
                         us=t_ours * 1e6, public_us=t_pub * 1e6, qe_status=qe_status, qe_pivots=int(qres.num_iter),
                         qe_us=t_qe * 1e6, ratio=t_ours / t_qe))
    return rows


_COMPILE_SNIPPET = (
    "import time; t0 = time.perf_counter()\n"
    "import numpy as np\n"
    "import planar_lcp\n"
    "t1 = time.perf_counter()\n"
    "planar_lcp.lemke(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0]))\n"
    "t2 = time.perf_counter()\n"
    "print(t1 - t0, t2 - t1)\n"
)


def _cold_and_warm(snippet):
    """Run `snippet` (which prints two timings) in a subprocess twice with one fresh NUMBA_CACHE_DIR: the first run
    compiles, the second loads the cache. Returns [(t1, t2) cold, (t1, t2) warm]."""
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
                warm_first_call_s=out[1][1])


def format_lcp_table(rows, compile_times=None):
    lines = [
        "| instance | n | ours: status | pivots | µs | QuantEcon: status | pivots | µs | ratio ours/QE | public lemke() µs |",
        "|---|---:|---|---:|---:|---|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['id']} | {r['n']} | {r['status']} | {r['pivots']} | {r['us']:.2f} | {r['qe_status']} | "
                     f"{r['qe_pivots']} | {r['qe_us']:.2f} | {r['ratio']:.3f} | {r['public_us']:.2f} |")
    ratios = [r["ratio"] for r in rows]
    lines.append("")
    lines.append(f"median ratio ours/QuantEcon over {len(rows)} instances: {statistics.median(ratios):.3f} "
                 f"(target <= 1.0); geometric mean {float(np.exp(np.mean(np.log(ratios)))):.3f}")
    both = [r for r in rows if r["status"] == "solved" and r["qe_status"] == "solved"]
    if both:
        lines.append(f"median ratio where both solve ({len(both)} instances): "
                     f"{statistics.median([r['ratio'] for r in both]):.3f}")
    if compile_times:
        lines.append(f"first-call JIT compile (fresh cache): import {compile_times['cold_import_s']:.2f} s, "
                     f"first lemke() {compile_times['cold_first_call_s']:.2f} s; warm cache: import "
                     f"{compile_times['warm_import_s']:.2f} s, first lemke() {compile_times['warm_first_call_s']:.3f} s")
    return "\n".join(lines)


STEP_SCENES = ("falling_rod", "box_push", "box_tip", "push_t")

_STEP_COMPILE_SNIPPET = (
    "import time; t0 = time.perf_counter()\n"
    "import planar_lcp\n"
    "t1 = time.perf_counter()\n"
    "planar_lcp.simulate('falling_rod', t_end=0.01)\n"
    "t2 = time.perf_counter()\n"
    "print(t1 - t0, t2 - t1)\n"
)


def measure_step_compile_time():
    """First simulate() with a fresh numba cache (compile) and again with the cache warm."""
    out = _cold_and_warm(_STEP_COMPILE_SNIPPET)
    return dict(cold_import_s=out[0][0], cold_first_simulate_s=out[0][1], warm_import_s=out[1][0],
                warm_first_simulate_s=out[1][1])


def _time_pymunk_median(scene, n, rounds):
    """Median seconds for n pymunk steps over `rounds` fresh spaces (the same statistic as ours)."""
    from .pymunk_bridge import build_space
    times = []
    for _ in range(rounds):
        space, _handles = build_space(scene, h=scene.sim.h)
        step = space.step
        t0 = time.perf_counter()
        for _i in range(n):
            step(scene.sim.h)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench_step(scenes=STEP_SCENES, rounds=5, pymunk=True):
    """Microseconds per step of our stepper (one jitted rollout over the scene's duration, warm JIT), with its defaults
    and with the LCP warm start the planners use, and, in the same run, of pymunk on the same scene and h through
    planar_lcp.pymunk_bridge (10 iterations, its defaults)."""
    from .model import compile_scene
    from .scene import load_scene
    from .sim import SimOptions, Simulator
    from .kernels.step import ST_WARM_STARTS
    rows = []
    for name in scenes:
        sc = load_scene(name)
        n = int(round(sc.sim.t_end / sc.sim.h))
        us, stats = {}, {}
        for warm in (False, True):
            sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, solver=sc.sim.solver,
                                                          formulation=sc.sim.formulation, warm_start=warm))
            q, v, qk, vk = sim.initial_state()
            sim.rollout(q, v, qk, vk[None], 5)  # warm JIT
            times = []
            for _ in range(rounds):
                t0 = time.perf_counter()
                out = sim.rollout(q, v, qk, vk[None], n)
                times.append(time.perf_counter() - t0)
            us[warm] = statistics.median(times) / n * 1e6
            stats[warm] = out["stats"]
        st, stw = stats[False], stats[True]
        with_lcp = stw[:, 0] > 0
        row = dict(scene=name, steps=n, h=sc.sim.h, us_per_step=us[False], warm_us_per_step=us[True],
                   mean_lcp_size=float(st[:, 0].mean()), max_lcp_size=int(st[:, 1].max()),
                   pivots_per_step=float(st[:, 2].mean()), warm_pivots_per_step=float(stw[:, 2].mean()),
                   warm_start_share=float(stw[with_lcp, ST_WARM_STARTS].mean()) if with_lcp.any() else 0.0)
        if pymunk:
            row["pymunk_us_per_step"] = _time_pymunk_median(sc, n, rounds) / n * 1e6
            row["ratio"] = row["us_per_step"] / row["pymunk_us_per_step"]
            row["warm_ratio"] = row["warm_us_per_step"] / row["pymunk_us_per_step"]
        rows.append(row)
    return rows


def format_step_table(rows, compile_times=None):
    lines = ["| scene | steps | h (s) | ours µs / step | pymunk µs / step | ratio ours/pymunk | mean LCP size | "
             "largest LCP | pivots / step | ours with warm start µs / step | ratio | warm-started LCPs | "
             "pivots / step |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        pm = f"{r['pymunk_us_per_step']:.1f} | {r['ratio']:.1f}" if "ratio" in r else "- | -"
        wr = f"{r['warm_ratio']:.1f}" if "warm_ratio" in r else "-"
        lines.append(f"| {r['scene']} | {r['steps']} | {r['h']} | {r['us_per_step']:.1f} | {pm} | "
                     f"{r['mean_lcp_size']:.1f} | {r['max_lcp_size']} | {r['pivots_per_step']:.1f} | "
                     f"{r['warm_us_per_step']:.1f} | {wr} | {100 * r['warm_start_share']:.0f} % | "
                     f"{r['warm_pivots_per_step']:.1f} |")
    if any("ratio" in r for r in rows):
        lines.append("")
        lines.append("target: ratio <= 1.0 on each scene (pymunk through planar_lcp.pymunk_bridge, 10 iterations); "
                     "ours with the defaults, then with SimOptions(warm_start=True) as the planners run it")
    if compile_times:
        lines.append("")
        lines.append(f"first simulate() with a fresh numba cache (compile): {compile_times['cold_first_simulate_s']:.1f} s "
                     f"(import {compile_times['cold_import_s']:.2f} s); with the cache warm: "
                     f"{compile_times['warm_first_simulate_s']:.2f} s (import {compile_times['warm_import_s']:.2f} s); "
                     f"targets <= 20 s and <= 2 s")
    return "\n".join(lines)


SCALING_SIZES = (1, 2, 4, 8, 16, 32, 64)


def _scaling_scene(n, kind):
    """n boxes (0.2 x 0.1 m, 1 kg) on a table: a tower (one island: every box touches the next) or a row of
    separate boxes 0.5 m apart (n islands)."""
    from .scene import parse_scene
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


def bench_scaling(sizes=SCALING_SIZES, steps=20):
    """Cost per step of a tower of n boxes (one island, LCP of 8 n unknowns) and of n separate boxes (n islands of
    8 unknowns), with the growth exponent fitted on log(cost) against log(n) over n >= 4."""
    from .model import compile_scene
    from .sim import SimOptions, Simulator
    rows = []
    for kind in ("pile", "islands"):
        for n in sizes:
            sim = Simulator(compile_scene(_scaling_scene(n, kind)), SimOptions(h=0.005))
            q, v, qk, vk = sim.initial_state()
            sim.rollout(q, v, qk, vk[None], 2)
            reps = max(1, int(200 / n))
            times = []
            for _ in range(3):
                t0 = time.perf_counter()
                for _ in range(reps):
                    out = sim.rollout(q, v, qk, vk[None], steps)
                times.append((time.perf_counter() - t0) / (reps * steps))
            rows.append(dict(kind=kind, bodies=n, us_per_step=statistics.median(times) * 1e6,
                             lcp_max=int(out["stats"][:, 1].max()), pivots_per_step=float(out["stats"][:, 2].mean())))
    fits = {}
    for kind in ("pile", "islands"):
        pts = [(r["bodies"], r["us_per_step"]) for r in rows if r["kind"] == kind and r["bodies"] >= 4]
        x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
        fits[kind] = float(np.polyfit(x, y, 1)[0])
    return rows, fits


def format_scaling_table(rows, fits):
    lines = ["| layout | bodies | µs / step | largest LCP | pivots / step |", "|---|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['kind']} | {r['bodies']} | {r['us_per_step']:.1f} | {r['lcp_max']} | "
                     f"{r['pivots_per_step']:.1f} |")
    lines.append("")
    lines.append(f"fitted growth exponent (cost ~ n^p over n >= 4): pile p = {fits['pile']:.2f} (one island: "
                 f"Lemke on a dense tableau), islands p = {fits['islands']:.2f}")
    return "\n".join(lines)


def run_bench(which, json_path=None):
    report = {}
    if which in ("scaling", "all"):
        rows, fits = bench_scaling()
        print(format_scaling_table(rows, fits))
        report["scaling"] = dict(rows=rows, fits=fits)
    if which in ("step", "all"):
        compile_times = measure_step_compile_time()
        rows = bench_step()
        print(format_step_table(rows, compile_times))
        report["step"] = dict(rows=rows, compile=compile_times)
    if which in ("lcp", "all"):
        compile_times = measure_compile_time()
        rows = bench_lcp()
        if not rows:
            raise SystemExit("bench lcp: the LCP corpus ../shared/data/lcp was not found (set PLANAR_LCP_CORPUS)")
        print(format_lcp_table(rows, compile_times))
        report["lcp"] = dict(rows=rows, compile=compile_times,
                             median_ratio=statistics.median([r["ratio"] for r in rows]))
    if json_path:
        with open(json_path, "w") as f:
            json.dump(report, f, indent=1)
        print(f"wrote {json_path}")
    return report
