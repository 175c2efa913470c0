"""Derivatives of the time step: Jacobians of (q+, v+, qk+) with respect to the state, the kinematic velocities and
named scene parameters, at the step's certified LCP basis (docs/method.md, "Derivatives of the step").

    d = sim.step_derivatives(q, v, qk, vk, params=["world.friction"])
    d.dv_dv, d.dv_dq, d.dv_dvk, d.dv_dp[:, 0], d.exact, d.degenerate

The step's own code runs on forward-mode dual numbers (forward.py): every branch as the compiled step takes it, every
value bit for bit the compiled step's, and each LCP answer's derivatives those of its basis's linear solve, or at a
degenerate answer its directional derivatives (the derivative LCP). Run once along +e_k and once along -e_k, it gives
the one-sided derivatives along every input. Where they agree, no LCP answer is non-unique in a way the inputs
break, no contact sits on a switch of its geometry and the compiled step's one-sided differences agree with them,
the step is differentiable and these are its derivatives: `exact` is True. Elsewhere `jacobian` is the mean of the
two sides and `degenerate` says where and why.

With method="differences" the step's checked central differences answer instead, in one compiled call
(differences.py: tens of times faster, about 1e-6 of the Jacobian's scale), where their checks say they stand for
the derivatives; elsewhere the dual numbers do. With method="one_sided" the same, but where the checked differences
find a switch at the state the compiled step's one-sided differences answer (not exact; near the one-sided
derivatives where no second switch lies within their step, docs/method.md; `degenerate` names the inputs, not the
contact), the dual numbers only where those fail too: compiled, two steps per input, for gradients whose use checks
its own outcome (planners.refine).

Scene parameters are named as `planar_lcp.fit` names them (`world.friction`, `world.restitution`,
`bodies.NAME.mass`, `bodies.NAME.inertia`, `bodies.NAME.support_friction`, `friction_pairs.A.B`,
`restitution_pairs.A.B`): the compiled model's arrays they change are differentiated by central differences of the
compile (the arrays are linear or rational in them: error about 1e-10 relative), the step on from there by duals.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from planar_lcp.derivatives import forward
from planar_lcp.derivatives.differences import (checked_differences, first_try, one_sided_differences,
                                                param_differences)
from planar_lcp.derivatives.dual import Dual, grads, values, with_derivatives
from planar_lcp.engine.layout import Stat
from planar_lcp.engine.rollout import (DIFF_MOVES, DIFF_NONFINITE, DIFF_OK, DIFF_REASONS, SIDE_LEFT_ONLY,
                                       SIDE_RIGHT_ONLY, SIDES_DIFFER)
from planar_lcp.engine.step import FORM_VELOCITY, STEP_LCP_FAILED, STEP_NONFINITE, STEP_OK
from planar_lcp.errors import SimulationError

__all__ = ["Degenerate", "StepDerivatives", "RolloutDerivatives", "step_derivatives", "rollout_derivatives",
           "scene_with_param", "scene_param"]

#: the pose step (m or rad, times max(1, |coordinate|)) of the one-sided differences that find a contact on a switch
#: of its geometry, and how much the two sides' rates may differ (relative): far above the collision kernel's
#: tolerance (1e-10 of the coordinates) and its round-off, far below a real switch's O(1) change of rate
SWITCH_STEP = 1e-7
SWITCH_RTOL = 1e-3


@dataclass(frozen=True)
class Degenerate:
    """Why a step is not differentiable at the point (docs/method.md, "Derivatives of the step"): `kind`
    ("complementarity", "tie", "non-unique", "geometry", "switch", "unbounded", "failed", "uncertified", "solver",
    "parameter", "mixed", "sides", "structure"), `where` (the contact, LCP unknown or input, by body names) and
    `detail`."""

    kind: str
    where: str
    detail: str

    def __str__(self):
        return f"{self.kind} at {self.where}: {self.detail}"


@dataclass
class StepDerivatives:
    """The Jacobians of one step (q, v, qk, vk) -> (q+, v+, qk+) over the flattened states.

    States flatten row-major: q, v (ndyn, 3) -> 3 ndyn entries (body 0's x, y, theta, then body 1's, ...); qk, vk
    (nkin, 3) -> 3 nkin. `dA_dB` is d(A+)/dB, shape (size of A, size of B): e.g. dv_dq (3 ndyn, 3 ndyn); dq_dp,
    dv_dp, dqk_dp have one column per name in `params`. Units follow the states' (m, rad, m/s, rad/s) and the
    parameters' own.
    """

    q: np.ndarray
    v: np.ndarray
    qk: np.ndarray
    status: int
    jacobian: np.ndarray            # (3 ndyn + 3 ndyn + 3 nkin, 6 ndyn + 6 nkin + len(params))
    ndyn: int
    nkin: int
    params: tuple = ()
    exact: bool = True
    degenerate: tuple = ()
    #: the one-sided derivatives along each input (+e_k and -e_k); `jacobian` is their mean, which is what central
    #: differences converge to; equal where `exact`
    jacobian_right: np.ndarray | None = None
    jacobian_left: np.ndarray | None = None
    #: how they were computed: "dual" (the step on dual numbers), "differences" (checked central differences of
    #: the compiled step) or "one_sided" (its one-sided differences, at a switch); `fallback`: why a "differences" or
    #: "one_sided" request did not take the checked differences ("" otherwise)
    method: str = "dual"
    fallback: str = ""

    def _block(self, out, inp):
        n, k = 3 * self.ndyn, 3 * self.nkin
        rows = {"q": slice(0, n), "v": slice(n, 2 * n), "qk": slice(2 * n, 2 * n + k)}[out]
        o = 2 * n + 2 * k
        cols = {"q": slice(0, n), "v": slice(n, 2 * n), "qk": slice(2 * n, 2 * n + k),
                "vk": slice(2 * n + k, o), "p": slice(o, o + len(self.params))}[inp]
        return self.jacobian[rows, cols]

    dq_dq = property(lambda s: s._block("q", "q"))
    dq_dv = property(lambda s: s._block("q", "v"))
    dq_dqk = property(lambda s: s._block("q", "qk"))
    dq_dvk = property(lambda s: s._block("q", "vk"))
    dq_dp = property(lambda s: s._block("q", "p"))
    dv_dq = property(lambda s: s._block("v", "q"))
    dv_dv = property(lambda s: s._block("v", "v"))
    dv_dqk = property(lambda s: s._block("v", "qk"))
    dv_dvk = property(lambda s: s._block("v", "vk"))
    dv_dp = property(lambda s: s._block("v", "p"))
    dqk_dq = property(lambda s: s._block("qk", "q"))
    dqk_dv = property(lambda s: s._block("qk", "v"))
    dqk_dqk = property(lambda s: s._block("qk", "qk"))
    dqk_dvk = property(lambda s: s._block("qk", "vk"))
    dqk_dp = property(lambda s: s._block("qk", "p"))

    @property
    def state_jacobian(self):
        """d(q+, v+, qk+)/d(q, v, qk): the square block a rollout's chain multiplies."""
        n = 6 * self.ndyn + 3 * self.nkin
        return self.jacobian[:, :n]


