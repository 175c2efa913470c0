"""Which shipped scenes' runs are reproducible to rounding, and why not (docs/method.md, "Reproducibility").

    python examples/measurements/reproducibility.py [--scenes NAME ...] [--formulations ...] [--every K] [--no-lcps]

Runs each shipped scene as tests/simulation/test_golden.py records it (the scene's [sim], each formulation, and the horizontal
scenes with support_model = "points" too), then:

1. **Last-bit perturbations** (what another machine's floating point does to a run): the same run from initial poses
   moved by one unit in the last place (each coordinate up or down, seeded; PERTURBED_RUNS runs). Printed:
   the largest difference from the unperturbed run over the whole run (q in m and rad, v in m/s and rad/s), the
   first step where it exceeds GOLDEN_TOL, the golden test's tolerance, and the most steps of one run whose Lemke
   pivot count differs from the unperturbed run's. A run that stays within GOLDEN_TOL is reproducible to rounding;
   one that does not cannot be compared to 1e-12 across machines. For runs with the limit-surface table friction,
   also the steps that start with a body at rest up to round-off (0 < |v| < ROUNDOFF_TWIST): the re-centred
   column of its limit surface then points along the round-off, which differs from machine to machine.
2. **The LCPs' solutions** (why): at every K-th state of the run, the LCP of each island at the step's first
   linearization (the LCP Lemke solves first), solved three ways with dense Lemke (`planar_lcp.lemke`): as
   assembled, with its unknowns in reverse order, and with its constant vector perturbed by 1e-15 (relative,
   seeded). A unique solution comes back three times up to rounding; where the LCP has several, the order of the
   unknowns and the last bits of the data pick one. Per island LCP:
   - several motions: two answers' contact velocities (the rows K z + b of the force unknowns, K the Delassus
     matrix, friction rows without lambda) differ by more than MOTION_TOL m/s. K (z1 - z2) = 0 means the same body
     velocities (dv^T M dv = dz^T K dz), so this is the bodies' motion itself that is not unique;
   - impulses only: the answers' contact impulses (c_n, f_t) differ by more than IMPULSE_TOL N s, the motion not;
   - statically indeterminate: K over the loaded contacts' impulses (c_n and f_t of each contact with c_n > 0 in
     the first answer) is rank-deficient: more impulses than the bodies' motion can tell apart.
"""

import argparse
import sys

import numpy as np
from numba import njit

import planar_lcp.engine.step as S
from planar_lcp.engine.assemble import assemble_lcp, island_problem_size, support_column_count
from planar_lcp.engine.constants import SUPPORT_LIMIT_SURFACE
from planar_lcp.engine.islands import island_members
from planar_lcp.engine.layout import NSTAT, Stat
from planar_lcp.lcp import lemke
from planar_lcp.model import compile_scene
from planar_lcp.sim import FORMULATIONS, SimOptions, Simulator
from planar_lcp.spec.scene import list_scenes, load_scene

#: m/s: two certified answers whose contact velocities differ by more move the bodies differently
MOTION_TOL = 1e-9
#: N s: two certified answers whose impulses differ by more are two solutions (the motion may still be the same)
IMPULSE_TOL = 1e-9


@njit
def _prepare(m, q, v, qk, vk, h, opt, w, qk_out, stats):
    """The step's first contacts and islands at its first linearization pose (engine/step.py step_pipeline)."""
    S.begin_step(m, q, v, qk, vk, h, opt, w, qk_out, stats)
    qk_lin = S.kinematic_linearization(w, qk, opt.formulation == S.FORM_VELOCITY)
    return S.prepare_contacts(m, w, opt, qk_lin, stats)


@njit
def _island_size(m, w, isl, ncon):
    nci, nsi = island_members(m, w, isl, ncon)
    n, nf, _ = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)
    return n, nf, nci, nsi


@njit
def _island_lcp(m, w, vk, isl, ncon, h, velocity_form, A, b):
    nci, nsi = island_members(m, w, isl, ncon)
    assemble_lcp(m, w, vk, nci, nsi, h, velocity_form, A, b)
    return support_column_count(m)


def island_lcps(sim, q, v, qk, vk):
    """[(A, b, nci, nf, nsi, k)] of each island of the step from (q, v, qk) at its first linearization."""
    m, w = sim.kmodel, sim.kwork
    velocity_form = sim.kopt.formulation == S.FORM_VELOCITY
    ncon, nisl = _prepare(m, q, v, qk, vk, sim.h, sim.kopt, w, np.empty_like(qk), np.zeros(NSTAT))
    out = []
    for isl in range(nisl):
        n, nf, nci, nsi = _island_size(m, w, isl, ncon)
        if n == 0:
            continue
        A, b = np.zeros((n, n)), np.zeros(n)
        k = _island_lcp(m, w, vk, isl, ncon, sim.h, velocity_form, A, b)
        out.append((A, b, int(nci), int(nf), int(nsi), int(k)))
    return out


