"""The `planar-lcp` command."""

import argparse
import importlib
import importlib.metadata
import importlib.util
import math
import signal
import sys

from planar_lcp.cli_support import (SCENE_OPERAND, SIMULATE_FLAGS, InputError, MissingPackage, ProgressBar,
                                    add_command, check_output_file, finite_number, missing_optional, one_line_errors,
                                    raised_while_interrupted, require)
from planar_lcp.interrupt import catch_sigint, clear, interrupted, raise_if_interrupted

def _how_it_ran():
    """How a simulate() run's wall time is to be read: it ran as Python while this process's background compilation
    ran (a cold cache: engine/interpreted.py), or compiled, including any compilation."""
    from planar_lcp.compilation import background
    if background.started() is not None:
        return "as Python while the kernels compile in the background"
    return "including any JIT compilation"


def cmd_demo(args):
    import time
    from pathlib import Path

    import numpy as np

    from planar_lcp.lcp import lemke
    from planar_lcp.benchmarks.lcp_corpus import find_corpus_dir, load_corpus
    from planar_lcp.sim import SimulationError, simulate
    from planar_lcp.viz import plot_trajectory

    # Part 3 plans, parts 1 and 3 draw: checked before any work; ompl first, since its extra ("plan") has all three.
    require("ompl", "matplotlib", "shapely")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    written = []

    print("planar-lcp demo")
    print("1. Stewart & Trinkle's falling rod (their section 4.1), their time-stepping with Lemke")
    t0 = time.perf_counter()
    try:
        traj = simulate("falling_rod")
    except SimulationError as e:
        print(f"planar-lcp demo: error: part 1 (the falling rod) failed: {e}", file=sys.stderr)
        return 1
    wall = time.perf_counter() - t0
    first = int(np.argmax(traj.stats["n_contacts"] > 0))
    x, y, th = traj.q[-1, 0]
    print(f"   {len(traj.t) - 1} steps of h = {traj.options.h} s in {wall:.2f} s ({_how_it_ran()}); "
          f"first contact in the step ending at t = {traj.t[first + 1]:.4f} s; at rest at x = {x:.4f} m, "
          f"theta = {th:.6f} rad; max penetration {traj.stats['penetration'].max():.1e} m")
    for name, write in (("falling_rod.csv", traj.to_csv), ("falling_rod.png", lambda p: plot_trajectory(traj, p))):
        write(out / name)
        written.append(out / name)

    print("2. Lemke's algorithm (lexicographic) on LCPs written by other projects")
    insts = load_corpus()
    if not insts:
        print("   (the corpus ../shared/data/lcp is absent; solving built-in examples instead)")
        examples = [("murty_2x2", np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0])),
                    ("kostreva_cycling", np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 2.0], [2.0, 0.0, 1.0]]),
                     -np.ones(3))]
    else:
        print(f"   corpus: {find_corpus_dir()}")
        wanted = ("siconos_lcp_deudeu", "kostreva_ex1_cycling", "drake_testPSD_artificial_tie", "dart_12d",
                  "siconos_lcp_tobenna", "murty_ex2_9_ray")
        examples = [(i.id, i.M, i.q) for i in insts if i.id in wanted]
    for name, M, q in examples:
        r = lemke(M, q)
        print(f"   {name:32s} n={len(q):3d}  {r.status:16s} pivots={r.pivots:4d}  residual={r.residual:.1e}")
    status = demo_plan(out, written)
    print("wrote:")
    for p in written:
        print(f"  {p}")
    return status


# The demo's planning run: the shipped task file scenes/push_box.toml with its planner, a fixed seed and an
# ITERATION budget, so the result is the same on every machine (only the wall time differs); see docs/planning.md,
# "The demo", for how seed and budget were chosen.
DEMO_PLAN = dict(task="push_box", planner="RRT", seed=5, iterations=15000)  # found after 2034: margin 7.4x


