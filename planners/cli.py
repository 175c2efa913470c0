"""Subcommands `plan`, `replay` and `plan-bench` of `planar-lcp`, registered through the entry-point group
`planar_lcp.commands` (pyproject.toml): planar_lcp does not name this package.

`register()` imports nothing heavy: ompl, matplotlib and pymunk are imported inside the commands.
"""

import sys
from pathlib import Path

from planar_lcp.cli import finite_number, one_line_errors

from planar_lcp.spec.task import MAX_RUNS, MAX_SEED, MAX_TIME

from .tasks import PLANNERS, TaskError, check_planner

TIME_BOUND = " s (as a task file's time)"
SEED_BOUND = " (OMPL's seed)"
TASK_HELP = ("a shipped task's name (planar-lcp scenes marks them) or a scene file with a [task] table "
             "(docs/scene-format.md, \"Task files\")")


def register(sub):
    p = one_line_errors(sub.add_parser(
        "plan", help="plan pusher motions for a task with OMPL (our simulator as the forward model)",
        description="Plan a task (a shipped task or your own task file) with an OMPL kinodynamic planner. Writes "
                    "plan.json (self-contained: it holds the task), plan.png and plan.gif into --out. Exit status 0 "
                    "only for an exact solution."))
    p.add_argument("task", metavar="TASK", help=TASK_HELP)
    p.add_argument("--planner", default=None, metavar="NAME",
                   help=f"one of {', '.join(PLANNERS)} (default: the task's planner, RRT unless its file says "
                        "otherwise)")
    p.add_argument("--time", type=finite_number(float, 0, True, MAX_TIME, TIME_BOUND), default=None, metavar="SECONDS",
                   help=f"wall-clock limit, at most {MAX_TIME:g} s (default: the task's time, 60 s unless its file "
                        "says otherwise)")
    p.add_argument("--iterations", type=finite_number(int, 0, True), default=None, metavar="N",
                   help="iteration budget instead of a time limit: with --seed the plan is reproducible")
    p.add_argument("--seed", type=finite_number(int, 0, True, MAX_SEED, SEED_BOUND), default=1, metavar="N",
                   help=f"OMPL random seed (1 to {MAX_SEED}, default 1)")
    p.add_argument("--out", default="plan_out", metavar="DIR", help="output directory (default ./plan_out)")
    p.add_argument("--no-gif", action="store_true", help="skip plan.gif")
    p.add_argument("--no-shorten", action="store_true",
                   help="keep the planner's first exact plan as it is; by default it is shortened after the planner "
                        "stops (docs/planning.md, \"Shorter plans\")")
    p.set_defaults(func=cmd_plan)

    r = one_line_errors(sub.add_parser(
        "replay", help="re-simulate a plan's controls open loop and check the goal",
        description="Re-simulate the controls of PLAN.json open loop (our LCP simulator, or pymunk through "
                    "planar_lcp.experiments.pymunk_bridge), report the final goal error, write replay.png. Exit "
                    "status 0 only when the goal holds at the end."))
    r.add_argument("plan", metavar="PLAN.json")
    r.add_argument("--simulator", choices=["lcp", "pymunk"], default="lcp")
    r.add_argument("--out", default=None, metavar="DIR", help="where to write replay.png (default: the plan's dir)")
    r.set_defaults(func=cmd_replay)

    b = one_line_errors(sub.add_parser(
        "plan-bench", help="benchmark planners on a task (Dask, OMPL benchmark log and database)",
        description="Run each planner --runs times with seeds 1..N as Dask tasks, on the cluster at --scheduler or "
                    "on a local cluster of --jobs worker processes (127.0.0.1); write an OMPL benchmark log, its "
                    "SQLite database, summary.md / summary.json and box plots into --out. Each finished run is kept "
                    "in --out as it arrives: after Ctrl-C or a lost scheduler, --resume finishes the benchmark."))
    b.add_argument("task", metavar="TASK", help=TASK_HELP)
    b.add_argument("--planners", nargs="+", default=list(PLANNERS), metavar="NAME",
                   help=f"planners to compare (default: all of {', '.join(PLANNERS)})")
    b.add_argument("--runs", type=finite_number(int, 0, True, MAX_RUNS), default=10, metavar="N",
                   help=f"runs per planner, seeds 1..N (N <= {MAX_RUNS})")
    b.add_argument("--time", type=finite_number(float, 0, True, MAX_TIME, TIME_BOUND), default=None, metavar="T",
                   help=f"seconds per run, at most {MAX_TIME:g} (default: the task's time, 60 s unless its file says "
                        "otherwise)")
    b.add_argument("--iterations", type=finite_number(int, 0, True), default=None, metavar="N",
                   help="an iteration budget per run instead of --time: the same results on any machine")
    b.add_argument("--jobs", type=finite_number(int, 0, True), default=None, metavar="J",
                   help="worker processes of the local cluster (default: CPUs)")
    b.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on the Dask cluster at ADDRESS (e.g. tcp://127.0.0.1:8786) instead of a local one "
                        "(docs/planning.md: a one-machine and a multi-machine recipe, and how to secure it)")
    b.add_argument("--out", default=None, metavar="DIR", help="output directory (default ./bench_TASK)")
    b.add_argument("--resume", action="store_true",
                   help="finish the benchmark whose finished runs --out holds (records.jsonl, written as each run "
                        "finishes): only the missing runs run; the task, planners, --runs and budget must be the "
                        "same")
    b.set_defaults(func=cmd_bench)


