"""Subcommands `plan`, `replay` and `plan-bench` of `planar-lcp`, registered through the entry-point group
`planar_lcp.commands` (pyproject.toml): planar_lcp does not name this package.

`register()` imports nothing heavy: ompl, matplotlib and pymunk are imported inside the commands.
"""

import argparse
import math
import sys
from pathlib import Path

from planar_lcp.cli_support import add_command, finite_number

from planar_lcp.spec.task import MAX_RUNS, MAX_SEED, MAX_TIME

from .tasks import PLANNERS, TaskError, check_planner

TIME_BOUND = " s (as a task file's time)"
SEED_BOUND = " (OMPL's seed)"
#: the positional argument of the commands that take a task (plan, plan-bench): add_command's `operand`
TASK_OPERAND = ("task", dict(metavar="TASK", help="a shipped task's name (planar-lcp scenes marks them) or a scene "
                                                  "file with a [task] table (docs/scene-format.md, \"Task files\")"))


def register(sub):
    p = add_command(
        sub, "plan", cmd_plan, TASK_OPERAND,
        help="plan pusher motions for a task with OMPL (our simulator as the forward model)",
        description="Plan a task (a shipped task or your own task file) with an OMPL kinodynamic planner. Writes "
                    "plan.json (self-contained: it holds the task), plan.png and plan.gif into --out: the first "
                    "exact plan's plan.json and plan.png before it is shortened, so that Ctrl-C while shortening "
                    "keeps the best exact plan so far (exit status 130). Exit status 0 only for an exact solution.")
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
    p.add_argument("--shorten-time", type=shorten_seconds, default=None, metavar="S",
                   help="shorten the first exact plan for S seconds of wall time instead of until it stops paying "
                        "(the default rule, the same on every machine: docs/planning.md, \"When shortening "
                        "stops\"); 0: no candidate. Ctrl-C while shortening keeps the best plan so far")

    r = add_command(
        sub, "replay", cmd_replay, help="re-simulate a plan's controls open loop and check the goal",
        description="Re-simulate the controls of PLAN.json open loop (our LCP simulator, or pymunk through "
                    "planar_lcp.bridges.pymunk), or execute it closed loop (--closed-loop), optionally in "
                    "a world whose friction and masses differ from the task's (--perturb); report the final goal "
                    "error and the deepest penetration, write replay_SIMULATOR[_closed_loop].png and .gif. Exit "
                    "status 0 only when the goal holds at the end.")
    r.add_argument("plan", metavar="PLAN.json")
    r.add_argument("--simulator", choices=["lcp", "pymunk"], default="lcp")
    r.add_argument("--closed-loop", action="store_true",
                   help="feedback at every propagation step (planners.closed_loop.PlanTracker: receding-horizon "
                        "tracking of the plan over our simulator, docs/closed_loop.md); stops when the goal holds")
    r.add_argument("--perturb", type=_perturbation, default=None, metavar="mu=F,mass=G",
                   help="factors on every friction coefficient (mu) and dynamic mass (mass) of the world executed "
                        "in (pymunk's, or ours); the plan and the controller's model keep the task's")
    r.add_argument("--out", default=None, metavar="DIR",
                   help="where to write the replay's figure and GIF (default: the plan's dir)")
    r.add_argument("--no-gif", action="store_true", help="skip the replay's GIF")

    b = add_command(
        sub, "plan-bench", cmd_bench, TASK_OPERAND,
        help="benchmark planners on a task (Dask, OMPL benchmark log and database)",
        description="Run each planner --runs times with seeds 1..N as Dask tasks, on the cluster at --scheduler or "
                    "on a local cluster of --jobs worker processes (127.0.0.1); write an OMPL benchmark log, its "
                    "SQLite database, summary.md / summary.json and box plots into --out. Each finished run is kept "
                    "in --out as it arrives: after Ctrl-C or a lost scheduler, --resume finishes the benchmark.")
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

    from .environments.pusht_eval import ENVS, MAX_EPISODES
    e = add_command(
        sub, "pusht-eval", cmd_pusht_eval,
        help="run PushTPolicy's episodes in gym-pusht's Push-T or ours and score them",
        description="Episodes of planners.PushTPolicy (a feedback controller with our simulator as its model, "
                    "docs/closed_loop.md) in a Push-T environment as registered (300 actions, success at coverage "
                    "> 0.95): seeds SEED..SEED+N-1. Writes OUT/episodes.csv (one row per episode: success, "
                    "coverage, actions, the policy's compute per action) and OUT/summary.json. Exit status 0 when "
                    "every episode ran (whatever their success).")
    e.add_argument("--env", required=True, choices=ENVS, help="the environment")
    e.add_argument("--episodes", type=finite_number(int, 1, False, MAX_EPISODES), required=True, metavar="N")
    e.add_argument("--seed", type=finite_number(int, 0, True, MAX_SEED, " (a reset seed)"), default=0, metavar="S",
                   help="the first episode's reset seed (default 0)")
    e.add_argument("--out", required=True, metavar="DIR", help="output directory")
    e.add_argument("--world", choices=["gym_pusht", "planar_lcp"], default=None,
                   help="the physics of the policy's model (default: the environment's own: gym_pusht for "
                        "gym_pusht/PushT-v0, planar_lcp for ours)")
    e.add_argument("--table-friction", type=finite_number(float, 0, True), default=None, metavar="MU",
                   help="planar_lcp/PushT-v0 only: the T's table friction in the world (the model keeps 0.3)")
    e.add_argument("--contact-friction", type=finite_number(float, 0, True), default=None, metavar="MU",
                   help="planar_lcp/PushT-v0 only: the pusher-T and T-wall friction in the world (the model keeps "
                        "0.3)")
    e.add_argument("--pusht-python", default=None, metavar="PY",
                   help="gym_pusht/PushT-v0 when gym_pusht does not import here: the python of a virtualenv with "
                        "gym-pusht==0.1.8 (default $PLANAR_LCP_PUSHT_PYTHON)")
    e.add_argument("--jobs", type=finite_number(int, 1, False), default=None, metavar="N",
                   help="run the episodes on a local Dask cluster of N worker processes (127.0.0.1)")
    e.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run them on the Dask scheduler at ADDRESS (docs/planning.md: securing it with TLS)")


