"""The step's own code run on dual numbers: forward-mode derivatives of exactly what the compiled step computes.

`dual_version(kernel)` is the kernel's Python function (as engine/interpreted.py makes it) whose calls go to the
Python functions of the numba dispatchers it calls, recursively, with `numpy`, `math`, `max` and `min` replaced by
the dual-aware stand-ins of dual.py. Run on dual inputs, every floating-point operation of the step (contacts,
assembly, the certificate, integration) computes its value as the compiled kernel does and its derivatives along the
seeded directions. Lemke's pivots are the exception: they run compiled on the LCP's values (`_on_values`, the same
answer bit for bit), and the answer's derivatives are set from the LCP data's at its basis (`_directional`): the
positive z's rows held, the implicit-function derivative of the LCP there.

Where the answer is degenerate (an index with z_i = 0 and w_i = 0) the basis is one of several, and its derivative
holds on one side at most: `_directional` gives the directional derivative along each seeded direction instead, the
solution of the derivative LCP over the degenerate indices (docs/method.md, "Derivatives of the step"). Seeded with
the directions +e_k and -e_k side by side, one run gives the two one-sided derivatives along each input.
"""

import itertools
import math
import types

import numpy as np
from numba.core.dispatcher import Dispatcher

from planar_lcp.derivatives import dual
from planar_lcp.derivatives.dual import MATH, NP, Dual, dual_max, dual_min
from planar_lcp.engine import assemble as _assemble
from planar_lcp.engine import step as _step
from planar_lcp.engine.assemble import REST_SPEED
from planar_lcp.engine.constants import SUPPORT_POINTS
from planar_lcp.engine.solvers import lemke as _lemke


class Recorder:
    """What one step run on duals met: `solves`, one record per LCP answer it applied, (A, b, z, beta, layout,
    nonunique): the LCP and its answer as duals (z's derivatives set by `_directional`), the degenerate indices' mask,
    the island's layout (its contacts' pairs, support elements, servos and each friction unknown's lambda; or the
    velocity form's projection's pairs) and the unknowns of the free directions the inputs break (`_check_unique`);
    `unrecorded` (answers from a solver that writes no dense LCP: PGS), `ties` (the functions where max or min met a
    tie), `unsolved` (derivative LCPs Lemke did not solve: the positive z's rows' derivative was kept), `fp_extra` (the
    fixed-point iterations run past the compiled step's for its derivatives)."""

    def __init__(self, res_tol):
        self.res_tol = res_tol
        self.pending = None
        self.solves = []
        self.unrecorded = 0
        self.ties = []
        self.unsolved = 0
        self.projection = False
        self.layout = None
        self.fp_extra = 0


#: the recorder of the step running now (a step on duals is not re-entrant)
_active = [None]


def degenerate_indices(A, b, z, res_tol):
    """(values z, values w, masks of the strictly positive z, the degenerate and the strictly positive w indices) of
    an LCP answer: zero is below the certificate's tolerance, res_tol times the LCP's scale for w (the residual test
    of engine/solvers/certificate.py) and res_tol times max(1, max z) for z."""
    n = len(z)
    zv = dual.values(np.array(z, dtype=object))
    Av, bv = dual.values(A), dual.values(b)
    wv = Av @ zv + bv
    scale = max(1.0, float(np.max(np.abs(Av), initial=0.0)), float(np.max(np.abs(bv), initial=0.0)))
    tol_w = res_tol * scale
    tol_z = res_tol * max(1.0, float(np.max(np.abs(zv), initial=0.0)) if n else 1.0)
    zpos = zv > tol_z
    wpos = (wv > tol_w) & ~zpos
    return zv, wv, zpos, ~zpos & ~wpos, wpos


