"""`planar-lcp plan-bench`: each planner N times (seeds 1..N) as Dask tasks, an OMPL benchmark log and its SQLite
database, a summary table and box plots.

Where the runs go: with `--scheduler ADDRESS` to an existing Dask cluster (`dask scheduler` / `dask worker`, or any
Dask deployment), else to a local cluster of `--jobs` worker processes (one thread each) bound to 127.0.0.1, started
and stopped by the command. Each run records the worker that ran it ("worker" in summary.json). A worker lost
mid-run: Dask runs its tasks again on another worker; the command says how many runs that hit.

Why not `ompl.tools.Benchmark`: it runs every planner in the calling process, one after another, and `solve()`
holds the GIL; custom columns (simulated steps per second) cannot be added from Python in 2.0.1. So each run is a
separate `plan_task` in a worker process, and the log is written here in OMPL's benchmark log format
(doc/markdown/benchmark.md), then loaded with the wheel's `ompl_benchmark_statistics` (`readBenchmarkLog`).
"""

import json
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

import numpy as np
from ompl import base as ob

from planar_lcp.parallel.cluster import (SchedulerLost, close_cluster, host_info, local_jobs, lost_scheduler_message,
                                         open_cluster, retried_runs, worker_address)
from planar_lcp.parallel.records import RECORDS, STOPPED, RecordWriter, prepare, read_records, write_text_atomic
from planar_lcp.parallel.sweep import run_recorded, say_resumed

#: OMPL's planner statuses; a run's `status ENUM` column holds the value of one of them
STATUS = ob.PlannerStatus.PlannerStatusType
#: the label of each status value in order, the log's enum line as OMPL's Benchmark writes it (spelled out: the
#: 2.0.1 bindings' PlannerStatus.asString() says "Unknown status" for ABORT and INFEASIBLE too)
STATUS_LABELS = ("Unknown status", "Invalid start", "Invalid goal", "Unrecognized goal type", "Timeout",
                 "Approximate solution", "Exact solution", "Crash", "Abort", "Infeasible")
STATUS_ENUM = "status|" + "|".join(STATUS_LABELS)
# run properties in the log: (name TYPE, key in the run record)
RUN_FIELDS = [("time REAL", "solve_time"), ("memory REAL", None), ("status ENUM", "status"),
              ("solved BOOLEAN", "exact"), ("approximate solution BOOLEAN", "approximate"),
              ("solution difference REAL", "goal_distance"), ("solution length REAL", "path_duration"),
              ("first solution length REAL", "first_path_duration"), ("pusher path length REAL", "pusher_path_length"),
              ("first pusher path length REAL", "first_pusher_path_length"),
              ("object path length REAL", "object_path_length"),
              ("first object path length REAL", "first_object_path_length"), ("shorten time REAL", "shorten_time"),
              ("solution segments INTEGER", "segments"), ("graph motions INTEGER", "propagations"),
              ("iterations INTEGER", "iterations"), ("simulated steps INTEGER", "sim_steps"),
              ("simulated steps per second REAL", "steps_per_second")]


#: the costs a run reports, of the final (shortened) plan and, with first_, of the planner's first exact plan
COST_KEYS = ("path_duration", "pusher_path_length", "object_path_length", "first_path_duration",
             "first_pusher_path_length", "first_object_path_length")


def _crash_record(planner, seed, error, solve_time, worker, host=None, cpuinfo=None):
    """The record of a run that ended without a plan by an error (OMPL's status Crash); a run Dask gave up on has
    no worker and no host."""
    return dict(planner=planner, seed=seed, exact=False, approximate=False, solve_time=solve_time,
                status=STATUS.CRASH.value, error=error, goal_distance=float("nan"), path_duration=float("nan"),
                **{k: float("nan") for k in COST_KEYS if k != "path_duration"}, shorten_time=float("nan"),
                segments=0, propagations=0, iterations=0, sim_steps=0, steps_per_second=float("nan"), replayed=None,
                worker=worker,
                host=host, cpuinfo=cpuinfo)


