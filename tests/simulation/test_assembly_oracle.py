"""Oracle for `engine.assemble.assemble_lcp`: an independent dense numpy build of one island's contact LCP.

The reference below is written from the mathematics (docs/method.md, "The scheme", Stewart & Trinkle eqs. 13-20 in
2D), not from the kernel: it forms the generalized impulse matrix G = [N, D_c, D_s] over ALL dynamic dofs, the mass
matrix M = blockdiag(m, m, J), the friction incidence matrices E_c, E_s and the Coulomb matrix U explicitly, then

    A = [[G^T M^-1 G,  [E_c 0; 0 E_s]],        b = [G^T v~ (+ normal / kinematic terms),
         [U  -[E_c 0; 0 E_s]^T,  0   ]]             0 (contacts), mu_s h load_s (support points)]

with z = [c_n | beta_c (+t, -t per frictional contact) | beta_s (k per support point) | lambda_c | lambda_s].
Inputs come from the real pipeline (scene -> model -> rollout -> contacts -> islands) or from hand-made scenes with
random states; only the assembly is under test.
"""

import functools
import os

import numpy as np
import pytest

from planar_lcp.engine import assemble as AS
from planar_lcp.engine import contacts as C
from planar_lcp.engine.layout import WORK_LAYOUT, Stat, StepWork, model_struct, work_struct
from planar_lcp.lcp import lemke
from planar_lcp.model import BODY_DYNAMIC, BODY_KINEMATIC, SUPPORT_POINTS, compile_scene
from planar_lcp.spec.scene import list_scenes, load_scene, parse_scene
from planar_lcp.sim import SimOptions, Simulator

JIT_DISABLED = os.environ.get("NUMBA_DISABLE_JIT", "0") == "1"
RTOL = 1e-12
MARGIN = SimOptions(h=1.0).contact_margin


# ----------------------------------------------------------------------------------------------------------------
# the reference
# ----------------------------------------------------------------------------------------------------------------

def _cross(r, d):
    return r[0] * d[1] - r[1] * d[0]


def _contact_bodies(m, con_pair, j):
    p = con_pair[j]
    return int(m.shape_body[m.pair_a[p]]), int(m.shape_body[m.pair_b[p]])


def _contact_column(m, poses, con_pair, con_p, j, d):
    """(3 ndyn,) generalized impulse of a unit impulse along world direction d at contact j: + on A, - on B."""
    g = np.zeros(3 * len(m.dyn_mass))
    p = con_p[j]
    for body, sign in zip(_contact_bodies(m, con_pair, j), (1.0, -1.0)):
        if m.body_kind[body] == BODY_DYNAMIC:
            s = int(m.body_slot[body])
            g[3 * s:3 * s + 3] += sign * np.array([d[0], d[1], _cross(p - poses[body, :2], d)])
    return g


def _support_column(m, poses, s, d):
    """(3 ndyn,) generalized impulse of a unit table-friction impulse along d at support point s."""
    g = np.zeros(3 * len(m.dyn_mass))
    slot = int(m.sup_dyn[s])
    body = int(m.dyn_body[slot])
    th = poses[body, 2]
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    p = poses[body, :2] + R @ m.sup_local[s]
    g[3 * slot:3 * slot + 3] = [d[0], d[1], _cross(p - poses[body, :2], d)]
    return g


def recentred_columns(m):
    """The limit-surface elements' re-centred columns (body frame) as the stage before assembly leaves them: here a
    fixed random array, so that the assembly's use of them is checked (their values: tests/simulation/test_limit_surface.py)."""
    return np.ascontiguousarray(np.random.default_rng(len(m.sup_dyn)).normal(size=(max(1, len(m.sup_dyn)), 3)))


def _limit_surface_columns(m, poses, s):
    """(3 ndyn,) generalized impulses of a limit-surface element's columns: its fixed twists' unit-load wrenches and
    the re-centred one, rotated from the body frame to the world at the linearization pose."""
    slot = int(m.sup_dyn[s])
    th = poses[int(m.dyn_body[slot]), 2]
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    cols = []
    for wb in list(m.ls_wrench[s]) + [recentred_columns(m)[s]]:
        g = np.zeros(3 * len(m.dyn_mass))
        g[3 * slot:3 * slot + 2] = R @ wb[:2]
        g[3 * slot + 2] = wb[2]
        cols.append(g)
    return cols


def kinematic_relative_velocity(m, poses, vk, con_pair, con_p, j):
    """(2,) velocity at p_j of the kinematic bodies of contact j: A's minus B's (static and dynamic bodies: 0)."""
    out = np.zeros(2)
    p = con_p[j]
    for body, sign in zip(_contact_bodies(m, con_pair, j), (1.0, -1.0)):
        if m.body_kind[body] == BODY_KINEMATIC:
            vx, vy, om = vk[int(m.body_slot[body])]
            r = p - poses[body, :2]
            out += sign * np.array([vx - om * r[1], vy + om * r[0]])
    return out