# --- scene parameters --------------------------------------------------------------------------------------------

def _pair_entry(pairs, a, b):
    for i, (x, y, _) in enumerate(pairs):
        if {x, y} == {a, b}:
            return i
    return -1


def scene_param(scene, name):
    """The value of the scene parameter `name` (module docstring); KeyError naming what is missing."""
    parts = name.split(".")
    if parts[0] == "world" and len(parts) == 2 and parts[1] in ("friction", "restitution", "damping",
                                                                   "support_gravity"):
        return float(getattr(scene.world, parts[1]))
    if parts[0] == "bodies" and len(parts) == 3 and parts[2] in ("mass", "inertia", "support_friction"):
        b = scene.body(parts[1])
        val = getattr(b, parts[2])
        if val is None:
            raise KeyError(f"parameter {name!r}: body {parts[1]!r} gives no {parts[2]} (it is computed from its "
                           "shapes or taken from the world); name the key the scene sets")
        return float(val)
    if parts[0] in ("friction_pairs", "restitution_pairs") and len(parts) == 3:
        f = scene.friction_between if parts[0] == "friction_pairs" else scene.restitution_between
        return float(f(parts[1], parts[2]))
    raise KeyError(f"parameter {name!r}: expected world.friction, world.restitution, world.damping, "
                   "world.support_gravity, bodies.NAME.mass, bodies.NAME.inertia, bodies.NAME.support_friction, "
                   "friction_pairs.A.B or restitution_pairs.A.B")


def scene_with_param(scene, name, value):
    """The scene with parameter `name` set to `value` (a new Scene; module docstring for the names)."""
    scene_param(scene, name)                    # the name's check
    parts = name.split(".")
    value = float(value)
    if parts[0] == "world":
        return dataclasses.replace(scene, world=dataclasses.replace(scene.world, **{parts[1]: value}))
    if parts[0] == "bodies":
        bodies = tuple(dataclasses.replace(b, **{parts[2]: value}) if b.name == parts[1] else b
                       for b in scene.bodies)
        return dataclasses.replace(scene, bodies=bodies)
    pairs = list(getattr(scene.world, parts[0]))
    i = _pair_entry(pairs, parts[1], parts[2])
    if i >= 0:
        pairs[i] = (pairs[i][0], pairs[i][1], value)
    else:
        pairs.append((parts[1], parts[2], value))
    return dataclasses.replace(scene, world=dataclasses.replace(scene.world, **{parts[0]: tuple(pairs)}))


def _compile_like(model, scene):
    """`scene` compiled with the settings `model` was compiled with (its table friction's)."""
    from planar_lcp.engine.constants import SUPPORT_POINTS
    from planar_lcp.model import compile_scene
    from planar_lcp.spec.scene import SUPPORT_MODELS
    a = model.arrays
    points = int(a.support_model) == SUPPORT_POINTS
    return compile_scene(scene, friction_directions=a.fric_dirs.shape[0] if points else None,
                         seed_friction_arm=bool(a.seed_friction_arm),
                         support_model=SUPPORT_MODELS[int(a.support_model)],
                         limit_surface_twists=None if points else a.ls_wrench.shape[1])


#: the last model's parameter compiles (`param_compiles`) and arrays with parameter derivatives
#: (`_model_with_param_derivatives`): a rollout's steps share them
_param_models = {}


def _remember(key, model, *value):
    """Keep value under key, with the entries of this model only (a fit makes a model per guess)."""
    if any(entry[0] is not model for entry in _param_models.values()):
        _param_models.clear()
    _param_models[key] = (model, *value)