def demo_plan(out, written):
    """Part 3 of the demo: plan push_box with OMPL in a child process (the ompl 2.0.1 bindings need the cyclic GC
    off, which must not leak into the caller). Returns the demo's exit status: 0 only when the part succeeded, i.e.
    the child found an exact plan (the seed and budget are fixed so that it does on every machine); otherwise the
    child's error output is passed on to stderr with one line saying what failed."""
    import subprocess
    import time

    d = DEMO_PLAN
    print(f"3. Kinodynamic planning with OMPL: the task file scenes/{d['task']}.toml ({d['planner']}, seed "
          f"{d['seed']}, budget {d['iterations']} iterations), our simulator as the forward model")
    cmd = [sys.executable, "-c", "import sys; from planar_lcp.cli import main; sys.exit(main())", "plan",
           d["task"], "--planner", d["planner"], "--seed", str(d["seed"]), "--iterations", str(d["iterations"]),
           "--out", str(out)]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    for line in r.stdout.splitlines():
        if line.startswith("wrote"):
            written.append(line.split(None, 1)[1].strip())
        else:
            print(f"   {line}")
    if r.returncode == 0:
        print(f"   an exact plan in {wall:.1f} s (including start-up and drawing)")
        return 0
    sys.stdout.flush()
    if r.stderr:
        sys.stderr.write(r.stderr if r.stderr.endswith("\n") else r.stderr + "\n")
    why = ("no exact plan within the budget" if r.returncode == 1 else f"exit status {r.returncode}")
    print(f"planar-lcp demo: error: part 3 (`planar-lcp {' '.join(cmd[3:])}`) failed: {why}", file=sys.stderr)
    return 1


#: `bench` options -> the benchmarks they apply to
BENCH_OPTION_USERS = {"kinds": ("scaling",), "sizes": ("scaling",), "step_budget": ("scaling",),
                      "settle_budget": ("scaling",), "steps": ("scaling", "pile"), "scenes": ("pile", "derivatives")}


def cmd_bench(args):
    try:
        options = _bench_options(args)
    except InputError as e:
        print(f"planar-lcp bench: error: {e}", file=sys.stderr)
        return 2
    from planar_lcp.benchmarks.bench import run_bench
    run_bench(args.what, json_path=args.json, **options)
    return 0


def _bench_options(args):
    """Before any work: each option given applies to the benchmark chosen, the sizes are distinct and at most
    MAX_SCALING_SIZE, the JSON file can be written. Returns run_bench's keyword arguments."""
    from planar_lcp.benchmarks.bench import MAX_SCALING_SIZE, SETTLE_BUDGET_S, STEP_BUDGET_S
    for dest, users in BENCH_OPTION_USERS.items():
        if getattr(args, dest) is not None and args.what not in users:
            flag = "--" + dest.replace("_", "-")
            raise InputError(f"{flag} applies to bench {' and '.join(users)} only, got bench {args.what}")
    if args.scenes is not None:
        _check_bench_scenes(args.what, args.scenes)
    if args.kinds is not None and len(set(args.kinds)) != len(args.kinds):
        raise InputError(f"--kinds must be distinct, got {' '.join(args.kinds)}")
    if args.sizes is not None:
        if len(set(args.sizes)) != len(args.sizes):
            raise InputError(f"--sizes must be distinct body counts, got {' '.join(map(str, args.sizes))}")
        if max(args.sizes) > MAX_SCALING_SIZE:
            raise InputError(f"--sizes must be body counts from 1 to {MAX_SCALING_SIZE}, got {max(args.sizes)}")
    if args.json is not None:
        check_output_file(args.json, "--json", (".json",))
    return dict(kinds=args.kinds, sizes=args.sizes, steps=args.steps, rounds=args.rounds, scenes=args.scenes,
                step_budget_s=STEP_BUDGET_S if args.step_budget is None else args.step_budget,
                settle_budget_s=SETTLE_BUDGET_S if args.settle_budget is None else args.settle_budget)


