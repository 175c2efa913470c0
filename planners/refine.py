"""Refining an exact plan by gradients: less pusher travel, the goal still held (docs/planning.md, "Refining a plan").

A plan's controls are its segments' pusher velocities u_j, each held for its steps (the durations stay). Its cost
here is the pusher's path length L = sum_j |u_j| t_j (t_j the segment's duration). `refine` lowers L by projected
gradient steps with the step's derivatives (`Simulator.rollout_derivatives` over the plan's whole run, by the checked
differences of the compiled step, the dual numbers where their checks fail: docs/method.md):

- G = d(object's final state)/d(u): the rows of the coordinates the goal names (the object frame's x, y, its angle,
  its velocities when the goal asks it at rest) with respect to every segment's pusher velocity, summed over the
  segment's simulation steps;
- the step -P grad L, with P = I - G^+ G the projection onto the controls that leave the object's final pose where
  it is to first order, scaled so that no control moves by more than `max_change` times the task's control bound,
  plus the Gauss-Newton step -G^+ e towards the goal's centre (e: the final pose less the goal's, over the
  coordinates the goal names), capped alike: the goal's tolerance is kept as a margin, not used up;
- a line search: the candidate (the controls clipped to the bound) is replayed by `TaskModel.execute`, exactly as
  the planner propagates, and accepted only when every propagation step succeeds, every state is admissible, the goal
  holds at the end and L is lower; else the step is halved, at most `halvings` times.

It stops after `iterations` accepted steps or at the first gradient whose line search accepts nothing. The derivatives
are of cold steps (no warm start), the replays the planner's own (warm-started within a propagation): the gradient
is the model's, the judge the plan's own replay, so the refined plan replays bit for bit like any other.
"""

import time

import numpy as np

#: the largest change of a control in one step, as a fraction of the task's control bound
MAX_CHANGE = 0.25
#: line-search halvings of a step before the refinement stops
HALVINGS = 6


def pusher_path_length(controls, durations):
    """L = sum_j |u_j| t_j (m): the pusher's travel as the controls prescribe it."""
    return float(np.sum(np.hypot(controls[:, 0], controls[:, 1]) * durations))


def _run_inputs(tm, x0, controls, steps):
    """The plan's run as one rollout of the task's scene: the start (q, v, qk) and the kinematic velocities of every
    simulation step (as `TaskModel.advance` sets them), and each step's segment."""
    m = tm.model
    n = tm.nobj
    x0 = np.asarray(x0, float)
    q, v = np.array(m.q0, float), np.array(m.v0, float)
    blocks = x0[:tm.ip].reshape(n, 6)
    q[tm.dyn_order] = blocks[:, 0:3]
    v[tm.dyn_order] = blocks[:, 3:6]
    qk = tm.qk0.copy()
    qk[tm.ipusher, :2] = x0[tm.ip:tm.ip + 2]
    per_segment = np.asarray(steps, int) * tm.steps_per_prop
    N = int(per_segment.sum())
    vk = np.zeros((N, m.nkin, 3))
    segment = np.repeat(np.arange(len(per_segment)), per_segment)
    vk[:, tm.ipusher, 0] = np.asarray(controls, float)[segment, 0]
    vk[:, tm.ipusher, 1] = np.asarray(controls, float)[segment, 1]
    if tm.timed:
        k0 = tm.step_index(x0)
        qk[tm.moving_idx] = tm.path_q[k0]
        K = tm.horizon_steps
        on = max(0, min(N, K - k0))
        vk[:on, tm.moving_idx] = tm.path_v[k0:k0 + on]
    return q, v, qk, vk, segment


def object_jacobian(tm, sim, x0, controls, steps):
    """The object's final state and its Jacobian G with respect to every segment's pusher vx, vy, by
    `rollout_derivatives` over the plan's run: rows the body frame's x, y (the goal's position is the frame's), the
    angle, and the velocities vx, vy, omega of the centre of mass; whether every step's derivatives were exact; and
    the run's steps and those whose derivatives the dual numbers gave (the checked differences gave way)."""
    from planar_lcp.derivatives import rollout_derivatives
    from planar_lcp.frames import frame_state
    q, v, qk, vk, segment = _run_inputs(tm, x0, controls, steps)
    r = rollout_derivatives(sim, q, v, qk, vk, len(vk), method="differences")
    nd = tm.model.ndyn
    d = int(tm.dyn_order[0])
    rows = [3 * d, 3 * d + 1, 3 * d + 2, 3 * nd + 3 * d, 3 * nd + 3 * d + 1, 3 * nd + 3 * d + 2]
    cols = [3 * tm.ipusher, 3 * tm.ipusher + 1]
    per_step = r.dx_dvk[:, rows][:, :, cols]                      # (N, 6, 2)
    G = np.zeros((6, 2 * len(controls)))
    for j in range(len(controls)):
        G[:, 2 * j:2 * j + 2] = per_step[segment == j].sum(axis=0)
    # the frame's origin is the COM less R(angle) com_local: a column's pose rates turn into the frame's as a velocity
    # does (planar_lcp.frames)
    G[:3] = frame_state(r.q[-1, d][None], G[:3].T[:, None, :], tm.com_local1)[1][:, 0, :].T
    return _coords(tm, np.concatenate([r.q[-1, d], r.v[-1, d]])), G, r.exact, (len(vk), len(r.fallbacks))


def _coords(tm, x):
    """object_jacobian's rows of a planning state: the object frame's x, y, angle and the COM's velocities."""
    return np.concatenate([tm.object_frame_pose(x)[:3], np.asarray(x[3:6], float)])