def param_compiles(model, params):
    """For each parameter: (name, lo, hi, {field: (array at hi, array at lo, array as compiled)} for the model's
    float arrays it changes), the model compiled with the parameter at hi and lo (central differences:
    p0 +- 1e-5 max(|p0|, 1e-3), one-sided into the physical range at a coefficient of 0); and the Degenerate notes
    of one-sided ones. Made once per model and parameters."""
    key = ("compiles", id(model), tuple(params))
    known = _param_models.get(key)
    if known is not None and known[0] is model:
        return known[1]
    arrays = model.arrays
    notes = []
    out = []
    for name in params:
        p0 = scene_param(model.scene, name)
        dp = 1e-5 * max(abs(p0), 1e-3)
        lo = p0 - dp
        if p0 >= 0.0 and lo < 0.0:
            # a coefficient at 0 (no friction, no restitution): the one-sided derivative into the physical range
            lo = p0
            notes.append(Degenerate("parameter", name, f"{name} = 0: the derivative is one-sided (towards > 0) and "
                                    "the step at 0 has no friction or restitution rows to differentiate"))
        hi = p0 + dp
        mp = _compile_like(model, scene_with_param(model.scene, name, hi)).arrays
        mm = _compile_like(model, scene_with_param(model.scene, name, lo)).arrays
        changed = {}
        for fname in arrays._fields:
            a0 = getattr(arrays, fname)
            if not (isinstance(a0, np.ndarray) and a0.dtype == np.float64):
                continue
            ap, am = getattr(mp, fname), getattr(mm, fname)
            if ap.shape != a0.shape or am.shape != a0.shape:
                raise ValueError(f"parameter {name!r} changes the model's {fname} shape {a0.shape}: its derivative "
                                 "is not defined (a parameter must not change the scene's structure)")
            if np.any(ap != a0) or np.any(am != a0):
                changed[fname] = (ap, am, a0.copy())
        out.append((name, lo, hi, changed))
    got = (out, notes)
    _remember(key, model, got)
    return got


def _model_with_param_derivatives(model, params, first, k, ncols):
    """model.arrays with the float arrays the parameters change as object arrays of duals (their derivatives by
    central differences of the compile, columns first, first + 1, ... of the k inputs along +e, and k + first, ...
    along -e, of ncols >= 2 k: the columns past 2 k, the mixed direction's, move no parameter). Made once per model
    and parameters (the step reads them, never writes)."""
    arrays = model.arrays
    if not params:
        return arrays, []
    key = (id(model), tuple(params), first, k, ncols)
    known = _param_models.get(key)
    if known is not None and known[0] is model:
        return known[1], list(known[2])
    compiles, notes = param_compiles(model, params)
    derivs = {}
    for i, (name, lo, hi, changed) in enumerate(compiles):
        for fname, (ap, am, _) in changed.items():
            diff = (ap - am) / (hi - lo)
            if np.any(diff):
                d = derivs.setdefault(fname, np.zeros(ap.shape + (ncols,)))
                d[..., first + i] = diff                 # the direction +e (module docstring: both signs)
                d[..., k + first + i] = -diff
    replaced = {f: with_derivatives(getattr(arrays, f), d) for f, d in derivs.items()}
    out = arrays._replace(**replaced)
    _remember(key, model, out, notes)
    return out, list(notes)


# --- the step ----------------------------------------------------------------------------------------------------

def _check_state(sim, q, v, qk, vk):
    """The state's arrays as aligned C-contiguous float64 of the model's shapes (ValueError naming the one that is
    not): the types the compiled kernels' entry points take (engine/entry.py); their finiteness is
    `_check_finite`'s."""
    q, v, qk, vk = [a if a.flags.aligned else a.copy() for a in (np.ascontiguousarray(q, dtype=np.float64),
                    np.ascontiguousarray(v, dtype=np.float64), np.ascontiguousarray(qk, dtype=np.float64),
                    np.ascontiguousarray(vk, dtype=np.float64))]
    m = sim.model
    dyn, kin = (len(m.dyn_names), 3), (len(m.kin_names), 3)
    if q.shape != dyn or v.shape != dyn or qk.shape != kin or vk.shape != kin:
        for name, a, rows in (("q", q, dyn), ("v", v, dyn), ("qk", qk, kin), ("vk", vk, kin)):
            if a.shape != rows:
                raise ValueError(f"step_derivatives: {name} must have shape {rows}, got {a.shape}")
    return q, v, qk, vk


def _check_finite(q, v, qk, vk):
    """ValueError naming the first of the state's arrays that is not finite (the differences' kernel tests the
    entries itself, for a few microseconds less)."""
    for name, a in (("q", q), ("v", v), ("qk", qk), ("vk", vk)):
        if not np.isfinite(a).all():
            raise ValueError(f"step_derivatives: {name} must be finite")


def _contact_name(model, pair):
    a = model.arrays
    names = [b.name for b in model.scene.bodies]
    sa, sb = int(a.pair_a[pair]), int(a.pair_b[pair])
    return f"contact {names[int(a.shape_body[sa])]}-{names[int(a.shape_body[sb])]}"


def _lcp_index_name(model, layout, i):
    """What LCP unknown i of an island (or of the velocity form's projection) is, by body names: the blocks of
    engine/assemble.py, z = [c_n | beta (contacts) | beta (table) | lambda (contacts) | lambda (table) | lags]."""
    a = model.arrays
    names = [b.name for b in model.scene.bodies]
    if layout is None:
        return f"LCP unknown {i}"
    if layout[0] == "projection":
        return f"the projection's normal impulse of {_contact_name(model, int(layout[1][i]))}"
    _, pairs, sups, _, _ = layout
    nci, nsi = len(pairs), len(sups)
    fric = [c for c in range(nci) if a.pair_mu[pairs[c]] > 0.0]
    nf = len(fric)
    k = model.support_columns()
    table = lambda s: f"table friction of {names[int(a.dyn_body[int(a.sup_dyn[int(sups[s])])])]}"
    if i < nci:
        return f"normal impulse of {_contact_name(model, int(pairs[i]))}"
    i -= nci
    if i < 2 * nf:
        return f"friction impulse ({'+' if i % 2 == 0 else '-'}t) of {_contact_name(model, int(pairs[fric[i // 2]]))}"
    i -= 2 * nf
    if i < k * nsi:
        return f"column {i % k} of the {table(i // k)}"
    i -= k * nsi
    if i < nf:
        return f"sliding speed (friction slack) of {_contact_name(model, int(pairs[fric[i]]))}"
    i -= nf
    if i < nsi:
        return f"sliding speed of the {table(i)}"
    return "lag of a force-limited kinematic body"