def _check_bench_scenes(what, scenes):
    """--scenes: distinct names, of PILE_SCENES for pile, shipped scenes for derivatives (each readable)."""
    from planar_lcp.benchmarks.bench import PILE_SCENES
    from planar_lcp.spec.scene import SceneError, load_scene
    if len(set(scenes)) != len(scenes):
        raise InputError(f"--scenes must be distinct, got {' '.join(scenes)}")
    if what == "pile":
        names = [name for name, _ in PILE_SCENES]
        for s in scenes:
            if s not in names:
                raise InputError(f"--scenes: expected one of {', '.join(names)} for bench pile, got {s!r}")
        return
    for s in scenes:
        try:
            load_scene(s)
        except SceneError as e:
            raise InputError(f"--scenes: {e}") from None


#: Output files of `simulate`: the extensions each writer produces (matplotlib's savefig(format="png"), PillowWriter).
OUTPUT_SUFFIXES = {"--csv": (".csv", ".txt"), "--contacts-csv": (".csv", ".txt"), "--plot": (".png",),
                   "--animate": (".gif",)}


def _cmd_scenes(args):
    from planar_lcp.spec.scene import SCENES_ENV, SceneError, list_scenes, scene_dirs

    try:
        scenes = list_scenes(tasks=True)
        dirs = scene_dirs()
    except SceneError as e:
        print(f"planar-lcp scenes: error: {e}", file=sys.stderr)
        return 2
    where = str(dirs[0]) if len(dirs) == 1 else (f"${SCENES_ENV} ({dirs[0]}) and {dirs[1]} (a name in both: "
                                                 f"${SCENES_ENV}'s)")
    if not scenes:
        print(f"no scenes in {where}")
        return 0
    width = max(len(n) for n, _, _ in scenes)
    print(f"{len(scenes)} scenes in {where} (run one with: planar-lcp simulate NAME; [task]: a planning "
          "task too, plan it with: planar-lcp plan NAME):")
    for name, description, has_task in scenes:
        print(f"  {name:<{width}}  {'[task]' if has_task else '      '}  {description}")
    return 0


def _cmd_warmup(args):
    """Compile every kernel a user can reach into numba's cache (planar_lcp/compilation/background.py, kernel set "all"), one
    line per stage; nothing to do on a warm cache."""
    import time

    import numba

    from planar_lcp.compilation.background import Background, lock_file
    from planar_lcp.compilation.kernel_sets import compilation_stages, compile_kernels
    from planar_lcp.compilation.notice import uninstall_all
    uninstall_all()              # this command's own line per stage says what compiles
    if numba.config.DISABLE_JIT:
        print("planar-lcp warmup: NUMBA_DISABLE_JIT is set: nothing is compiled")
        return 0
    from planar_lcp.engine import cache_dir
    where = cache_dir() or "numba's default cache (__pycache__ beside the sources)"
    # a background compilation another run started: let it finish first (its work is the first stages' work)
    if cache_dir():
        Background(None, lock_file(cache_dir()), 0.0).wait()
    total = len(compilation_stages("all"))
    t0 = time.perf_counter()
    print(f"planar-lcp warmup: compiling every kernel into {where} ({total} stages)", flush=True)

    def progress(label, done, n):
        print(f"  [{done}/{n}] {label:<14} {time.perf_counter() - t0:6.1f} s", flush=True)
    compile_kernels("all", progress)
    print(f"planar-lcp warmup: done in {time.perf_counter() - t0:.1f} s; later runs load the kernels from the cache")
    return 0


def _cmd_simulate(args):
    try:
        return _simulate(args)
    except InputError as e:
        print(f"planar-lcp simulate: error: {e}", file=sys.stderr)
        return 2


