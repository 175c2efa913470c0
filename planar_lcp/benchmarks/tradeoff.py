"""`planar-lcp tradeoff`: measure the speed/accuracy trade of the knobs users turn.

For each scene, every setting of the step size h, the solver (and its iteration count) and the formulation is run with
the scene's own table friction, and compared with a reference solution. In the horizontal plane the table friction's
support model and its knob are swept too, with the default solver and formulation (lemke, position) at every h: the
limit surface (`support_model = "limit_surface"`) with K = 6, 14, 26 fixed twists, and the per-point model
(`"points"`) with k = 4, 8, 16, 32 friction directions (`limit_surface_resolution` stays at its default).

The reference is the finest run of Lemke with the fixed-point formulation (h_ref = the smallest swept h / 2). In the
horizontal plane it uses the limit surface with K = 62. Why that model: the table presses a uniform pressure on the
footprint, and the exact friction wrench of that pressure is the limit surface. `"limit_surface"` converges to it as
h -> 0 and K grows. `"points"` has a different limit: its 4 support points (for a box) carry the load as point loads,
not as a uniform pressure, so as k -> infinity it tends to the Coulomb law of 4 point loads. A points reference
would score the limit surface against a modelling artefact. With the limit-surface reference, the points rows measure
the points model's modelling error, and the limit-surface rows measure the discretization error of h and K. Why
K = 62: every step re-centres one twist on the current slip twist, so the fixed twists matter only when the slip
twist changes within a step, which is rare at h_ref.
tests/commands/test_tradeoff.py checks both: K = 6 gives the K = 62 reference to round-off, and K = 254 moves it by less than
half the error of the finest swept default setting.

Per setting: the velocity error, the integral over [0, t_end] of ||v_h - v_ref|| dt, and the sup-norm position error
(Stewart & Trinkle's Table 1 measures, `accuracy.table1_errors`); the deepest penetration; the energy drift (the largest
rise of the energy above its starting value, J; 0 when the energy only decreases, as it must without external work);
and the CPU cost per simulated second. The cost is the least thread CPU time (`time.thread_time`, as in `bench`) of
REPEATS warm runs (1 with --quick), divided by t_end. The clock counts no time the core spends on other processes.
"""

import csv
import hashlib
import io
import itertools
import json
import math
import sys
import time
from pathlib import Path

from planar_lcp.parallel.cluster import (SchedulerLost, SchedulerUnreachable, close_cluster, local_jobs,
                                         lost_scheduler_message, open_cluster)
from planar_lcp.parallel.records import (RECORDS, STOPPED, RecordFileError, RecordWriter, prepare, read_records,
                                         write_text_atomic)
from planar_lcp.parallel.sweep import run_recorded, say_resumed
from planar_lcp.spec.scene import FORMULATIONS, SOLVERS, SimSpec
from planar_lcp.studies.accuracy import table1_errors

DEFAULT_SCENES = ("falling_rod", "four_disks", "box_push")
SOLVER_SETTINGS = (("lemke", None), ("pgs", 5), ("pgs", 20), ("pgs", 100), ("osqp", None))
H_FACTORS = (4.0, 2.0, 1.0, 0.5, 0.25)
#: the horizontal plane's support-model sweep: (support_model, knob) with the knob K (limit_surface_twists) of the
#: limit surface or k (friction_directions) of the points model
LIMIT_SURFACE_TWISTS = (6, 14, 26)
FRICTION_DIRECTIONS = (4, 8, 16, 32)
SUPPORT_SWEEP = tuple(("limit_surface", K) for K in LIMIT_SURFACE_TWISTS) + tuple(
    ("points", k) for k in FRICTION_DIRECTIONS)
QUICK_SUPPORT_SWEEP = (("limit_surface", 6), ("limit_surface", 14), ("points", 8))
#: the reference's support model in the horizontal plane (see the module docstring)
REFERENCE_SUPPORT = ("limit_surface", 62)
#: timed warm runs per setting (the least counts); --quick times one
REPEATS = 3