def _geometry_switches(model, q_hat, qk_lin, con_pair, con_p, con_cn, ncon, margin, impulse_tol):
    """Loaded contacts whose geometry (gap, normal, point) sits on a switch of the contact kernel's branches: a box
    flat on a box of the same width (which face gives the normal), a vertex at the end of the face it touches, a
    contact count that changes. Found by one-sided differences of the kernel (compiled: `contacts_at`) along each
    pose coordinate of the contact's bodies: where the two sides' rates differ, the step's derivatives do too."""
    from planar_lcp.engine.constants import BODY_DYNAMIC, BODY_KINEMATIC
    from planar_lcp.engine.contacts import contacts_at
    a = model.arrays
    m = model.struct
    out = []
    seen = set()

    def geometry(pair, point, q, qk):
        got = contacts_at(a, q, qk, margin, m=m)
        rows = np.flatnonzero(got[0] == pair)
        if len(rows) == 0:
            return None, 0
        i = rows[np.argmin(np.hypot(*(got[3][rows] - point).T))]
        return np.concatenate([[got[1][i]], got[2][i], got[3][i]]), len(rows)

    for j in range(ncon):
        p = int(con_pair[j])
        if not con_cn[j] > impulse_tol or p in seen:
            continue
        g0, n0 = geometry(p, con_p[j], q_hat, qk_lin)
        if g0 is None:
            continue
        switch = False
        for s in (int(a.pair_a[p]), int(a.pair_b[p])):
            body = int(a.shape_body[s])
            kind = int(a.body_kind[body])
            if kind not in (BODY_DYNAMIC, BODY_KINEMATIC):
                continue
            for c in range(3):
                rates = []
                for sign in (1.0, -1.0):
                    qq, kk = q_hat.copy(), qk_lin.copy()
                    arr = qq if kind == BODY_DYNAMIC else kk
                    eps = SWITCH_STEP * max(1.0, abs(arr[int(a.body_slot[body]), c]))
                    arr[int(a.body_slot[body]), c] += sign * eps
                    g, n = geometry(p, con_p[j], qq, kk)
                    if g is None or n != n0:
                        switch = True
                        break
                    rates.append(sign * (g - g0) / eps)
                if switch or np.max(np.abs(rates[0] - rates[1])) > SWITCH_RTOL * max(1.0, np.max(np.abs(rates))):
                    switch = True
                    break
            if switch:
                break
        if switch:
            seen.add(p)
            out.append(Degenerate("geometry", _contact_name(model, p),
                                  "the contact's gap, normal or point changes at different rates on the two sides of "
                                  "the pose (a switch of the contact's features, e.g. two faces of equal extent)"))
    return out


#: one-sided derivatives that agree to this, relative to the largest derivative in the entry's row or column (the
#: round-off of the derivative LCPs), make the step differentiable along that input
SIDES_RTOL = 1e-9
#: and to this fraction of the Jacobian's largest entry (a row and a column of round-off zeros are no scale)
SIDES_FLOOR = 1e-12

def _dense_twin(sim):
    """The simulator whose step is differentiated: `sim` itself, or for options that send large islands to the sparse
    solver (SimOptions.sparse_min_unknowns > 0: it writes no dense LCP to differentiate) its twin with every island on
    the dense path (`Simulator.twin`)."""
    limit = sim.options.sparse_min_unknowns
    if limit == 0 or sim.model.max_unknowns() < limit:
        return sim
    return sim.twin(sparse_min_unknowns=0)


def mixed_direction(x):
    """The direction that moves every input at once (the state's flattened inputs x): +-max(1, |x_k|) by the sign of
    sin(k + 1), the mixed direction of the differences' check (engine/rollout.py, `step_differences`)."""
    d = np.maximum(1.0, np.abs(x))
    return np.where(np.sin(np.arange(1.0, len(x) + 1.0)) >= 0.0, d, -d)


def mixed_agrees(J, d, right, left):
    """Whether the one-sided derivatives along the mixed direction d (right: along +d; left: minus that along -d)
    are J d, J the derivatives along each input (equal sides), to SIDES_RTOL of each row's |J| |d| (at least
    SIDES_FLOOR of the largest): a step differentiable along each input alone need not be along a mixture (a mode
    that switches only when two inputs move together, as max(0, min(x, y)) at 0 does)."""
    predicted = J @ d
    along = np.stack([right, left], axis=1)
    if not (np.all(np.isfinite(along)) and np.all(np.isfinite(predicted))):
        return False
    row_scale = np.maximum(np.abs(J) @ np.abs(d), np.max(np.abs(along), axis=1))
    tol = SIDES_RTOL * row_scale + SIDES_FLOOR * np.max(row_scale, initial=0.0)
    return bool(np.all(np.abs(along - predicted[:, None]) <= tol[:, None]))


