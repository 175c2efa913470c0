"""Fitting a scene's parameters to recorded runs: least squares of predicted against recorded poses.

    result = planar_lcp.fit(scene_doc, recordings, params=["bodies.box.support_friction", "world.friction"])

Each recording (`planar_lcp.spec.recordings.RecordedRun`: times and the poses of bodies the scene names) is simulated
with the scene: its kinematic bodies follow their recorded poses (`path`), its dynamic bodies start at rest at their
first recorded poses, and the run lasts the recording. The residuals are, at every recorded sample (or every
`every`-th) and for every observed (dynamic) body, the predicted minus the recorded x, y and length_scale times the
angle; scipy's least squares minimises their sum of squares over the named parameters (docs/real_pushes.md,
"Fitting").

A parameter is named by where it sits in the scene document: `world.KEY` or `sim.KEY`, `bodies.NAME.KEY` (e.g.
`bodies.box.support_friction`), `friction_pairs.A.B` (the coefficient of the pair A-B in world.friction_pairs), or any
name with a setter of your own (`setters={"name": fn(doc, value)}`, e.g. a ring of support points of a given
radius). The uncertainties are from the Jacobian J at the optimum: `stderr` the classical sqrt(diag(s^2 (J'J)^-1)),
right when the residuals are independent noise of one variance; `stderr_by_run` clusters the residuals by recording
(a sandwich estimator: the samples of one real run share its model error, so they are not independent), which needs
many recordings that each inform every parameter (with few, or a parameter that only some runs inform, it
understates).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["FitResult", "fit", "predict_run", "run_scene", "set_param"]


def set_param(doc: dict, name: str, value: float, setters=None) -> None:
    """Write parameter `name` = value into the scene document `doc` (in place); KeyError naming what is missing."""
    if setters and name in setters:
        setters[name](doc, value)
        return
    parts = name.split(".")
    if parts[0] in ("world", "sim") and len(parts) == 2:
        doc.setdefault(parts[0], {})[parts[1]] = float(value)
    elif parts[0] == "bodies" and len(parts) == 3:
        for b in doc.get("bodies", []):
            if b.get("name") == parts[1]:
                b[parts[2]] = float(value)
                return
        raise KeyError(f"parameter {name!r}: no body named {parts[1]!r} in the scene")
    elif parts[0] == "friction_pairs" and len(parts) == 3:
        pairs = doc.setdefault("world", {}).setdefault("friction_pairs", [])
        for p in pairs:
            if {p.get("a"), p.get("b")} == {parts[1], parts[2]}:
                p["mu"] = float(value)
                return
        pairs.append({"a": parts[1], "b": parts[2], "mu": float(value)})
    else:
        raise KeyError(f"parameter {name!r}: expected world.KEY, sim.KEY, bodies.NAME.KEY, friction_pairs.A.B or a "
                       f"name in setters")


def run_scene(doc: dict, recording) -> dict:
    """The scene document of one recording's run: a copy of `doc` whose kinematic bodies follow their recorded
    poses (`path`, times from the recording's first row), whose dynamic bodies named by the recording start at rest
    at their first recorded poses, and whose run lasts the recording (`sim.t_end`)."""
    out = copy.deepcopy(doc)
    t = np.asarray(recording.t, dtype=np.float64) - float(recording.t[0])
    names = list(recording.names)
    for b in out["bodies"]:
        if b.get("name") not in names:
            continue
        pose = np.asarray(recording.poses)[:, names.index(b["name"])]
        for key in ("position", "angle", "angle_deg", "velocity", "angular_velocity"):
            b.pop(key, None)
        if b.get("type") == "kinematic":
            b["path"] = np.column_stack([t, pose]).tolist()
        elif b.get("type") == "dynamic":
            b["position"] = [float(pose[0, 0]), float(pose[0, 1])]
            b["angle"] = float(pose[0, 2])
    out.setdefault("sim", {})["t_end"] = float(t[-1])
    return out


def _observed(doc: dict, recording) -> list:
    dynamic = {b["name"] for b in doc["bodies"] if b.get("type") == "dynamic"}
    return [n for n in recording.names if n in dynamic]


def predict_run(doc: dict, recording, **sim_options):
    """(t, poses): the recording's times from its first row (T,) and the predicted poses (T, nobs, 3) of its
    observed (dynamic) bodies there, in their order in the recording, interpolated linearly between steps (the
    angle continuous). Runs `planar_lcp.simulate` on `run_scene(doc, recording)` with on_failure="record"."""
    from planar_lcp.sim import simulate

    from planar_lcp.spec.scene import SceneError

    scene_doc = run_scene(doc, recording)
    try:
        traj = simulate(scene_doc, on_failure="record", record_contacts=False, **sim_options)
    except SceneError as e:
        # e.g. a start where the recorded poses overlap: the recording is named, not a "<dict>"
        raise SceneError(f"recording {getattr(recording, 'source', '?')}: {e}") from None
    t = np.asarray(recording.t, dtype=np.float64) - float(recording.t[0])
    idx = [traj.body_names.index(name) for name in _observed(doc, recording)]
    return t, _interpolated(t, traj.t, traj.q[:, idx])


def _interpolated(t, run_t, series):
    """series (len(run_t), ...) at the times t, linearly between the run's steps, each trailing entry on its own."""
    flat = series.reshape(len(run_t), -1)
    out = np.empty((len(t), flat.shape[1]))
    for c in range(flat.shape[1]):
        out[:, c] = np.interp(t, run_t, flat[:, c])
    return out.reshape((len(t),) + series.shape[1:])


def _recorded(doc, recording):
    """The recorded poses (T, nobs, 3) of the recording's observed bodies, in `_observed`'s order."""
    names = list(recording.names)
    return np.asarray(recording.poses)[:, [names.index(n) for n in _observed(doc, recording)]]


def _kept(a, recording, every, length_scale):
    """a (T, nobs, 3, ...) at the samples the residuals keep (`_residuals_size`), its angle entries times
    length_scale."""
    out = a[_residuals_size(recording, every)]
    out[:, :, 2] *= length_scale
    return out


def _residuals_by_derivatives(doc, recording, every, length_scale, sim_options, params):
    """The residual vector of one recording (as `_residuals`, bit for bit) and its Jacobian with respect to the
    scene parameters `params` (rows the residuals, one column per name), by `rollout_derivatives` over the run
    `predict_run` simulates (each step's by its checked differences, the dual numbers where their checks fail): each
    predicted pose's derivative interpolated as the pose is."""
    from planar_lcp.derivatives import rollout_derivatives
    from planar_lcp.frames import frame_state
    from planar_lcp.sim import Simulator, run_setup
    from planar_lcp.spec.path import kinematic_velocities
    setup = run_setup(run_scene(doc, recording), record_contacts=False, **sim_options)
    model, opts, n = setup.model, setup.options, setup.nsteps
    sim = Simulator(model, opts)
    vk_seq = kinematic_velocities(model.scene, model.kin_names, opts.h, n)
    try:
        r = rollout_derivatives(sim, model.q0, model.v0, model.qk0, vk_seq, n, params, method="differences")
    except RuntimeError as e:
        raise RuntimeError(f"recording {getattr(recording, 'source', '?')}: {e}") from None
    nd, p = model.ndyn, len(params)
    # the body frame's poses and their derivatives: a pose's derivative turns into the frame's as a velocity does
    # (the origin's offset from the COM turns with the angle), one parameter's at a time on the leading axis
    dq_com = np.moveaxis(r.dx_dp_steps[:, :3 * nd, :].reshape(n + 1, nd, 3, p), -1, 0)
    q_frame, dq_frame = frame_state(r.q, dq_com, model.com_local)
    idx = [model.dyn_names.index(name) for name in _observed(doc, recording)]
    t = np.asarray(recording.t, dtype=np.float64) - float(recording.t[0])
    traj_t = np.arange(n + 1) * opts.h
    pred = _interpolated(t, traj_t, q_frame[:, idx])
    dpred = _interpolated(t, traj_t, np.moveaxis(dq_frame, 0, -1)[:, idx])
    d = _kept(pred - _recorded(doc, recording), recording, every, length_scale)
    return d.reshape(-1), _kept(dpred, recording, every, length_scale).reshape(-1, p)


def _residuals(doc, recording, every, length_scale, sim_options):
    """The residual vector of one recording (predicted minus recorded x, y, length_scale * angle per sample kept)."""
    _, pred = predict_run(doc, recording, **sim_options)
    return _kept(pred - _recorded(doc, recording), recording, every, length_scale).reshape(-1)


@dataclass
class FitResult:
    """A fit's outcome. values, stderr, stderr_by_run by parameter name (module docstring); cost: half
    the sum of squared residuals (m^2); per_run: per recording, its rms and final position (m) and angle (rad)
    errors at the fitted values; nfev: simulations of all the recordings (a derivative run of them counts one);
    message: scipy's."""

    params: tuple
    values: dict
    stderr: dict
    stderr_by_run: dict
    covariance: np.ndarray
    cost: float
    per_run: list
    nfev: int
    success: bool
    message: str
    settings: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"params": list(self.params), "values": self.values, "stderr": self.stderr,
                "stderr_by_run": self.stderr_by_run, "covariance": self.covariance.tolist(), "cost": self.cost,
                "per_run": self.per_run, "nfev": self.nfev, "success": self.success, "message": self.message,
                "settings": self.settings}


