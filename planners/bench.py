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

from planar_lcp.experiments.cluster import (close_cluster, host_info, local_jobs, open_cluster, retried_runs,
                                            worker_address)

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
              ("solution segments INTEGER", "segments"), ("graph motions INTEGER", "propagations"),
              ("iterations INTEGER", "iterations"), ("simulated steps INTEGER", "sim_steps"),
              ("simulated steps per second REAL", "steps_per_second")]


def _crash_record(planner, seed, error, solve_time, worker, host=None, cpuinfo=None):
    """The record of a run that ended without a plan by an error (OMPL's status Crash); a run Dask gave up on has
    no worker and no host."""
    return dict(planner=planner, seed=seed, exact=False, approximate=False, solve_time=solve_time,
                status=STATUS.CRASH.value, error=error, goal_distance=float("nan"), path_duration=float("nan"),
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
                path_duration=plan["path_duration"] if (exact or approx) else float("nan"),
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
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


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
        ds = np.array([r["path_duration"] for r in ex])
        sps = np.array([r["steps_per_second"] for r in rs if np.isfinite(r["steps_per_second"])])
        rows.append(dict(planner=p, runs=len(rs), exact=len(ex), success_rate=len(ex) / max(len(rs), 1),
                         replayed=sum(1 for r in ex if r.get("replayed")),
                         time_q1_med_q3=_quartiles(ts), duration_q1_med_q3=_quartiles(ds),
                         steps_per_second_median=float(np.median(sps)) if len(sps) else float("nan")))
    return rows


def summary_markdown(task, rows, runs, budget, where):
    """budget: "60 s" or "5000 iterations" per run; where: "2 worker processes" or "the Dask cluster at ADDRESS"."""
    out = [f"Task `{task}`: {runs} runs per planner (seeds 1..{runs}), {budget} each, {where}.", "",
           "| planner | exact | exact plans replayed to the goal | time to exact solution [s] median (q1-q3) | "
           "path duration [s] median (q1-q3) | sim steps/s (median) |", "|---|---|---|---|---|---|"]
    for r in rows:
        t, d = r["time_q1_med_q3"], r["duration_q1_med_q3"]
        ft = f"{t[1]:.2f} ({t[0]:.2f}-{t[2]:.2f})" if r["exact"] else "-"
        fd = f"{d[1]:.2f} ({d[0]:.2f}-{d[2]:.2f})" if r["exact"] else "-"
        out.append(f"| {r['planner']} | {r['exact']}/{r['runs']} | {r['replayed']}/{r['exact']} | {ft} | {fd} | "
                   f"{r['steps_per_second_median']:.0f} |")
    return "\n".join(out) + "\n"


def box_plots(records, planners, time_limit, path, task):
    from planar_lcp.viz import new_figure

    fig = new_figure((10, 3.6), dpi=100)
    axs = fig.subplots(1, 3)
    # time: unsolved runs count at the time limit (as OMPL's plots do; with an iteration budget: at their own time)
    data_t = [[r["solve_time"] if r["exact"] or time_limit is None else time_limit for r in records
               if r["planner"] == p] for p in planners]
    data_d = [[r["path_duration"] for r in records if r["planner"] == p and r["exact"]] or [np.nan]
              for p in planners]
    data_s = [[r["steps_per_second"] for r in records if r["planner"] == p] for p in planners]
    for ax, data, lab in ((axs[0], data_t, "time to exact solution [s]\n(unsolved = time limit)"),
                          (axs[1], data_d, "path duration [s] (exact runs)"),
                          (axs[2], data_s, "simulated steps per second")):
        ax.boxplot(data)
        ax.set_xticks(range(1, len(planners) + 1), planners)
        ax.set_title(lab, fontsize=9)
        ax.tick_params(axis="x", labelrotation=30, labelsize=8)
    fig.suptitle(f"plan-bench {task}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)


def run_bench(task, planners, runs=10, time_limit=60.0, jobs=None, out=".", iterations=None, scheduler=None):
    """Run the benchmark of `task` (a Task, a shipped task's name or a task file; each worker gets the validated
    Task itself) with a time limit or, with `iterations`, an iteration budget per run, on Dask; write the log,
    database, summaries and box plots into `out`. Returns the summary rows."""
    from distributed import as_completed
    from tqdm import tqdm

    from .tasks import load_task

    t = load_task(task)
    task = t.name
    out = Path(out)
    jobs = local_jobs(jobs, runs * len(planners))
    limit = None if iterations else float(time_limit)
    todo = [(t, p, s, limit, iterations) for s in range(1, runs + 1) for p in planners]
    t0 = time.perf_counter()
    records = []
    client, cluster = open_cluster(scheduler, jobs)
    workers_at_start = set(client.scheduler_info()["workers"])
    print(f"cluster        {scheduler or 'local'}: {len(workers_at_start)} worker(s) "
          f"({', '.join(sorted(workers_at_start))})", flush=True)
    futs = []
    try:
        # pure=False: every run is its own task, even with equal arguments. A run whose worker is lost is run again
        # on another by the scheduler itself (up to Dask's distributed.scheduler.allowed-failures times)
        futs = [client.submit(_run_one, *a, pure=False) for a in todo]
        args_of = {f.key: a for f, a in zip(futs, todo)}
        with tqdm(total=len(futs), desc=f"plan-bench {task}", unit="run") as bar:
            for f in as_completed(futs):
                try:
                    r = f.result()
                except Exception as e:  # noqa: BLE001 - e.g. KilledWorker: the run counts as crashed, not the bench
                    _, p, seed, _, _ = args_of[f.key]
                    r = _crash_record(p, seed, repr(e), float("nan"), None)
                records.append(r)
                bar.set_postfix_str(f"{r['planner']} seed {r['seed']}: {'exact' if r['exact'] else 'no'}")
                bar.update()
        retried = retried_runs(client, [f.key for f in futs])
        lost = sorted(workers_at_start - set(client.scheduler_info()["workers"]))
    except KeyboardInterrupt:
        # cancel what is queued or running, stop the local workers now (a run holds its worker up to --time)
        close_cluster(client, cluster, futs)
        raise
    close_cluster(client, cluster)
    total = time.perf_counter() - t0
    records.sort(key=lambda r: (planners.index(r["planner"]), r["seed"]))
    # OMPL's log has a time limit per run; with an iteration budget, the longest run's time stands for it
    logs = write_logs(out, t, planners, records, limit if limit is not None else
                      max((r["solve_time"] for r in records), default=0.0), total)
    wrote = list(logs)
    try:
        wrote.append(make_database(logs, out / f"{task}.db"))
    except (RuntimeError, OSError) as e:
        print(f"warning: no database: {e}", file=sys.stderr)
    rows = summarize(records, planners, limit)
    budget = f"{iterations} iterations" if iterations else f"{limit:g} s"
    where = f"the Dask cluster at {scheduler}" if scheduler else f"{jobs} worker processes"
    md = summary_markdown(task, rows, runs, budget, where)
    (out / "summary.md").write_text(md)
    hosts = {r["host"]: r["cpuinfo"] for r in records if r.get("host")}
    (out / "summary.json").write_text(json.dumps(dict(
        task=task, task_source=t.source, task_sha256=t.sha256, runs=runs, time_limit=limit, iterations=iterations, jobs=None if scheduler else jobs,
        scheduler=scheduler or "local", workers=sorted({r["worker"] for r in records if r["worker"]}),
        lost_workers=lost, retried_runs=retried, total_time=total, hosts=hosts, summary=rows,
        records=[{k: v for k, v in r.items() if k != "cpuinfo"} for r in records]), indent=1))
    box_plots(records, planners, limit, out / "boxplots.png", task)
    wrote += [out / "summary.md", out / "summary.json", out / "boxplots.png"]
    print(md)
    if lost or retried:
        print(f"{len(lost)} worker(s) lost during the benchmark ({', '.join(lost) or 'none'}); {retried} run(s) "
              "were run again on another worker; every run completed")
    for w in wrote:
        print(f"wrote {w}")
    return rows
