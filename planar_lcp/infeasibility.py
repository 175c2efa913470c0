"""Why a step failed: a certificate that its contact problem has no solution at all, or the word that none was found.

A step fails when no method gives a certified answer of an island's LCP 0 <= z _|_ w = M z + q >= 0 (docs/method.md,
"Certified solves"). Either the LCP has no solution (a kinematic body driving a body into a static one: a rigid
pusher with no force limit asks for the impossible), or it has one the solvers missed. `branch_and_bound` decides
which, with a certificate a reader can check:

- Every solution lies in {z >= 0, M z + q >= 0}; by Farkas' lemma that set is empty exactly when some y >= 0 has
  M^T y <= 0 and q^T y < 0 (then y^T (M z + q) < 0 for every z >= 0). `farkas_certificate` finds such a y by a
  linear program (HiGHS, through scipy) and `impulse_bound` checks it in floating point with the rounding of its
  products bounded, so that the claim is exact: no z with total impulse sum(z) below the bound (N s) is in the set.
- With friction that set is rarely empty: the LP forgets that friction opposes sliding (a frictional jam: the
  pusher wedges the object against the block). The search branches on complementarity, z_i = 0 or w_i = 0 for
  the pair whose product z_i w_i is largest in the LP's point, and stops a branch at a Farkas certificate of its
  own set ({z >= 0, M z + q >= 0, z_i = 0 and w_j = 0 as decided}). When every branch ends so, every solution of
  the LCP would lie in one of the branches' sets, which are all empty: none exists, with impulses below the
  least of the branches' bounds. A branch whose LP point is complementary is a solution (the failure was the
  solvers').

A certificate is accepted when its bound is at least CERTIFICATE_MARGIN times the problem's own momentum scale
(max |q| / max |M|). The bodies named are those of the rows that carry the certificates' weight.
`diagnose_step(sim, q, v, qk, vk)` runs the step again from its state and examines the LCP of the island that no
method certified, as the first try of the solver chain assembled it (engine/solvers/lemke.py
`record_failed_island`).
"""

import math
from dataclasses import dataclass, field

import numpy as np

from planar_lcp.engine.constants import (BODY_KINEMATIC, BODY_STATIC, SERVO_FORCE_DIRECTIONS,
                                         SERVO_TORQUE_DIRECTIONS)
from planar_lcp.engine.solvers.certificate import lcp_scale

#: a certificate is accepted when no solution exists with impulses below this many times max |q| / max |M|
CERTIFICATE_MARGIN = 1e6
#: rows whose certificate weight is below this fraction of the largest do not name their bodies
ROW_WEIGHT_TOL = 1e-9
#: the most branches `branch_and_bound` examines before it says the question is open
MAX_BRANCHES = 4000
#: an LP point is complementary when every z_i w_i is below this times max(|M|, |q|) max(1, max z)
COMPLEMENTARITY_TOL = 1e-12


@dataclass(frozen=True)
class StepDiagnosis:
    """What a failed step's contact problem says about it.

    infeasible : True when the island's LCP is certified to have no solution (the step has no rigid-body answer)
    reason : one line: "no rigid solution: ..." or what was found instead
    bodies : names of the bodies whose rows carry the certificate (empty without one)
    impulse_bound : N s, no LCP solution has a total impulse below it (0 without a certificate)
    branches : the branches `branch_and_bound` examined (0: not examined)
    """

    infeasible: bool
    reason: str
    bodies: tuple = ()
    impulse_bound: float = 0.0
    branches: int = 0


@dataclass
class Search:
    """The answer of `branch_and_bound`: outcome "infeasible" (leaves: (zero_z, zero_w, y) each, the branch's
    decided pairs and its Farkas certificate over the rows of `branch_system`; bound: the least impulse bound),
    "solution" (z, with residual, the natural map's), or "open" (the branch budget ran out, or an LP failed)."""

    outcome: str
    branches: int
    bound: float = 0.0
    leaves: list = field(default_factory=list)
    z: np.ndarray = None
    residual: float = math.inf


def farkas_certificate(G, g):
    """y >= 0 with G^T y <= 0 and g^T y <= -1 (in the problem scaled by its largest entry), of least sum, by HiGHS:
    a certificate that {x >= 0, G x + g >= 0} is empty. None when the linear program says that set is not empty,
    or fails. Raises ImportError without scipy."""
    from scipy.optimize import linprog
    rows, cols = G.shape
    s = max(float(np.abs(G).max(initial=0.0)), float(np.abs(g).max(initial=0.0)))
    if rows == 0 or not (s > 0.0 and math.isfinite(s)):
        return None
    A_ub = np.vstack([G.T / s, g[None, :] / s])
    b_ub = np.concatenate([np.zeros(cols), [-1.0]])
    res = linprog(np.ones(rows), A_ub=A_ub, b_ub=b_ub, bounds=(0, None), method="highs")
    if res.status != 0:
        return None
    return np.maximum(res.x, 0.0)