def _run_one(task, planner, seed, time_limit, iterations=None):
    """One planning run in a worker process; returns a flat record with the worker's address (None outside Dask)."""
    import gc
    gc.disable()
    from .plans import plan_task
    t0 = time.perf_counter()
    worker = worker_address()
    host, cpuinfo = host_info()
    try:
        plan = plan_task(task, planner, seed=seed, time_limit=time_limit, iterations=iterations)
    except Exception as e:  # noqa: BLE001 - a crashed run is a result (status Crash), not the end of the benchmark
        return _crash_record(planner, seed, repr(e), time.perf_counter() - t0, worker, host, cpuinfo)
    exact, approx = plan["exact"], plan["approximate"]
    # every exact plan is replayed open loop in a fresh TaskModel, as `planar-lcp replay` would: it must reach the
    # planner's states bit for bit and the goal (None: no exact plan to replay)
    replayed = None
    if exact:
        from .plans import replay_lcp
        res = replay_lcp(plan)
        replayed = bool(res["report"]["goal_holds"] and np.array_equal(res["bound"], np.asarray(plan["states"])))
    return dict(planner=planner, seed=seed, exact=exact, approximate=approx, solve_time=plan["solve_time"],
                status=(STATUS.EXACT_SOLUTION if exact else STATUS.APPROXIMATE_SOLUTION if approx
                        else STATUS.TIMEOUT).value,       # the time limit ended a run without a solution
                goal_distance=plan.get("goal", {}).get("goal_distance", float("nan")),
                **{k: plan[k] if (exact or approx) else float("nan") for k in COST_KEYS},
                shorten_time=plan["shorten"]["time"],
                segments=len(plan["controls"]), propagations=plan["propagations"], iterations=plan["iterations"],
                sim_steps=plan["sim_steps"], steps_per_second=plan["steps_per_second"], replayed=replayed,
                worker=worker, host=host, cpuinfo=cpuinfo)


def _fmt(v):
    if isinstance(v, bool):
        return "1" if v else "0"
    if v is None:
        return ""
    if isinstance(v, float) and not np.isfinite(v):
        return "nan"
    return f"{v}"


#: the host of a run that no worker finished (Dask gave up on it): its log says so instead of naming a machine (one
#: word: ompl_benchmark_statistics reads the host as the last word of "Running on ...")
UNKNOWN_HOST = "unknown-host"


def write_logs(out, t, planners, records, time_limit, total_time):
    """OMPL benchmark logs of the runs, ONE PER HOST: OMPL's log format describes one experiment on one machine
    ("Running on <host>" and its CPU), and `ompl_benchmark_statistics` merges several logs into one database, so a
    benchmark spread over machines is one log per machine. With one host the log is `<task>.log`, otherwise
    `<task>_<host>.log` for each (t: the Task). Returns the paths."""
    task = t.name
    hosts = {}
    for r in records:
        hosts.setdefault(r.get("host") or UNKNOWN_HOST, r.get("cpuinfo") or "unknown")
    paths = []
    for host, cpu in sorted(hosts.items()):
        rs = [r for r in records if (r.get("host") or UNKNOWN_HOST) == host]
        name = f"{task}.log" if len(hosts) == 1 else f"{task}_{_file_safe(host)}.log"
        paths.append(write_log(Path(out) / name, t, planners, rs, host, cpu, time_limit, total_time))
    return paths


def _file_safe(s):
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in s.split(" ")[0])


def write_log(path, t, planners, records, host, cpuinfo, time_limit, total_time):
    """One OMPL benchmark log (doc/markdown/benchmark.md) of `records` of task `t` (a Task), all run on `host`."""
    task = t.name
    try:
        from importlib.metadata import version
        ver = version("ompl")
    except Exception:  # noqa: BLE001
        ver = "unknown"
    runs = max([sum(1 for r in records if r["planner"] == p) for p in planners], default=0)
    lines = [f"OMPL version {ver}", f"Experiment {task}", "0 experiment properties",
             f"Running on {host}", f"Starting at {datetime.now().strftime('%Y-%m-%d %H:%M:%S')}",
             "<<<|", f"task {task}: {t.description}; task file {t.source}; planar_lcp LCP simulator as forward model",
             "|>>>", "<<<|", cpuinfo, "|>>>",
             "0 is the random seed", f"{time_limit} seconds per run", "0 MB per run", f"{runs} runs per planner",
             f"{total_time} seconds spent to collect the data", "1 enum types", STATUS_ENUM,
             f"{len(planners)} planners"]
    for p in planners:
        rs = sorted([r for r in records if r["planner"] == p], key=lambda r: r["seed"])
        lines += [f"control_{p}", "0 common properties", f"{len(RUN_FIELDS)} properties for each run"]
        lines += [name for name, _ in RUN_FIELDS]
        lines.append(f"{len(rs)} runs")
        for r in rs:
            vals = [_fmt(r.get(k)) if k else "0" for _, k in RUN_FIELDS]
            lines.append("; ".join(vals) + "; ")
        lines.append(".")
    return write_text_atomic(path, "\n".join(lines) + "\n")


