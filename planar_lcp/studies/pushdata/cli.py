"""`planar-lcp pushdata predict` and `planar-lcp pushdata fit`: recorded pushes of the MIT pushing data set simulated
with the pusher on its recorded path, scored against the recorded object, and the model's friction fitted to them
(docs/real_pushes.md, "Predicting a push" and "Fitting").

predict: each push's scene (`mit.push_scene` with the model's parameters) simulated on its recording
(`planar_lcp.fitting.predict_run`), the predicted object pose at every recorded object sample written as CSV (columns
file, t, x, y, theta), optionally a figure per push, and the scores of `score` printed. A push whose simulation fails
is named; the others are written, and the command exits 1.

fit: every push file below the folders given, `planar_lcp.fitting.fit` of the named parameters (least squares of the
predicted against the recorded object poses), in this process or on Dask (a local cluster or --scheduler), written as
a model file (`model_file`).

Bad input is refused before any work, one line, exit status 2.
"""

from __future__ import annotations

import math
import shlex
import sys
import time
from pathlib import Path

PROG = "planar-lcp pushdata"
#: the model's parameters that are keys of the scene document `mit.push_scene` writes (`planar_lcp.fitting`'s names);
#: any other parameter is written by rebuilding the scene with `mit.push_scene` (fit's setters)
SCENE_KEYS = {"support_friction": "bodies.object.support_friction", "pusher_friction": "world.friction",
              "h": "sim.h"}
#: parameters `fit` does not take (the time step is the simulation's, not the world's)
NOT_FITTED = ("h",)
DEFAULT_FIT_PARAMS = ("support_friction", "pusher_friction")
#: the instants at which a push's figure draws the object's outline
OUTLINE_INSTANTS = 6
#: fit's forward-difference step, relative to each parameter's value (planar_lcp.fitting.fit's diff_step): a
#: simulated push is not smooth in its frictions at small scales (contacts change mode, a pivot goes another way), and
#: on the data set's 42 training pushes fitting's default of 1e-4 (a step of 2.5e-5 in a friction of 0.25) stops at
#: its start, where 1e-2 and 5e-2 find the minimum a scan of the cost shows (docs/real_pushes.md, "Fitting")
FIT_DIFF_STEP = 1e-2


class _Failed(Exception):
    """A push whose simulation failed: the message names why."""


def _error(prog, message, status=2):
    sys.stdout.flush()
    print(f"{prog}: error: {message}", file=sys.stderr)
    return status


# ---------------------------------------------------------------------------------------------------------------
# Inputs


def _check_push_file(path):
    """A push file given on the command line: it exists, is a file, ends in .h5 and is named as the data set's are.
    InputError otherwise."""
    from planar_lcp.cli_support import InputError
    from planar_lcp.studies.pushdata.mit import PushDataError, parse_push_name

    p = Path(path)
    if not p.exists():
        raise InputError(f"{path}: no such file")
    if p.is_dir():
        raise InputError(f"{path}: must be a push file (*.h5), got a directory")
    if p.suffix.lower() != ".h5":
        raise InputError(f"{path}: must be a push file of the data set (*.h5), got {p.suffix or 'no extension'!r}")
    try:
        parse_push_name(p)
    except PushDataError as e:
        raise InputError(str(e)) from None
    return p


def _no_repeated_names(files):
    from planar_lcp.cli_support import InputError
    seen = {}
    for f in files:
        if f.name in seen:
            what = "given twice" if f.resolve() == seen[f.name].resolve() else f"given twice ({seen[f.name]} and {f})"
            raise InputError(f"{f.name}: {what}: the outputs name a push by its file name")
        seen[f.name] = f


def _load(files):
    """(pushes, models): each file read (`mit.read_push`) and its object registered (`mit.object_model`, once per
    object). InputError naming the file for one that cannot be read or registered."""
    from planar_lcp.cli_support import InputError
    from planar_lcp.studies.pushdata import mit

    pushes, models = [], []
    try:
        for f in files:
            push = mit.read_push(f)
            pushes.append(push)
        for push in pushes:
            models.append(mit.object_model(push.shape, push.root))
    except mit.PushDataError as e:
        raise InputError(str(e)) from None
    return pushes, models