COLUMNS = ["scene", "h", "solver", "pgs_iterations", "formulation", "support_model", "limit_surface_twists",
           "friction_directions", "velocity_error", "position_error", "max_penetration", "energy_drift",
           "cpu_s_per_sim_s", "failed_steps", "reference"]
#: the keys of a setting (None: not set), which with the scene name one setting's run in the record file
SETTING_KEYS = ("h", "solver", "pgs_iterations", "formulation", "support_model", "limit_surface_twists",
                "friction_directions")


def _support(model, knob):
    """The setting keys of a table-friction model (None, None: the vertical plane, no table)."""
    return dict(support_model=model, limit_surface_twists=knob if model == "limit_surface" else None,
                friction_directions=knob if model == "points" else None)


def _settings(scene, quick):
    """(scene, the swept settings, the reference setting). A setting is a dict of h, solver, pgs_iterations,
    formulation, support_model, limit_surface_twists, friction_directions (None: not set)."""
    from planar_lcp.spec.scene import load_scene
    sc = load_scene(scene)
    h0 = sc.sim.h
    horizontal = sc.world.plane == "horizontal"
    if quick:
        hs = (2.0 * h0, h0)
        solvers = (("lemke", None), ("pgs", 20))
        forms = ("position",)
        sweep = QUICK_SUPPORT_SWEEP
    else:
        hs = tuple(h0 * f for f in H_FACTORS)
        solvers, forms = SOLVER_SETTINGS, FORMULATIONS
        sweep = SUPPORT_SWEEP
    if horizontal:
        model = sc.world.support_model
        own = (model, sc.sim.limit_surface_twists if model == "limit_surface" else sc.sim.friction_directions)
    else:
        own = (None, None)
    out = []
    for h, (solver, iters), form in itertools.product(hs, solvers, forms):
        out.append(dict(h=h, solver=solver, pgs_iterations=iters, formulation=form, **_support(*own)))
    if horizontal:
        # the support model and its knob, with the default solver and formulation at every h (the scene's own
        # model is in the grid above already)
        d = SimSpec()
        for h, sup in itertools.product(hs, sweep):
            if sup != own:
                out.append(dict(h=h, solver=d.solver, pgs_iterations=None, formulation=d.formulation, **_support(*sup)))
    ref = dict(h=min(hs) / 2.0, solver="lemke", pgs_iterations=None, formulation="fixed_point",
               **_support(*(REFERENCE_SUPPORT if horizontal else (None, None))))
    return sc, out, ref


def _run(sc, s, t_end, repeats):
    """The trajectory of setting s and the least thread CPU time (s) of `repeats` warm runs."""
    from planar_lcp.sim import simulate
    kw = dict(h=s["h"], t_end=t_end, solver=s["solver"], formulation=s["formulation"], on_failure="record",
              record_contacts=False)
    for key in ("pgs_iterations", "support_model", "limit_surface_twists", "friction_directions"):
        if s[key] is not None:
            kw[key] = s[key]
    simulate(sc, **dict(kw, t_end=min(t_end, 5 * s["h"])))  # warm the JIT for this setting
    best = math.inf
    for _ in range(repeats):
        t0 = time.thread_time()
        tr = simulate(sc, **kw)
        best = min(best, time.thread_time() - t0)
    return tr, best


def _support_label(s):
    """'K=6' (the limit surface), 'points k=8', or '' (no table)."""
    if s["support_model"] == "limit_surface":
        return f"K={s['limit_surface_twists']}"
    if s["support_model"] == "points":
        return f"points k={s['friction_directions']}"
    return ""


def _item(name, s):
    """A setting's key in the record file: the scene and the setting's keys."""
    return (name, *(s[k] for k in SETTING_KEYS))


def _scene_sha256(sc):
    """The hash of a scene's file as parsed (its TOML document in canonical JSON: comments and layout do not count),
    the scene's source itself when it is not a file."""
    from planar_lcp.spec.scene import parse_toml
    try:
        text = Path(sc.source).read_text()
    except OSError:
        text = None
    doc = parse_toml(text, sc.source) if text is not None else {"source": sc.source}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def tradeoff_header(plans, quick, repeats):
    """The record file's header of a sweep: what --resume compares (the scenes by name and by their files' hash, the
    sweep's settings, --quick)."""
    items = sorted(json.dumps(_item(name, st)) for name, _, settings, _ in plans for st in settings)
    return dict(command="tradeoff", scenes=[name for name, *_ in plans],
                scene_sha256={name: _scene_sha256(sc) for name, sc, _, _ in plans}, quick=bool(quick),
                repeats=repeats, settings=len(items),
                settings_sha256=hashlib.sha256("\n".join(items).encode()).hexdigest())