def make_database(logs, db):
    """The SQLite database of the logs (one experiment each), with the wheel's ompl_benchmark_statistics (its Python
    module if the console script is missing)."""
    if Path(db).exists():
        Path(db).unlink()
    logs = [str(p) for p in logs]
    exe = Path(sys.executable).parent / "ompl_benchmark_statistics"
    cmd = [str(exe), *logs, "-d", str(db)] if exe.exists() else \
        [sys.executable, "-m", "ompl.ompl_benchmark_statistics", *logs, "-d", str(db)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"ompl_benchmark_statistics failed: {r.stderr.strip()}")
    return db


def _quartiles(a):
    """[q1, median, q3] of a, NaNs for an empty a (a planner without an exact run)."""
    return np.percentile(a, [25, 50, 75]).tolist() if len(a) else [float("nan")] * 3


def summarize(records, planners, time_limit):
    rows = []
    for p in planners:
        rs = [r for r in records if r["planner"] == p]
        ex = [r for r in rs if r["exact"]]
        ts = np.array([r["solve_time"] for r in ex])
        sps = np.array([r["steps_per_second"] for r in rs if np.isfinite(r["steps_per_second"])])
        # records written by older versions have no first_ costs: their plan was the first plan
        cost = {k: _quartiles(np.array([r.get(k, r.get(k[len("first_"):], float("nan"))) for r in ex]))
                for k in COST_KEYS}
        rows.append(dict(planner=p, runs=len(rs), exact=len(ex), success_rate=len(ex) / max(len(rs), 1),
                         replayed=sum(1 for r in ex if r.get("replayed")),
                         time_q1_med_q3=_quartiles(ts), duration_q1_med_q3=cost["path_duration"],
                         first_duration_q1_med_q3=cost["first_path_duration"],
                         pusher_path_q1_med_q3=cost["pusher_path_length"],
                         first_pusher_path_q1_med_q3=cost["first_pusher_path_length"],
                         object_path_q1_med_q3=cost["object_path_length"],
                         first_object_path_q1_med_q3=cost["first_object_path_length"],
                         steps_per_second_median=float(np.median(sps)) if len(sps) else float("nan")))
    return rows