def _directional(A, b, z, res_tol, rec):
    """Overwrite the derivatives of the LCP answer z (an object array, in place) by its directional derivatives along
    each seeded direction, from the LCP data's derivatives alone: the positive z stay in their rows (w = 0), the
    positive w keep z = 0, and the degenerate indices (both zero) solve the derivative LCP (its Schur complement
    over them) by Lemke. Independent of the pivots that found z (their arithmetic skips exact zeros, and with them
    derivatives). Returns the degenerate indices' mask and `_check_unique`'s list."""
    n = len(z)
    zv, wv, alpha, beta, gamma = degenerate_indices(A, b, z, res_tol)
    k = next((x.d.shape[0] for x in list(A.ravel()) + list(b) + list(z) if isinstance(x, Dual)), 0)
    if k == 0 or n == 0:
        return beta, []
    Av = dual.values(A)
    dA = dual.grads(A, k)                                   # (n, n, k)
    db = dual.grads(np.array(b, dtype=object), k)           # (n, k)
    r = np.einsum("ijk,j->ik", dA, zv) + db                 # the data's change of w at fixed z, per direction
    ia, ib = np.flatnonzero(alpha), np.flatnonzero(beta)
    nonunique = _check_unique(Av, dA, np.flatnonzero(alpha | beta))
    Aaa, Aab, Aba, Abb = Av[np.ix_(ia, ia)], Av[np.ix_(ia, ib)], Av[np.ix_(ib, ia)], Av[np.ix_(ib, ib)]
    # redundant contacts can make A_aa singular (statically indeterminate impulses): the least-norm impulses then,
    # which give the same velocities
    P = np.linalg.pinv(Aaa) if len(ia) else np.zeros((0, 0))
    dz = np.zeros((n, k))
    dz[ia] = -(P @ r[ia])
    # the rows of the positive z hold exactly unless A_aa is singular and the data's change leaves its range
    tol = 1e-9 * max(1.0, float(np.max(np.abs(Av), initial=0.0)))
    for c in range(k):
        ra, rb = r[ia, c], r[ib, c]
        if not (np.all(np.isfinite(ra)) and np.all(np.isfinite(rb))):
            dz[:, c] = np.nan           # the data's derivative overflowed: step_derivatives reports it unbounded
            continue
        consistent = np.max(np.abs(Aaa @ dz[ia, c] + ra), initial=0.0) <= tol * max(1.0, np.max(np.abs(ra),
                                                                                                  initial=0.0))
        if consistent and (len(ib) == 0 or np.all(rb + Aba @ dz[ia, c] >= 0.0)):
            continue                                        # dz_beta = 0: the degenerate indices stay at zero
        sol = _mixed_lcp(Aaa, Aab, Aba, Abb, ra, rb)
        if sol is None:
            rec.unsolved += 1               # dz as the positive z's rows give it, the degenerate indices at zero
            continue
        dz[ia, c], dz[ib, c] = sol
    for i in range(n):
        z[i] = Dual(float(zv[i]), dz[i].copy())
    return beta, nonunique


def _check_unique(Av, dA, S):
    """The unknowns (tuples of indices) of the answer's free directions that a change of the inputs breaks.

    A null vector u of A over the unknowns that may be positive (S: the positive and the degenerate z) moves z
    without moving w: the LCP's answers form a segment there. Where A u stays zero for nearby inputs (the two
    friction rays +t, -t of one contact; a box's two corners squeezing it) every answer on the segment gives the same
    velocities, and the derivatives do not depend on which one Lemke found. Where a change of the inputs makes A u
    non-zero (the limit surface's re-centred column coinciding with a fixed twist's), the answers nearby leave the
    segment in a direction no first-order analysis at this point sees, and Lemke's answer at the point is not their
    limit: no derivative here is trustworthy."""
    out = []
    if len(S) == 0:
        return out
    M = Av[np.ix_(S, S)]
    U, sv, Vt = np.linalg.svd(M)
    if sv[0] == 0.0:
        return out
    null = Vt[sv <= 1e-9 * sv[0]]
    dM = dA[np.ix_(S, S)]                                   # (s, s, k)
    big = float(np.max(np.abs(dM), initial=0.0))
    for u in null:
        moved = np.einsum("ijk,j->ik", dM, u)
        if np.max(np.abs(moved), initial=0.0) > 1e-7 * max(big, 1e-300):
            out.append(tuple(int(S[i]) for i in np.flatnonzero(np.abs(u) > 1e-3)))
    return out


def _mixed_lcp(Aaa, Aab, Aba, Abb, ra, rb):
    """(dz_a, dz_b) with Aaa dz_a + Aab dz_b + ra = 0 (dz_a free) and 0 <= dz_b _|_ Aba dz_a + Abb dz_b + rb >= 0,
    by Lemke on the LCP that splits dz_a = u+ - u- (its two rows' blocks force the equality); None if Lemke finds
    none."""
    from planar_lcp.lcp import lemke
    na = len(ra)
    M = np.block([[Aaa, -Aaa, Aab], [-Aaa, Aaa, -Aab], [Aba, -Aba, Abb]])
    res = lemke(M, np.concatenate([ra, -ra, rb]))
    if res.solved:
        return res.z[:na] - res.z[na:2 * na], res.z[2 * na:]
    return _enumerate_mixed_lcp(Aaa, Aab, Aba, Abb, ra, rb)


#: the most degenerate indices whose 2^n sign patterns `_enumerate_mixed_lcp` tries
ENUMERATE_MAX = 10