def goal_rows(tm):
    """Which of object_jacobian's rows the goal names: x, y, angle; the velocities when it asks the object at rest."""
    g = tm.task.goal
    return np.array([g.x is not None, g.y is not None, g.angle is not None] + [bool(g.at_rest)] * 3)


def goal_error(tm, final):
    """The object's final state less the goal over what the goal names (x, y, angle; the velocities when it asks
    the object at rest), zero elsewhere: what the refinement's Gauss-Newton term pulls towards zero."""
    from .tasks import wrap_angle
    g = tm.task.goal
    e = np.zeros(6)
    if g.x is not None:
        e[0] = final[0] - g.x
    if g.y is not None:
        e[1] = final[1] - g.y
    if g.angle is not None:
        e[2] = wrap_angle(final[2] - g.angle)
    if g.at_rest:
        e[3:] = final[3:]
    return e


def refine(plan, iterations=10, max_change=MAX_CHANGE, halvings=HALVINGS):
    """A refined copy of an exact `plan` (a planners.Plan): lower pusher path length, the same steps, the goal held
    (module docstring). Its data's `refine` entry: the path length before and after, the steps taken and tried, the
    line-search replays, whether every derivative run was exact, the time, and `last_miss`: for the last candidate
    replayed that missed the goal, its largest control change and the goal's coordinates' change the derivatives
    predicted and the replay gave (None when every replay held it)."""
    from planar_lcp.sim import SimOptions, Simulator

    from .plans import Plan
    from .shorten import costs
    from .tasks import wrap_angle
    if not plan.exact:
        raise ValueError("refine: the plan is not exact (it does not reach the goal)")
    tm = plan.model
    t = tm.task
    cm, dt = float(t.control_max), float(t.step_duration)
    x0 = np.asarray(plan.data["start"], float)
    U = plan.controls.copy()
    steps = plan.steps.copy()
    dur = steps * dt
    opts = tm.sim.options
    sim = Simulator(tm.model, SimOptions(h=opts.h, solver=opts.solver, formulation=opts.formulation))
    t0, c0 = time.perf_counter(), time.process_time()

    def judge(controls):
        bound, dense, ok = tm.execute(x0, controls, steps, valid=tm.admissible)
        good = ok and len(bound) == len(controls) + 1 and tm.goal_distance(bound[-1]) <= 1.0
        return good, bound, dense

    ok, bound, dense = judge(U)
    if not ok:
        raise ValueError("refine: the plan's replay does not hold its goal")
    L = L0 = pusher_path_length(U, dur)
    accepted = tried = replays = 0
    last_miss = None
    all_exact = True
    derivative_steps = dual_steps = 0
    stopped_by = "iterations"
    while accepted < iterations:
        final, G, exact, (n_steps, n_dual) = object_jacobian(tm, sim, x0, U, steps)
        all_exact &= bool(exact)
        derivative_steps += n_steps
        dual_steps += n_dual
        if not np.all(np.isfinite(G)):
            stopped_by = "derivatives not finite"
            break
        e = goal_error(tm, final)
        named = goal_rows(tm)
        Gp = np.linalg.pinv(G[named]) if named.any() else np.zeros((2 * len(U), 0))
        speed = np.hypot(U[:, 0], U[:, 1])
        grad = np.zeros_like(U)
        moving = speed > 0.0
        grad[moving] = (U[moving] / speed[moving, None]) * dur[moving, None]
        g = grad.ravel()
        # down the path length's gradient within the controls that keep the goal's coordinates (G's null space),
        # scaled to at most max_change of the control bound, plus the Gauss-Newton step towards the goal's centre
        descent = -(g - Gp @ (G[named] @ g)) if named.any() else -g
        if not np.any(descent):
            stopped_by = "no descent"
            break
        descent *= max_change * cm / np.max(np.abs(descent))
        toward = -(Gp @ e[named]) if named.any() else np.zeros_like(g)
        big = np.max(np.abs(toward), initial=0.0)
        if big > max_change * cm:
            toward *= max_change * cm / big
        d = (descent + toward).reshape(U.shape)
        found = False
        now = _coords(tm, bound[-1])
        for k in range(halvings + 1):
            tried += 1
            cand = np.clip(U + d * 0.5 ** k, -cm, cm)
            Lc = pusher_path_length(cand, dur)
            if Lc >= L:
                continue
            replays += 1
            good, b2, d2 = judge(cand)
            if good:
                U, L, bound, dense, found = cand, Lc, b2, d2, True
                break
            if len(b2) == len(cand) + 1:
                # what the derivatives predicted for the goal's coordinates against what the replay gave
                moved = _coords(tm, b2[-1]) - now
                moved[2] = wrap_angle(moved[2])
                last_miss = dict(control_change=float(np.max(np.abs(cand - U))),
                                 predicted=(G[named] @ (cand - U).ravel()).tolist(), replayed=moved[named].tolist())
        if not found:
            stopped_by = "line search"
            break
        accepted += 1
    data = dict(plan.data)
    data.update(controls=U.tolist(), states=bound.tolist(), goal=tm.goal_report(bound[-1]))
    data.update(costs(tm, steps, dense))
    data["refine"] = dict(objective="pusher_path_length", before=L0, after=L, accepted=accepted, tried=tried,
                          replays=replays, stopped_by=stopped_by, exact_derivatives=all_exact,
                          derivative_steps=derivative_steps, dual_steps=dual_steps, last_miss=last_miss,
                          time=time.perf_counter() - t0, cpu_time=time.process_time() - c0)
    return Plan(data, plan.task, tm=tm, task_file=plan.task_file)