def reference_lcp(m, poses, vk, isl_con, isl_sup, con_pair, con_phi, con_n, con_p, v_tilde, v_hat, h,
                  velocity_form):
    """Dense (A, b, G, parts) of one island's LCP; parts holds the block sizes and the matrices it is made of."""
    ndyn = len(m.dyn_mass)
    points = m.support_model == SUPPORT_POINTS
    k = m.fric_dirs.shape[0] if points else m.ls_wrench.shape[1] + 1
    con = [int(j) for j in isl_con]
    sup = [int(s) for s in isl_sup]
    mu = np.array([m.pair_mu[con_pair[j]] for j in con])
    fric = [a for a in range(len(con)) if mu[a] > 0.0]
    nc, nf, ns = len(con), len(fric), len(sup)
    tang = {j: np.array([-con_n[j, 1], con_n[j, 0]]) for j in con}

    cols = [_contact_column(m, poses, con_pair, con_p, j, con_n[j]) for j in con]
    for a in fric:
        j = con[a]
        cols += [_contact_column(m, poses, con_pair, con_p, j, tang[j]),
                 _contact_column(m, poses, con_pair, con_p, j, -tang[j])]
    for s in sup:
        cols += ([_support_column(m, poses, s, m.fric_dirs[i]) for i in range(k)] if points
                 else _limit_surface_columns(m, poses, s))
    G = np.column_stack(cols) if cols else np.zeros((3 * ndyn, 0))
    nforce = G.shape[1]
    assert nforce == nc + 2 * nf + k * ns

    Minv = np.diag(1.0 / np.column_stack([m.dyn_mass, m.dyn_mass, m.dyn_inertia]).ravel())
    W = G.T @ Minv @ G
    E_c = np.zeros((2 * nf, nf))
    for f in range(nf):
        E_c[2 * f:2 * f + 2, f] = 1.0
    E_s = np.zeros((k * ns, ns))
    for a in range(ns):
        E_s[k * a:k * a + k, a] = 1.0
    E = np.zeros((nforce, nf + ns))
    E[nc:nc + 2 * nf, :nf] = E_c
    E[nc + 2 * nf:, nf:] = E_s
    U = np.zeros((nf + ns, nforce))          # slack rows: mu c_n for contacts, 0 for supports (load is in b)
    for f, a in enumerate(fric):
        U[f, a] = mu[a]
    n = nforce + nf + ns
    A = np.zeros((n, n))
    A[:nforce, :nforce] = W
    A[:nforce, nforce:] = E
    A[nforce:, :nforce] = U - E.T
    # A[nforce:, nforce:] stays 0

    vt = np.asarray(v_tilde, float).ravel()
    vh = np.asarray(v_hat, float).ravel()
    b = np.zeros(n)
    b[:nforce] = G.T @ vt
    for a, j in enumerate(con):
        if velocity_form:
            vkin = kinematic_relative_velocity(m, poses, vk, con_pair, con_p, j)
            b[a] += max(con_phi[j], 0.0) / h + con_n[j] @ vkin
        else:
            b[a] += con_phi[j] / h - G[:, a] @ vh
    for f, a in enumerate(fric):
        j = con[a]
        vt_kin = tang[j] @ kinematic_relative_velocity(m, poses, vk, con_pair, con_p, j)
        b[nc + 2 * f] += vt_kin
        b[nc + 2 * f + 1] -= vt_kin
    for a, s in enumerate(sup):
        b[nforce + nf + a] = m.sup_mu[s] * h * m.sup_load[s]
    parts = dict(nc=nc, nf=nf, ns=ns, k=k, n=n, nforce=nforce, W=W, E=E, U=U, Minv=Minv)
    return A, b, G, parts


# ----------------------------------------------------------------------------------------------------------------
# the kernel, the comparator, the inputs
# ----------------------------------------------------------------------------------------------------------------

_DTYPES = {"f8": np.float64, "i8": np.int64, "bool": np.bool_}


def work_with(**arrays):
    """A StepWork holding the given arrays, every other field a one-element dummy of its declared type."""
    return StepWork(*(arrays[f.name] if f.name in arrays else np.zeros((1,) * len(f.shape.split(" x ")),
                                                                       _DTYPES[f.dtype]) for f in WORK_LAYOUT))