def _err(cmd, msg, code=2):
    print(f"planar-lcp {cmd}: error: {msg}", file=sys.stderr)
    return code


def cmd_plan(args):
    from .plans import Plan, plan_task
    from .tasks import TaskModel

    try:
        if args.time is not None and args.iterations is not None:
            raise TaskError(f"give either --time or --iterations, not both: got --time {args.time:g} and "
                            f"--iterations {args.iterations}")
        tm = TaskModel(args.task)            # the task file is validated before anything is written
        task = tm.task
        planner = check_planner(args.planner or task.planner)
        tlim = args.time if (args.time is not None or args.iterations is not None) else task.time
        out = Path(args.out)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise TaskError(f"--out {args.out}: cannot create the directory ({e.strerror or e})") from None
    except TaskError as e:
        return _err("plan", e)
    budget = f"{args.iterations} iterations" if args.iterations else f"{tlim:g} s"
    print(f"task           {task.name} ({task.source}): {task.description or 'no description'}")
    print(f"planner        {planner} (seed {args.seed}, budget {budget})")
    data = plan_task(task, planner, seed=args.seed, time_limit=None if args.iterations else tlim,
                     iterations=args.iterations, tm=tm, shorten=not args.no_shorten)
    p = Plan(data, task)            # a fresh TaskModel for the drawings: the planner's is warm-started state
    status = "exact" if p.exact else ("approximate" if data["approximate"] else "none")
    print(f"solution       {status} after {data['solve_time']:.2f} s, {data['iterations']} iterations, "
          f"{data['sim_steps']} simulated steps ({data['steps_per_second']:.0f} steps/s)")
    wrote = [out / "plan.json"]
    p.save(out / "plan.json")
    sh = data["shorten"]
    if "first_plan" in data:
        print(f"first plan     {len(data['first_plan']['controls'])} controls, {data['first_path_duration']:.2f} s, "
              f"pusher path {data['first_pusher_path_length']:.3f} m, object path "
              f"{data['first_object_path_length']:.3f} m")
        print(f"shortened      {sh['accepted']} of {sh['candidates']} candidates accepted in {sh['time']:.2f} s: "
              f"{data['path_duration']:.2f} s, pusher path {data['pusher_path_length']:.3f} m, object path "
              f"{data['object_path_length']:.3f} m")
    if data["controls"]:
        print(f"path           {len(data['controls'])} controls, {p.path_duration:.2f} s; goal: "
              + ", ".join(_show(k, v) for k, v in p.goal_report.items()))
        rep = p.replay()
        from .plans import animate_plan, plot_plan
        plot_plan(p.model, rep["dense"], out / "plan.png", title=p.title())
        wrote.append(out / "plan.png")
        if not args.no_gif:
            animate_plan(p.model, rep["dense"], out / "plan.gif")
            wrote.append(out / "plan.gif")
    for w in wrote:
        print(f"wrote          {w}")
    return 0 if p.exact else 1


