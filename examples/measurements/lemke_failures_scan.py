"""Count failed steps (Lemke unsolved after the pivot-tolerance retries) over 240 phase-shifted falling-rod runs:
5 step sizes x 16 start phases x 3 formulations. Used for docs/method.md:

    python examples/measurements/lemke_failures_scan.py
"""

from planar_lcp import simulate
from planar_lcp.spec.scene import FORMULATIONS, load_scene
from planar_lcp.studies.common import shift_scene

base = load_scene("falling_rod")
runs = failed = retried = 0
for h in (0.02, 0.01, 0.005, 0.0025, 0.00125):
    for k in range(16):
        sc = shift_scene(base, 0.02 * k / 16 + 0.0001)
        for form in FORMULATIONS:
            tr = simulate(sc, h=h, formulation=form, on_failure="record", record_contacts=False)
            runs += 1
            failed += len(tr.failures)
            retried += int((tr.stats["lemke_retries"] > 0).sum())
print(f"{runs} runs: {failed} failed steps, {retried} steps needed a pivot-tolerance retry")