def _run_on_duals(sim, m, q, v, qk, vk, K, d):
    """The step on duals along 2 K + 2 directions: +e_k (columns 0 ... K - 1) and -e_k (K ... 2 K - 1) of the K
    inputs (q, v, qk, vk, then the parameters': the model arrays m carry those), then +d and -d (columns 2 K and
    2 K + 1), d a direction of the state's inputs (`mixed_direction`). Every direction is propagated on its own (the
    dual `max` and `min` and the derivative LCP act column by column), so one run gives both one-sided derivatives
    along each input and along d. Returns (outputs (q+, v+, qk+) as object arrays, status, stats, work, the
    Recorder)."""
    from planar_lcp.engine.layout import StepWork
    from planar_lcp.engine.rollout import lemke_step, pgs_step
    nd, nk = len(q), len(qk)
    w = StepWork(*[forward.objects(a) for a in sim.work])
    w.warm_size[:] = -1
    w.sparse_pair_mode[:] = -1
    opt = sim.kopt._replace(warm_start=False)
    n = len(d)
    seeds = np.zeros((n, 2 * K + 2))
    seeds[np.arange(n), np.arange(n)] = 1.0
    seeds[np.arange(n), K + np.arange(n)] = -1.0
    seeds[:, 2 * K] = d
    seeds[:, 2 * K + 1] = -seeds[:, 2 * K]
    cuts = np.cumsum([0, q.size, v.size, qk.size, vk.size])
    state = tuple(with_derivatives(a, seeds[cuts[i]:cuts[i + 1]].reshape(a.shape + (2 * K + 2,)))
                  for i, a in enumerate((q, v, qk, vk)))
    out = (np.zeros((nd, 3), dtype=object), np.zeros((nd, 3), dtype=object), np.zeros((nk, 3), dtype=object))
    stats = np.zeros(len(sim.stats), dtype=object)
    kernel = pgs_step if sim.options.solver == "pgs" else lemke_step
    rec = forward.Recorder(sim.options.res_tol)
    st = forward.run(kernel, (m, state, float(sim.h), opt, w, out, stats), rec)
    return out, int(st), stats, w, rec


#: the one-sided differences of the compiled step that check the one-sided derivatives: their steps (times
#: max(1, |x|); either may agree: the smaller can fall within the certified solves' tolerance, where a small body's
#: friction impulse is accepted as zero, the larger can reach a contact a few micrometres away), and how far they may
#: differ (relative to the column's largest entry, at least NEARBY_FLOOR): O(step) for a smooth step, O(1) across a
#: switch
NEARBY_STEPS = (1e-6, 1e-5)
NEARBY_RTOL = 1e-3
NEARBY_FLOOR = 1e-3


def _input_names(nd, nk, params):
    """The names of the Jacobian's columns: q[i, c], v[i, c], qk[i, c], vk[i, c], then the parameters'."""
    return ([f"q[{i // 3}, {i % 3}]" for i in range(3 * nd)] + [f"v[{i // 3}, {i % 3}]" for i in range(3 * nd)]
            + [f"qk[{i // 3}, {i % 3}]" for i in range(3 * nk)] + [f"vk[{i // 3}, {i % 3}]" for i in range(3 * nk)]
            + list(params))


def flat_step(sim, state):
    """The cold step as a function of the flattened inputs: x (q, v, qk, vk of `state`'s shapes, row-major, in the
    Jacobian's column order) -> ((q+, v+, qk+) flattened in its row order, the step's status)."""
    shapes = [np.shape(a) for a in state]
    cuts = np.cumsum([int(np.prod(shp)) for shp in shapes])[:-1]

    def step(x):
        sim.reset_warm_start()
        q1, v1, qk1, status = sim.step(*(c.reshape(shp) for c, shp in zip(np.split(x, cuts), shapes)))
        return np.concatenate([q1.ravel(), v1.ravel(), qk1.ravel()]), status
    return step


def _switches_nearby(sim, state, f0, right, left):
    """Inputs along which the compiled step's one-sided differences over NEARBY_STEPS disagree with the one-sided
    derivatives: a switch of one of the engine's discrete choices that the analysis of the LCP and of the contact
    geometry does not see (which of two equally deep vertices is a contact's first row, the active-set check's
    penetration threshold), at the state or within NEARBY_STEPS[0] of it. f0: the step's (q+, v+, qk+) at the state,
    flattened."""
    x = np.concatenate([a.ravel() for a in state])
    step = flat_step(sim, state)

    def f(xx):
        return step(xx)[0]

    names = _input_names(len(state[0]), len(state[2]), ())
    bad = []
    for k in range(len(x)):
        agree = False
        for rel in NEARBY_STEPS:
            e = rel * max(1.0, abs(x[k]))
            xp, xm = x.copy(), x.copy()
            xp[k] += e
            xm[k] -= e
            fr, fl = (f(xp) - f0) / e, (f0 - f(xm)) / e
            scale = max(np.max(np.abs(right[:, k])), np.max(np.abs(left[:, k])), np.max(np.abs(fr)),
                        np.max(np.abs(fl)), NEARBY_FLOOR)
            if max(np.max(np.abs(fr - right[:, k])), np.max(np.abs(fl - left[:, k]))) <= NEARBY_RTOL * scale:
                agree = True
                break
        if not agree:
            bad.append(names[k])
    sim.reset_warm_start()
    if not bad:
        return []
    return [Degenerate("switch", ", ".join(bad), "the step's one-sided differences along these inputs change at "
                       "another rate than its one-sided derivatives: one of the engine's discrete choices (a "
                       "contact's row order, the active-set check's penetration threshold) switches at the state or "
                       f"within {NEARBY_STEPS[0]:g} of it")]