def _simulate(args):
    import time

    import numpy as np

    from planar_lcp.spec.scene import SceneError, load_scene
    from planar_lcp.sim import SimulationError, run_setup, simulate

    for path, option in ((args.csv, "--csv"), (args.contacts_csv, "--contacts-csv"), (args.plot, "--plot"),
                         (args.animate, "--animate")):
        if path is not None:
            check_output_file(path, option, OUTPUT_SUFFIXES[option])
    if args.plot or args.animate:
        require("matplotlib", "shapely")
    try:
        scene = load_scene(args.scene)
    except SceneError as e:
        raise InputError(str(e)) from None
    settings = dict(t_end=args.t_end, h=args.h, solver=args.solver, formulation=args.formulation,
                    fixed_point_iterations=args.fixed_point_iterations, friction_directions=args.friction_directions,
                    limit_surface_twists=args.limit_surface_twists,
                    limit_surface_resolution=args.limit_surface_resolution)
    settings["support_model"] = args.support_model
    settings["restitution"] = args.restitution
    try:
        # the settings and the run's size checked (and the model compiled) as simulate() does, which keeps the setup:
        # here so that nothing is printed or started before bad input is refused
        run_setup(scene, **settings, option_names=SIMULATE_FLAGS)
    except SceneError as e:
        raise InputError(str(e)) from None
    except (ValueError, NotImplementedError) as e:
        raise InputError(f"{scene.source}: {e}") from None
    print(f"scene          {scene.name} ({scene.source})", flush=True)
    t0 = time.perf_counter()
    bar = ProgressBar(f"simulate {scene.name}")
    try:
        traj = simulate(scene, **settings, on_failure=args.on_failure, option_names=SIMULATE_FLAGS, progress=bar)
    except SimulationError as e:
        bar.close()                       # before the message (closing twice is harmless)
        print(f"planar-lcp simulate: simulation failed: {e}", file=sys.stderr)
        return 1
    except SceneError as e:
        # a setting out of range or a run too large: the message names the scene file and the flag
        raise InputError(str(e)) from None
    except (ValueError, NotImplementedError) as e:
        # options the scene accepts but the simulator rejects (e.g. a solver not available there)
        raise InputError(f"{scene.source}: {e}") from None
    finally:
        bar.close()
    wall = time.perf_counter() - t0

    o = traj.options
    steps = len(traj.t) - 1
    st = traj.stats
    pen = float(np.max(st["penetration"])) if steps else 0.0
    print(f"steps          {steps} (h = {o.h:g} s, t = 0 to {traj.t[-1]:.6g} s)")
    print(f"solver         {o.solver}")
    print(f"formulation    {o.formulation}")
    print(f"wall time      {wall:.3f} s ({_how_it_ran()})")
    print("final pose     (body-frame origin: x [m], y [m], theta [rad])")
    width = max([len(n) for n in traj.body_names] + [1])
    for j, name in enumerate(traj.body_names):
        x, y, th = traj.q[-1, j]
        print(f"  {name:<{width}}  x = {x: .6f}  y = {y: .6f}  theta = {th: .6f}")
    if not traj.body_names:
        print("  (no dynamic bodies)")
    print(f"max penetration {pen:.3e} m")
    print(f"failed steps   {len(traj.failures)}")
    for i, t, cause in traj.failures[:3]:
        print(f"  step {i} (t = {t:.6g} s): {cause}")
    if len(traj.failures) > 3:
        print(f"  ... and {len(traj.failures) - 3} more")
    print(f"total pivots   {int(np.sum(st['pivots']))}")

    wrote = []
    try:
        if args.csv:
            traj.to_csv(args.csv)
            wrote.append(args.csv)
        if args.contacts_csv:
            traj.contacts_to_csv(args.contacts_csv)
            wrote.append(args.contacts_csv)
        if args.plot or args.animate:
            from planar_lcp.viz import animate_trajectory, plot_trajectory
            if args.plot:
                plot_trajectory(traj, args.plot)
                wrote.append(args.plot)
            if args.animate:
                animate_trajectory(traj, args.animate)
                wrote.append(args.animate)
    except OSError as e:
        print(f"planar-lcp simulate: error: cannot write {e.filename or ''}: {e.strerror or e}", file=sys.stderr)
        return 1
    for path in wrote:
        print(f"wrote          {path}")
    return 0