def header_differences(old, new):
    """What differs between the sweep a record file was written for (`old`, its header) and the one asked (`new`):
    a list of (the file's, the command's) phrases, empty for the same sweep."""
    if old.get("command") != new["command"]:
        return [(f"planar-lcp {old.get('command')}", f"planar-lcp {new['command']}")]
    out = []
    if sorted(old.get("scenes") or []) != sorted(new["scenes"]):
        out.append((f"scenes {' '.join(old.get('scenes') or [])}", f"scenes {' '.join(new['scenes'])}"))
    if old.get("quick") != new["quick"]:
        out.append(("the --quick sweep" if old.get("quick") else "the full sweep (no --quick)",
                    "the --quick sweep" if new["quick"] else "the full sweep (no --quick)"))
    if out:
        return out
    for name in new["scenes"]:
        was = (old.get("scene_sha256") or {}).get(name)
        if was != new["scene_sha256"][name]:
            out.append((f"scene {name} as its file read then (sha256 {str(was)[:12]})",
                        f"scene {name} as it reads now (sha256 {new['scene_sha256'][name][:12]})"))
    if not out and (old.get("settings_sha256"), old.get("repeats")) != (new["settings_sha256"], new["repeats"]):
        out.append((f"a sweep of {old.get('settings')} settings, {old.get('repeats')} timed run(s) each (sha256 "
                    f"{str(old.get('settings_sha256'))[:12]})",
                    f"this version's sweep of {new['settings']} settings, {new['repeats']} timed run(s) each "
                    f"(sha256 {new['settings_sha256'][:12]})"))
    return out