def _one_sided(sim, model, q, v, qk, vk, why):
    """The step's derivatives by its one-sided differences (differences.py `one_sided_differences`) where the checked
    differences found a switch at the state (`why`, their reason): not exact, the inputs whose two sides differ (the
    checked differences' kink test) and those whose one side changes the step's structure (both its derivatives the
    other side's) named in `degenerate`. None where they fail too."""
    got, _ = one_sided_differences(sim, q, v, qk, vk)
    if got is None:
        return None
    (q1, v1, qk1), right, left, sides = got
    nd, nk = model.ndyn, model.nkin
    names = _input_names(nd, nk, ())
    differ = sides == SIDES_DIFFER
    degenerate = []
    if differ.any():
        degenerate.append(Degenerate("sides", ", ".join(names[k] for k in np.flatnonzero(differ)),
                                     "the step's one-sided differences along these inputs differ: it is not "
                                     "differentiable there (method=\"dual\" names the contact and gives its one-sided "
                                     "derivatives exactly)"))
    one = np.flatnonzero((sides == SIDE_RIGHT_ONLY) | (sides == SIDE_LEFT_ONLY))
    if one.size:
        degenerate.append(Degenerate("structure", ", ".join(names[k] for k in one),
                                     "a step a difference's length away on one side of these inputs has other "
                                     "contacts, islands, re-solves or LCP sizes (the step may jump there): both "
                                     "one-sided derivatives are the other side's"))
    if not degenerate:
        degenerate.append(Degenerate("sides", "the step", why))
    return StepDerivatives(q=q1, v=v1, qk=qk1, status=STEP_OK, jacobian=0.5 * (right + left), ndyn=nd, nkin=nk,
                           exact=False, degenerate=tuple(degenerate), jacobian_right=right, jacobian_left=left,
                           method="one_sided", fallback=why)


#: step_derivatives' methods (module docstring)
METHODS = ("dual", "differences", "one_sided")


def _differences_answer(nd, nk, q1, v1, qk1, status, J, params, fallback):
    """The checked differences' `StepDerivatives`; fallback: "" or the reason that comes with an answer, the mixed
    direction's check (differences.py): the step is not linear in its inputs together there."""
    degenerate = (Degenerate("mixed", "the step", fallback + ": each input's differences hold, their sum does not "
                             "(the step is not linear in its inputs together)"),) if fallback else ()
    # by position (a dataclass takes them so in under half the time it takes them by keyword): q, v, qk, status,
    # jacobian, ndyn, nkin, params, exact, degenerate, jacobian_right, jacobian_left, method
    return StepDerivatives(q1, v1, qk1, status, J, nd, nk, params, not degenerate, degenerate, J, J, "differences")