def _enumerate_mixed_lcp(Aaa, Aab, Aba, Abb, ra, rb):
    """The mixed LCP of `_mixed_lcp` by its sign patterns, where Lemke ends on a ray (the split problem is not
    copositive-plus, as with a force-limited body's lag blocks, minus each other's transpose): for each subset B of
    the degenerate indices (fewest first), dz_B free with their rows held, the others at zero, accepted when dz_B >= 0
    and the others' rows >= 0 (to round-off). None if no pattern is a solution, or there are too many to try."""
    na, nb = len(ra), len(rb)
    if nb > ENUMERATE_MAX:
        return None
    A = np.block([[Aaa, Aab], [Aba, Abb]])
    r = np.concatenate([ra, rb])
    tol = 1e-9 * max(1.0, float(np.max(np.abs(A), initial=0.0)), float(np.max(np.abs(r), initial=0.0)))
    for size in range(nb + 1):
        for B in itertools.combinations(range(nb), size):
            rows = list(range(na)) + [na + i for i in B]
            x = np.linalg.lstsq(A[np.ix_(rows, rows)], -r[rows], rcond=None)[0]
            dz = np.zeros(na + nb)
            dz[rows] = x
            dw = A @ dz + r
            if (np.max(np.abs(dw[rows]), initial=0.0) <= tol and np.all(dz[na:] >= -tol)
                    and np.all(dw[na:] >= -tol)):
                return dz[:na], np.maximum(dz[na:], 0.0)
    return None


def _after_solve(w, A, b, n):
    rec = _active[0]
    if rec is None:
        return
    z = w.lemke_z
    zs = np.array(z[:n], dtype=object)
    beta, nonunique = _directional(A[:n, :n], b[:n], zs, rec.res_tol, rec)
    for i in range(n):
        z[i] = zs[i]
    if rec.projection:
        layout = ("projection", np.array(w.check_pair[:n]))
    else:
        layout = rec.layout
    zv = dual.values(zs)
    nonunique = [idx for idx in nonunique if not _pinned(layout, zv, idx)]
    rec.pending = (A[:n, :n].copy(), np.array(b[:n], dtype=object), zs, beta, layout, nonunique)


def _on_values(w, A, b, n, settings, block):
    """Lemke's kernel (block Lemke's with `block`), compiled, on the values of the LCP (A, b) of size n and of the
    work's Lemke buffers, its results written back into them: the pivots compute no derivatives (`_directional` sets
    the answer's from the LCP data), and compiled they cost what a step's do. The same floating-point operations as
    the kernel's Python function on duals (no fast-math), so the same answer bit for bit, which `step_derivatives`
    checks against the compiled step. Returns the kernel's (status, pivots, residual)."""
    from planar_lcp.engine.layout import (BLOCK_LAYOUT, LEMKE_LAYOUT, BlockLemkeWork, LemkeWork,
                                          lemke_work_struct)
    from planar_lcp.engine.solvers.block_lemke import block_lemke
    layout = LEMKE_LAYOUT + BLOCK_LAYOUT if block else LEMKE_LAYOUT
    arrays = []
    for f in layout:
        a = getattr(w, f.name)
        arrays.append(np.ascontiguousarray(dual.values(a) if a.dtype == object else a))
    work = (BlockLemkeWork if block else LemkeWork)(*arrays)
    Av = np.ascontiguousarray(dual.values(A[:n, :n]))
    bv = np.ascontiguousarray(dual.values(b[:n]))
    kernel = block_lemke if block else _lemke.lemke_kernel
    out = kernel(Av, bv, settings, lemke_work_struct(work))
    for f, a in zip(layout, arrays):
        target = getattr(w, f.name)
        target[...] = a if target.dtype != object else a.astype(object)
    return out


def _hook_lemke_in_work(_dual_pivots):
    """Lemke on the values (the dual version of the pivots is not run), then the answer's derivatives."""
    def lemke_in_work(w, A, b, n, opt, piv_tol, equilibrate, max_pivots=-1):
        from planar_lcp.engine.layout import LemkeSettings
        if max_pivots < 0:
            max_pivots = _lemke.default_max_pivots(n)
        out = _on_values(w, A, b, n, LemkeSettings(max_pivots, piv_tol, opt.ratio_tol, opt.res_tol,
                                                   np.bool_(equilibrate)), False)
        _after_solve(w, A, b, n)
        return out
    return lemke_in_work