#: Modules that add subcommands: each has `register(subparsers)`, which adds its parsers (cli_support.add_command)
#: and must import heavy or optional libraries (matplotlib, pymunk, ompl) only inside the command's function.
COMMAND_MODULES = ["planar_lcp.studies.compare_cli", "planar_lcp.studies.study_cli",
                   "planar_lcp.benchmarks.tradeoff", "planar_lcp.studies.pushdata.cli"]
#: Other installed packages add subcommands the same way through this entry-point group (`register(subparsers)`):
#: planners (plan, replay, plan-bench) does, in pyproject.toml. planar_lcp itself never names them.
COMMAND_ENTRY_POINTS = "planar_lcp.commands"


class _VersionAction(argparse.Action):
    """--version: the installed distribution's version (planar_lcp.__version__) and where the package runs from,
    looked up only when asked for."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        import planar_lcp
        from pathlib import Path
        print(f"planar-lcp {planar_lcp.__version__} ({Path(planar_lcp.__file__).parent}, Python "
              f"{sys.version.split()[0]})")
        parser.exit()


def build_parser():
    from planar_lcp.spec.scene import (FORMULATIONS, MAX_FIXED_POINT_ITERATIONS, MAX_FRICTION_DIRECTIONS,
                                       MAX_LIMIT_SURFACE_RESOLUTION, MAX_LIMIT_SURFACE_TWISTS, MAX_STEPS, SOLVERS,
                                       SUPPORT_MODELS)

    p = one_line_errors(argparse.ArgumentParser(prog="planar-lcp", description=__doc__))
    p.add_argument("--version", action=_VersionAction, help="print the installed version and exit")
    sub = p.add_subparsers(dest="command", required=True)

    d = add_command(sub, "demo", cmd_demo, help="the main job: a short tour of what the toolkit does")
    d.add_argument("--out", default="planar_lcp_demo", metavar="DIR",
                   help="where to write the demo's files (default ./planar_lcp_demo)")

    from planar_lcp.benchmarks.bench import (DERIVATIVE_SCENES, PILE_SCALING_SIZES, PILE_SCENES, SCALING_KINDS,
                                              SCALING_SIZES, SETTLE_BUDGET_S, STEP_BUDGET_S)
    b = add_command(
        sub, "bench", cmd_bench, help="benchmarks against peers measured in the same run",
        description="Benchmarks in alternating rounds of thread CPU time (docs/performance.md, Method).")
    b.add_argument("what", choices=["step", "lcp", "scaling", "pile", "derivatives", "all"],
                   help="step: microseconds per step and compile time; lcp: our Lemke vs QuantEcon's lcp_lemke; "
                        "scaling: cost per step against the number of bodies (the small layouts pile and islands, "
                        "and the large piles tower, pyramid, bin with the sparse solver and the dense path); pile: "
                        "towers and a bin against Box2D v3; derivatives: all the Jacobians of a step against central "
                        "differences and MuJoCo's mjd_transitionFD; all: step, lcp and scaling's pile and islands "
                        "(the large piles, pile and derivatives are runs of their own)")
    b.add_argument("--json", metavar="FILE", help="also write the measurements as JSON")
    b.add_argument("--rounds", type=finite_number(int, 1, False), metavar="N",
                   help="alternating rounds (default 15; 7 for scaling and pile)")
    b.add_argument("--kinds", nargs="+", choices=SCALING_KINDS, metavar="KIND",
                   help=f"scaling: the layouts and piles to time, of {', '.join(SCALING_KINDS)} (default all)")
    b.add_argument("--sizes", nargs="+", type=finite_number(int, 1, False), metavar="N",
                   help=f"scaling: body counts (default {' '.join(map(str, SCALING_SIZES))} for pile and islands, "
                        f"{' '.join(map(str, PILE_SCALING_SIZES))} for the large piles; pyramids: the row count with "
                        "the nearest number of boxes)")
    b.add_argument("--steps", type=finite_number(int, 1, False), metavar="N",
                   help="scaling and pile: steps per timed run (default 20 for the layouts pile and islands, 10 for "
                        "the large piles, 120 for bench pile)")
    b.add_argument("--step-budget", type=finite_number(float, 0, True), metavar="S",
                   help="scaling: a large pile's path whose steps take more thread CPU seconds than this each (run "
                        "once before its rounds, stopped when over) is reported from those steps alone and its "
                        f"larger sizes are skipped (default {STEP_BUDGET_S:g})")
    b.add_argument("--settle-budget", type=finite_number(float, 0, True), metavar="S",
                   help=f"scaling: a bin whose settling takes more thread CPU seconds than this is skipped, as are "
                        f"the larger bins (default {SETTLE_BUDGET_S:g})")
    b.add_argument("--scenes", nargs="+", metavar="SCENE",
                   help=f"pile: the scenes to run, of {', '.join(name for name, _ in PILE_SCENES)} (default all); "
                        f"derivatives: shipped scene names (default {' '.join(DERIVATIVE_SCENES)}; MuJoCo's peer "
                        "where planar_lcp.bridges.mujoco maps the scene)")

    s = add_command(
        sub, "simulate", _cmd_simulate, SCENE_OPERAND,
        help="simulate a scene; print a summary, optionally write CSV, a plot and an animation",
        description="Simulate a scene (a shipped name, see `planar-lcp scenes`, or a path to a .toml file). "
                    "Options override the scene's [sim] table.")
    s.add_argument("--h", type=finite_number(float, 0, True), metavar="H",
                   help=f"time step [s]; below the duration, and at most {MAX_STEPS} steps in all")
    s.add_argument("--t-end", type=finite_number(float, 0, True), metavar="T",
                   help=f"duration [s] (t_end / h <= {MAX_STEPS} steps)")
    s.add_argument("--solver", choices=SOLVERS, help="LCP solver")
    s.add_argument("--formulation", choices=FORMULATIONS,
                   help="position (Stewart-Trinkle), fixed_point (re-linearized), velocity (Anitescu-Potra)")
    s.add_argument("--fixed-point-iterations", type=finite_number(int, 1, False), metavar="N",
                   help=f"iterations of the fixed_point formulation (1 to {MAX_FIXED_POINT_ITERATIONS})")
    s.add_argument("--friction-directions", type=finite_number(int, 3, False), metavar="K",
                   help=f"friction directions per support point (3 to {MAX_FRICTION_DIRECTIONS}; horizontal-plane "
                        "scenes only)")
    s.add_argument("--support-model", choices=SUPPORT_MODELS,
                   help="table friction in the horizontal plane: limit_surface (default: the support pressure's limit "
                        "surface) or points (Coulomb friction at each support point); docs/method.md")
    s.add_argument("--limit-surface-twists", type=finite_number(int, 6, False), metavar="K",
                   help=f"fixed twists of the limit surface's polytope (even, 6 to {MAX_LIMIT_SURFACE_TWISTS}: the "
                        "accuracy knob; each body's table friction has K + 2 LCP unknowns)")
    s.add_argument("--limit-surface-resolution", type=finite_number(int, 1, False), metavar="N",
                   help=f"Gauss points per direction on curved support pieces (1 to {MAX_LIMIT_SURFACE_RESOLUTION})")
    # any finite number here: restitution_setting checks [0, 1] with the scene file's message
    s.add_argument("--restitution", type=finite_number(float, -math.inf, False), metavar="E",
                   help="coefficient of restitution in [0, 1] of every contact pair without a world.restitution_pairs "
                        "entry (default: the scene's world.restitution; docs/method.md, Restitution)")
    s.add_argument("--on-failure", choices=["raise", "record"], default="raise",
                   help="raise (default): stop with exit status 1 at the first failed step; record: continue and "
                        "count the failures")
    s.add_argument("--csv", metavar="FILE",
                   help="write t and each dynamic body's pose and velocity per step (.csv or .txt)")
    s.add_argument("--contacts-csv", metavar="FILE",
                   help="write a row per contact per step: t, step, contact, pair (bodies A|B), normal and friction "
                        "impulse, gap, mode, slip velocity, point and normal (.csv or .txt; docs/scene-format.md, "
                        "Output files of simulate)")
    s.add_argument("--plot", metavar="FILE.png", help="write a strobe of the motion and time series (PNG)")
    s.add_argument("--animate", metavar="FILE.gif", help="write an animation (GIF)")
    s.epilog = ("Output files are checked before the run (extension, an existing writable directory). A run whose "
                "trajectory and LCP buffers would need more than a quarter of physical memory is refused before it "
                "starts, with the estimate (docs/scene-format.md, Limits).")

    add_command(sub, "scenes", _cmd_scenes, help="list the shipped scenes with their descriptions")

    add_command(
        sub, "warmup", _cmd_warmup,
        help="compile every simulation kernel into numba's cache now (every solver and formulation)",
        description="Compile every kernel a run can reach (every solver, formulation and scene: one compilation "
                    "serves them all) into numba's on-disk cache, with a line per stage, so that no later run "
                    "waits for the compiler. The first run on a cold cache does the same for the default solver "
                    "in a background process.")
    for module in COMMAND_MODULES:
        importlib.import_module(module).register(sub)
    for ep in sorted(importlib.metadata.entry_points(group=COMMAND_ENTRY_POINTS), key=lambda e: e.name):
        ep.load()(sub)
    return p


def main(argv=None):
    # Ctrl-C that numba's dispatcher cannot swallow (planar_lcp.interrupt); a program calling main() gets its own
    # handler back at the end
    previous = catch_sigint()
    try:
        return _main(argv)
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        clear()


def _main(argv):
    try:
        parser = build_parser()
        args, extra = parser.parse_known_args(argv)
        if extra:
            # named by the command that was given them (argparse's own message comes from the top-level parser)
            # (a command another package adds without cli_support.add_command has none: the top-level parser says it)
            getattr(args, "command_parser", parser).error(f"unrecognized arguments: {' '.join(extra)}")
    except KeyboardInterrupt:
        # Ctrl-C while the commands' modules load (about a second): the one line of any interrupt
        print("planar-lcp: error: interrupted (Ctrl-C); stopped", file=sys.stderr)
        return 130
    from planar_lcp.compilation.notice import announce_compilation, uninstall
    # one line on stderr before a cold numba cache's wait (nothing when the cache is warm)
    notice = announce_compilation(f"planar-lcp {args.command}")
    try:
        return _run(args)
    finally:
        uninstall(notice)


def _run(args):
    kept = ""
    try:
        rc = args.func(args)
        # a Ctrl-C swallowed where nothing checked for it after (planar_lcp.interrupt) is still an interrupt: the
        # command's outputs may be whole, but it does not report success over the user's Ctrl-C
        raise_if_interrupted()
        return rc
    except Exception as e:
        missing = missing_optional(e)
        if missing:
            sys.stdout.flush()
            print(f"planar-lcp {args.command}: error: {MissingPackage(missing)}", file=sys.stderr)
            return 2
        # Ctrl-C while numba compiles: numba's clean-up then raises its own error ("no compiled object yet", while
        # saving the unfinished function to its cache) in place of the KeyboardInterrupt, which it may also have
        # swallowed (planar_lcp.interrupt remembers it then). Still an interrupt.
        if not (raised_while_interrupted(e) or interrupted()):
            raise
    except KeyboardInterrupt as e:
        # a command that kept something (plan-bench and tradeoff: the finished runs) says what in the interrupt's
        # message (planar_lcp.parallel.records.BenchmarkInterrupted); a plain Ctrl-C has none
        kept = str(e)
    # Long runs return to Python often enough for this (rollouts in chunks, a flag in the planners' termination
    # condition), so Ctrl-C ends any command within about a second: one line, exit status 130 (128 + SIGINT).
    sys.stdout.flush()
    print(f"planar-lcp {args.command}: error: interrupted (Ctrl-C); stopped{' ' + kept if kept else ''}",
          file=sys.stderr)
    return 130


if __name__ == "__main__":
    sys.exit(main())
