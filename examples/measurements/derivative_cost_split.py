"""Where the time of the step's derivatives goes: the derivatives at the cold step's bases (engine/tangent.py
`step_tangent`) and one cold step, each timed in a jitted loop (no Python dispatch in the measurement), beside the
same calls from Python (`Simulator.step`, `Simulator.step_derivatives(method="differences")`), at the state
`planar-lcp bench derivatives` differentiates each scene at. Thread CPU time, median of the rounds, each round the
calls in turn.

The ratio in compiled steps is the derivatives' own cost: the tangent's three cold steps (the state's and the mixed
direction's two, timed alone too: its certificate, so that in compiled time it costs more than three steps whatever
the rest costs) and its smooth part's evaluations, two per input; the ratio in Python calls is what `bench
derivatives` reports, where a step's call from Python carries its dispatch.

    python examples/measurements/derivative_cost_split.py
    (--scenes NAME ..., --rounds R and --n N, the calls of each timed loop, for a shorter run)
"""

import argparse
import time

import numpy as np
from numba import njit

from planar_lcp.benchmarks.bench import derivative_state
from planar_lcp.derivatives.differences import kernel_settings
from planar_lcp.engine.layout import NSTAT
from planar_lcp.engine.rollout import DIFF_OK, cold_step_at, mixed_direction_check
from planar_lcp.engine.step import lemke_step
from planar_lcp.engine.tangent import step_tangent
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec.scene import load_scene

SCENES = ("falling_rod", "box_push", "painleve_rod", "bouncing_disk", "block_on_incline", "box_tip", "tip_box",
          "four_disks", "box_stack")


@njit
def _steps(m, q, v, qk, vk, h, opt, w, qo, vo, qko, st, n):
    for _ in range(n):
        lemke_step(m, (q, v, qk, vk), h, opt, w, (qo, vo, qko), st)


@njit
def _tangents(m, h, cold_opt, warm_opt, w, q, v, qk, vk, tols, jac, q1, v1, qk1, st, n):
    code = 0
    for _ in range(n):
        code = step_tangent(m, h, cold_opt, warm_opt, w, q, v, qk, vk, tols, jac, q1, v1, qk1, st)
    return code


@njit
def _cold_steps(m, h, cold_opt, warm_opt, w, q, v, qk, vk, tols, jac, q1, v1, qk1, st, n):
    """The first try's three cold steps alone: the state's (`cold_step_at`) and the mixed direction's two
    (`mixed_direction_check`, against the Jacobian jac the first try gave)."""
    code = 0
    fp, fm = np.empty(jac.shape[0]), np.empty(jac.shape[0])
    for _ in range(n):
        _, x, steps, base, rec, memory = cold_step_at(m, h, cold_opt, w, q, v, qk, vk, tols[0], st)
        code = mixed_direction_check(m, h, warm_opt, w, rec, x, steps, jac, base, memory, tols, fp, fm, q1, v1, qk1)
    return code


def measure(name, rounds, n):
    sc = load_scene(name)
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, solver=sc.sim.solver, formulation=sc.sim.formulation))
    at = derivative_state(sim, sc)
    if at is None:
        return None
    q, v, qk, vk, t = at
    nd, nk = len(q), len(qk)
    warm_opt, tols, _ = kernel_settings(sim)
    jac = np.empty((6 * nd + 3 * nk, 6 * nd + 6 * nk))
    q1, v1, qk1, st = np.empty((nd, 3)), np.empty((nd, 3)), np.empty((nk, 3)), np.empty(NSTAT)
    m, w, opt = sim.kmodel, sim.kwork, sim.kopt

    def api_step():
        sim.reset_warm_start()
        sim.step(q, v, qk, vk)

    def api_derivatives():
        sim.step_derivatives(q, v, qk, vk, method="differences")

    def compiled_step():
        sim.reset_warm_start()
        _steps(m, q, v, qk, vk, sim.h, opt, w, q1, v1, qk1, st, n)

    code = [DIFF_OK, DIFF_OK]          # the first try's code, and its mixed direction's check's alone

    def compiled_tangent():
        sim.forget_last_step()
        code[0] = _tangents(m, sim.h, opt, warm_opt, w, q, v, qk, vk, tols, jac, q1, v1, qk1, st, n)

    def cold_steps():
        sim.forget_last_step()
        code[1] = _cold_steps(m, sim.h, opt, warm_opt, w, q, v, qk, vk, tols, jac, q1, v1, qk1, st, n)

    calls = dict(api_step=(api_step, n), api_derivatives=(api_derivatives, n), compiled_step=(compiled_step, 1),
                 compiled_tangent=(compiled_tangent, 1), cold_steps=(cold_steps, 1))
    per = {k: [] for k in calls}
    for f, _ in calls.values():
        f()                                             # compiles the loops
    for _ in range(rounds):
        for k, (f, reps) in calls.items():
            t0 = time.thread_time()
            for _ in range(reps):
                f()
            per[k].append((time.thread_time() - t0) / n * 1e6)
    sim.reset_warm_start()
    us = {k: float(np.median(x)) for k, x in per.items()}
    # the mixed direction's check holds against the first try's Jacobian where it answers
    answers = code[0] == DIFF_OK and code[1] == DIFF_OK
    return dict(scene=name, t=t, inputs=jac.shape[1], tangent_answers=answers, **us)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--rounds", type=int, default=11)
    ap.add_argument("--n", type=int, default=500, help="calls of each timed loop")
    a = ap.parse_args(argv)
    print("| scene | inputs | tangent answers | step from Python µs | compiled step µs | derivatives from Python µs | "
          "compiled tangent µs | its three cold steps µs | tangent in compiled steps | derivatives in steps from "
          "Python |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in a.scenes:
        r = measure(name, a.rounds, a.n)
        if r is None:
            print(f"| {name} | - | no step of its run meets a contact | | | | | | | |")
            continue
        print(f"| {name} | {r['inputs']} | {'yes' if r['tangent_answers'] else 'no'} | {r['api_step']:.1f} | "
              f"{r['compiled_step']:.1f} | {r['api_derivatives']:.1f} | {r['compiled_tangent']:.1f} | "
              f"{r['cold_steps']:.1f} | {r['compiled_tangent'] / r['compiled_step']:.1f} | "
              f"{r['api_derivatives'] / r['api_step']:.1f} |")


if __name__ == "__main__":
    main()