def _hook_block_lemke_in_work(_dual_pivots):
    """Block Lemke on the values, then the answer's derivatives."""
    def block_lemke_in_work(w, A, b, n, opt):
        from planar_lcp.engine.layout import LemkeSettings
        out = _on_values(w, A, b, n, LemkeSettings(_lemke.BLOCK_PIVOTS_PER_UNKNOWN * n + 100, opt.piv_tol,
                                                   opt.ratio_tol, opt.res_tol, np.bool_(False)), True)
        _after_solve(w, A, b, n)
        return out
    return block_lemke_in_work


def _hook_apply_impulses(inner):
    def apply_impulses(nforce, col_dyn, col_g, z, m, v):
        """engine.assemble.apply_impulses without its skip of zero impulses: an impulse whose value is zero can have
        derivatives (a degenerate index the derivative LCP moves). Adding its zero changes no value (but the sign
        of a zero)."""
        rec = _active[0]
        if rec is not None:
            if rec.pending is None:
                rec.unrecorded += 1
            else:
                rec.solves.append(rec.pending)
            rec.pending = None
        for u in range(nforce):
            zu = z[u]
            if not isinstance(zu, Dual) and zu == 0.0:
                continue
            for side in range(2):
                d = col_dyn[u, side]
                if d >= 0:
                    v[d, 0] += col_g[u, side, 0] * zu / m.dyn_mass[d]
                    v[d, 1] += col_g[u, side, 1] * zu / m.dyn_mass[d]
                    v[d, 2] += col_g[u, side, 2] * zu / m.dyn_inertia[d]
    return apply_impulses


def _hook_project(inner):
    def project_out_of_penetration(m, w, opt, qk_new, stats):
        rec = _active[0]
        if rec is not None:
            rec.projection = True
        try:
            return inner(m, w, opt, qk_new, stats)
        finally:
            if rec is not None:
                rec.projection = False
    return project_out_of_penetration


def _slack_of(m, pairs, nf, nsi, k):
    """Per LCP unknown of an island (engine/assemble.py's blocks), the index of the sliding-speed unknown (lambda) of
    its friction, or -1 (a normal impulse, a lambda, a servo's lag)."""
    nci = len(pairs)
    o_bs, o_lc = nci + 2 * nf, nci + 2 * nf + k * nsi
    out = {}
    f = 0
    for c in range(nci):
        if m.pair_mu[pairs[c]] > 0.0:
            out[nci + 2 * f] = out[nci + 2 * f + 1] = o_lc + f
            f += 1
    for a in range(nsi):
        for i in range(k):
            out[o_bs + k * a + i] = o_lc + nf + a
    return out


def _pinned(layout, zv, idx):
    """Whether the unknowns idx of an answer's free direction leave the velocities where they are: normal impulses
    (their rows hold the gaps' velocities) and friction of a contact or table that sticks (its lambda is zero, so
    its rows hold the slip at zero). Friction of a sliding element is not: the split moves how it opposes the slip."""
    if layout is None:
        return False
    if layout[0] == "projection":
        return True
    slack = layout[4]
    for i in idx:
        lam = slack.get(i, -1)
        if i in slack and zv[lam] > 0.0:
            return False
    return True


def _hook_assemble_lcp(inner):
    def assemble_lcp(m, w, vk, nci, nsi, h, velocity_form, A, b, elastic=True):
        rec = _active[0]
        if rec is not None:
            pairs = np.array(w.con_pair[np.array(w.island_con[:nci], dtype=np.int64)])
            nf = int(sum(1 for p in pairs if m.pair_mu[p] > 0.0))
            k = m.fric_dirs.shape[0] if int(m.support_model) == SUPPORT_POINTS else m.ls_wrench.shape[1] + 1
            rec.layout = ("island", pairs, np.array(w.island_sup[:nsi]), np.array(w.island_servo),
                          _slack_of(m, pairs, nf, nsi, k))
        return inner(m, w, vk, nci, nsi, h, velocity_form, A, b, elastic)
    return assemble_lcp


#: the fixed-point form on duals iterates on (at most this many more times) until the derivatives of q_hat, not
#: only its value, change by less than this fraction of their size: a state at rest reaches its fixed point's value
#: in one iteration and its derivatives only at the iteration's linear rate
FP_DERIVATIVE_RTOL = 1e-12
FP_EXTRA_ITERATIONS = 200