def run_tradeoff(scenes=DEFAULT_SCENES, quick=False, out_dir="tradeoff", progress=True, jobs=None, scheduler=None,
                 resume=False):
    """Run the sweep; write tradeoff.csv, summary.json and one Pareto plot per scene into out_dir. Returns the rows.

    Every setting (and each scene's reference) is a Dask task: on the cluster at `scheduler`, else on a local
    cluster of `jobs` worker processes (default: the CPUs). A task's cost is its own worker's thread CPU time.

    Each setting's row is appended to `out_dir`/records.jsonl as soon as it is measured against its scene's
    reference (planar_lcp.parallel.records), and the outputs are made from those rows: at the end, and also
    when Ctrl-C, a lost scheduler or an error stops the sweep (then partial: summary.json says how many settings
    finished of how many). `resume`: the rows already in the record file are kept and only the other settings run
    (with their scenes' references again); the file must be of the same sweep, which is checked before any work,
    as is, without `resume`, that the file holds no row.

    Raises RecordFileError before any work when the record file is of another sweep (`resume`) or holds rows (not
    `resume`); after a stop, BenchmarkInterrupted (Ctrl-C) or SchedulerLost, each saying what was kept
    (planar_lcp.parallel.sweep.run_recorded).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    repeats = 1 if quick else REPEATS
    plans = [(name, *_settings(name, quick)) for name in scenes]
    header = tradeoff_header(plans, quick, repeats)
    previous = prepare(out, header, header_differences, resume, "tradeoff", "setting")     # before any work
    planned = [(_item(name, st), name, sc, st, ref) for name, sc, settings, ref in plans for st in settings]
    keys = {k for k, *_ in planned}
    done = {k: r for k, r in (previous.runs.items() if previous else ()) if k in keys}
    todo = [p for p in planned if p[0] not in done]
    say_resumed(previous, resume, out / RECORDS, len(done), len(planned), "setting")
    writer = RecordWriter(out / RECORDS, header, resume=previous)
    t0 = time.perf_counter()

    def run(live):
        if todo:
            _sweep_on_dask(todo, repeats, progress, jobs, scheduler, writer, done, t0, live, len(planned))
            close_cluster(live["client"], live["cluster"])

    run_recorded(run, writer, [k for k, *_ in planned], len(done), "setting",
                 lambda ended: _write_outputs(out, scenes, planned, partial=ended),
                 "tradeoff.csv, summary.json and the plots of their rows", t0=t0)
    return _write_outputs(out, scenes, planned)


def _sweep_on_dask(todo, repeats, progress, jobs, scheduler, writer, done, t0, live, total):
    """Run the settings `todo` ((key, scene name, scene, setting, reference setting) each) and their scenes'
    references; append each setting's row to the record file (`writer`) and to `done` once both its run and its
    reference have arrived. What it opens goes to `live` as soon as it exists: the caller closes it."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from tqdm import tqdm

    client, cluster = live["client"], live["cluster"] = open_cluster(scheduler, local_jobs(jobs))
    refs = {}
    for _, name, sc, _, ref in todo:
        if name not in refs:
            refs[name] = (sc, ref)
    futs = live["futures"] = []
    what = {}
    for name, (sc, ref) in refs.items():
        f = client.submit(_run, sc, ref, sc.sim.t_end, 1, pure=False)
        what[f.key] = ("reference", name)
        futs.append(f)
    for item in todo:
        f = client.submit(_run, item[2], item[3], item[2].sim.t_end, repeats, pure=False)
        what[f.key] = ("setting", item)
        futs.append(f)
    # disable=None: on a terminal only (a log or a pipe gets no bar frames)
    bar = live["bar"] = tqdm(total=total, initial=total - len(todo), disable=None if progress else True,
                             desc="tradeoff", unit="setting")
    ref_tr = {}
    waiting = {name: [] for name in refs}      # settings run before their scene's reference arrived

    def measured(item, tr, cpu):
        key, name, sc, s, ref_setting = item
        t_end = sc.sim.t_end
        ref_label = f"lemke/fixed_point h={ref_setting['h']:g} {_support_label(ref_setting)}".rstrip()
        verr, qerr = table1_errors(tr, ref_tr[name], t_end)
        e = tr.stats["energy"]
        row = dict(scene=name, **{k: "" if v is None else v for k, v in s.items()}, velocity_error=verr,
                   position_error=qerr, max_penetration=float(tr.stats["penetration"].max()),
                   energy_drift=float(max(0.0, (e - e[0]).max())), cpu_s_per_sim_s=cpu / t_end,
                   failed_steps=len(tr.failures), reference=ref_label)
        done[key] = writer.run(key, row, time.perf_counter() - t0)
        bar.set_postfix_str(f"{name} {s['solver']} {s['formulation']} h={s['h']:g} {_support_label(s)}")
        bar.update(1)

    for f in as_completed(futs):
        kind, item = what[f.key]
        try:
            tr, cpu = f.result()
        except FutureCancelledError as e:
            # not a result of the run: the client lost its scheduler, which cancels every future it holds
            raise SchedulerLost(lost_scheduler_message(scheduler, e)) from None
        if kind == "reference":
            ref_tr[item] = tr
            for args in waiting.pop(item):
                measured(*args)
        elif item[1] in ref_tr:
            measured(item, tr, cpu)
        else:
            waiting[item[1]].append((item, tr, cpu))


def _write_outputs(out, scenes, planned, partial=None):
    """tradeoff.csv (the rows in the sweep's order), summary.json and each scene's Pareto plot from the rows of the
    record file `out`/records.jsonl; `partial` ("interrupted", "failed"): the sweep stopped before its end, and
    summary.json says how many settings finished of how many. Returns the rows."""
    contents = read_records(out / RECORDS)
    rows = [contents.runs[k] for k, *_ in planned if k in contents.runs]
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=COLUMNS)
    w.writeheader()
    w.writerows(rows)
    write_text_atomic(out / "tradeoff.csv", buf.getvalue(), newline="")    # the csv module's own line ends
    per_scene = {name: dict(planned=sum(1 for _, n, *_ in planned if n == name),
                            finished=sum(1 for r in rows if r["scene"] == name)) for name in scenes}
    write_text_atomic(out / "summary.json", json.dumps(dict(
        command="tradeoff", scenes=list(scenes), quick=contents.header.get("quick"), planned_settings=len(planned),
        finished_settings=len(rows), complete=not partial, stopped=STOPPED.get(partial),
        invocations=contents.last_invocation,
        wall_time=sum(contents.invocation_times().values()), records_file=RECORDS, per_scene=per_scene), indent=1))
    for name in scenes:
        sub = [r for r in rows if r["scene"] == name]
        if sub:
            plot_pareto(sub, out / f"pareto_{name}.png", name)
    return rows