def impulse_bound(G, g, y):
    """For y >= 0: the largest Z such that no x >= 0 with sum(x) < Z has G x + g >= 0, from y alone, with the
    rounding of G^T y and g^T y bounded (n eps times the sums of the magnitudes). 0.0 when y certifies nothing."""
    y = np.maximum(np.asarray(y, dtype=float), 0.0)
    eps = np.finfo(float).eps * (max(G.shape) + 4)
    slack = G.T @ y + eps * (np.abs(G).T @ y)          # an upper bound on each exact (G^T y)_j
    gy = float(g @ y + eps * (np.abs(g) @ y))           # an upper bound on the exact g^T y
    if not gy < 0.0:
        return 0.0
    worst = float(slack.max(initial=0.0))
    return math.inf if worst <= 0.0 else -gy / worst


def branch_system(M, q, zero_z, zero_w):
    """A branch's set as {x >= 0, G x + g >= 0}: x the z_i not decided zero (`free`, a boolean mask), the rows
    w >= 0, then -w_j >= 0 for the decided w_j = 0. Returns (G, g, free, rows): rows[k] is the LCP row of G's row k."""
    n = q.shape[0]
    free = np.ones(n, bool)
    free[list(zero_z)] = False
    E = sorted(zero_w)
    G = np.vstack([M[:, free], -M[np.ix_(E, free)]]) if E else M[:, free]
    g = np.concatenate([q, -q[E]]) if E else q.copy()
    return G, g, free, list(range(n)) + E


def _natural_residual(M, q, z):
    w = M @ z + q
    return float(np.abs(np.minimum(z, w)).max(initial=0.0))


def _polished(M, q, z, w):
    """An LP's complementary point made exact where it can be: z on the basis {z_i > w_i} solved from (M, q) by
    numpy (the LP's answer is within its own feasibility tolerance). Returns the better point and its residual."""
    best, res = z, _natural_residual(M, q, z)
    basic = z > w
    if basic.any():
        try:
            zb = np.linalg.solve(M[np.ix_(basic, basic)], -q[basic])
        except np.linalg.LinAlgError:
            return best, res
        exact = np.zeros_like(z)
        exact[basic] = zb
        r = _natural_residual(M, q, exact)
        if r < res:
            best, res = exact, r
    return best, res


def branch_and_bound(M, q, max_branches=MAX_BRANCHES):
    """Decide whether the LCP (M, q) has a solution (module docstring). Returns a Search."""
    from scipy.optimize import linprog
    n = q.shape[0]
    s = max(float(np.abs(M).max(initial=0.0)), float(np.abs(q).max(initial=0.0)), 1e-300)
    stack = [(frozenset(), frozenset())]
    leaves, bound, branches = [], math.inf, 0
    while stack:
        zero_z, zero_w = stack.pop()
        branches += 1
        if branches > max_branches:
            return Search("open", branches - 1)
        G, g, free, _ = branch_system(M, q, zero_z, zero_w)
        lp = linprog(np.ones(int(free.sum())), A_ub=-G / s, b_ub=g / s, bounds=(0, None), method="highs")
        if lp.status == 2:                       # empty, says HiGHS: a certificate of it, checked
            y = farkas_certificate(G, g)
            b = impulse_bound(G, g, y) if y is not None else 0.0
            if not b > 0.0:
                return Search("open", branches)
            leaves.append((zero_z, zero_w, y))
            bound = min(bound, b)
            continue
        if lp.status != 0:
            return Search("open", branches)
        z = np.zeros(n)
        z[free] = np.maximum(lp.x, 0.0)
        w = M @ z + q
        open_pairs = [i for i in range(n) if i not in zero_z and i not in zero_w]
        product = z * w
        if not open_pairs or product[open_pairs].max() <= COMPLEMENTARITY_TOL * s * max(1.0, z.max()):
            z, residual = _polished(M, q, z, w)
            return Search("solution", branches, z=z, residual=residual)
        j = max(open_pairs, key=lambda i: product[i])
        stack.append((zero_z, zero_w | {j}))
        stack.append((zero_z | {j}, zero_w))
    return Search("infeasible", branches, bound, leaves)


