"""Subcommands `plan`, `replay` and `plan-bench` of `planar-lcp`, registered through the entry-point group
`planar_lcp.commands` (pyproject.toml): planar_lcp does not name this package.

`register()` imports nothing heavy: ompl, matplotlib and pymunk are imported inside the commands.
"""

import sys
from pathlib import Path

from planar_lcp.cli import finite_number, one_line_errors

from .tasks import PLANNERS, TASKS, TaskError, check_planner


def register(sub):
    tasks = ", ".join(sorted(TASKS))
    p = one_line_errors(sub.add_parser(
        "plan", help="plan pusher motions for a task with OMPL (our simulator as the forward model)",
        description=f"Plan a task ({tasks}) with an OMPL kinodynamic planner. Writes plan.json, plan.png and "
                    "plan.gif into --out. Exit status 0 only for an exact solution."))
    p.add_argument("task", metavar="TASK", help=f"one of: {tasks}")
    p.add_argument("--planner", default=None, metavar="NAME",
                   help=f"one of {', '.join(PLANNERS)} (default: the task's best, see docs/planning.md)")
    p.add_argument("--time", type=finite_number(float, 0, True), default=None, metavar="SECONDS",
                   help="wall-clock limit (default 60 s unless --iterations is given)")
    p.add_argument("--iterations", type=finite_number(int, 0, True), default=None, metavar="N",
                   help="iteration budget instead of a time limit: with --seed the plan is reproducible")
    p.add_argument("--seed", type=finite_number(int, 0, True), default=1, metavar="N",
                   help="OMPL random seed (>= 1, default 1)")
    p.add_argument("--out", default="plan_out", metavar="DIR", help="output directory (default ./plan_out)")
    p.add_argument("--no-gif", action="store_true", help="skip plan.gif")
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
                    "SQLite database, summary.md / summary.json and box plots into --out."))
    b.add_argument("task", metavar="TASK", help=f"one of: {tasks}")
    b.add_argument("--planners", nargs="+", default=list(PLANNERS), metavar="NAME",
                   help=f"planners to compare (default: all of {', '.join(PLANNERS)})")
    b.add_argument("--runs", type=finite_number(int, 0, True), default=10, metavar="N",
                   help="runs per planner, seeds 1..N")
    b.add_argument("--time", type=finite_number(float, 0, True), default=None, metavar="T",
                   help="seconds per run (default 60)")
    b.add_argument("--iterations", type=finite_number(int, 0, True), default=None, metavar="N",
                   help="an iteration budget per run instead of --time: the same results on any machine")
    b.add_argument("--jobs", type=finite_number(int, 0, True), default=None, metavar="J",
                   help="worker processes of the local cluster (default: CPUs)")
    b.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on the Dask cluster at ADDRESS (e.g. tcp://127.0.0.1:8786) instead of a local one "
                        "(docs/planning.md: a one-machine and a multi-machine recipe, and how to secure it)")
    b.add_argument("--out", default=None, metavar="DIR", help="output directory (default ./bench_TASK)")
    b.set_defaults(func=cmd_bench)


DEFAULT_PLANNER = {"push_box": "RRT", "push_t": "RRT", "tip_box": "RRT", "push_clutter": "RRT"}   # measured best (docs/planning.md)


def _err(cmd, msg, code=2):
    print(f"planar-lcp {cmd}: error: {msg}", file=sys.stderr)
    return code


def cmd_plan(args):
    from .plan import animate_plan, plan_task, plot_plan, save_plan
    from .tasks import TaskModel, get_task

    try:
        task = get_task(args.task)
        planner = check_planner(args.planner or DEFAULT_PLANNER.get(task.name, "RRT"))
        if args.time is not None and args.iterations is not None:
            raise TaskError("give either --time or --iterations, not both")
        tlim = args.time if (args.time is not None or args.iterations is not None) else 60.0
        out = Path(args.out)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise TaskError(f"--out {args.out}: cannot create the directory ({e.strerror or e})") from None
        tm = TaskModel(task)
    except TaskError as e:
        return _err("plan", e)
    budget = f"{args.iterations} iterations" if args.iterations else f"{tlim:g} s"
    print(f"task           {task.name}: {task.description}")
    print(f"planner        {planner} (seed {args.seed}, budget {budget})")
    plan = plan_task(task, planner, seed=args.seed, time_limit=None if args.iterations else tlim,
                     iterations=args.iterations, tm=tm)
    status = "exact" if plan["exact"] else ("approximate" if plan["approximate"] else "none")
    print(f"solution       {status} after {plan['solve_time']:.2f} s, {plan['iterations']} iterations, "
          f"{plan['sim_steps']} simulated steps ({plan['steps_per_second']:.0f} steps/s)")
    wrote = [out / "plan.json"]
    save_plan(plan, out / "plan.json")
    if plan["controls"]:
        print(f"path           {len(plan['controls'])} controls, {plan['path_duration']:.2f} s; goal: "
              + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in plan["goal"].items()))
        from .plan import replay_lcp
        rep = replay_lcp(plan, tm=TaskModel(task))
        title = (f"{task.name}, {planner}, seed {args.seed}: {status} solution, "
                 f"{plan['path_duration']:.2f} s of pushing")
        plot_plan(tm, rep["dense"], out / "plan.png", title=title)
        wrote.append(out / "plan.png")
        if not args.no_gif:
            animate_plan(tm, rep["dense"], out / "plan.gif")
            wrote.append(out / "plan.gif")
    for w in wrote:
        print(f"wrote          {w}")
    return 0 if plan["exact"] else 1


def cmd_replay(args):
    from .plan import load_plan, plot_plan, replay_lcp

    try:
        plan = load_plan(args.plan)
    except TaskError as e:
        return _err("replay", e)
    out = Path(args.out) if args.out else Path(args.plan).resolve().parent
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return _err("replay", f"--out {args.out}: cannot create the directory ({e.strerror or e})")
    print(f"plan           {args.plan} (task {plan['task']}, planner {plan.get('planner')}, "
          f"{len(plan['controls'])} controls)")
    print(f"simulator      {args.simulator}", flush=True)
    if args.simulator == "pymunk":
        try:
            from .plan import replay_pymunk
            res = replay_pymunk(plan)
        except (ImportError, NotImplementedError) as e:
            return _err("replay", f"--simulator pymunk is not available: {e}")
    else:
        res = replay_lcp(plan)
    tm, rep = res["tm"], res["report"]
    for k, v in rep.items():
        print(f"{k:<14} {v:.6g}" if isinstance(v, float) else f"{k:<14} {v}")
    name = f"replay_{args.simulator}.png"
    plot_plan(tm, res["dense"], out / name,
              title=f"replay of {plan['task']} in {args.simulator}: goal {'holds' if rep['goal_holds'] else 'missed'}")
    print(f"wrote          {out / name}")
    return 0 if rep["goal_holds"] else 1


def cmd_bench(args):
    from planar_lcp.cli import require
    from planar_lcp.experiments.cluster import SchedulerUnreachable

    require("distributed")                 # the runs are Dask tasks: checked before any work
    from .bench import run_bench
    from .tasks import get_task

    try:
        task = get_task(args.task)
        for p in args.planners:
            check_planner(p)
    except TaskError as e:
        return _err("plan-bench", e)
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
        run_bench(task.name, args.planners, runs=args.runs, time_limit=60.0 if args.time is None else args.time,
                  jobs=args.jobs, out=out, iterations=args.iterations, scheduler=args.scheduler)
    except SchedulerUnreachable as e:
        return _err("plan-bench", str(e), 1)
    return 0