def kernel_lcp(m, poses, vk, isl_con, isl_sup, con_pair, con_phi, con_n, con_p, v_tilde, v_hat, h, velocity_form,
               n):
    """Call assemble_lcp on NaN-filled buffers (an entry it forgets to write shows up as NaN). b has a tail of
    3 extra entries that must stay untouched. Returns (A, b, n_returned, nf_returned, col_dyn, col_g)."""
    isl_con = np.ascontiguousarray(isl_con, np.int64)
    isl_sup = np.ascontiguousarray(isl_sup, np.int64)
    cap = max(1, n)
    col_dyn = np.full((cap, 2), 12345, np.int64)
    col_g = np.full((cap, 2, 3), np.nan)
    A = np.full((n, n), np.nan)
    b = np.full(n + 3, np.nan)
    w = work_with(body_pose=poses, island_con=isl_con, island_sup=isl_sup, con_pair=con_pair, con_phi=con_phi,
                  con_n=con_n, con_p=con_p, v_tilde=np.ascontiguousarray(v_tilde, float),
                  v_hat=np.ascontiguousarray(v_hat, float), column_slot=col_dyn, column_g=col_g,
                  sup_recentred=recentred_columns(m))
    if hasattr(AS.assemble_lcp, "py_func"):
        m, w = model_struct(m), work_struct(w)  # the kernel as the step calls it (a python run reads the tuples)
    nret, nf = AS.assemble_lcp(m, w, np.ascontiguousarray(vk, float), len(isl_con), len(isl_sup), float(h),
                               bool(velocity_form), A, b)
    assert np.all(np.isnan(b[n:])), "assemble_lcp wrote past the end of its problem in b"
    return A, b[:n], int(nret), int(nf), col_dyn, col_g


def lcp_mismatch(A, b, A_ref, b_ref, rtol=RTOL):
    """None if (A, b) equals (A_ref, b_ref) to rtol relative to max|A_ref|, max|b_ref|; else a description."""
    if A.shape != A_ref.shape or b.shape != b_ref.shape:
        return f"shapes differ: A {A.shape} vs {A_ref.shape}, b {b.shape} vs {b_ref.shape}"
    out = []
    for name, x, ref in (("A", A, A_ref), ("b", b, b_ref)):
        if x.size == 0:
            continue
        scale = float(np.max(np.abs(ref)))
        err = np.abs(x - ref)
        err[~np.isfinite(x)] = np.inf
        bad = err > rtol * scale
        if np.any(bad):
            idx = np.unravel_index(int(np.argmax(err)), err.shape)
            out.append(f"{name}{list(idx)} = {x[idx]!r} vs reference {ref[idx]!r} ({int(bad.sum())} entries off, "
                       f"max|{name}_ref| = {scale:.3e})")
    return "; ".join(out) or None


def island_lists(m, ncon, con_pair, island_of_slot):
    """{island: (contacts, support points)}: a contact belongs to the island of its dynamic bodies."""
    groups = {}
    for j in range(ncon):
        dyn = [b for b in _contact_bodies(m, con_pair, j) if m.body_kind[b] == BODY_DYNAMIC]
        isl = {int(island_of_slot[m.body_slot[b]]) for b in dyn}
        assert len(isl) == 1, "a contact between two dynamic bodies spans two islands"
        groups.setdefault(isl.pop(), ([], []))[0].append(j)
    for s in range(len(m.sup_dyn)):
        groups.setdefault(int(island_of_slot[m.sup_dyn[s]]), ([], []))[1].append(s)
    return groups


def islands_of(m, ncon, con_pair):
    """Connected components of the dynamic bodies under dynamic-dynamic contacts (plain python, no kernel)."""
    ndyn = len(m.dyn_mass)
    label = list(range(ndyn))

    def root(i):
        while label[i] != i:
            i = label[i]
        return i

    for j in range(ncon):
        ba, bb = _contact_bodies(m, con_pair, j)
        if m.body_kind[ba] == BODY_DYNAMIC and m.body_kind[bb] == BODY_DYNAMIC:
            ra, rb = root(int(m.body_slot[ba])), root(int(m.body_slot[bb]))
            label[max(ra, rb)] = min(ra, rb)
    return np.array([root(i) for i in range(ndyn)])