def _scenes(pushes, models, params):
    """The scene document and the recording of each push (`mit.push_scene` with `params`, `mit.push_recording`);
    InputError naming the file where one cannot be made (e.g. a start overlap deeper than the reconciliation takes)."""
    from planar_lcp.cli_support import InputError
    from planar_lcp.studies.pushdata import mit

    docs, recs = [], []
    try:
        for push, model in zip(pushes, models):
            docs.append(mit.push_scene(push, params, model=model))
            recs.append(mit.push_recording(push, model))
    except mit.PushDataError as e:
        raise InputError(str(e)) from None
    return docs, recs


def _registrations(pushes, models):
    """One line per object: how its outline was registered."""
    lines, seen = [], set()
    for push, model in zip(pushes, models):
        if model.shape in seen:
            continue
        seen.add(model.shape)
        used = sum(o is not None for o in model.onsets)
        lines.append(f"object         {model.shape}: outline registered from the contact onsets of {used} of its "
                     f"{len(model.files)} pushes (RMS {1000 * model.registration.rms:.2f} mm)")
    return lines


def _params_text(params):
    return ", ".join(f"{k} {v:g}" for k, v in params.items())


# ---------------------------------------------------------------------------------------------------------------
# predict


def predict_push(doc, recording):
    """(t (T,), predicted object poses (T, 3), recorded ones (T, 3), CPU seconds) of one push; _Failed when its
    simulation fails."""
    import numpy as np

    from planar_lcp.studies.pushdata.mit import OBJECT
    from planar_lcp.fitting import predict_run
    from planar_lcp.sim import SimulationError
    from planar_lcp.spec.scene import SceneError

    c0 = time.process_time()
    try:
        t, pred = predict_run(doc, recording)
    except (SimulationError, SceneError) as e:
        raise _Failed(str(e)) from None
    cpu = time.process_time() - c0
    pred = pred[:, 0]
    if not np.isfinite(pred).all():
        raise _Failed(f"the simulated pose is not finite from t = {t[np.argmax(~np.isfinite(pred).all(axis=1))]:g} s")
    rec = np.asarray(recording.poses)[:, recording.index(OBJECT)]
    return t, pred, rec, cpu


def write_predictions_csv(path, rows):
    """The CSV of `predict`: columns file, t, x, y, theta; `rows` is a list of (file name, t (T,), poses (T, 3))."""
    import csv
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["file", "t", "x", "y", "theta"])
        for name, t, poses in rows:
            for tk, (x, y, th) in zip(t, poses):
                w.writerow([name, repr(float(tk)), repr(float(x)), repr(float(y)), repr(float(th))])


def _table(results):
    """The per-push lines of predict and fit: final, rms and max errors (mm, deg) and CPU s."""
    width = max(len(r["file"]) for r in results)
    lines = [f"{'push':<{width}}  {'final mm':>8}  {'final deg':>9}  {'rms mm':>7}  {'rms deg':>7}  {'max mm':>7}  "
             f"{'max deg':>7}  {'CPU s':>6}"]
    for r in results:
        cpu = f"{r['cpu_s']:6.2f}" if r.get("cpu_s") is not None else f"{'-':>6}"
        lines.append(f"{r['file']:<{width}}  {1000 * r['final_position_error_m']:8.2f}  "
                     f"{math.degrees(r['final_angle_error_rad']):9.2f}  {1000 * r['rms_position_m']:7.2f}  "
                     f"{math.degrees(r['rms_angle_rad']):7.2f}  {1000 * r['max_position_m']:7.2f}  "
                     f"{math.degrees(r['max_angle_rad']):7.2f}  {cpu}")
    return lines


def _push_result(push, t, pred, rec, cpu):
    """The scores of one push (m, rad), as `per_push` of a model file holds them."""
    from planar_lcp.studies.pushdata import score
    d_pred, d_rec = score.final_displacement(pred), score.final_displacement(rec)
    pos, ang = score.final_errors(d_pred[None], d_rec[None])
    along = score.along_push_errors(pred, rec)
    return {"file": Path(push.path).name, "object": push.shape, "samples": int(len(t)),
            "final_position_error_m": float(pos[0]), "final_angle_error_rad": float(ang[0]),
            "rms_position_m": along["rms_position"], "max_position_m": along["max_position"],
            "rms_angle_rad": along["rms_angle"], "max_angle_rad": along["max_angle"],
            "recorded_displacement": [float(v) for v in d_rec], "predicted_displacement": [float(v) for v in d_pred],
            "cpu_s": None if cpu is None else float(cpu)}