def summary_markdown(task, rows, runs, budget, where):
    """budget: "60 s" or "5000 iterations" per run; where: "2 worker processes" or "the Dask cluster at ADDRESS"."""
    out = [f"Task `{task}`: {runs} runs per planner (seeds 1..{runs}), {budget} each, {where}.", "",
           "| planner | exact | exact plans replayed to the goal | time to first exact solution [s] median (q1-q3) | "
           "first path duration [s] median (q1-q3) | final path duration [s] median (q1-q3) | "
           "pusher path [m] first, final (medians) | object path [m] first, final (medians) | sim steps/s (median) |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        def q(k, f=".2f"):
            v = r[k]
            return f"{v[1]:{f}} ({v[0]:{f}}-{v[2]:{f}})" if r["exact"] else "-"

        def m(k):
            return f"{r['first_' + k][1]:.3f}, {r[k][1]:.3f}" if r["exact"] else "-"
        out.append(f"| {r['planner']} | {r['exact']}/{r['runs']} | {r['replayed']}/{r['exact']} | "
                   f"{q('time_q1_med_q3')} | {q('first_duration_q1_med_q3')} | {q('duration_q1_med_q3')} | "
                   f"{m('pusher_path_q1_med_q3')} | {m('object_path_q1_med_q3')} | {r['steps_per_second_median']:.0f} |")
    return "\n".join(out) + "\n"


def box_plots(records, planners, time_limit, path, task):
    from planar_lcp.viz import new_figure

    fig = new_figure((10, 3.6), dpi=100)
    axs = fig.subplots(1, 3)
    # time: unsolved runs count at the time limit (as OMPL's plots do; with an iteration budget: at their own time)
    data_t = [[r["solve_time"] if r["exact"] or time_limit is None else time_limit for r in records
               if r["planner"] == p] or [np.nan] for p in planners]
    data_d = [[r["path_duration"] for r in records if r["planner"] == p and r["exact"]] or [np.nan]
              for p in planners]
    data_s = [[r["steps_per_second"] for r in records if r["planner"] == p] or [np.nan] for p in planners]
    for ax, data, lab in ((axs[0], data_t, "time to exact solution [s]\n(unsolved = time limit)"),
                          (axs[1], data_d, "final path duration [s] (exact runs)"),
                          (axs[2], data_s, "simulated steps per second")):
        ax.boxplot(data)
        ax.set_xticks(range(1, len(planners) + 1), planners)
        ax.set_title(lab, fontsize=9)
        ax.tick_params(axis="x", labelrotation=30, labelsize=8)
    fig.suptitle(f"plan-bench {task}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)


def bench_header(t, planners, runs, time_limit, iterations):
    """The record file's header of a benchmark: what --resume compares (the task by name and by its document's
    hash, the planners as a set, the runs, the budget)."""
    return dict(command="plan-bench", task=t.name, task_sha256=t.sha256, task_source=t.source, planners=list(planners),
                runs=runs, time_limit=time_limit, iterations=iterations)


def _budget(h):
    return (f"a budget of {h.get('iterations')} iterations per run" if h.get("iterations")
            else f"a budget of {h.get('time_limit'):g} s per run" if isinstance(h.get("time_limit"), (int, float))
            else f"a budget of {h.get('time_limit')!r}")


def header_differences(old, new):
    """What differs between the benchmark a record file was written for (`old`, its header) and the one asked
    (`new`): a list of (the file's, the command's) phrases, empty for the same benchmark."""
    if old.get("command") != new["command"]:
        return [(f"planar-lcp {old.get('command')}", f"planar-lcp {new['command']}")]
    out = []
    if old.get("task") != new["task"]:
        out.append((f"task '{old.get('task')}'", f"task '{new['task']}'"))
    elif old.get("task_sha256") != new["task_sha256"]:
        out.append((f"task '{old['task']}' as its file read then (document sha256 {str(old.get('task_sha256'))[:12]})",
                    f"the task file as it reads now ({new['task_source']}: document sha256 "
                    f"{new['task_sha256'][:12]})"))
    if sorted(old.get("planners") or []) != sorted(new["planners"]):
        out.append((f"planners {', '.join(old.get('planners') or [])}", f"planners {', '.join(new['planners'])}"))
    if old.get("runs") != new["runs"]:
        out.append((f"{old.get('runs')} runs per planner", f"{new['runs']} runs per planner"))
    if (old.get("time_limit"), old.get("iterations")) != (new["time_limit"], new["iterations"]):
        out.append((_budget(old), _budget(new)))
    return out


def run_bench(task, planners, runs=10, time_limit=60.0, jobs=None, out=".", iterations=None, scheduler=None,
              resume=False):
    """Run the benchmark of `task` (a Task, a shipped task's name or a task file; each worker gets the validated
    Task itself) with a time limit or, with `iterations`, an iteration budget per run, on Dask; write the log,
    database, summaries and box plots into `out`. Returns the summary rows.

    Each finished run is appended to `out`/records.jsonl as its result arrives (planar_lcp.parallel.records),
    and the outputs are made from those records: at the end, and also when Ctrl-C, a lost scheduler or an error
    stops the benchmark (then partial: they say how many runs finished of how many). `resume`: the runs already
    in the record file are kept and only the others run; the file must be of the same benchmark (task, planners,
    runs, budget), which is checked before any work, as is, without `resume`, that the file holds no run.

    Raises
    ------
    TaskError
        Before any work: a bad task, `runs` beyond spec.task.MAX_RUNS or a time limit beyond a task file's `time`
        bound.
    RecordFileError
        Before any work: the record file is of another benchmark (`resume`) or holds runs (not `resume`).
    BenchmarkInterrupted
        Ctrl-C: the cluster stopped, the finished runs kept with partial outputs; its message says what was kept.
    SchedulerLost
        The scheduler went away during the benchmark; the finished runs are kept as after Ctrl-C.
    """
    from planar_lcp.spec.task import MAX_RUNS, check_time_limit

    from .tasks import TaskError, load_task

    t = load_task(task)
    out = Path(out)
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or not 1 <= runs <= MAX_RUNS:
        raise TaskError(f"runs must be an integer from 1 to {MAX_RUNS} (seeds 1..runs), got {runs!r}")
    runs = int(runs)
    limit = None if iterations else check_time_limit(time_limit)
    header = bench_header(t, planners, runs, limit, iterations)
    previous = prepare(out, header, header_differences, resume, "plan-bench")     # before any work
    planned = [(p, s) for s in range(1, runs + 1) for p in planners]
    done = {k: r for k, r in (previous.runs.items() if previous else ()) if k in set(planned)}
    todo = [k for k in planned if k not in done]
    # the local cluster as an uninterrupted benchmark sizes it (one worker per run at most), so that a resumed
    # benchmark's summary says the same
    jobs = local_jobs(jobs, len(planned))
    where = f"the Dask cluster at {scheduler}" if scheduler else f"{jobs} worker processes"
    say_resumed(previous, resume, out / RECORDS, len(done), len(planned), "run", width=15)
    writer = RecordWriter(out / RECORDS, header, resume=previous)
    t0 = time.perf_counter()
    cluster_events = dict(lost_workers=[], retried_runs=0)

    def run(live):
        if todo:
            _run_on_dask(t, todo, limit, iterations, scheduler, jobs, writer, done, t0, cluster_events, live)
            close_cluster(live["client"], live["cluster"])

    run_recorded(run, writer, planned, len(done), "run",
                 lambda ended: _write_outputs(out, t, planners, planned, header, where, scheduler, jobs, partial=ended),
                 "a partial summary", info=cluster_events, t0=t0)
    rows, md, wrote = _write_outputs(out, t, planners, planned, header, where, scheduler, jobs)
    print(md)
    lost, retried = cluster_events["lost_workers"], cluster_events["retried_runs"]
    if lost or retried:
        print(f"{len(lost)} worker(s) lost during the benchmark ({', '.join(lost) or 'none'}); {retried} run(s) "
              "were run again on another worker; every run completed")
    for w in wrote:
        print(f"wrote {w}")
    return rows


def _run_on_dask(t, todo, limit, iterations, scheduler, jobs, writer, done, t0, cluster_events, live):
    """Submit the runs `todo` ((planner, seed) each) and append each finished run to the record file (`writer`) and
    to `done` as it arrives; the lost workers and retried runs go to `cluster_events`. What it opens (client, cluster,
    futures, progress bar) goes to `live` as soon as it exists: the caller closes it, also after Ctrl-C."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from tqdm import tqdm

    client, cluster = live["client"], live["cluster"] = open_cluster(scheduler, jobs)
    workers_at_start = set(client.scheduler_info()["workers"])
    print(f"cluster        {scheduler or 'local'}: {len(workers_at_start)} worker(s) "
          f"({', '.join(sorted(workers_at_start))})", flush=True)
    # pure=False: every run is its own task, even with equal arguments. A run whose worker is lost is run again on
    # another by the scheduler itself (up to Dask's distributed.scheduler.allowed-failures times)
    futs = live["futures"] = [client.submit(_run_one, t, p, s, limit, iterations, pure=False) for p, s in todo]
    key_of = {f.key: k for f, k in zip(futs, todo)}
    # on a terminal only (disable=None): a log or a pipe gets no bar frames
    bar = live["bar"] = tqdm(total=len(done) + len(todo), initial=len(done), desc=f"plan-bench {t.name}",
                             unit="run", disable=None)
    for f in as_completed(futs):
        p, seed = key_of[f.key]
        try:
            r = f.result()
        except FutureCancelledError as e:
            # not a result of the run: the client lost its scheduler, which cancels every future it holds
            raise SchedulerLost(lost_scheduler_message(scheduler, e)) from None
        except Exception as e:  # noqa: BLE001 - e.g. KilledWorker: the run counts as crashed, not the bench
            r = _crash_record(p, seed, repr(e), float("nan"), None)
        done[(p, seed)] = writer.run((p, seed), r, time.perf_counter() - t0)
        bar.set_postfix_str(f"{p} seed {seed}: {'exact' if r['exact'] else 'no'}")
        bar.update()
    cluster_events["retried_runs"] = retried_runs(client, [f.key for f in futs])
    cluster_events["lost_workers"] = sorted(workers_at_start - set(client.scheduler_info()["workers"]))


def _write_outputs(out, t, planners, planned, header, where, scheduler, jobs, partial=None):
    """The log(s), database, summary.md, summary.json and box plots of the runs in the record file `out`/records.jsonl,
    in this command's planner order; `partial` ("interrupted", "failed"): the benchmark stopped before its end, and
    the summaries say how many runs finished of how many. Returns (summary rows, summary.md's text, paths
    written)."""
    contents = read_records(out / RECORDS)
    planned_set = set(planned)
    records = [r for k, r in contents.runs.items() if k in planned_set]
    records.sort(key=lambda r: (planners.index(r["planner"]), r["seed"]))
    limit, iterations, runs = header["time_limit"], header["iterations"], header["runs"]
    total = sum(contents.invocation_times().values())
    ends = list(contents.invocations.values())
    lost = sorted({w for e in ends for w in e["info"].get("lost_workers", [])})
    retried = sum(e["info"].get("retried_runs", 0) for e in ends)
    wrote = []
    # OMPL's log has a time limit per run; with an iteration budget, the longest run's time stands for it
    logs = write_logs(out, t, planners, records, limit if limit is not None else
                      max((r["solve_time"] for r in records), default=0.0), total) if records else []
    _remove_stale_logs(out, logs)
    wrote += logs
    if logs:
        try:
            wrote.append(make_database(logs, out / f"{t.name}.db"))
        except (RuntimeError, OSError) as e:
            print(f"warning: no database: {e}", file=sys.stderr)
    rows = summarize(records, planners, limit)
    budget = f"{iterations} iterations" if iterations else f"{limit:g} s"
    md = summary_markdown(t.name, rows, runs, budget, where)
    if partial:
        md = (f"**Partial: {len(records)} of {len(planned)} runs finished** ({STOPPED[partial]}); "
              f"`planar-lcp plan-bench ... --resume` with the same settings runs the other "
              f"{len(planned) - len(records)}.\n\n" + md)
    wrote.append(write_text_atomic(out / "summary.md", md))
    hosts = {r["host"]: r["cpuinfo"] for r in records if r.get("host")}
    wrote.append(write_text_atomic(out / "summary.json", json.dumps(dict(
        task=t.name, task_source=t.source, task_sha256=t.sha256, runs=runs, time_limit=limit, iterations=iterations,
        jobs=None if scheduler else jobs, scheduler=scheduler or "local",
        workers=sorted({r["worker"] for r in records if r["worker"]}), lost_workers=lost, retried_runs=retried,
        total_time=total, planned_runs=len(planned), finished_runs=len(records), complete=not partial,
        invocations=contents.last_invocation, records_file=RECORDS, logs=[p.name for p in logs], hosts=hosts,
        summary=rows, records=[{k: v for k, v in r.items() if k != "cpuinfo"} for r in records]), indent=1)))
    if records:
        box_plots(records, planners, limit, out / "boxplots.png", t.name)
        wrote.append(out / "boxplots.png")
    return rows, md, wrote


def _remove_stale_logs(out, logs):
    """Remove the logs an earlier write of this benchmark's outputs listed (summary.json's "logs") that this one
    does not write: a benchmark resumed on more hosts has one log per host, not the one of the first hosts alone."""
    try:
        before = json.loads((out / "summary.json").read_text()).get("logs") or []
    except (OSError, ValueError, AttributeError):
        return
    keep = {Path(p).name for p in logs}
    for name in before:
        if isinstance(name, str) and name not in keep and Path(name).name == name and name.endswith(".log"):
            (out / name).unlink(missing_ok=True)
