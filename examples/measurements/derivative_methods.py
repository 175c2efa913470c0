"""The step's checked differences (step_derivatives(method="differences")) against its dual numbers on the states
the derivative oracles use (docs/method.md, "Derivatives of the step"): 5 states along each shipped scene's run in
the three formulations and 4 along each of 28 seeded random scenes in the position and fixed-point forms. Printed:
how many states the differences stood on, by whether the dual numbers call the state exact, the reasons they gave
way or call the state not exact (the mixed direction's check), the kinds of degeneracy the dual numbers name where
the differences stood on a state they do not call exact, and the differences' largest difference from the dual
numbers' derivatives, relative to the largest entry of its row or column (at least 1e-4), over the states both call
exact; then the same for their first try alone, the derivatives at the cold step's bases (engine/tangent.py): the
states it answered and why it left the others to the differences of whole steps.

    python examples/measurements/derivative_methods.py
"""

import collections
import os
import sys

import numpy as np

from planar_lcp.derivatives.differences import tangent_at_bases
from planar_lcp.engine.rollout import DIFF_MOVES, DIFF_OK
from planar_lcp.engine.tangent import TANGENT_CONTACTS, TANGENT_DEGENERATE, TANGENT_KINK, TANGENT_NOT_COVERED
from planar_lcp.model import compile_scene
from planar_lcp.sim import Simulator
from planar_lcp.spec.scene import load_scene

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "tests", "derivatives"))
from derivative_scenes import (SHIPPED, options, random_pushing_scene, random_vertical_scene,  # noqa: E402
                               states_along)


#: why the derivatives at the bases left a state to the differences of whole steps
TANGENT_REASONS = {TANGENT_NOT_COVERED: "not covered (formulation, solver, re-solve)",
                   TANGENT_DEGENERATE: "left: a degenerate index that moves",
                   TANGENT_CONTACTS: "left: contacts or a re-solve change nearby",
                   TANGENT_KINK: "left: the smooth part's one-sided differences differ",
                   DIFF_MOVES: "answered, not exact (mixed)"}


def runs():
    for formulation in ("position", "fixed_point", "velocity"):
        for name in SHIPPED:
            sim = Simulator(compile_scene(load_scene(name)), options(formulation))
            yield f"{name} ({formulation})", sim, states_along(sim, *sim.initial_state(), 40, 8)
    for formulation in ("position", "fixed_point"):
        for seed in range(14):
            for scene in (random_vertical_scene(seed), random_pushing_scene(seed)):
                sim = Simulator(compile_scene(scene), options(formulation))
                yield f"{scene.name} ({formulation})", sim, states_along(sim, *sim.initial_state(), 60, 15)


def main():
    counts = collections.Counter()
    kinds = collections.Counter()
    worst, where = 0.0, ""
    tangent = collections.Counter()
    t_worst, t_where = 0.0, ""
    for label, sim, states in runs():
        for s in states:
            ref = sim.step_derivatives(*s)
            code, jac = tangent_at_bases(sim, *(np.ascontiguousarray(a, dtype=float) for a in s))
            tangent[(ref.exact, TANGENT_REASONS.get(code, "answered"))] += 1
            if code == DIFF_OK and ref.exact:
                A = np.abs(ref.jacobian)
                scale = np.maximum(np.maximum(A.max(axis=0)[None, :], A.max(axis=1)[:, None]), 1e-4)
                err = float(np.max(np.abs(jac - ref.jacobian) / scale))
                if err > t_worst:
                    t_worst, t_where = err, label
            d = sim.step_derivatives(*s, method="differences")
            why = d.fallback or "; ".join(g.kind for g in d.degenerate)
            counts[(ref.exact, d.method + ("" if d.exact else ", not exact"), why)] += 1
            if d.method != "differences" or not d.exact:
                continue
            if not ref.exact:
                kinds[", ".join(sorted({g.kind for g in ref.degenerate}))] += 1
                continue
            A = np.abs(ref.jacobian)
            scale = np.maximum(np.maximum(A.max(axis=0)[None, :], A.max(axis=1)[:, None]), 1e-4)
            err = float(np.max(np.abs(d.jacobian - ref.jacobian) / scale))
            if err > worst:
                worst, where = err, label
    exact = sum(n for (e, _, _), n in counts.items() if e)
    print(f"{sum(counts.values())} states, {exact} exact by the dual numbers")
    print("| dual numbers: exact | answered by | why the differences gave way, or are not exact | states |")
    print("|---|---|---|---:|")
    for (e, method, why), n in sorted(counts.items(), key=lambda kv: (not kv[0][0], kv[0][1], kv[0][2])):
        print(f"| {'yes' if e else 'no'} | {method} | {why or '-'} | {n} |")
    for kind, n in kinds.most_common():
        print(f"differences exact on {n} state(s) the dual numbers call degenerate: {kind}")
    print(f"largest difference from the dual numbers where both are exact: {worst:.2g} of the row's or column's "
          f"largest entry ({where})")
    print("")
    print("| dual numbers: exact | the derivatives at the bases | states |")
    print("|---|---|---:|")
    for (e, why), n in sorted(tangent.items(), key=lambda kv: (not kv[0][0], kv[0][1] != "answered", kv[0][1])):
        print(f"| {'yes' if e else 'no'} | {why} | {n} |")
    print(f"their largest difference from the dual numbers where they answer: {t_worst:.2g} of the row's or column's "
          f"largest entry ({t_where})")


if __name__ == "__main__":
    main()
