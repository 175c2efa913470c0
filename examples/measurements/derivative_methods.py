"""The step's checked differences (step_derivatives(method="differences")) against its dual numbers on the states
the derivative oracles use (docs/method.md, "Derivatives of the step"): 5 states along each shipped scene's run in
the three formulations and 4 along each of 28 seeded random scenes in the position and fixed-point forms. Printed:
how many states the differences stood on, by whether the dual numbers call the state exact, the reasons they gave
way or call the state not exact (the mixed direction's check), the kinds of degeneracy the dual numbers name where
the differences stood on a state they do not call exact, and the differences' largest difference from the dual
numbers' derivatives, relative to the largest entry of its row or column (at least 1e-4), over the states both call
exact; then the same for their first try alone, the derivatives at the cold step's bases (engine/tangent.py): the
states it answered and why it left the others to the differences of whole steps; then, on the states where the
checked differences gave way to the dual numbers, method "one_sided": the states it answered by the compiled step's
one-sided differences, and how far those are from the dual numbers' one-sided derivatives (each side against its
own, relative to the largest entry of its row or column in either, at least 1e-4).

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
    sided = []
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
            if d.method == "dual":
                sided.append(_one_sided_error(sim, s, ref, label))
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
    print("")
    answered = sorted((err, label, kinds) for err, label, kinds in sided if err is not None)
    print(f"one-sided differences: answered {len(answered)} of the {len(sided)} states the checked differences left "
          "to the dual numbers")
    for bound in (1e-6, 1e-4, 1e-2):
        print(f"  within {bound:g} of the dual numbers' one-sided derivatives: "
              f"{sum(err <= bound for err, _, _ in answered)}")
    far = [kinds for err, _, kinds in answered if err > 1e-4]
    print(f"  farther than 1e-4: {len(far)}, where the dual numbers name a switch within 1e-6 or a non-unique answer: "
          f"{sum(bool({'switch', 'non-unique'} & kinds) for kinds in far)}")
    if answered:
        print(f"  farthest: {answered[-1][0]:.2g} ({answered[-1][1]})")


def _one_sided_error(sim, state, ref, label):
    """(the largest relative difference of method "one_sided"'s one-sided derivatives from the dual numbers' ref,
    label, the kinds of degeneracy the dual numbers name), or (None, label, kinds) where it did not answer."""
    kinds = {g.kind for g in ref.degenerate}
    o = sim.step_derivatives(*state, method="one_sided")
    if o.method != "one_sided":
        return None, label, kinds
    err = 0.0
    for got, want in ((o.jacobian_right, ref.jacobian_right), (o.jacobian_left, ref.jacobian_left)):
        A = np.maximum(np.abs(got), np.abs(want))
        scale = np.maximum(np.maximum(A.max(axis=0)[None, :], A.max(axis=1)[:, None]), 1e-4)
        err = max(err, float(np.max(np.abs(got - want) / scale)))
    return err, label, kinds


if __name__ == "__main__":
    main()