def _run_errors(doc, recording, sim_options):
    _, pred = predict_run(doc, recording, **sim_options)
    rec = _recorded(doc, recording)
    pos = np.hypot(*(pred[..., :2] - rec[..., :2]).transpose(2, 0, 1))
    ang = np.abs(pred[..., 2] - rec[..., 2])
    return {"source": str(getattr(recording, "source", "")), "rms_position": float(np.sqrt(np.mean(pos ** 2))),
            "rms_angle": float(np.sqrt(np.mean(ang ** 2))), "final_position": float(pos[-1].max()),
            "final_angle": float(ang[-1].max())}


def fit(scene, recordings, params, *, x0=None, bounds=None, setters=None, every=1, length_scale=None,
        map_runs=None, progress=None, max_nfev=200, diff_step=1e-4, jacobian="differences",
        **sim_options) -> FitResult:
    """Least squares of predicted against recorded poses over many recordings, for the named scene parameters.

    Parameters
    ----------
    scene : dict, a sequence of dicts (one per recording), or a function
        The scene document(s) (a TOML file's document, e.g. `planar_lcp.spec.scene.read_document(path)[0]`) whose
        named places the parameters are written to; or a function (i, {name: value}) -> the scene document of
        recording i at those values (then `x0` is required and `setters` unused), for parameters that change more
        than one key (e.g. `planar_lcp.studies.pushdata.mit.push_scene`'s support ring).
    recordings : sequence of RecordedRun
        Times and poses of bodies the scene names: kinematic ones are inputs, dynamic ones observations.
    params : sequence of str
        The parameters' names (module docstring); their starting values are `x0` (default: read from the first
        scene document, e.g. its body's support_friction) and their bounds `bounds` ((lo, hi) per parameter,
        default (0, inf)).
    every : int
        Keep every `every`-th sample of each recording in the residuals (and its last).
    length_scale : float
        m per rad in the residuals (default: the mean gyration radius of the shapes of the FIRST recording's observed
        bodies, so that an angle error weighs as the displacement of a typical point; give it for recordings of
        objects of different sizes). `FitResult.settings` records the one used.
    map_runs : callable(fn, list of args) -> list
        How the recordings' runs are evaluated (default: in this process, in order); e.g. a Dask client's map.
    progress : callable(evaluations_done) or None
    jacobian : "differences" or "derivatives"
        How the residuals' Jacobian is found: forward differences (steps `diff_step` times max(|x|, 0.01); one run
        of every recording per parameter), or the step's derivatives (`Simulator.rollout_derivatives`, each step's
        by its checked differences, the dual numbers where their checks fail: one derivative run of every
        recording; parameters named as `planar_lcp.derivatives.scene_param` names them, the scene given as
        documents and no `setters`).
    sim_options : keywords for `planar_lcp.simulate` (h, solver, support_model, ...).

    Notes
    -----
    The result is deterministic: the same inputs give the same values bit for bit.
    """
    from scipy.optimize import least_squares

    recordings = list(recordings)
    if not recordings:
        raise ValueError("fit: no recordings")
    params = tuple(params)
    if not params:
        raise ValueError("fit: no parameters to fit")
    build = scene if callable(scene) else None
    if build is None:
        docs = list(scene) if isinstance(scene, (list, tuple)) else [scene] * len(recordings)
        if len(docs) != len(recordings):
            raise ValueError(f"fit: {len(docs)} scenes for {len(recordings)} recordings; give one scene or one per "
                             f"recording")
    elif x0 is None:
        raise ValueError("fit: a scene given as a function needs x0, the parameters' starting values")
    if jacobian not in ("differences", "derivatives"):
        raise ValueError(f"fit: jacobian must be 'differences' or 'derivatives', got {jacobian!r}")
    if jacobian == "derivatives" and (build is not None or setters):
        raise ValueError("fit: jacobian='derivatives' differentiates named scene parameters (planar_lcp.derivatives."
                         "scene_param): give the scene as documents and no setters")
    if x0 is None:
        x0 = [_read_param(docs[0], p) for p in params]
    x0 = np.asarray(x0, dtype=np.float64)
    lo, hi = (np.zeros(len(params)), np.full(len(params), np.inf)) if bounds is None else map(
        np.asarray, zip(*bounds))
    if build is not None:
        docs = [build(i, dict(zip(params, map(float, x0)))) for i in range(len(recordings))]
    if length_scale is None:
        length_scale = _mean_gyration(docs, recordings)
    every = max(1, int(every))
    mapper = map_runs or (lambda fn, args: [fn(*a) for a in args])
    evaluations = [0]

    def with_values(i, x):
        if build is not None:
            return build(i, dict(zip(params, map(float, x))))
        d = copy.deepcopy(docs[i])
        for name, value in zip(params, x):
            set_param(d, name, value, setters)
        return d

    def residuals_at(xs):
        """The residual vectors at several parameter points, every run of every point in one batch."""
        jobs = [(with_values(i, x), rec, every, length_scale, sim_options) for x in xs
                for i, rec in enumerate(recordings)]
        parts = mapper(_residuals, jobs)
        evaluations[0] += len(xs)
        if progress is not None:
            progress(evaluations[0])
        n = len(recordings)
        return [np.concatenate(parts[i * n:(i + 1) * n]) for i in range(len(xs))], parts

    cache = {}

    def fun(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = residuals_at([x])[0][0]
        return cache[key]

    def jac(x):
        if jacobian == "derivatives":
            jobs = [(with_values(i, x), rec, every, length_scale, sim_options, params)
                    for i, rec in enumerate(recordings)]
            parts = mapper(_residuals_by_derivatives, jobs)
            evaluations[0] += 1
            if progress is not None:
                progress(evaluations[0])
            return np.vstack([J for _, J in parts])
        # forward differences, all parameters' runs in one batch; a step into a bound goes the other way
        steps = diff_step * np.maximum(np.abs(x), 1e-2)
        xs = []
        for i in range(len(x)):
            xi = x.copy()
            xi[i] = x[i] + steps[i] if x[i] + steps[i] <= hi[i] else x[i] - steps[i]
            steps[i] = xi[i] - x[i]
            xs.append(xi)
        cols, _ = residuals_at(xs)
        r0 = fun(x)
        return np.column_stack([(c - r0) / s for c, s in zip(cols, steps)])

    res = least_squares(fun, np.clip(x0, lo, hi), jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                        max_nfev=max_nfev, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    J, r = res.jac, res.fun
    m, p = J.shape
    JtJ_inv = np.linalg.pinv(J.T @ J)
    s2 = float(r @ r) / max(1, m - p)
    cov_iid = s2 * JtJ_inv
    # clustered by recording: the sandwich (J'J)^-1 (sum_k J_k' r_k r_k' J_k) (J'J)^-1
    sizes = [len(_residuals_size(rec, every)) * 3 * len(_observed(doc, rec)) for doc, rec in zip(docs, recordings)]
    meat = np.zeros((p, p))
    start = 0
    for size in sizes:
        g = J[start:start + size].T @ r[start:start + size]
        meat += np.outer(g, g)
        start += size
    k = len(recordings)
    cov = JtJ_inv @ meat @ JtJ_inv * (k / max(1, k - 1))
    # the errors at the fitted values, run as the residuals were (a Dask cluster's map when given)
    per_run = mapper(_run_errors, [(with_values(i, res.x), rec, sim_options) for i, rec in enumerate(recordings)])
    names = list(params)
    return FitResult(params=params, values=dict(zip(names, map(float, res.x))),
                     stderr=dict(zip(names, map(float, np.sqrt(np.diag(cov_iid))))),
                     stderr_by_run=dict(zip(names, map(float, np.sqrt(np.diag(cov))))),
                     covariance=cov_iid, cost=float(res.cost), per_run=per_run, nfev=evaluations[0],
                     success=bool(res.success), message=str(res.message),
                     settings={"every": every, "length_scale": float(length_scale), "jacobian": jacobian,
                               "sim_options": {k2: v for k2, v in sim_options.items()}})


def _residuals_size(recording, every):
    """The indices of the samples the residuals keep: every `every`-th, and the final pose always."""
    n = len(recording.t)
    keep = np.arange(0, n, every)
    return keep if keep[-1] == n - 1 else np.append(keep, n - 1)


def _read_param(doc, name):
    parts = name.split(".")
    try:
        if parts[0] in ("world", "sim") and len(parts) == 2:
            return float(doc[parts[0]][parts[1]])
        if parts[0] == "bodies" and len(parts) == 3:
            return float(next(b for b in doc["bodies"] if b.get("name") == parts[1])[parts[2]])
        if parts[0] == "friction_pairs" and len(parts) == 3:
            return float(next(p["mu"] for p in doc["world"]["friction_pairs"]
                              if {p["a"], p["b"]} == {parts[1], parts[2]}))
    except (KeyError, StopIteration, TypeError):
        pass
    raise KeyError(f"parameter {name!r}: the scene gives no starting value; pass x0")


def _mean_gyration(docs, recordings):
    from planar_lcp.spec.massprops import body_area_properties
    from planar_lcp.spec.scene import parse_scene

    radii = []
    for doc, rec in zip(docs[:1], recordings[:1]):
        scene = parse_scene(run_scene(doc, rec))
        for name in _observed(doc, rec):
            area, _, polar = body_area_properties(scene.body(name))
            radii.append(math.sqrt(polar / area))
    return float(np.mean(radii)) if radii else 1.0