def _row_owners(n, nci, nsi, nf, k, frictional):
    """For each row of an island LCP (engine/assemble.py `assemble_lcp`'s layout): ("contact", a) or ("support",
    s) in the island's numbering; frictional: the island contacts with friction, in order."""
    owners = [("contact", a) for a in range(nci)]
    owners += [("contact", frictional[f // 2]) for f in range(2 * nf)]
    owners += [("support", s // k) for s in range(k * nsi)]
    owners += [("contact", frictional[f]) for f in range(nf)]
    owners += [("support", s) for s in range(nsi)]
    assert len(owners) == n, (len(owners), n)
    return owners


def _quoted(names):
    return " and ".join(f"'{x}'" for x in names)


def _jam_sentence(model, bodies):
    """One sentence that names the bodies of a certificate by their kind."""
    a = model.arrays
    names = [b.name for b in model.scene.bodies]
    kinds = {name: a.body_kind[names.index(name)] for name in bodies}
    kin = [b for b in bodies if kinds[b] == BODY_KINEMATIC]
    static = [b for b in bodies if kinds[b] == BODY_STATIC]
    dyn = [b for b in bodies if kinds[b] not in (BODY_KINEMATIC, BODY_STATIC)]
    moved = _quoted(dyn) or "nothing"
    if kin and static:
        return (f"kinematic bod{'y' if len(kin) == 1 else 'ies'} {_quoted(kin)} drive{'s' if len(kin) == 1 else ''} "
                f"{moved} into static bod{'y' if len(static) == 1 else 'ies'} {_quoted(static)}")
    if len(kin) >= 2:
        return f"kinematic bodies {_quoted(kin)} squeeze {moved}"
    return f"the contacts of {_quoted(bodies)} admit no impulses"


def diagnose_step(sim, q, v, qk, vk):
    """A StepDiagnosis of the step of `sim` (a Simulator) from (q, v, qk) with kinematic velocities vk: the step is
    run again from that state (cold: the warm-start memory forgotten), and the LCP of its first island that no
    method certified (the step's kernels keep it: engine/solvers/lemke.py `record_failed_island`) is examined for a
    Farkas certificate."""
    try:
        import scipy.optimize  # noqa: F401
    except ImportError:
        return StepDiagnosis(False, "not examined for a certificate of infeasibility: scipy is not installed "
                                    "(pip install scipy; it comes with the extra 'osqp')")
    model = sim.model
    a = model.arrays
    names = [b.name for b in model.scene.bodies]
    q, v, qk = (np.ascontiguousarray(x, dtype=float) for x in (q, v, qk))
    vk = np.ascontiguousarray(vk, dtype=float).reshape(qk.shape)
    sim.reset_warm_start()
    sim.step(q, v, qk, vk)
    sim.reset_warm_start()
    w = sim.work
    n, nci, nsi, nf, ns = (int(x) for x in w.fail_size)
    if n < 0:
        return StepDiagnosis(False, "the step did not fail again when run from its state: not examined")
    M = w.fail_matrix[:n * n].reshape(n, n).copy()
    b = w.fail_vector[:n].copy()
    con, sup = w.fail_con[:nci].copy(), w.fail_sup[:nsi].copy()
    search = branch_and_bound(M, b)
    if search.outcome == "solution":
        tol = sim.options.res_tol * lcp_scale(M, b)
        return StepDiagnosis(False, f"the contact LCP has a solution to within a residual of {search.residual:.3e} "
                                    f"(found by branch and bound in {search.branches} branches; the step's tolerance "
                                    f"is {tol:.3e}) that no method certified: a solver failure",
                             branches=search.branches)
    scale = float(np.abs(b).max()) / max(float(np.abs(M).max()), 1e-300)
    if search.outcome == "open" or not search.bound >= CERTIFICATE_MARGIN * scale:
        return StepDiagnosis(False, f"whether the contact LCP has a solution was not decided ({search.branches} "
                                    "branches of the search for a certificate): unclassified",
                             branches=search.branches)
    frictional = [c for c in range(nci) if a.pair_mu[con[c]] > 0.0]
    owners = _row_owners(n - ns, nci, nsi, nf, model.support_columns(), frictional)
    # the force-limited bodies' lag rows (engine/assemble.py `assemble_servo`): their own bodies
    kin_bodies = [i for i, b in enumerate(model.scene.bodies) if b.type == "kinematic"]
    for k in w.fail_servo:
        if len(owners) >= n:
            break
        owners += [("servo", int(k))] * (SERVO_FORCE_DIRECTIONS + (SERVO_TORQUE_DIRECTIONS if a.kin_max_torque[k] > 0.0
                                                                   else 0))
    bodies = []
    for zero_z, zero_w, y in search.leaves:
        rows = branch_system(M, b, zero_z, zero_w)[3]
        for r in np.flatnonzero(y > ROW_WEIGHT_TOL * y.max()):
            kind, j = owners[rows[r]]
            if kind == "contact":
                p = con[j]
                found = [a.shape_body[a.pair_a[p]], a.shape_body[a.pair_b[p]]]
            elif kind == "servo":
                found = [kin_bodies[j]]
            else:
                found = [a.dyn_body[a.sup_dyn[sup[j]]]]
            bodies += [names[bi] for bi in found if names[bi] not in bodies]
    bound = search.bound
    what = "none at all" if math.isinf(bound) else f"none with a total impulse below {bound:.3g} N s"
    how = ("a Farkas certificate" if len(search.leaves) == 1 else
           f"Farkas certificates of the {len(search.leaves)} branches of its complementarity")
    return StepDiagnosis(True, f"no rigid solution: {_jam_sentence(model, bodies)} (certified: the contact LCP of the "
                               f"step has {what}; {how})", tuple(bodies), bound, search.branches)