def _show(k, v):
    if isinstance(v, float):
        return f"{k} {v:.4g}"
    if isinstance(v, list):
        return f"{k} [" + ", ".join(f"{x:.4g}" for x in v) + "]"
    return f"{k} {v}"


def cmd_replay(args):
    from .plans import load_plan, plot_plan

    try:
        plan = load_plan(args.plan)
    except TaskError as e:
        return _err("replay", e)
    out = Path(args.out) if args.out else Path(args.plan).resolve().parent
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return _err("replay", f"--out {args.out}: cannot create the directory ({e.strerror or e})")
    data = plan.data
    print(f"plan           {args.plan} (task {data['task']}, planner {data.get('planner')}, "
          f"{len(data['controls'])} controls)")
    note = {"unchanged": "unchanged since planning", "edited": "EDITED since planning: replaying the plan's own "
            "copy of the task", "missing": "not found: replaying the plan's own copy of the task",
            "none": "given as text or a dict: replaying the plan's own copy"}[plan.task_file]
    print(f"task file      {data['task_source']} ({note})")
    print(f"simulator      {args.simulator}", flush=True)
    try:
        res = plan.replay(args.simulator)
    except ImportError as e:
        return _err("replay", f"--simulator pymunk is not available: {e}")
    rep = res["report"]
    for k, v in rep.items():
        print(f"{k:<16} {v:.6g}" if isinstance(v, float) else _show(f"{k:<16}", v) if isinstance(v, list)
              else f"{k:<16} {v}")
    name = f"replay_{args.simulator}.png"
    plot_plan(plan.model, res["dense"], out / name,
              title=f"replay of {data['task']} in {args.simulator}: goal {'holds' if rep['goal_holds'] else 'missed'}")
    print(f"wrote          {out / name}")
    return 0 if rep["goal_holds"] else 1


def cmd_bench(args):
    from planar_lcp.cli import require
    from planar_lcp.experiments.cluster import SchedulerLost, SchedulerUnreachable
    from planar_lcp.experiments.records import RecordFileError

    require("distributed")                 # the runs are Dask tasks: checked before any work
    from .bench import run_bench
    from .tasks import TaskModel

    try:
        task = TaskModel(args.task).task     # validated here, before any worker starts
        for p in args.planners:
            check_planner(p)
    except TaskError as e:
        return _err("plan-bench", e)
    if len(set(args.planners)) != len(args.planners):
        # a run is named by its planner and seed (records.jsonl, --resume)
        return _err("plan-bench", f"--planners must be distinct, got {' '.join(args.planners)}")
    if args.time is not None and args.iterations is not None:
        return _err("plan-bench", f"give --time or --iterations, not both: got --time {args.time:g} and "
                                  f"--iterations {args.iterations}")
    if args.scheduler is not None and args.jobs is not None:
        return _err("plan-bench", f"--jobs sizes the local cluster: not with --scheduler {args.scheduler}")
    out = Path(args.out or f"bench_{task.name}")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return _err("plan-bench", f"--out {out}: cannot create the directory ({e.strerror or e})")
    try:
        run_bench(task, args.planners, runs=args.runs, time_limit=task.time if args.time is None else args.time,
                  jobs=args.jobs, out=out, iterations=args.iterations, scheduler=args.scheduler, resume=args.resume)
    except RecordFileError as e:
        return _err("plan-bench", e)               # checked before any work: nothing was written
    except (SchedulerUnreachable, SchedulerLost) as e:
        return _err("plan-bench", str(e), 1)
    return 0