def step_derivatives(sim, q, v, qk, vk, params=(), method="dual"):
    """The Jacobians of `sim.step(q, v, qk, vk)` (a `StepDerivatives`); `params`, scene parameter names (module
    docstring). The step is the cold one (no warm start: a function of its inputs alone). method "dual": the step on
    dual numbers (exact to round-off); "differences": checked central differences of the compiled step
    (differences.py: about 1e-6 of the Jacobian's scale, tens of times faster) where their checks hold, not exact
    ("mixed") where only the mixed direction's fails, else the dual numbers', the reason in `fallback`; "one_sided":
    as "differences", but where their checks find a switch at the state the compiled step's one-sided differences
    (`_one_sided`), the dual numbers only where those fail too or with `params`."""
    tangent_code = None
    if method != "dual" and not params:
        # the usual call first: the simulator's first try bound once (differences.py `FirstTry`), the state's arrays
        # as its kernel takes them. The general way's checks, conversions and look-ups at every call are a part of a
        # small scene's call that counts where its cost is counted in steps (docs/performance.md, "The step's
        # derivatives"); the bound first try makes them once. Where it gives way, the general way goes on from its
        # code
        first = first_try(sim) if method in METHODS else None
        if first is not None and first.takes(q, v, qk, vk):
            tangent_code, (q1, v1, qk1), J = first(sim, q, v, qk, vk)
            if tangent_code == DIFF_OK or tangent_code == DIFF_MOVES:
                return _differences_answer(first.nd, first.nk, q1, v1, qk1, STEP_OK, J, (),
                                           "" if tangent_code == DIFF_OK else DIFF_REASONS[DIFF_MOVES])
    if sim.options.solver == "osqp":
        raise ValueError("step_derivatives: solver 'osqp' is not differentiable here (its QP solver is a C library); "
                         "use solver 'lemke'")
    if method not in METHODS:
        raise ValueError(f"step_derivatives: method must be one of {', '.join(METHODS)}, got {method!r}")
    params = tuple(params)
    q, v, qk, vk = _check_state(sim, q, v, qk, vk)
    model = sim.model
    sim = _dense_twin(sim)
    fallback = ""
    if method != "dual":
        if sim.options.solver == "pgs":
            fallback = "PGS keeps no LCP basis"
        else:
            got, fallback = checked_differences(sim, q, v, qk, vk, tangent_code)
            if got is None and fallback == DIFF_REASONS[DIFF_NONFINITE]:
                _check_finite(q, v, qk, vk)
            if got is not None and params:
                compiles, notes = param_compiles(model, params)
                Jp, why = ((None, "a parameter at 0 has a one-sided derivative only") if notes else
                           param_differences(sim, q, v, qk, vk, compiles, got[0]))
                got = None if Jp is None else (got[0], got[1], np.hstack([got[2], Jp]))
                fallback = why or fallback
            if got is not None:
                (q1, v1, qk1), status, J = got
                return _differences_answer(model.ndyn, model.nkin, q1, v1, qk1, status, J, params, fallback)
            if method == "one_sided" and not params and fallback != DIFF_REASONS[DIFF_NONFINITE]:
                sided = _one_sided(sim, model, q, v, qk, vk, fallback)
                if sided is not None:
                    return sided
    _check_finite(q, v, qk, vk)
    nd, nk = model.ndyn, model.nkin
    K = 6 * nd + 6 * nk + len(params)
    m, notes = _model_with_param_derivatives(model, params, 6 * nd + 6 * nk, K, 2 * K + 2)
    # the compiled step first: its answer is the reference, and it grows the dense buffers the LCPs need
    sim.reset_warm_start()
    q1, v1, qk1, status = sim.step(q, v, qk, vk)
    sim.reset_warm_start()
    d = mixed_direction(np.concatenate([q.ravel(), v.ravel(), qk.ravel(), vk.ravel()]))
    out, st, stats, w, rec = _run_on_duals(sim, m, q, v, qk, vk, K, d)
    qd, vd, qkd = (values(a) for a in out)
    # the fixed-point form on duals may iterate on past the compiled step (forward.py, FP_DERIVATIVE_RTOL): its
    # values then move by less than the iteration's tolerance
    tol_q = 0.0 if not rec.fp_extra else 10.0 * sim.options.fixed_point_tol * (1.0 + np.max(np.abs(q1)))
    if st != int(status) or not (np.allclose(qd, q1, rtol=0.0, atol=tol_q)
                                 and np.allclose(vd, v1, rtol=0.0, atol=tol_q / sim.h)
                                 and np.allclose(qkd, qk1, rtol=0.0, atol=tol_q)):
        raise RuntimeError("step_derivatives: the step run on dual numbers does not reproduce the compiled step "
                           f"(status {st} vs {status}; largest difference "
                           f"{max(np.max(np.abs(qd - q1), initial=0), np.max(np.abs(vd - v1), initial=0)):.3g})")
    both = np.concatenate([grads(a, 2 * K + 2).reshape(-1, 2 * K + 2) for a in out], axis=0)
    right, left = both[:, :K], -both[:, K:2 * K]
    ns = 6 * nd + 6 * nk
    mixed_agree = mixed_agrees(0.5 * (right[:, :ns] + left[:, :ns]), d, both[:, 2 * K], -both[:, 2 * K + 1])
    unbounded = ~np.all(np.isfinite(right) & np.isfinite(left), axis=0)
    big = np.maximum(np.abs(right), np.abs(left))
    scale = np.maximum(np.max(big, axis=0)[None, :], np.max(big, axis=1)[:, None])
    floor = SIDES_FLOOR * float(np.max(big, initial=0.0))
    sides_agree = bool(np.all(np.abs(right - left) <= SIDES_RTOL * scale + floor))

    degenerate = list(notes)
    if unbounded.any():
        degenerate.append(Degenerate("unbounded", ", ".join(_input_names(nd, nk, params)[i]
                                                            for i in np.flatnonzero(unbounded)),
                                     "the derivatives along these inputs overflow (not finite): the step is not "
                                     "differentiable there"))
    if status != STEP_OK:
        degenerate.append(Degenerate("failed", "the step", f"status {status}: no certified LCP answer"))
    if sim.options.solver == "pgs":
        degenerate.append(Degenerate("solver", "the step", "PGS's iterate is not an LCP solution: the derivatives "
                                     "are those of its fixed number of sweeps"))
    if rec.unrecorded:
        degenerate.append(Degenerate("uncertified", "the step", f"{rec.unrecorded} answer(s) from a solver that writes "
                                     "no LCP (PGS after a failed solve): complementarity not checked"))
    if rec.unsolved:
        degenerate.append(Degenerate("complementarity", "the step", f"{rec.unsolved} derivative LCP(s) without a "
                                     "solution: there the derivatives hold the positive impulses' rows, the "
                                     "degenerate ones at zero"))
    for A, b, z, beta, layout, nonunique in rec.solves:
        for idx in nonunique:
            degenerate.append(Degenerate("non-unique", ", ".join(_lcp_index_name(model, layout, i) for i in idx),
                                         "the LCP's answers form a segment here that a change of the inputs "
                                         "breaks (two coinciding friction columns): the step's answer nearby is "
                                         "not the limit of its answer here"))
    if not sides_agree:
        for A, b, z, beta, layout, _ in rec.solves:
            for i in np.flatnonzero(beta):
                degenerate.append(Degenerate("complementarity", _lcp_index_name(model, layout, int(i)),
                                             "z = 0 and w = 0: the contact's mode (touching or not, sticking or "
                                             "sliding) can switch here"))
        for where in sorted(set(rec.ties)):
            degenerate.append(Degenerate("tie", where, "max or min of two equal values with different "
                                         "derivatives (a kink of the step's rows)"))
        if len(degenerate) == len(notes):
            degenerate.append(Degenerate("sides", "the step", "the one-sided derivatives differ"))
    elif not mixed_agree and not unbounded.any():
        degenerate.append(Degenerate("mixed", "the step", "each input's one-sided derivatives agree, the derivative "
                                     "along a mixture of the inputs is not their sum (the step is not linear in its "
                                     "inputs together: a mode that two inputs switch together)"))
    ncon = int(values(stats)[Stat.N_CONTACTS])
    velocity_form = sim.kopt.formulation == FORM_VELOCITY
    degenerate += _switches_nearby(sim, (q, v, qk, vk), np.concatenate([q1.ravel(), v1.ravel(), qk1.ravel()]), right,
                                   left)
    degenerate += _geometry_switches(model, values(w.q_hat), qk if velocity_form else values(w.qk_hat),
                                     w.con_pair, values(w.con_p[:ncon]), values(w.con_cn[:ncon]), ncon,
                                     sim.options.contact_margin, sim.options.impulse_tol)
    return StepDerivatives(q=q1, v=v1, qk=qk1, status=int(status), jacobian=0.5 * (right + left), ndyn=nd, nkin=nk,
                           params=params, exact=not degenerate, degenerate=tuple(degenerate),
                           jacobian_right=right, jacobian_left=left, fallback=fallback)