def _hook_needs_another_solve(inner):
    def needs_another_solve(m, w, opt, q, h, qk_out, fp_iter, stats):
        rec = _active[0]
        moved = 0.0
        size = 0.0
        if rec is not None and opt.formulation == _step.FORM_FIXED_POINT:
            for d in range(q.shape[0]):
                for c in range(3):
                    a, b = w.q_new[d, c], w.q_hat[d, c]
                    if isinstance(a, Dual):
                        moved = max(moved, float(np.max(np.abs(a.d - (b.d if isinstance(b, Dual) else 0.0)))))
                        size = max(size, float(np.max(np.abs(a.d))))
        again, it = inner(m, w, opt, q, h, qk_out, fp_iter, stats)
        if (not again and it >= 0 and it <= opt.fp_iters and moved > FP_DERIVATIVE_RTOL * max(size, 1.0)
                and rec.fp_extra < FP_EXTRA_ITERATIONS and fp_iter < opt.fp_iters):
            rec.fp_extra += 1
            return True, it
        return again, it
    return needs_another_solve


def _hook_recentre(inner):
    def recentre_limit_surfaces(m, w):
        """engine.assemble.recentre_limit_surfaces, with the derivatives of a body's free-motion velocity (and of
        its angle) left out where the body is at rest up to round-off (REST_SPEED). The re-centred column follows
        the velocity's direction in the body frame, whose derivative grows as 1 / |v~|: at |v~| = 1e-260 (a resting
        body's velocity decays that far) it overflows, where the compiled step takes the direction as it comes.
        Without derivatives there the column is fixed in the body frame for the derivatives, as it is for a body
        exactly at rest (the fixed column 0)."""
        held = []                                   # (array, index, the dual it held)
        for d in range(w.v_tilde.shape[0]):
            if max(abs(_value(w.v_tilde[d, c])) for c in range(3)) >= REST_SPEED:
                continue
            # the body frame's angle too: it turns v~ into the body frame, and its derivative times 1 / |v~|
            # overflows as well; the column is rotated back to the world with the angle's derivatives (assembly)
            for arr, idx in [(w.v_tilde, (d, c)) for c in range(3)] + [(w.body_pose, (m.dyn_body[d], 2))]:
                if isinstance(arr[idx], Dual):
                    held.append((arr, idx, arr[idx]))
                    arr[idx] = arr[idx].v
        try:
            return inner(m, w)
        finally:
            for arr, idx, saved in held:
                arr[idx] = saved
    return recentre_limit_surfaces


def _value(x):
    return x.v if isinstance(x, Dual) else float(x)


def _python(f):
    """A kernel's Python function (a numba dispatcher's py_func; the function itself under NUMBA_DISABLE_JIT=1)."""
    return getattr(f, "py_func", f)


_HOOKS = {
    _python(_step.needs_another_solve): _hook_needs_another_solve,
    _python(_assemble.assemble_lcp): _hook_assemble_lcp,
    _python(_lemke.lemke_in_work): _hook_lemke_in_work,
    _python(_lemke.block_lemke_in_work): _hook_block_lemke_in_work,
    _python(_assemble.apply_impulses): _hook_apply_impulses,
    _python(_assemble.recentre_limit_surfaces): _hook_recentre,
    _python(_step.project_out_of_penetration): _hook_project,
}

_dual = {}


def dual_version(kernel):
    """The Python function of `kernel` (a numba dispatcher or a function) run on duals: its numba callees replaced
    by their dual versions down the whole call tree, `numpy`, `math`, `max` and `min` by dual.py's (made once per
    function)."""
    func = _python(kernel)
    known = _dual.get(func)
    if known is not None:
        return known
    module_globals = {"max": dual_max, "min": dual_min}
    copy = types.FunctionType(func.__code__, module_globals, func.__name__, func.__defaults__, func.__closure__)
    copy.__kwdefaults__ = func.__kwdefaults__
    hook = _HOOKS.get(func)
    _dual[func] = hook(copy) if hook else copy   # before its globals: recursion reaches it again
    for name, value in func.__globals__.items():
        if isinstance(value, Dispatcher) or _engine_function(value):
            value = dual_version(value)
        elif value is np:
            value = NP
        elif value is math:
            value = MATH
        module_globals[name] = value
    return _dual[func]


def _engine_function(value):
    """A plain Python function of the engine's (its kernels under NUMBA_DISABLE_JIT=1, which are not dispatchers)."""
    return isinstance(value, types.FunctionType) and getattr(value, "__module__", "").startswith("planar_lcp.engine")


def objects(a):
    """A copy of a float64 array as an object array of Python floats (duals can be written into it); other arrays
    copied as they are."""
    a = np.asarray(a)
    if a.dtype == np.float64:
        return a.astype(object)
    return a.copy()


def run(kernel, args, recorder):
    """Call the dual version of `kernel` with `args`, recording what it meets in `recorder`."""
    fn = dual_version(kernel)
    _active[0] = recorder
    dual._tie_listeners.append(recorder.ties.append)
    try:
        return fn(*args)
    finally:
        _active[0] = None
        dual._tie_listeners.remove(recorder.ties.append)

