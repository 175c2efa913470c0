"""What one OMPL propagation costs: `TaskModel.advance` (which reuses its arrays through `Simulator.rollout_into`)
against the same rollout through `Simulator.rollout` (fresh arrays per call, the code path advance used before it
reused its arrays), in the same process, in alternating rounds, thread CPU time per call: median [min-max] over the
rounds.

Each task's pusher is first driven into its object (0.5 s towards the object's centre of mass), so the timed
propagations push: contacts, the table's friction and the LCP are all in the cost. Both paths give bit-identical
states (checked here too).

Used for docs/planning.md:   python examples/measurements/propagation_cost.py
"""

import time

import numpy as np

from planners.tasks import TaskModel, wrap_angle

ROUNDS, CALLS = 15, 200


def advance_by_rollout(tm, x, u, nsteps):
    """advance() as it was before it reused its arrays: Simulator.rollout, which allocates its outputs on every call
    (for one object its code then, verbatim; for push_clutter the same with the obstacles' blocks)."""
    m, n, ip = tm.model, tm.nobj, tm.ip
    if n == 1:
        q = np.array([[x[0], x[1], x[2]]])
        v = np.array([[x[3], x[4], x[5]]])
        qk = tm.qk0.copy()
        qk[tm.ipusher, 0] = x[6]
        qk[tm.ipusher, 1] = x[7]
        vk = np.zeros((1, m.nkin, 3))
        vk[0, tm.ipusher, 0] = u[0]
        vk[0, tm.ipusher, 1] = u[1]
        out = tm.sim.rollout(q, v, qk, vk, int(nsteps), stop_on_failure=True)
        done = out["steps_done"]
        ok = bool(done == nsteps and not np.any(out["status"][:done]))
        y = np.empty(8)
        y[0:3] = out["q"][done, 0]
        y[2] = wrap_angle(y[2])
        y[3:6] = out["v"][done, 0]
        y[6:8] = out["qk"][done, tm.ipusher, :2]
        return y, ok and bool(np.all(np.isfinite(y)))
    q = np.empty((n, 3))
    v = np.empty((n, 3))
    blocks = np.asarray(x[:ip], float).reshape(n, 6)
    q[tm.dyn_order] = blocks[:, 0:3]
    v[tm.dyn_order] = blocks[:, 3:6]
    qk = tm.qk0.copy()
    qk[tm.ipusher, 0:2] = x[ip:ip + 2]
    vk = np.zeros((1, m.nkin, 3))
    vk[0, tm.ipusher, 0:2] = u
    out = tm.sim.rollout(q, v, qk, vk, int(nsteps), stop_on_failure=True)
    done = out["steps_done"]
    y = np.empty(ip + 2)
    yb = y[:ip].reshape(n, 6)
    yb[:, 0:3] = out["q"][done][tm.dyn_order]
    yb[:, 2] = [wrap_angle(a) for a in yb[:, 2]]
    yb[:, 3:6] = out["v"][done][tm.dyn_order]
    y[ip:ip + 2] = out["qk"][done, tm.ipusher, :2]
    return y, done == nsteps and not np.any(out["status"][:done])


def per_call(f, tm, x, u, nsteps):
    t0 = time.thread_time()
    for _ in range(CALLS):
        f(tm, x, u, nsteps)
    return (time.thread_time() - t0) / CALLS


def main():
    print(f"thread CPU time per propagation, us: median [min-max] over {ROUNDS} alternating rounds of {CALLS} calls")
    print("| task | steps per propagation | advance (rollout_into) | via rollout | ratio |")
    print("|---|---|---|---|---|")
    for name in ("push_box", "push_t", "push_clutter", "tip_box"):
        tm = TaskModel(name)
        x = tm.initial_state()
        d = x[0:2] - x[tm.ip:tm.ip + 2]
        u = 0.1 * d / np.hypot(*d)
        x, ok = tm.advance(x, u, 5 * tm.steps_per_prop)            # into contact
        n = tm.steps_per_prop
        a, ok_a = tm.advance(x, u, n)
        b, ok_b = advance_by_rollout(tm, x, u, n)
        assert ok_a and ok_b and np.array_equal(a, b), name
        new, old = [], []
        for _ in range(ROUNDS):
            new.append(per_call(lambda t, *r: t.advance(*r), tm, x, u, n))
            old.append(per_call(advance_by_rollout, tm, x, u, n))
        new, old = np.array(new) * 1e6, np.array(old) * 1e6
        r = new / old
        print(f"| {name} | {n} | {np.median(new):.1f} [{new.min():.1f}-{new.max():.1f}] | "
              f"{np.median(old):.1f} [{old.min():.1f}-{old.max():.1f}] | "
              f"{np.median(r):.2f} [{r.min():.2f}-{r.max():.2f}] |")


if __name__ == "__main__":
    main()