class Problem:
    """Contacts at the linearization pose of one step, as the step pipeline forms them (see engine/step.py)."""

    def __init__(self, model, q, v, qk, vk, h, velocity_form, v_hat=None, force_all=False, margin=MARGIN):
        m = model.arrays
        self.m, self.h, self.velocity_form = m, float(h), bool(velocity_form)
        q, v, qk, vk = (np.ascontiguousarray(x, float) for x in (q, v, qk, vk))
        self.vk = vk
        self.v_tilde = np.ascontiguousarray(v + h * np.r_[m.gravity, 0.0][None, :])
        if v_hat is None:
            v_hat = np.zeros_like(v) if velocity_form else v
        self.v_hat = np.ascontiguousarray(v_hat, float)
        q_lin = q + h * self.v_hat
        qk_lin = qk if velocity_form else qk + h * vk
        nbody = len(m.body_kind)
        self.poses = np.zeros((nbody, 3))
        C.body_poses(m, np.ascontiguousarray(q_lin), np.ascontiguousarray(qk_lin), self.poses)
        vw = np.zeros((max(1, len(m.vert_local)), 2))
        C.world_vertices(m, self.poses, vw)
        npair = len(m.pair_a)
        cap = max(1, 2 * npair)
        force = np.full(max(1, npair), bool(force_all))
        self.con_pair = np.zeros(cap, np.int64)
        self.con_phi = np.zeros(cap)
        self.con_n = np.zeros((cap, 2))
        self.con_p = np.zeros((cap, 2))
        self.ncon = int(C.find_contacts(m, vw, margin, force, self.con_pair, self.con_phi, self.con_n, self.con_p,
                                        np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2))))
        self.groups = island_lists(m, self.ncon, self.con_pair, islands_of(m, self.ncon, self.con_pair))

    def args(self, isl_con, isl_sup):
        return (self.m, self.poses, self.vk, isl_con, isl_sup, self.con_pair, self.con_phi, self.con_n,
                self.con_p, self.v_tilde, self.v_hat, self.h, self.velocity_form)


def check_island(prob, isl_con, isl_sup, rng=None):
    """Kernel vs reference on one island; returns the reference parts. Also checks sizes and the impulse update."""
    A_ref, b_ref, G, parts = reference_lcp(*prob.args(isl_con, isl_sup))
    n = parts["n"]
    assert n == parts["nc"] + 3 * parts["nf"] + (parts["k"] + 1) * parts["ns"]
    A, b, nret, nf, col_dyn, col_g = kernel_lcp(*prob.args(isl_con, isl_sup), n)
    assert (nret, nf) == (n, parts["nf"])
    msg = lcp_mismatch(A, b, A_ref, b_ref)
    assert msg is None, msg
    # the impulse update the step applies with the same columns: v += M^-1 G z
    if rng is not None and parts["nforce"] > 0:
        z = rng.uniform(0.0, 1.0, parts["nforce"])
        v = np.ascontiguousarray(prob.v_tilde.copy())
        AS.apply_impulses(parts["nforce"], col_dyn, col_g, z, prob.m, v)
        ref = prob.v_tilde.ravel() + parts["Minv"] @ G @ z
        np.testing.assert_allclose(v.ravel(), ref, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(ref))))
    return A_ref, b_ref, G, parts


# ----------------------------------------------------------------------------------------------------------------
# 1. every shipped scene, along its own trajectory
# ----------------------------------------------------------------------------------------------------------------

SCENES = [name for name, _ in list_scenes()]
ISSUE_B_SCENES = {"falling_rod", "four_disks", "block_on_incline", "box_push", "box_tip", "painleve_rod", "box_stack",
                  "push_t"}


@functools.lru_cache(maxsize=None)
def _trajectory(name):
    sc = load_scene(name)
    model = compile_scene(sc)
    sim = Simulator(model, SimOptions(h=sc.sim.h))
    q, v, qk, vk = sim.initial_state()
    nsteps = int(round(sc.sim.t_end / sc.sim.h))
    if JIT_DISABLED:
        nsteps = min(nsteps, 200)
    out = sim.rollout(q, v, qk, vk[None], nsteps, stop_on_failure=False)
    return sc, model, vk, out


def _step_choices(out):
    done = out["steps_done"]
    ncon = out["stats"][:done, Stat.N_CONTACTS]            # contacts found during each step
    steps = {0, done}
    with_contacts = np.flatnonzero(ncon > 0)
    if len(with_contacts):
        steps.add(int(with_contacts[0]))           # first contact (falling_rod lands late)
        steps.add(int(np.argmax(ncon)))            # most contacts
        steps.update(int(s) for s in with_contacts[np.linspace(0, len(with_contacts) - 1, 5).astype(int)])
    return sorted(steps)


@pytest.mark.parametrize("name", SCENES)
def test_shipped_scene_matches_reference(name):
    sc, model, vk, out = _trajectory(name)
    h = sc.sim.h
    cases = cases_with_contacts = 0
    for step in _step_choices(out):
        q, v, qk = out["q"][step], out["v"][step], out["qk"][step]
        for velocity_form in (False, True):
            prob = Problem(model, q, v, qk, vk, h, velocity_form)
            if prob.ncon == 0 and len(model.arrays.sup_dyn) == 0:
                continue
            seen = 0
            for isl, (isl_con, isl_sup) in sorted(prob.groups.items()):
                if not isl_con and not isl_sup:
                    continue
                check_island(prob, isl_con, isl_sup, np.random.default_rng(step))
                cases += 1
                cases_with_contacts += bool(isl_con)
                seen += len(isl_con)
            assert seen == prob.ncon, "every contact belongs to exactly one island"
    # the scenes of ISSUE_B_SCENES all make contact; a planning-task scene starts with its pusher at rest and clear of
    # the object (the planner sets the velocity), so only its table-friction islands are compared
    if name in ISSUE_B_SCENES:
        assert cases_with_contacts > 0, f"{name}: no island with contacts was compared"
    assert cases >= 4