def shorten_seconds(text):
    """argparse type of --shorten-time: seconds in [0, MAX_TIME] (the bound of a task's time)."""
    from planar_lcp.spec.task import MAX_TIME
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of seconds, got {text!r}") from None
    if not (math.isfinite(x) and 0 <= x <= MAX_TIME):
        raise argparse.ArgumentTypeError(f"must be a number of seconds in [0, {MAX_TIME:g}], got {text!r}")
    return x


def _perturbation(text):
    """--perturb's argparse type (planar_lcp.spec.scene.parse_perturbation)."""
    from planar_lcp.spec.scene import parse_perturbation
    try:
        return parse_perturbation(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _err(cmd, msg, code=2):
    print(f"planar-lcp {cmd}: error: {msg}", file=sys.stderr)
    return code


def cmd_plan(args):
    from .tasks import TaskModel

    try:
        if args.time is not None and args.iterations is not None:
            raise TaskError(f"give either --time or --iterations, not both: got --time {args.time:g} and "
                            f"--iterations {args.iterations}")
        if args.no_shorten and args.shorten_time is not None:
            raise TaskError(f"--shorten-time sets how long the shortening runs: not with --no-shorten, got "
                            f"--shorten-time {args.shorten_time:g}")
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
    return _plan_and_write(args, tm, planner, tlim, out)


def task_lines(task):
    """The task as planned, in a compact block: its bodies, goal, control, bounds and search settings, every key
    the file gave or `planar_lcp.spec.task.parse_task` derived, and which the file gave."""
    from planar_lcp.spec.task import TASK_KEYS
    g, ws, pws = task.goal, task.workspace, task.pusher_workspace

    def region(r):
        return f"x {r[0][0]:.4g}..{r[0][1]:.4g}, y {r[1][0]:.4g}..{r[1][1]:.4g} m"

    named = [f"{k} {v:.4g} m" for k, v in (("x", g.x), ("y", g.y)) if v is not None]
    if g.angle is not None:
        named.append(f"angle {math.degrees(g.angle):.4g} deg")
    goal = ", ".join(named) + "; "
    if g.min_cover is not None:
        goal += f"min_cover {g.min_cover:.4g} of its footprint"
    else:
        goal += ", ".join(([f"position_tol {g.position_tol:.4g} m"] if g.x is not None or g.y is not None else [])
                          + ([f"angle_tol {math.degrees(g.angle_tol):.4g} deg"] if g.angle is not None else []))
    if g.at_rest:
        goal += f"; at rest: speed_tol {g.speed_tol:.4g} m/s, omega_tol {g.omega_tol:.4g} rad/s"
    nsub = int(round(task.step_duration / task.scene.sim.h))
    control = (f"control_max {task.control_max:.4g} m/s per axis, step_duration {task.step_duration:.4g} s "
               f"({nsub} steps of h {task.scene.sim.h:.4g} s), control_steps {task.min_steps}..{task.max_steps}")
    if "pusher_max_force" in task.given:
        control += f", pusher_max_force {task.document['task']['pusher_max_force']:.4g} N"
    w = task.weights
    given = [k for k in TASK_KEYS if k in task.given]
    return [
        f"  bodies       object {task.object}, pusher {task.pusher}, "
        + (f"{len(task.obstacles)} movable obstacles ({', '.join(task.obstacles)})" if task.obstacles
           else "no movable obstacle")
        + (f"; {', '.join(task.moving)} on {'its path' if len(task.moving) == 1 else 'their paths'} (the state "
           f"holds the time, up to {task.horizon:g} s)" if task.timed else ""),
        f"  goal         {goal}",
        f"  control      {control}",
        f"  bounds       workspace {region(ws)}; pusher_workspace {region(pws)}; speed_max {task.speed_max:.4g} m/s, "
        f"omega_max {task.omega_max:.4g} rad/s",
        f"  search       planner {task.planner}, time {task.time:g} s, goal_bias {task.goal_bias:.4g}; weights "
        f"position {w[0]:.4g}, angle {w[1]:.4g}, velocity {w[2]:.4g}, pusher {w[3]:.4g}, obstacle "
        f"{task.obstacle_weight:.4g}{f', time {task.time_weight:.4g}' if task.timed else ''}; kpiece_cell "
        f"{task.kpiece_cell:.4g} m",
        f"  given        {', '.join(given)} (the rest derived)",
    ]


def _plan_and_write(args, tm, planner, tlim, out):
    """`plan` after its input was checked: plan, write the first exact plan before shortening it, then the final
    one. Ctrl-C after the first exact plan was written says what plan.json holds (exit status 130)."""
    from .plans import Plan, ShorteningInterrupted, plan_task

    task = tm.task
    budget = f"{args.iterations} iterations" if args.iterations else f"{tlim:g} s"
    print(f"task           {task.name} ({task.source}): {task.description or 'no description'}")
    for line in task_lines(task):
        print(line)
    print(f"planner        {planner} (seed {args.seed}, budget {budget})", flush=True)
    # what plan.json holds once it holds an exact plan, and what the command was doing: Ctrl-C's message
    kept = dict(plan=None, doing="writing the first plan", first=None)

    def first_plan(data):
        """The planner's plan: announced, and written at once when the shortening is to follow."""
        status = "exact" if data["exact"] else ("approximate" if data["approximate"] else "none")
        solution = (f"solution       {status} after {data['solve_time']:.2f} s, {data['iterations']} iterations, "
                    f"{data['sim_steps']} simulated steps ({data['steps_per_second']:.0f} steps/s)")
        if data["shorten"].get("status") != "running":
            print(solution)
            return               # nothing follows the search: written below, once
        # an exact plan to shorten: written first, then announced, so that whoever sees "solution exact" finds it
        p = Plan(data, task)
        p.save(out / "plan.json")
        kept["plan"] = f"the first exact plan ({data['first_path_duration']:.2f} s) in {out / 'plan.json'}"
        kept["first"] = dict(data)           # as written (plan_task goes on to replace its values)
        _draw(p, out, gif=False)
        kept["doing"] = "shortening"
        print(solution)
        print(f"first plan     {len(data['controls'])} controls, {data['first_path_duration']:.2f} s, pusher path "
              f"{data['first_pusher_path_length']:.3f} m, object path {data['first_object_path_length']:.3f} m")
        print(f"saved          {out / 'plan.json'} and {out / 'plan.png'}: the first exact plan, kept if the "
              "shortening is interrupted (Ctrl-C)")
        sh = data["shorten"]
        how = (f"for {sh['shorten_time']:g} s" if sh["shorten_time"] is not None else
               f"until {sh['patience']} candidates in a row are rejected, at most {sh['max_candidates']} "
               f"candidates and {sh['max_sim_steps']} simulated steps")
        print(f"shortening     {how}; Ctrl-C keeps the best plan so far", flush=True)

    try:
        try:
            data = plan_task(task, planner, seed=args.seed, time_limit=None if args.iterations else tlim,
                             iterations=args.iterations, tm=tm, shorten=not args.no_shorten,
                             shorten_time=args.shorten_time, on_first=first_plan)
        except ShorteningInterrupted as e:
            data = e.data
            p = Plan(data, task)
            p.save(out / "plan.json")
            sh = data["shorten"]
            kept["first"] = None
            kept["plan"] = (f"the {'best exact plan so far' if sh['status'] == 'interrupted' else 'shortened plan'} "
                            f"({data['path_duration']:.2f} s; the first plan {data['first_path_duration']:.2f} s; "
                            f"{sh['accepted']} of {sh['candidates']} candidates accepted) in {out / 'plan.json'}")
            _draw(p, out, gif=False)
            raise KeyboardInterrupt(f"shortening: kept {kept['plan']} and its plan.png") from None
        p = Plan(data, task)            # a fresh TaskModel for the drawings: the planner's is warm-started state
        sh = data["shorten"]
        if "first_plan" in data:
            print(f"shortened      {sh['accepted']} of {sh['candidates']} candidates accepted in {sh['time']:.2f} s "
                  f"({_stopped(sh)}): {data['path_duration']:.2f} s, pusher path {data['pusher_path_length']:.3f} "
                  f"m, object path {data['object_path_length']:.3f} m" + _truncated(sh))
        p.save(out / "plan.json")
        if data["exact"]:
            kept.update(plan=f"the final plan in {out / 'plan.json'}", doing="writing the figures", first=None)
        wrote = [out / "plan.json"]
        if data["controls"]:
            print(f"path           {len(data['controls'])} controls, {p.path_duration:.2f} s; goal: "
                  + ", ".join(_show(k, v) for k, v in p.goal_report.items()))
            wrote += _draw(p, out, gif=not args.no_gif)
        for w in wrote:
            print(f"wrote          {w}")
        return 0 if p.exact else 1
    except KeyboardInterrupt as e:
        if kept["plan"] is None or str(e):
            raise
        if kept["doing"] == "shortening" and kept["first"] is not None:
            # Ctrl-C before the shortening could read it: the first plan is the best so far, and says so
            first = kept["first"]
            first["shorten"] = dict(first["shorten"], status="interrupted", stopped_by="interrupted")
            Plan(first, task).save(out / "plan.json")
        raise KeyboardInterrupt(f"{kept['doing']}: kept {kept['plan']}") from None


def _draw(p, out, gif):
    """plan.png (and plan.gif) of the plan `p`, replayed; returns the paths written."""
    from .plans import animate_plan, plot_plan
    rep = p.replay()
    plot_plan(p.model, rep["dense"], out / "plan.png", title=p.title())
    wrote = [out / "plan.png"]
    if gif:
        animate_plan(p.model, rep["dense"], out / "plan.gif")
        wrote.append(out / "plan.gif")
    return wrote


#: why the shortening stopped (plan.json's shorten.stopped_by), as `plan` and `replay` say it
STOPPED_BY = {"patience": "stopped by its patience: {patience} rejected in a row",
              "effort": "stopped by its effort bound: {max_sim_steps} simulated steps",
              "candidates": "stopped after {max_candidates} candidates",
              "time_limit": "stopped at the end of the time budget",
              "shorten_time": "stopped after --shorten-time {shorten_time:g} s",
              "interrupted": "interrupted by Ctrl-C",
              "nothing left": "stopped: no shorter stretch left to try"}


def _stopped(sh):
    why = sh.get("stopped_by")
    if why not in STOPPED_BY:
        return "stopped" if why is None else f"stopped by {why}"
    try:
        return STOPPED_BY[why].format(**sh)
    except (KeyError, TypeError, ValueError):
        return STOPPED_BY[why].split(":")[0]


def _truncated(sh):
    """What the shortening's line adds when the planner's plan reached the goal before its end (`truncated`)."""
    if not sh.get("truncated"):
        return ""
    if sh.get("accepted", 0) == 0:
        return "; only truncated: cut where the goal first holds, no candidate accepted"
    return "; truncated first, where the goal first holds"


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
    sh = data.get("shorten")
    if isinstance(sh, dict) and sh.get("status") in ("running", "interrupted"):
        print("shortening     " + ("interrupted (Ctrl-C): the best exact plan it had" if sh["status"] == "interrupted"
                                   else "never finished (the plan file written before it): the planner's plan"))
    print(f"simulator      {args.simulator}", flush=True)
    if args.closed_loop or args.perturb:
        how = "closed loop (PlanTracker)" if args.closed_loop else "open loop"
        world = (", world perturbed: " + ", ".join(f"{k} x{v:g}" for k, v in args.perturb.items())) \
            if args.perturb else ""
        print(f"execution      {how}{world}", flush=True)
    try:
        res = plan.replay(args.simulator, closed_loop=args.closed_loop, perturb=args.perturb)
    except ImportError as e:
        return _err("replay", f"--simulator pymunk is not available: {e}")
    if args.closed_loop:
        import numpy as np
        c = res["compute_s"]
        print(f"{'steps':<16} {res['steps']} propagation steps of {plan.task.step_duration:g} s (the plan: "
              f"{int(plan.steps.sum())})")
        if len(c):
            print(f"{'compute':<16} median {1e3 * np.median(c):.1f} ms, max {1e3 * c.max():.1f} ms of thread CPU "
                  f"per step")
    rep = res["report"]
    for k, v in rep.items():
        print(f"{k:<16} {v:.6g}" if isinstance(v, float) else _show(f"{k:<16}", v) if isinstance(v, list)
              else f"{k:<16} {v}")
    print(f"{'max_penetration':<16} {res['penetration']:.3g} m (deepest overlap of any two bodies after any step; "
          f"in the propagation step ending at t = {res['penetration_time']:.2f} s)")
    name = f"replay_{args.simulator}" + ("_closed_loop" if args.closed_loop else "")
    plot_plan(plan.model, res["dense"], out / f"{name}.png",
              title=f"replay of {data['task']} in {args.simulator}: goal {'holds' if rep['goal_holds'] else 'missed'}")
    wrote = [out / f"{name}.png"]
    if not args.no_gif:
        from .plans import animate_plan
        animate_plan(plan.model, res["dense"], out / f"{name}.gif")
        wrote.append(out / f"{name}.gif")
    for w in wrote:
        print(f"wrote          {w}")
    return 0 if rep["goal_holds"] else 1


def cmd_bench(args):
    from planar_lcp.cli_support import require
    from planar_lcp.parallel.cluster import SchedulerLost, SchedulerUnreachable
    from planar_lcp.parallel.records import RecordFileError

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


def cmd_pusht_eval(args):
    import os

    from planar_lcp.cli_support import require
    require("gymnasium")
    if args.jobs is not None or args.scheduler is not None:
        require("distributed")
    from planar_lcp.parallel.cluster import SchedulerLost, SchedulerUnreachable

    from .environments.pusht_eval import evaluate
    if args.scheduler is not None and args.jobs is not None:
        return _err("pusht-eval", f"--jobs sizes the local cluster: not with --scheduler {args.scheduler}")
    env_kwargs = {}
    for flag, value, key in (("--table-friction", args.table_friction, "table_friction"),
                             ("--contact-friction", args.contact_friction, "contact_friction")):
        if value is not None:
            if args.env != "planar_lcp/PushT-v0":
                return _err("pusht-eval", f"{flag} changes our PushT-v0's world: only with --env "
                                          f"planar_lcp/PushT-v0, got --env {args.env}")
            env_kwargs[key] = value
    python = args.pusht_python or os.environ.get("PLANAR_LCP_PUSHT_PYTHON")
    if args.pusht_python is not None and not Path(args.pusht_python).is_file():
        return _err("pusht-eval", f"--pusht-python {args.pusht_python}: no such file")
    if args.env.startswith("gym_pusht/") and not python:
        import importlib.util
        if importlib.util.find_spec("gym_pusht") is None:
            return _err("pusht-eval", f"--env {args.env}: gym_pusht does not import here; give --pusht-python PY "
                                      "(or $PLANAR_LCP_PUSHT_PYTHON), the python of a virtualenv with "
                                      "gym-pusht==0.1.8")
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return _err("pusht-eval", f"--out {out}: cannot create the directory ({e.strerror or e})")
    from .environments.pusht_eval import default_world
    world = args.world or default_world(args.env)
    print(f"pusht-eval     {args.episodes} episodes of {args.env} (seeds {args.seed}..{args.seed + args.episodes - 1})"
          f", PushTPolicy(world={world!r})" + (f", the world's {env_kwargs}" if env_kwargs else ""), flush=True)
    try:
        s = evaluate(args.env, args.episodes, args.seed, out, world=world, pusht_python=python,
                     env_kwargs=env_kwargs, jobs=args.jobs, scheduler=args.scheduler,
                     say=lambda line: print(line, flush=True))
    except RuntimeError as e:
        return _err("pusht-eval", e, 1)
    except (SchedulerUnreachable, SchedulerLost) as e:
        return _err("pusht-eval", str(e), 1)
    print(f"success        {s['successes']}/{s['episodes']} ({100 * s['success_rate']:.1f} %), mean final coverage "
          f"{s['mean_final_coverage']:.3f}; the policy's compute per action: median {s['compute_median_ms']:.2f} ms, "
          f"max {s['compute_max_ms']:.1f} ms (thread CPU time)")
    print(f"wrote          {out / 'episodes.csv'}, {out / 'summary.json'}")
    return 0
