"""Where simulate()'s time outside the rollout goes, for one scene: the call against the rollout it makes
(contacts and the Trajectory's rows recorded, on a Simulator made once), alternately in rounds of 20 calls, thread
CPU time, median; the call with the scene's name against the call with its Scene and against load_scene; then each
part of the call timed while 300 calls run. Used for docs/performance.md ("Compile time", the set-up of every call):

    python examples/measurements/simulate_setup.py [SCENE]          (default falling_rod)
"""

import sys
import time

import numpy as np

import planar_lcp.sim as S
from planar_lcp import load_scene

name = sys.argv[1] if len(sys.argv) > 1 else "falling_rod"
sc = load_scene(name)
S.simulate(sc)                                           # compile (a warm cache: loads) and remember the model
sim = S.Simulator(S.compiled_scene(sc), S.SimOptions(h=sc.sim.h))
q, v, qk, vk = sim.initial_state()
n = int(round(sc.sim.t_end / sc.sim.h))


def per_call(f, k=20):
    t0 = time.thread_time()
    for _ in range(k):
        f()
    return (time.thread_time() - t0) / k


whole, rollout = [], []
for _ in range(15):
    whole.append(per_call(lambda: S.simulate(sc)))
    rollout.append(per_call(lambda: sim.rollout(q, v, qk, vk[None], n, record_contacts=True,
                                                trajectory_rows=True)))
whole, rollout = np.array(whole), np.array(rollout)
print(f"{name}: simulate() {1e6 * np.median(whole):.0f} µs, its rollout {1e6 * np.median(rollout):.0f} µs, "
      f"the rest {1e6 * np.median(whole - rollout):.0f} µs (median of 15 rounds)")

# the scene by name: simulate() reads and validates the file once per version of it (`sim._loaded_scenes`); the code
# before read it every call, which is what load_scene costs
by_name, by_object, load = [], [], []
for _ in range(15):
    by_name.append(per_call(lambda: S.simulate(name)))
    by_object.append(per_call(lambda: S.simulate(sc)))
    load.append(per_call(lambda: load_scene(name)))
print(f"{name}: simulate({name!r}) {1e6 * np.median(by_name):.0f} µs, simulate(Scene) {1e6 * np.median(by_object):.0f} "
      f"µs, load_scene({name!r}) {1e6 * np.median(load):.0f} µs (median of 15 rounds)")

spent = {}


def timed(owner, attr, label=None):
    f = getattr(owner, attr)

    def g(*a, **k):
        t0 = time.thread_time()
        try:
            return f(*a, **k)
        finally:
            spent[label or attr] = spent.get(label or attr, 0.0) + time.thread_time() - t0
    setattr(owner, attr, g)


# the settings, the model and the run-size check are made once per Scene object and arguments (`sim._RunSetup`):
# after the first call they no longer show
for attr in ("sim_settings", "support_model_setting", "restitution_setting", "compiled_scene", "check_run_size",
             "frame_state", "_trajectory_stats", "_take_simulator", "_give_back"):
    timed(S, attr)
timed(S.Simulator, "__init__", "Simulator()")
timed(S.Simulator, "rollout", "the rollout")
N = 300
t0 = time.thread_time()
for _ in range(N):
    S.simulate(sc)
total = (time.thread_time() - t0) / N
print(f"timed by parts over {N} calls: the call {1e6 * total:.0f} µs")
for part, s in sorted(spent.items(), key=lambda kv: -kv[1]):
    print(f"  {part}: {1e6 * s / N:.1f} µs")
print(f"  simulate()'s own code: {1e6 * (total - sum(spent.values()) / N):.1f} µs")