def _summary_lines(results):
    """The summary of a set of pushes' results: NMSE of the final displacements and the median final errors."""
    import numpy as np

    from planar_lcp.studies.pushdata import score
    pred = np.array([r["predicted_displacement"] for r in results])
    rec = np.array([r["recorded_displacement"] for r in results])
    s = score.summary(pred, rec)
    objects = {}
    for r in results:
        objects[r["object"]] = objects.get(r["object"], 0) + 1
    what = ", ".join(f"{k} {v}" for k, v in sorted(objects.items()))
    if len(results) < 2 or not all(math.isfinite(c) for c in s["nmse_components"]):
        nmse = "n/a: the recorded final displacements must vary (2 pushes at least)"
    else:
        dx, dy, dth = s["nmse_components"]
        nmse = f"{s['nmse']:.3f} (dx {dx:.3f}, dy {dy:.3f}, dtheta {dth:.3f}) of the final displacements"
    return s, [f"pushes         {len(results)} ({what})",
               f"NMSE           {nmse}",
               f"median error   {1000 * s['median_position_error']:.2f} mm, "
               f"{math.degrees(s['median_angle_error']):.2f} deg at the end of the push"]


def _cmd_predict(args):
    from planar_lcp.cli_support import InputError, MissingPackage
    try:
        return _predict(args)
    except InputError as e:
        return _error(f"{PROG} predict", e)
    except MissingPackage as e:
        return _error(f"{PROG} predict", e)


def _predict(args):
    from planar_lcp.cli_support import ProgressBar, check_output_file, prepare_output_dir, require
    from planar_lcp.studies.pushdata import mit
    from planar_lcp.studies.pushdata.model_file import ModelFileError, read_model
    from planar_lcp.cli_support import InputError

    prog = f"{PROG} predict"
    require("h5py", "scipy")
    if args.plots is not None:
        require("matplotlib")
    check_output_file(args.csv, "--csv", (".csv",))
    files = [_check_push_file(f) for f in args.files]
    _no_repeated_names(files)
    if args.model is not None:
        try:
            model_file = read_model(args.model)
        except ModelFileError as e:
            raise InputError(f"--model {e}") from None
        params, where = model_file.parameters, args.model
    else:
        params, where = dict(mit.DEFAULT_PARAMS), "mit.DEFAULT_PARAMS"
    if args.plots is not None:
        prepare_output_dir(args.plots, "--plots")
    pushes, models = _load(files)
    docs, recs = _scenes(pushes, models, params)

    print(f"model          {where}: {_params_text(params)}", flush=True)
    for line in _registrations(pushes, models):
        print(line, flush=True)
    bar = ProgressBar(prog, unit="push")
    results, rows, failed, curves = [], [], [], []
    try:
        for k, (push, doc, rec) in enumerate(zip(pushes, docs, recs)):
            try:
                t, pred, recorded, cpu = predict_push(doc, rec)
            except _Failed as e:
                failed.append((Path(push.path).name, str(e)))
            else:
                results.append(_push_result(push, t, pred, recorded, cpu))
                rows.append((Path(push.path).name, t, pred))
                curves.append((push, models[k], rec, pred))
            bar(k + 1, len(pushes))
    finally:
        bar.close()

    wrote = []
    try:
        write_predictions_csv(args.csv, rows)
        wrote.append(args.csv)
        if args.plots is not None:
            for (push, model, rec, pred), r in zip(curves, results):
                path = Path(args.plots) / (Path(push.path).stem + ".png")
                plot_push(path, push, model, rec, pred, r)
                wrote.append(str(path))
    except OSError as e:
        return _error(prog, f"cannot write {e.filename or ''}: {e.strerror or e}", 1)

    if results:
        for line in _table(results):
            print(line)
        _, lines = _summary_lines(results)
        for line in lines:
            print(line)
    for name, why in failed:
        print(f"failed         {name}: {why}")
    for w in wrote:
        print(f"wrote          {w}")
    if failed:
        names = ", ".join(n for n, _ in failed)
        return _error(prog, f"{len(failed)} of {len(pushes)} pushes failed to simulate ({names}); the others are "
                            f"written", 1)
    return 0