def test_every_shipped_scene_is_covered():
    assert set(SCENES) >= {"falling_rod", "four_disks", "box_push", "push_t", "box_stack", "box_tip",
                           "block_on_incline", "painleve_rod"}


# ----------------------------------------------------------------------------------------------------------------
# 2. hand-made scenes with random states (every branch of the assembly)
# ----------------------------------------------------------------------------------------------------------------

def _horizontal_scene():
    """Top-down: box A pushed by a kinematic disk, touching a dynamic hexagon; the pusher-hexagon pair has mu 0."""
    hexagon = [[0.06 * np.cos(a), 0.06 * np.sin(a)] for a in np.arange(6) * np.pi / 3]
    return parse_scene({
        "name": "oracle_horizontal",
        "world": {"plane": "horizontal", "friction": 0.3,
                  "friction_pairs": [{"a": "pusher", "b": "hex", "mu": 0.0}, {"a": "box", "b": "hex", "mu": 0.6}]},
        "sim": {"h": 0.01, "friction_directions": 6},
        "bodies": [
            {"name": "box", "type": "dynamic", "mass": 1.3, "position": [0.0, 0.0], "support_friction": 0.45,
             "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]},
            {"name": "hex", "type": "dynamic", "mass": 0.7, "position": [0.16, 0.01], "angle": 0.3,
             "shapes": [{"type": "polygon", "vertices": hexagon}],
             "support_points": [[0.02, 0.0], [-0.01, 0.02], [-0.01, -0.02]]},
            {"name": "pusher", "type": "kinematic", "position": [-0.12, 0.02],
             "shapes": [{"type": "disk", "radius": 0.02}]},
        ]})


def _vertical_scene():
    """Elevation: box1 on a frictionless table (mu 0), box2 on box1, a kinematic capsule finger on box2, a disk."""
    return parse_scene({
        "name": "oracle_vertical",
        "world": {"plane": "vertical", "gravity": [0.3, -9.81], "friction": 0.5,
                  "friction_pairs": [{"a": "box1", "b": "table", "mu": 0.0}, {"a": "finger", "b": "box2", "mu": 0.2},
                                     {"a": "disk", "b": "table", "mu": 0.0}]},
        "sim": {"h": 0.004},
        "bodies": [
            {"name": "box1", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.05],
             "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]},
            {"name": "box2", "type": "dynamic", "mass": 0.4, "inertia": 0.003, "position": [0.02, 0.16],
             "shapes": [{"type": "box", "width": 0.12, "height": 0.1, "radius": 0.005}]},
            {"name": "disk", "type": "dynamic", "mass": 0.2, "position": [0.2, 0.05],
             "shapes": [{"type": "disk", "radius": 0.05}]},
            {"name": "finger", "type": "kinematic", "position": [-0.07, 0.19], "angle": 0.4,
             "shapes": [{"type": "capsule", "length": 0.03, "radius": 0.01}]},
            {"name": "table", "type": "static",
             "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]},
        ]})


def _random_state(model, rng, pos_noise=0.01, ang_noise=0.15):
    q = model.q0 + np.column_stack([rng.normal(0, pos_noise, (model.ndyn, 2)), rng.normal(0, ang_noise, model.ndyn)])
    v = rng.normal(0, 0.5, (model.ndyn, 3))
    qk = model.qk0 + np.column_stack([rng.normal(0, pos_noise, (model.nkin, 2)), rng.normal(0, ang_noise, model.nkin)])
    vk = rng.normal(0, 0.5, (model.nkin, 3))
    vk[:, 2] = rng.uniform(1.0, 3.0, model.nkin) * rng.choice([-1, 1], model.nkin)   # spin: omega x r matters
    return q, v, qk, vk


def _body(model, name):
    return [b.name for b in model.scene.bodies].index(name)


def _contacts_between(prob, model, a, b):
    ia, ib = _body(model, a), _body(model, b)
    return [j for j in range(prob.ncon) if set(_contact_bodies(prob.m, prob.con_pair, j)) == {ia, ib}]


def _synthetic_problems(scene, seeds, support_model=None):
    model = compile_scene(scene, support_model=support_model)
    for seed in seeds:
        rng = np.random.default_rng(seed)
        q, v, qk, vk = _random_state(model, rng)
        h = scene.sim.h * rng.uniform(0.5, 2.0)
        for velocity_form in (False, True):
            for v_hat in ([None, rng.normal(0, 0.5, v.shape)] if not velocity_form else [None]):
                # force every pair: contacts at any gap, so phi takes both signs
                yield model, rng, Problem(model, q, v, qk, vk, h, velocity_form, v_hat=v_hat, force_all=True)


# points: friction_directions = 6 per support point, 4 + 3 points; limit surface: 6 fixed twists and the re-centred
# one per body, one element per body
@pytest.mark.parametrize("support, columns, elements", [("points", 6, 4 + 3), ("limit_surface", 7, 2)])
def test_synthetic_horizontal_pusher_two_bodies_mu_zero(support, columns, elements):
    seen_kin_tangent = seen_mu0 = seen_coupling = 0
    for model, rng, prob in _synthetic_problems(_horizontal_scene(), range(6), support):
        assert len(prob.groups) == 1      # box-hex contact joins the two bodies
        (isl_con, isl_sup), = prob.groups.values()
        A_ref, b_ref, G, parts = check_island(prob, isl_con, isl_sup, rng)
        k = parts["k"]
        assert k == columns and parts["ns"] == elements and parts["nc"] > parts["nf"] > 0
        # the pusher-box contact: the kinematic tangential velocity enters the two friction rows with opposite signs
        fric = [j for j in isl_con if prob.m.pair_mu[prob.con_pair[j]] > 0]
        for j in _contacts_between(prob, model, "box", "pusher"):
            f = fric.index(j)
            t = np.array([-prob.con_n[j, 1], prob.con_n[j, 0]])
            vt = t @ kinematic_relative_velocity(prob.m, prob.poses, prob.vk, prob.con_pair, prob.con_p, j)
            assert abs(vt) > 1e-3
            u = parts["nc"] + 2 * f
            assert b_ref[u] - G[:, u] @ prob.v_tilde.ravel() == pytest.approx(vt, abs=1e-12)
            assert b_ref[u + 1] - G[:, u + 1] @ prob.v_tilde.ravel() == pytest.approx(-vt, abs=1e-12)
            seen_kin_tangent += 1
        # the pusher-hex pair has mu = 0: a normal unknown and no friction unknowns
        for j in _contacts_between(prob, model, "hex", "pusher"):
            assert j not in fric
            seen_mu0 += 1
        # box-hex: both bodies get columns; W couples them with contacts of either body
        box_hex = _contacts_between(prob, model, "box", "hex")
        for j in box_hex:
            a = isl_con.index(j)
            assert np.any(G[0:3, a] != 0) and np.any(G[3:6, a] != 0)
            seen_coupling += 1
        # support friction of the box couples (through the box) with the box-hex normal
        if box_hex:
            a = isl_con.index(box_hex[0])
            assert np.any(A_ref[a, parts["nc"] + 2 * parts["nf"]:parts["nforce"]] != 0)
    assert seen_kin_tangent and seen_mu0 and seen_coupling


def test_synthetic_kinematic_body_on_side_a():
    """The compiler always puts a dynamic body as A; the kernel loops over both sides, so swap A and B of every
    pair (and flip the normals) to run the kinematic-on-A and dynamic-on-B branches."""
    scene = _horizontal_scene()
    model = compile_scene(scene)
    m = model.arrays
    swapped = model.arrays._replace(pair_a=m.pair_b.copy(), pair_b=m.pair_a.copy())
    for seed in range(4):
        rng = np.random.default_rng(100 + seed)
        q, v, qk, vk = _random_state(model, rng)
        for velocity_form in (False, True):
            prob = Problem(model, q, v, qk, vk, scene.sim.h, velocity_form, force_all=True)
            (isl_con, isl_sup), = prob.groups.values()
            A0, b0, _, parts = check_island(prob, isl_con, isl_sup)
            prob.m = swapped
            prob.con_n = np.ascontiguousarray(-prob.con_n)
            A1, b1, _, parts1 = check_island(prob, isl_con, isl_sup, rng)
            # same physics: the normal rows do not change (the friction rays swap places)
            nc = parts["nc"]
            np.testing.assert_allclose(b1[:nc], b0[:nc], rtol=0, atol=1e-12 * np.max(np.abs(b0)))
            np.testing.assert_allclose(A1[:nc, :nc], A0[:nc, :nc], rtol=0, atol=1e-12 * np.max(np.abs(A0)))


def test_synthetic_vertical_stack_finger_mu_zero():
    seen = dict(coupled=0, mu0=0, kin=0)
    for model, rng, prob in _synthetic_problems(_vertical_scene(), range(6)):
        box1_box2 = _contacts_between(prob, model, "box1", "box2")
        box1_table = _contacts_between(prob, model, "box1", "table")
        finger = _contacts_between(prob, model, "box2", "finger")
        assert box1_box2 and box1_table and finger
        for isl_con, isl_sup in prob.groups.values():
            assert not isl_sup
            A_ref, b_ref, G, parts = check_island(prob, isl_con, isl_sup, rng)
            if box1_table[0] not in isl_con:
                continue
            a_tab = isl_con.index(box1_table[0])
            a_12 = isl_con.index(box1_box2[0])
            a_fin = isl_con.index(finger[0])
            assert A_ref[a_tab, a_12] != 0.0                     # share box1
            assert A_ref[a_12, a_fin] != 0.0                     # share box2
            assert A_ref[a_tab, a_fin] == 0.0                    # no common body
            seen["coupled"] += 1
            fric = [j for j in isl_con if prob.m.pair_mu[prob.con_pair[j]] > 0]
            assert box1_table[0] not in fric                     # mu 0
            seen["mu0"] += 1
            if prob.velocity_form:
                # velocity form: the finger's normal velocity at the contact enters the normal row
                j = finger[0]
                vn = prob.con_n[j] @ kinematic_relative_velocity(prob.m, prob.poses, prob.vk, prob.con_pair,
                                                                 prob.con_p, j)
                extra = b_ref[a_fin] - G[:, a_fin] @ prob.v_tilde.ravel() - max(prob.con_phi[j], 0.0) / prob.h
                assert abs(vn) > 1e-3 and extra == pytest.approx(vn, abs=1e-12)
                seen["kin"] += 1
    assert all(seen.values()), seen


# ----------------------------------------------------------------------------------------------------------------
# 3. physics of the assembled problem (independent of both implementations)
# ----------------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("velocity_form", [False, True])
def test_box_resting_on_table_stays_at_rest(velocity_form):
    mass, g, h, mu = 2.0, 9.81, 0.005, 0.5
    scene = parse_scene({
        "name": "rest", "world": {"plane": "vertical", "gravity": [0.0, -g], "friction": mu}, "sim": {"h": h},
        "bodies": [{"name": "box", "type": "dynamic", "mass": mass, "position": [0.3, 0.05],
                    "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]},
                   {"name": "table", "type": "static",
                    "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]}]})
    model = compile_scene(scene)
    q, v, qk, vk = model.q0, model.v0, model.qk0, model.vk0
    prob = Problem(model, q, v, qk, vk, h, velocity_form)
    (isl_con, isl_sup), = prob.groups.values()
    assert len(isl_con) == 2
    A_ref, b_ref, G, parts = check_island(prob, isl_con, isl_sup)
    A, b, *_ = kernel_lcp(*prob.args(isl_con, isl_sup), parts["n"])
    res = lemke(A, b)
    assert res.solved, res.status
    z = res.z
    nc, nf = parts["nc"], parts["nf"]
    assert np.sum(z[:nc]) == pytest.approx(mass * g * h, rel=1e-9)
    np.testing.assert_allclose(z[nc:nc + 2 * nf], 0.0, atol=1e-12)
    v_new = prob.v_tilde.ravel() + parts["Minv"] @ G @ z[:parts["nforce"]]
    np.testing.assert_allclose(v_new, 0.0, atol=1e-12)


def test_box_sliding_on_table_loses_mu_g_h():
    """Horizontal plane: a box sliding along a friction direction loses exactly mu g h of speed per step."""
    mass, g, h, mu, v0 = 1.5, 9.81, 0.01, 0.3, 0.5
    scene = parse_scene({
        "name": "slide", "world": {"plane": "horizontal", "support_gravity": g, "friction": mu},
        "sim": {"h": h, "friction_directions": 8},
        "bodies": [{"name": "box", "type": "dynamic", "mass": mass, "velocity": [v0, 0.0],
                    "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]},
                   {"name": "post", "type": "static", "position": [5.0, 5.0],
                    "shapes": [{"type": "disk", "radius": 0.01}]}]})
    model = compile_scene(scene)
    prob = Problem(model, model.q0, model.v0, model.qk0, model.vk0, h, False)
    assert prob.ncon == 0
    (isl_con, isl_sup), = prob.groups.values()
    A_ref, b_ref, G, parts = check_island(prob, isl_con, isl_sup)
    A, b, *_ = kernel_lcp(*prob.args(isl_con, isl_sup), parts["n"])
    res = lemke(A, b)
    assert res.solved, res.status
    v_new = prob.v_tilde.ravel() + parts["Minv"] @ G @ res.z[:parts["nforce"]]
    np.testing.assert_allclose(v_new, [v0 - mu * g * h, 0.0, 0.0], atol=1e-10)


# ----------------------------------------------------------------------------------------------------------------
# 4. the comparator can fail
# ----------------------------------------------------------------------------------------------------------------

def test_comparator_detects_small_perturbations():
    scene = _vertical_scene()
    model = compile_scene(scene)
    q, v, qk, vk = _random_state(model, np.random.default_rng(3))
    prob = Problem(model, q, v, qk, vk, scene.sim.h, False, force_all=True)
    (isl_con, isl_sup), = prob.groups.values()
    A_ref, b_ref, G, parts = reference_lcp(*prob.args(isl_con, isl_sup))
    A, b, *_ = kernel_lcp(*prob.args(isl_con, isl_sup), parts["n"])
    assert lcp_mismatch(A, b, A_ref, b_ref) is None
    n = parts["n"]
    rng = np.random.default_rng(7)
    for _ in range(5):
        b2 = b.copy()
        i = rng.integers(n)
        b2[i] += 1e-9 * np.max(np.abs(b_ref))
        assert lcp_mismatch(A, b2, A_ref, b_ref) is not None
        A2 = A.copy()
        A2[rng.integers(n), rng.integers(n)] += 1e-9 * np.max(np.abs(A_ref))
        assert lcp_mismatch(A2, b, A_ref, b_ref) is not None
    A2 = A.copy()
    A2[0, 0] = np.nan
    assert lcp_mismatch(A2, b, A_ref, b_ref) is not None
    assert lcp_mismatch(A[:-1, :-1], b[:-1], A_ref, b_ref) is not None
    # plausible bugs: the tangent's sign, the transposed coupling, a forgotten v_hat
    u = parts["nc"]
    b2 = b.copy()
    b2[[u, u + 1]] = b2[[u + 1, u]]
    assert lcp_mismatch(A, b2, A_ref, b_ref) is not None
    A_t = A.copy()
    A_t[parts["nforce"]:, :] = A.T[parts["nforce"]:, :]
    assert lcp_mismatch(A_t, b, A_ref, b_ref) is not None
    A_ref2, b_ref2, *_ = reference_lcp(*prob.args(isl_con, isl_sup)[:-3], np.zeros_like(prob.v_hat), prob.h, False)
    assert lcp_mismatch(A, b, A_ref2, b_ref2) is not None



def _shifted_poses(orig):
    def contact_column(m, poses, *rest):
        moved = poses.copy()
        moved[:, :2] += 1e-4
        return orig(m, moved, *rest)
    return contact_column


# (kernel helper replaced, replacement built from the original): plausible slips in the kernel's building blocks
MUTANTS = {
    "kinematic velocity dropped": ("kinematic_velocity_along", lambda orig: (lambda *a: 0.0)),
    "column . v off by 1e-9": ("column_dot", lambda orig: (lambda *a: orig(*a) * (1.0 + 1e-9))),
    "support directions rotated": ("table_column_at",
                                   lambda orig: (lambda d, rx, ry, dx, dy, *r: orig(d, rx, ry, dy, -dx, *r))),
    "lever arm about a shifted point": ("contact_column", _shifted_poses),
}


@pytest.mark.parametrize("mutant", sorted(MUTANTS))
def test_oracle_catches_a_mutated_kernel(mutant, monkeypatch):
    """Run the kernel's own python source (py_func: its callees are looked up in the module at call time, so they
    can be replaced) with one helper broken: the unmutated source must match the reference, the mutant must not."""
    name, make = MUTANTS[mutant]
    assemble = getattr(AS.assemble_lcp, "py_func", AS.assemble_lcp)
    problems = []
    for scene, support in ((_horizontal_scene(), "limit_surface"), (_horizontal_scene(), "points"),
                           (_vertical_scene(), None)):
        model = compile_scene(scene, support_model=support)
        q, v, qk, vk = _random_state(model, np.random.default_rng(11))
        for velocity_form in (False, True):
            prob = Problem(model, q, v, qk, vk, scene.sim.h, velocity_form, force_all=True)
            problems += [(prob, c, s) for c, s in prob.groups.values()]

    def mismatches():
        out = []
        for prob, isl_con, isl_sup in problems:
            A_ref, b_ref, _, parts = reference_lcp(*prob.args(isl_con, isl_sup))
            with monkeypatch.context() as mp:
                mp.setattr(AS, "assemble_lcp", assemble)
                # its helper that calls the mutated ones runs as python too, so that it sees them
                mp.setattr(AS, "assemble_columns", getattr(AS.assemble_columns, "py_func", AS.assemble_columns))
                mp.setattr(AS, "normal_column", getattr(AS.normal_column, "py_func", AS.normal_column))
                mp.setattr(AS, "support_columns", getattr(AS.support_columns, "py_func", AS.support_columns))
                A, b, *_ = kernel_lcp(*prob.args(isl_con, isl_sup), parts["n"])
            out.append(lcp_mismatch(A, b, A_ref, b_ref))
        return out

    assert mismatches() == [None] * len(problems)
    monkeypatch.setattr(AS, name, make(getattr(AS, name)))
    assert any(mismatches()), f"the oracle did not notice the mutant '{mutant}'"