# --- a rollout -----------------------------------------------------------------------------------------------------

@dataclass
class RolloutDerivatives:
    """A rollout's states (q, v (n + 1, ndyn, 3), qk (n + 1, nkin, 3)) and the Jacobians of its final state
    x_n = (q_n, v_n, qk_n) (flattened as `StepDerivatives`): `dx_dx0` (the initial state's), `dx_dvk`
    (n, size of x_n, 3 nkin: the kinematic velocities of each step) and `dx_dp` (the parameters'); `dx_dp_steps`
    (n + 1, size of x, len(params)): the parameters' Jacobian of every state of the rollout (row 0 zero, row n
    `dx_dp`). `exact`: every step's; `degenerate`: (step, Degenerate) pairs."""

    q: np.ndarray
    v: np.ndarray
    qk: np.ndarray
    dx_dx0: np.ndarray
    dx_dvk: np.ndarray
    dx_dp: np.ndarray
    params: tuple = ()
    exact: bool = True
    degenerate: tuple = field(default_factory=tuple)
    dx_dp_steps: np.ndarray | None = None
    #: with method "differences" or "one_sided": the steps whose derivatives the dual numbers gave, and why ((step,
    #: reason) pairs)
    fallbacks: tuple = ()
    #: with method "one_sided": the steps whose derivatives the one-sided differences gave, and why the checked
    #: differences gave way there
    one_sided: tuple = ()


def rollout_derivatives(sim, q, v, qk, vk_seq, nsteps, params=(), method="dual"):
    """`nsteps` steps from (q, v, qk), step i with vk_seq[min(i, len - 1)] ((nvk, nkin, 3)), and the chain rule over
    their `step_derivatives` (by `method`): the final state's Jacobians (a `RolloutDerivatives`). Stops with a
    `SimulationError` (planar_lcp.errors, a RuntimeError) naming the step that fails: the steps are cold, and a cold
    step can fail where a warm-started run of the same controls went through. Every step's Jacobian is kept until
    the end (nsteps (6 ndyn + 3 nkin)^2 floats), for the kinematic velocities' backward sweep."""
    vk_seq = np.asarray(vk_seq, dtype=np.float64)
    m = sim.model
    if vk_seq.ndim != 3 or vk_seq.shape[1:] != (m.nkin, 3) or len(vk_seq) < 1:
        raise ValueError(f"rollout_derivatives: vk_seq must have shape (nvk >= 1, {m.nkin}, 3), got {vk_seq.shape}")
    if int(nsteps) < 1:
        raise ValueError(f"rollout_derivatives: nsteps must be >= 1, got {nsteps}")
    nsteps = int(nsteps)
    params = tuple(params)
    nx = 6 * m.ndyn + 3 * m.nkin
    nvk = 3 * m.nkin
    dx = np.eye(nx)
    state_jacobians, vk_jacobians = [], []
    dp = np.zeros((nx, len(params)))
    dp_steps = np.zeros((nsteps + 1, nx, len(params)))
    qs, vs, qks = [np.asarray(q, float)], [np.asarray(v, float)], [np.asarray(qk, float)]
    degenerate = []
    fallbacks, one_sided = [], []
    for i in range(nsteps):
        d = step_derivatives(sim, qs[-1], vs[-1], qks[-1], vk_seq[min(i, len(vk_seq) - 1)], params, method)
        if d.fallback:
            (one_sided if d.method == "one_sided" else fallbacks).append((i, d.fallback))
        if d.status != STEP_OK:
            why = {STEP_LCP_FAILED: "no certified LCP answer", STEP_NONFINITE: "the new state is not finite"}
            raise SimulationError(f"rollout_derivatives: step {i} (t = {i * sim.h:.6g} s) failed: "
                                  f"{why.get(int(d.status), f'status {int(d.status)}')}")
        J = d.state_jacobian
        Jp = d.jacobian[:, nx + nvk:]
        dx = J @ dx
        state_jacobians.append(J)
        vk_jacobians.append(d.jacobian[:, nx:nx + nvk])
        dp = dp_steps[i + 1] = J @ dp + Jp
        degenerate += [(i, g) for g in d.degenerate]
        qs.append(d.q)
        vs.append(d.v)
        qks.append(d.qk)
    # step i's kinematic velocities reach the final state through the later steps: J_(n-1) ... J_(i+1) Jvk_i, by one
    # backward sweep, linear in the steps (carrying every earlier step's columns forward at each step is quadratic)
    dvk = np.empty((nsteps, nx, nvk))
    later = np.eye(nx)
    for i in range(nsteps - 1, -1, -1):
        dvk[i] = later @ vk_jacobians[i]
        if i > 0:
            later = later @ state_jacobians[i]
    return RolloutDerivatives(q=np.array(qs), v=np.array(vs), qk=np.array(qks), dx_dx0=dx, dx_dvk=dvk, dx_dp=dp,
                              params=params, exact=not degenerate, degenerate=tuple(degenerate),
                              dx_dp_steps=dp_steps, fallbacks=tuple(fallbacks), one_sided=tuple(one_sided))