def plot_push(path, push, model, recording, pred, result):
    """A push's figure (PNG): the recorded (solid) and predicted (dashed) paths of the object's centre (its
    outline's centroid) and the pusher's path, the outline (and a tick along the body's x axis from the centre) at
    OUTLINE_INSTANTS instants recorded (solid) and predicted (dashed), with the pusher there, mm, equal aspect; the
    title gives the file's parameters and the final errors."""
    import numpy as np

    from planar_lcp.studies.pushdata.mit import OBJECT, PUSHER, PUSHER_RADIUS
    from planar_lcp.studies.pushdata.outline import centroid
    from planar_lcp.viz import new_figure

    rec = np.asarray(recording.poses)[:, recording.index(OBJECT)]
    tip = np.asarray(recording.poses)[:, recording.index(PUSHER), :2]
    c = centroid(model.outline)

    def placed(points, pose):
        x, y, th = pose
        R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        return (np.asarray(points) @ R.T + (x, y)) * 1000.0

    def centres(poses):
        return np.array([placed(c[None], p)[0] for p in poses])

    fig = new_figure((7.5, 6.5), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    closed = np.vstack([model.outline, model.outline[:1]])
    instants = np.unique(np.linspace(0, len(rec) - 1, OUTLINE_INSTANTS).round().astype(int))
    shades = np.linspace(0.35, 1.0, len(instants))
    for k, a in zip(instants, shades):
        o = placed(closed, rec[k])
        ax.plot(o[:, 0], o[:, 1], "-", color="tab:blue", alpha=a, lw=1.0,
                label="recorded outline" if k == instants[0] else None)
        o = placed(closed, pred[k])
        ax.plot(o[:, 0], o[:, 1], "--", color="tab:red", alpha=a, lw=1.0,
                label="predicted outline" if k == instants[0] else None)
        # a tick along the body's x axis from the centre: the turn, which a round outline does not show
        reach = 0.4 * float(np.max(np.linalg.norm(model.outline - c, axis=1)))
        for poses, style, color in ((rec, "-", "tab:blue"), (pred, "--", "tab:red")):
            tick = placed(np.array([c, c + (reach, 0.0)]), poses[k])
            ax.plot(tick[:, 0], tick[:, 1], style, color=color, alpha=a, lw=0.8)
        circle = np.column_stack([np.cos(np.linspace(0, 2 * np.pi, 40)), np.sin(np.linspace(0, 2 * np.pi, 40))])
        d = (tip[k] + PUSHER_RADIUS * circle) * 1000.0
        ax.plot(d[:, 0], d[:, 1], "-", color="0.3", alpha=a, lw=0.8)
    rc, pc = centres(rec), centres(pred)
    ax.plot(rc[:, 0], rc[:, 1], "-", color="tab:blue", lw=2.0, label="recorded centre")
    ax.plot(pc[:, 0], pc[:, 1], "--", color="tab:red", lw=2.0, label="predicted centre")
    ax.plot(tip[:, 0] * 1000.0, tip[:, 1] * 1000.0, "-", color="0.3", lw=1.2, label="pusher")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(loc="best", fontsize=7)
    n = push.name
    err_mm, err_deg = 1000 * result["final_position_error_m"], math.degrees(result["final_angle_error_rad"])
    ax.set_title(f"{Path(push.path).name}\n{n.shape} on {n.surface}: v = {n.v:g} mm/s, side {n.i}, s = {n.s:g}, "
                 f"t = {n.t:g} rad ({math.degrees(n.t):.0f} deg)\nfinal error {err_mm:.2f} mm, {err_deg:.2f} deg; "
                 f"outlines at {len(instants)} instants (recorded solid, predicted dashed)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, format="png")


# ---------------------------------------------------------------------------------------------------------------
# fit


class PushDoc(dict):
    """A push's scene document (`mit.push_scene`) that remembers its push (`index`) and the values of the parameters
    that are not scene keys (`values`), so that a setter can rebuild it (`fit_setup`)."""

    index: int = -1
    values: dict = {}


def _read_key(doc, key):
    parts = key.split(".")
    if parts[0] == "bodies":
        return float(next(b for b in doc["bodies"] if b.get("name") == parts[1])[parts[2]])
    return float(doc[parts[0]][parts[1]])


def fit_setup(pushes, models, names, start, via_setters=()):
    """What `planar_lcp.fitting.fit` takes to fit the model's parameters `names` from `start` (all of
    mit.DEFAULT_PARAMS' keys): (docs, fit names, setters, x0, bounds).

    A parameter that is a key of the scene document (SCENE_KEYS) is fitted under that key's name; any other (or one
    in `via_setters`) under its own name, with a setter that rebuilds the push's document with `mit.push_scene` at the
    values it holds (the scene keys read back from the document), so that a parameter pushing several keys (e.g. a
    support pressure) is written as `push_scene` writes it."""
    from planar_lcp.studies.pushdata import mit
    from planar_lcp.studies.pushdata.model_file import RANGES

    by_setter = [n for n in names if n not in SCENE_KEYS or n in via_setters]
    docs = []
    for i, (push, model) in enumerate(zip(pushes, models)):
        d = PushDoc(mit.push_scene(push, start, model=model))
        d.index, d.values = i, {k: float(v) for k, v in start.items() if k not in SCENE_KEYS}
        docs.append(d)

    def setter(name):
        def put(doc, value):
            values = dict(doc.values)
            values.update({k: _read_key(doc, key) for k, key in SCENE_KEYS.items()})
            values[name] = float(value)
            new = mit.push_scene(pushes[doc.index], values, model=models[doc.index])
            doc.clear()
            doc.update(new)
            doc.values = {k: v for k, v in values.items() if k not in SCENE_KEYS}
        return put

    fit_names = [n if n in by_setter else SCENE_KEYS[n] for n in names]
    setters = {n: setter(n) for n in by_setter}
    x0 = [float(start[n]) for n in names]
    bounds = []
    for n in names:
        lo, lo_in, hi, hi_in = RANGES.get(n, (-math.inf, True, math.inf, True))
        bounds.append((lo if lo_in else lo + 1e-9, hi if hi_in else hi))
    return docs, fit_names, setters, x0, bounds


def collect_push_files(dirs):
    """Every *.h5 below the folders `dirs` (recursively), sorted by path, each once. InputError for a folder that
    does not exist, is a file or holds none."""
    from planar_lcp.cli_support import InputError
    files = {}
    for d in dirs:
        p = Path(d)
        if not p.exists():
            raise InputError(f"{d}: no such directory")
        if not p.is_dir():
            raise InputError(f"{d}: must be a directory of push files (*.h5), got a file")
        found = [f for f in p.rglob("*") if f.suffix.lower() == ".h5" and f.is_file()]
        if not found:
            raise InputError(f"{d}: holds no push files (*.h5)")
        for f in found:
            files.setdefault(str(f.resolve()), f)
    return [files[k] for k in sorted(files)]


def _command_line(args):
    parts = ["planar-lcp", "pushdata", "fit", *args.dirs, "--out", args.out, "--params", ",".join(args.params),
             "--every", str(args.every)]
    if args.scheduler is not None:
        parts += ["--scheduler", args.scheduler]
    else:
        parts += ["--jobs", str(args.jobs)]
    for s in args.exclude_shape or ():
        parts += ["--exclude-shape", s]
    return shlex.join(str(p) for p in parts)


def _parse_params(text):
    from planar_lcp.cli_support import InputError
    from planar_lcp.studies.pushdata.mit import DEFAULT_PARAMS
    known = [k for k in DEFAULT_PARAMS if k not in NOT_FITTED]
    names = [n.strip() for n in text.split(",")]
    if not all(names):
        raise InputError(f"--params must be parameter names separated by commas, got {text!r}")
    for n in names:
        if n in NOT_FITTED:
            raise InputError(f"--params: {n} is the simulation's time step, not a parameter to fit (fitted: "
                             f"{', '.join(known)})")
        if n not in DEFAULT_PARAMS:
            raise InputError(f"--params: unknown parameter {n!r} (known: {', '.join(known)})")
    if len(set(names)) != len(names):
        raise InputError(f"--params must be distinct, got {text!r}")
    return names


class _FitProgress:
    """The progress bar of a fit (planar_lcp.cli_support.ProgressBar on stderr: a terminal only, after 2 s): the simulated
    runs, and the evaluations (parameter points) done."""

    def __init__(self, n_runs):
        from planar_lcp.cli_support import ProgressBar
        self.bar, self.runs, self.n_runs = ProgressBar(f"{PROG} fit", unit="run"), 0, n_runs

    def run_done(self):
        self.runs += 1
        self.bar(self.runs, None)

    def evaluation(self, n):
        if self.bar.bar is not None:
            self.bar.bar.set_postfix_str(f"{n} evaluation{'s' if n != 1 else ''} of {self.n_runs} pushes")

    def close(self):
        self.bar.close()


def local_map(progress):
    """fit's map_runs in this process, in order."""
    from planar_lcp.interrupt import raise_if_interrupted

    def map_runs(fn, jobs):
        out = []
        for job in jobs:
            out.append(fn(*job))
            progress.run_done()
            raise_if_interrupted()
        return out
    return map_runs


def dask_map(client, progress):
    """fit's map_runs on a Dask client: every run a task (pure=False), the results in the jobs' order. The scene
    documents go as plain dicts."""
    def map_runs(fn, jobs):
        from distributed import as_completed
        jobs = [(dict(j[0]),) + tuple(j[1:]) for j in jobs]
        futures = client.map(fn, *zip(*jobs), pure=False)
        for _ in as_completed(futures):
            progress.run_done()
        return client.gather(futures)
    return map_runs


def _predict_job(doc, recording):
    """A run of the predictions after a fit (a Dask task): `predict_push`'s answer, None if it failed."""
    try:
        return predict_push(dict(doc), recording)
    except _Failed:
        return None


def _cmd_fit(args):
    from planar_lcp.cli_support import InputError, MissingPackage
    from planar_lcp.parallel.cluster import SchedulerLost, SchedulerUnreachable
    try:
        return _fit(args)
    except (InputError, MissingPackage) as e:
        return _error(f"{PROG} fit", e)
    except (SchedulerUnreachable, SchedulerLost) as e:
        return _error(f"{PROG} fit", e, 1)


def _fit(args):
    from planar_lcp.cli_support import InputError, check_output_file, require
    from planar_lcp.studies.pushdata import mit
    from planar_lcp.studies.pushdata.model_file import ModelFileError, read_model

    require("h5py", "scipy")
    if args.scheduler is not None and args.jobs_given:
        raise InputError(f"--jobs sizes the local cluster: not with --scheduler {args.scheduler}")
    parallel = args.scheduler is not None or args.jobs > 1
    if parallel:
        require("distributed")
    check_output_file(args.out, "--out", (".json",))
    names = _parse_params(args.params)
    args.params = names
    files = collect_push_files(args.dirs)
    for f in files:
        _check_push_file(f)
    _no_repeated_names(files)
    shapes = sorted({mit.parse_push_name(f).shape for f in files})
    for s in args.exclude_shape or ():
        if s not in shapes:
            raise InputError(f"--exclude-shape {s}: no push of {s!r} in {' '.join(args.dirs)} (objects: "
                             f"{', '.join(shapes)})")
    files = [f for f in files if mit.parse_push_name(f).shape not in set(args.exclude_shape or ())]
    if not files:
        raise InputError(f"--exclude-shape leaves no push to fit (objects: {', '.join(shapes)})")
    start, where = dict(mit.DEFAULT_PARAMS), "mit.DEFAULT_PARAMS"
    if args.start is not None:
        try:
            start, where = read_model(args.start).parameters, args.start
        except ModelFileError as e:
            raise InputError(f"--start {e}") from None
    pushes, models = _load(files)
    _scenes(pushes, models, start)               # every push makes a scene: checked before the work
    docs, fit_names, setters, x0, bounds = fit_setup(pushes, models, names, start)
    recs = [mit.push_recording(p, m) for p, m in zip(pushes, models)]

    counts = {}
    for p in pushes:
        counts[p.shape] = counts.get(p.shape, 0) + 1
    objects = ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
    print(f"fitting        {', '.join(names)} from {_params_text({n: start[n] for n in names})} ({where})",
          flush=True)
    print(f"pushes         {len(pushes)} of {len(counts)} object(s): {objects}", flush=True)
    for line in _registrations(pushes, models):
        print(line, flush=True)
    return _run_fit(args, names, start, pushes, models, docs, recs, fit_names, setters, x0, bounds)


def _run_fit(args, names, start, pushes, models, docs, recs, fit_names, setters, x0, bounds):
    from planar_lcp.parallel.cluster import (SchedulerLost, close_cluster, local_jobs, lost_scheduler_message,
                                                open_cluster, sigint_ignored)
    from planar_lcp.fitting import fit

    parallel = args.scheduler is not None or args.jobs > 1
    progress = _FitProgress(len(pushes))
    client = cluster = None
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        if parallel:
            client, cluster = open_cluster(args.scheduler, local_jobs(args.jobs, len(pushes)))
            workers = client.scheduler_info()["workers"]
            print(f"cluster        {args.scheduler or 'local'}: {len(workers)} worker(s)", flush=True)
            mapper = dask_map(client, progress)
        else:
            mapper = local_map(progress)
        result = fit(docs, recs, fit_names, x0=x0, bounds=bounds, setters=setters, every=args.every,
                     map_runs=mapper, progress=progress.evaluation, diff_step=FIT_DIFF_STEP)
        # the predictions at the fitted values, for the scores
        fitted = dict(start)
        fitted.update({n: result.values[fn] for n, fn in zip(names, fit_names)})
        final_docs, _ = _scenes(pushes, models, fitted)
        preds = mapper(_predict_job, list(zip(final_docs, recs)))
    except BaseException as e:
        # Ctrl-C, a lost scheduler, any error: the cluster is stopped quietly, the command's line is the last
        with sigint_ignored():
            progress.close()
            close_cluster(client, cluster, quiet=True)
        if parallel and type(e).__name__ == "FutureCancelledError":
            # the client lost its scheduler, which cancels every future it holds
            raise SchedulerLost(lost_scheduler_message(args.scheduler, e)) from None
        raise
    progress.close()
    close_cluster(client, cluster)
    return _report_fit(args, names, start, pushes, result, fit_names, bounds, fitted, preds,
                       time.perf_counter() - t0, time.process_time() - c0)


def _report_fit(args, names, start, pushes, result, fit_names, bounds, fitted, preds, wall, cpu):
    from planar_lcp.studies.pushdata.model_file import write_model

    results, failed = [], []
    for push, p in zip(pushes, preds):
        if p is None:
            failed.append(Path(push.path).name)
        else:
            results.append(_push_result(push, *p))
    stderr = {n: result.stderr[fn] for n, fn in zip(names, fit_names)}
    by_run = {n: result.stderr_by_run[fn] for n, fn in zip(names, fit_names)}
    scores = None
    if results:
        s, summary = _summary_lines(results)
        scores = {"nmse": s["nmse"], "nmse_components": s["nmse_components"],
                  "median_position_error_m": s["median_position_error"],
                  "median_angle_error_rad": s["median_angle_error"]}
    settings = {"start": start, "fitted": list(names), "fit_names": dict(zip(names, fit_names)),
                "every": result.settings["every"], "length_scale_m": result.settings["length_scale"],
                "diff_step": FIT_DIFF_STEP, "bounds": dict(zip(names, map(list, bounds))),
                "evaluations": result.nfev, "success": result.success, "message": result.message,
                "jobs": None if args.scheduler else args.jobs, "scheduler": args.scheduler, "wall_s": wall,
                "cpu_s_this_process": cpu}
    write_model(args.out, fitted, stderr=stderr, stderr_by_run=by_run,
                fitted_on=[Path(p.path).name for p in pushes], objects=sorted({p.shape for p in pushes}),
                cost=result.cost, per_push=results, settings=settings, scores=scores, command=_command_line(args))
    if results:
        for line in _table(results):
            print(line)
    print(f"fit            {result.nfev} evaluations of {len(pushes)} pushes in {wall:.1f} s; {result.message}")
    width = max(len(n) for n in names)
    for n in names:
        print(f"  {n:<{width}} = {fitted[n]:.6g} +- {stderr[n]:.2g} (by push: +- {by_run[n]:.2g})")
    print(f"cost           {result.cost:.6g} m^2 (half the sum of squared residuals)")
    if results:
        print("at the fitted values:")
        for line in summary[1:]:
            print(line)
    for name in failed:
        print(f"failed         {name}: its simulation at the fitted values failed")
    print(f"wrote          {args.out}")
    if failed:
        return _error(f"{PROG} fit", f"{len(failed)} of {len(pushes)} pushes failed to simulate at the fitted values "
                                     f"({', '.join(failed)}); their errors are not in {args.out}", 1)
    return 0


# ---------------------------------------------------------------------------------------------------------------
# The parsers


def register(subparsers):
    import argparse

    from planar_lcp.cli_support import add_command, finite_number

    p = add_command(
        subparsers, "pushdata",
        help="recorded pushes (the MIT pushing data set): predict them, fit the model's friction",
        description="Recorded pushes of the MIT pushing data set (Yu et al. 2016; docs/real_pushes.md): simulate "
                    "them with the pusher on its recorded path and score the predicted object against the recorded "
                    "one (predict), or fit the model's parameters to them (fit). Needs the extra 'pushdata'.")
    sub = p.add_subparsers(dest="pushdata_command", required=True, metavar="{predict,fit}")

    pr = add_command(
        sub, "predict", _cmd_predict,
        help="simulate recorded pushes and write the predicted object poses (CSV), figures and scores",
        description="Simulate each push with the pusher on its recorded path (mit.push_scene with the model's "
                    "parameters) and write the predicted object pose at every recorded object sample: CSV columns "
                    "file, t (s from the push's first object sample), x, y (m, the data's frame), theta (rad, "
                    "continuous from the recorded start angle). Prints each push's final, rms and max position and "
                    "angle errors and CPU time, then the final displacements' NMSE and the median final errors. A "
                    "push whose simulation fails is named and left out; the others are written, exit status 1.")
    pr.add_argument("files", nargs="+", metavar="FILE.h5", help="push files of the data set")
    pr.add_argument("--model", metavar="MODEL.json",
                    help="the parameters (a model file, as `pushdata fit` writes; default mit.DEFAULT_PARAMS)")
    pr.add_argument("--csv", required=True, metavar="OUT.csv", help="the predicted poses (columns file,t,x,y,theta)")
    pr.add_argument("--plots", metavar="DIR",
                    help="a figure per push, DIR/<file stem>.png: recorded and predicted paths and outlines, mm")

    class _Jobs(argparse.Action):
        def __call__(self, parser, namespace, values, option_string=None):
            setattr(namespace, self.dest, values)
            namespace.jobs_given = True

    ft = add_command(
        sub, "fit", help="fit the model's parameters (default: the two frictions) to recorded pushes; write MODEL.json",
        description="Fit the named parameters of mit.push_scene to every push file (*.h5) below the folders given "
                    "(sorted by path), by least squares of the predicted against the recorded object poses "
                    "(planar_lcp.fitting.fit), from mit.DEFAULT_PARAMS; write the model file (values, standard "
                    "errors, per-push errors, the command line). --jobs N > 1 or --scheduler: the simulations run on "
                    "Dask, with the same result bit for bit.")
    ft.add_argument("dirs", nargs="+", metavar="DIR", help="folders of push files (searched recursively)")
    ft.add_argument("--out", required=True, metavar="MODEL.json", help="the model file to write")
    ft.add_argument("--params", default=",".join(DEFAULT_FIT_PARAMS), metavar="NAME,NAME",
                    help=f"the parameters to fit, separated by commas (default {','.join(DEFAULT_FIT_PARAMS)})")
    ft.add_argument("--start", metavar="MODEL.json", help="start from this model file's parameters (the local "
                    "minimum least squares finds depends on the start; default mit.DEFAULT_PARAMS); the parameters "
                    "not fitted keep their values from it too")
    ft.add_argument("--every", type=finite_number(int, 1, False), default=1, metavar="K",
                    help="keep every K-th recorded sample of each push (and its last) in the residuals (default 1)")
    ft.add_argument("--jobs", type=finite_number(int, 1, False), default=1, action=_Jobs, metavar="N",
                    help="worker processes of a local Dask cluster (127.0.0.1); 1 (default): in this process")
    ft.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="run the simulations on the Dask cluster at ADDRESS (e.g. tcp://127.0.0.1:8786)")
    ft.add_argument("--exclude-shape", nargs="+", action="extend", default=None, metavar="SHAPE",
                    help="leave out the pushes of these objects (e.g. butter, kept for testing)")
    ft.set_defaults(func=_cmd_fit, jobs_given=False)
    return p