def pareto_front(points):
    """Indices of the non-dominated (cost, error) points, sorted by cost: no other point is cheaper AND better."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def _label(r):
    s = r["solver"] + (f"({r['pgs_iterations']})" if r["pgs_iterations"] else "")
    sup = _support_label(r)
    return f"{s} {r['formulation']} h={float(r['h']):g}" + (f" {sup}" if sup else "")


def support_series(rows):
    """The support-model series of a scene's rows: {(support_model, knob): its rows with the default solver and
    formulation, by h}, limit surface first, then points, each by knob ({} in the vertical plane). Works on rows as
    run_tradeoff returns them or as csv.DictReader reads them back."""
    d = SimSpec()
    series = {}
    for r in rows:
        if r["support_model"] and r["solver"] == d.solver and r["formulation"] == d.formulation:
            knob = r["limit_surface_twists"] if r["support_model"] == "limit_surface" else r["friction_directions"]
            series.setdefault((r["support_model"], int(knob)), []).append(r)
    order = sorted(series, key=lambda key: (key[0] != "limit_surface", key[1]))
    return {key: sorted(series[key], key=lambda r: float(r["h"])) for key in order}


def plot_pareto(rows, path, title):
    from matplotlib import colormaps
    from matplotlib.lines import Line2D

    from planar_lcp.viz import new_figure
    fig = new_figure((11, 6.5))
    ax = fig.add_subplot(1, 1, 1)
    markers = dict(zip(SOLVERS, ("o", "s", "^")))
    colors = dict(zip(FORMULATIONS, ("C0", "C1", "C2")))
    floor = 1e-12
    pts = [(float(r["cpu_s_per_sim_s"]), max(float(r["velocity_error"]), floor)) for r in rows]
    series = support_series(rows)
    grid_alpha = 0.35 if series else 0.6
    for r, (c, e) in zip(rows, pts):
        ax.scatter(c, e, marker=markers[r["solver"]], color=colors[r["formulation"]], alpha=grid_alpha, s=30)
    handles = [Line2D([], [], marker=m, ls="", color="gray", label=k) for k, m in markers.items()]
    handles += [Line2D([], [], marker="o", ls="", color=c, label=k) for k, c in colors.items()]
    legend = ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                       title="solver, formulation", title_fontsize=8)
    if series:
        # one line per support model and knob across h: blues for the limit surface, reds for the points model,
        # darker and another marker for a larger knob
        d = SimSpec()
        ax.add_artist(legend)
        shandles = []
        for model, cmap, marks in (("limit_surface", "Blues", "Dhp"), ("points", "Reds", "XvP*")):
            keys = [key for key in series if key[0] == model]
            for j, key in enumerate(keys):
                color = colormaps[cmap](0.45 + 0.5 * j / max(1, len(keys) - 1))
                marker = marks[j % len(marks)]
                sr = series[key]
                xs = [float(r["cpu_s_per_sim_s"]) for r in sr]
                ys = [max(float(r["velocity_error"]), floor) for r in sr]
                name = f"limit surface K={key[1]}" if model == "limit_surface" else f"points k={key[1]}"
                shandles += ax.plot(xs, ys, ls="-", lw=1.2, marker=marker, ms=6, color=color, label=name)
        ax.legend(handles=shandles, fontsize=8, loc="lower left", bbox_to_anchor=(1.01, 0.0),
                  title=f"support model\n({d.solver}, {d.formulation};\nh grows to the left)", title_fontsize=8)
    front = pareto_front(pts)
    ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "k-", lw=1)
    for i in front:
        ax.annotate(_label(rows[i]), pts[i], fontsize=7, xytext=(4, 2), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("CPU seconds per simulated second")
    ax.set_ylabel("velocity error  integral ||v_h - v_ref|| dt")
    what = "marker = solver, colour = formulation; black line = Pareto front"
    if series:
        what += ";\nlines = the table-friction support model and its knob across h"
    ax.set_title(f"{title}: speed/accuracy ({what})", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _cmd(args):
    from planar_lcp.cli_support import InputError, prepare_output_dir, require
    from planar_lcp.spec.scene import list_scenes
    require("distributed")                 # the runs are Dask tasks: checked before any work
    known = [n for n, _ in list_scenes()]
    bad = [n for n in args.scenes if n not in known]
    if bad:
        print(f"planar-lcp tradeoff: error: unknown scene {bad[0]!r} (shipped: {', '.join(known)})", file=sys.stderr)
        return 2
    if len(set(args.scenes)) != len(args.scenes):
        # a row is named by its scene and setting (records.jsonl, --resume)
        print(f"planar-lcp tradeoff: error: --scenes must be distinct, got {' '.join(args.scenes)}", file=sys.stderr)
        return 2
    if args.scheduler is not None and args.jobs is not None:
        print(f"planar-lcp tradeoff: error: --jobs sizes the local cluster: not with --scheduler {args.scheduler}",
              file=sys.stderr)
        return 2
    try:
        prepare_output_dir(args.out, "--out")
    except InputError as e:
        print(f"planar-lcp tradeoff: error: {e}", file=sys.stderr)
        return 2
    try:
        rows = run_tradeoff(scenes=tuple(args.scenes), quick=args.quick, out_dir=args.out,
                            progress=not args.no_progress, jobs=args.jobs, scheduler=args.scheduler,
                            resume=args.resume)
    except RecordFileError as e:
        print(f"planar-lcp tradeoff: error: {e}", file=sys.stderr)        # before any work: nothing was written
        return 2
    except (SchedulerUnreachable, SchedulerLost) as e:
        print(f"planar-lcp tradeoff: error: {e}", file=sys.stderr)
        return 1
    print(f"{len(rows)} settings; wrote {Path(args.out) / 'tradeoff.csv'} and the Pareto plots")
    for name in args.scenes:
        sub = [r for r in rows if r["scene"] == name]
        front = pareto_front([(r["cpu_s_per_sim_s"], r["velocity_error"]) for r in sub])
        print(f"{name}: Pareto front (cheapest first)")
        for i in front:
            r = sub[i]
            print(f"  {_label(r):50s} cost {r['cpu_s_per_sim_s']:.3g} s/s  velocity error {r['velocity_error']:.3g}  "
                  f"penetration {r['max_penetration']:.2g} m")
    return 0


def register(sub):
    from planar_lcp.cli_support import add_command, finite_number
    p = add_command(sub, "tradeoff", _cmd, help="measure the speed/accuracy trade of h, solver, formulation and, in "
                                                "the horizontal plane, the support model and its knob")
    p.add_argument("--scenes", nargs="+", default=list(DEFAULT_SCENES), metavar="SCENE",
                   help=f"scenes to sweep (default: {' '.join(DEFAULT_SCENES)})")
    p.add_argument("--quick", action="store_true", help="two step sizes, lemke and pgs(20), position form only, "
                   "limit surface K=6 and 14 and points k=8, one timed run")
    p.add_argument("--out", default="tradeoff", metavar="DIR", help="output directory (default ./tradeoff)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--jobs", type=finite_number(int, 0, True), default=None, metavar="J",
                   help="worker processes of the local Dask cluster (default: CPUs)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on the Dask cluster at ADDRESS instead of a local one (docs/planning.md, "
                        "\"Distributed benchmarks\")")
    p.add_argument("--resume", action="store_true",
                   help="finish the sweep whose finished rows --out holds (records.jsonl, written as each setting "
                        "finishes): only the missing settings run; --scenes and --quick must be the same")