def _contact_velocities(A, b, z, nforce, nci, nf):
    """The force unknowns' rows of w = A z + b without lambda's part: the contacts' normal and tangential velocities
    (and the support columns' table velocities)."""
    w = A[:nforce] @ z + b[:nforce]
    lam = z[nforce:nforce + nf]
    w[nci:nci + 2 * nf] -= np.repeat(lam, 2)
    return w


def _contact_impulses(z, nci, nf):
    """The contacts' impulses as `Trajectory.contacts` reports them: c_n, then f_t = beta+ - beta- of each frictional
    contact (the split of f_t into beta+ and beta- is not unique where a contact sticks: both rows are then 0)."""
    return np.concatenate([z[:nci], z[nci:nci + 2 * nf:2] - z[nci + 1:nci + 2 * nf:2]])


def examine(A, b, nci, nf, nsi, k, rng):
    """(motion difference m/s, impulse difference N s, statically indeterminate?, every answer certified?)"""
    n = len(b)
    nforce = nci + 2 * nf + k * nsi
    ref = lemke(A, b)
    answers = []
    rev = np.arange(n)[::-1]
    r = lemke(A[np.ix_(rev, rev)], b[rev])
    if r.solved:
        z = np.empty(n)
        z[rev] = r.z
        answers.append(z)
    bp = b * (1.0 + 1e-15 * rng.uniform(-1.0, 1.0, n))
    r = lemke(A, bp)
    if r.solved:
        answers.append(r.z)
    certified = ref.solved and len(answers) == 2
    if not ref.solved:
        return 0.0, 0.0, False, False
    vel = _contact_velocities(A, b, ref.z, nforce, nci, nf)
    motion = max([np.abs(_contact_velocities(A, b, z, nforce, nci, nf) - vel).max() for z in answers], default=0.0)
    impulses = max([np.abs(_contact_impulses(z, nci, nf) - _contact_impulses(ref.z, nci, nf)).max(initial=0.0)
                    for z in answers], default=0.0)
    # the loaded contacts' (c_n, f_t) columns: c_n's, and beta+'s of the frictional ones (f_t = beta+ - beta-);
    # slack row f of the LCP holds mu in its contact's column
    loaded = ref.z[:nci] > 1e-12
    o_lc = nforce
    friction_of = {int(np.flatnonzero(A[o_lc + f, :nci] > 0.0)[0]): f for f in range(nf)}
    cols = [a for a in range(nci) if loaded[a]] + [nci + 2 * f for a, f in friction_of.items() if loaded[a]]
    K = A[np.ix_(cols, cols)]
    indeterminate = bool(cols) and np.linalg.matrix_rank(K, tol=1e-10 * max(np.abs(K).max(), 1e-300)) < len(cols)
    return motion, impulses, indeterminate, certified


def cases(scenes=None, formulations=None):
    """tests/simulation/test_golden.py's cases: every shipped scene x formulation, the horizontal ones with "points" too."""
    names = [n for n, _ in list_scenes()]
    forms = formulations or list(FORMULATIONS)
    horizontal = sorted(n for n in names if load_scene(n).world.plane == "horizontal")
    out = [(n, f, None) for n in names for f in forms] + [(n, f, "points") for n in horizontal for f in forms]
    return [c for c in out if not scenes or c[0] in scenes]


#: the golden test's tolerance (m, rad, m/s, rad/s)
GOLDEN_TOL = 1e-12
#: m/s, rad/s: a body slower than this in every component, but not at 0, is at rest up to round-off
ROUNDOFF_TWIST = 1e-9
PERTURBED_RUNS = 8


def case_simulator(name, formulation, support_model):
    """The Simulator and step count tests/simulation/test_golden.py records a case with."""
    sc = load_scene(name)
    s = sc.sim
    sim = Simulator(compile_scene(sc, support_model=support_model), SimOptions(
        h=s.h, solver=s.solver, formulation=formulation, fixed_point_iterations=s.fixed_point_iterations,
        pgs_iterations=s.pgs_iterations))
    return sim, int(round(s.t_end / s.h))


def one_ulp(q, rng):
    """q with each entry moved one unit in the last place up or down at random (a zero by 2^-56, the unit in the
    last place of a coordinate of 0.1)."""
    up = rng.random(q.shape) < 0.5
    moved = np.where(up, np.nextafter(q, np.inf), np.nextafter(q, -np.inf))
    return np.where(q != 0.0, moved, np.where(up, 2.0 ** -56, -(2.0 ** -56)))


def perturbation(sim, nsteps, runs=PERTURBED_RUNS, seed=0):
    """(largest difference over `runs` runs from one-ulp-perturbed initial poses, the first step where one exceeds
    GOLDEN_TOL or -1, the most steps of one run whose pivot count differs from the unperturbed run's, that run)."""
    q, v, qk, vk = sim.initial_state()
    base = sim.rollout(q, v, qk, vk[None], nsteps, stop_on_failure=False)
    rng = np.random.default_rng(seed)
    largest, first, pivots = 0.0, -1, 0
    for _ in range(runs):
        run = sim.rollout(one_ulp(q, rng), v, qk, vk[None], nsteps, stop_on_failure=False)
        d = np.maximum(np.abs(run["q"] - base["q"]).max(axis=(1, 2), initial=0.0),
                       np.abs(run["v"] - base["v"]).max(axis=(1, 2), initial=0.0))
        largest = max(largest, float(d.max()))
        if (d > GOLDEN_TOL).any():
            k = int(np.argmax(d > GOLDEN_TOL)) - 1      # the step that produced the first state beyond it
            first = k if first < 0 else min(first, k)
        pivots = max(pivots, int(np.sum(run["stats"][:, Stat.PIVOTS] != base["stats"][:, Stat.PIVOTS])))
    return largest, first, pivots, base


def roundoff_twists(sim, run):
    """Steps of the run that start with a body at rest up to round-off (0 < |v| < ROUNDOFF_TWIST in every component)
    under the limit-surface table friction, whose re-centred column -L(v~) then points along the round-off
    (docs/method.md, "Table friction"); None for a run without it."""
    a = sim.model.arrays
    if a.sup_dyn.shape[0] == 0 or a.support_model != SUPPORT_LIMIT_SURFACE:
        return None
    mag = np.abs(run["v"][:-1]).max(axis=2)
    return int(((mag > 0.0) & (mag < ROUNDOFF_TWIST)).any(axis=1).sum())


def lcp_census(sim, run, nsteps, every, seed=0):
    """Part 2 over the run's states: counts of island LCPs by kind."""
    rng = np.random.default_rng(seed)
    row = dict(lcps=0, several_motions=0, impulses_only=0, indeterminate=0, uncertified=0, first=-1, motion=0.0,
               largest=0)
    vk = sim.initial_state()[3]
    for step in range(0, nsteps, every):
        state = [np.ascontiguousarray(run[key][step]) for key in ("q", "v", "qk")]
        for A, b, nci, nf, nsi, k in island_lcps(sim, *state, vk):
            motion, impulses, indeterminate, certified = examine(A, b, nci, nf, nsi, k, rng)
            row["lcps"] += 1
            row["largest"] = max(row["largest"], len(b))
            row["uncertified"] += not certified
            row["indeterminate"] += indeterminate
            if motion > MOTION_TOL:
                row["several_motions"] += 1
                if row["first"] < 0:
                    row["first"] = step
            elif impulses > IMPULSE_TOL:
                row["impulses_only"] += 1
            row["motion"] = max(row["motion"], motion)
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="*", help="shipped scene names (default: all)")
    ap.add_argument("--formulations", nargs="*", choices=list(FORMULATIONS))
    ap.add_argument("--every", type=int, default=1, help="examine the LCPs of every K-th step (default 1)")
    ap.add_argument("--no-lcps", action="store_true", help="the perturbed runs only")
    args = ap.parse_args(argv)
    print(f"| scene | formulation | support | steps | one-ulp runs: largest difference | first step > {GOLDEN_TOL:g} | "
          "steps with other pivot counts | steps from a round-off twist (limit surface) | island LCPs | several "
          "motions | impulses only | statically indeterminate | first step of several motions | largest motion "
          "difference (m/s) | largest LCP |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, formulation, support in cases(args.scenes, args.formulations):
        sim, nsteps = case_simulator(name, formulation, support)
        largest, first, pivots, run = perturbation(sim, nsteps)
        twists = roundoff_twists(sim, run)
        cells = [name, formulation, support or "default", nsteps, f"{largest:.1e}", first if first >= 0 else "-",
                 pivots, "-" if twists is None else twists]
        if args.no_lcps:
            cells += [""] * 7
        else:
            r = lcp_census(sim, run, nsteps, args.every)
            cells += [r["lcps"], r["several_motions"], r["impulses_only"], r["indeterminate"],
                      r["first"] if r["first"] >= 0 else "-", f"{r['motion']:.1e}", r["largest"]]
            if r["uncertified"]:
                print(f"  ({name} {formulation}: {r['uncertified']} island LCPs with an answer not certified, "
                      "left out)", file=sys.stderr)
        print("| " + " | ".join(str(c) for c in cells) + " |", flush=True)


if __name__ == "__main__":
    main()
