"""Refining an exact plan by gradients: a shorter plan, or less pusher travel, the goal still held (docs/planning.md,
"Refining a plan").

A plan's controls are its segments' pusher velocities u_j, each held for its t_j = k_j propagation steps. Both
objectives use the step's derivatives (`Simulator.rollout_derivatives` over the plan's whole run, by the checked
differences of the compiled step, its one-sided differences where their checks find a switch at the state, the dual
numbers where those fail too: method "one_sided", docs/method.md; every candidate is judged by its replay, so a
gradient through a switch need not be exact) through G = d(object's
final state)/d(u): the rows of the coordinates the goal names (the object frame's x, y, its angle, its velocities
when the goal asks it at rest) with respect to every segment's pusher velocity, summed over the segment's simulation
steps.

- `objective="path_duration"` (the planner's cost): one propagation step fewer in a segment (the last segment
  first; a segment at the task's fewest steps is dropped whole), then Gauss-Newton steps on all the controls pull the
  shorter plan's final state back into the goal: the step is -J^+ r with r the goal's error over the coordinates it
  names divided by their tolerances and J = G's rows so divided, scaled so that no control moves by more than
  `max_change` times the task's control bound, and halved until the replay comes closer to the goal (at most
  `halvings` times); after `repairs` steps, or a step that comes no closer, the next segment is tried. A shorter
  plan whose replay holds the goal is kept, and the search starts again from the last segment; it stops when no
  segment gives up a step.
- `objective="pusher_path_length"`: L = sum_j |u_j| t_j lowered at the same steps: the step -P grad L, with
  P = I - G^+ G the projection onto the controls that leave the object's final pose where it is to first order,
  scaled to at most `max_change` of the control bound, plus the Gauss-Newton step -G^+ e towards the goal's centre
  (e: the final pose less the goal's), capped alike; halved until the candidate's replay holds the goal with L lower,
  at most `halvings` times; it stops at the first gradient whose line search keeps nothing.

Every candidate (its controls clipped to the bound) is replayed by `TaskModel.execute`, exactly as the planner
propagates, and kept only when every propagation step succeeds, every state is admissible and the goal holds at the
end. The derivatives are of cold steps (no warm start), the replays the planner's own (warm-started within a
propagation): the gradient is the model's, the judge the plan's own replay, so the refined plan replays bit for bit
like any other.
"""

import time

import numpy as np

#: the largest change of a control in one step, as a fraction of the task's control bound
MAX_CHANGE = 0.25
#: line-search halvings of a step before the refinement gives it up
HALVINGS = 6
#: Gauss-Newton steps that pull a plan one propagation step shorter back into its goal before that shortening is
#: given up
REPAIRS = 10
#: a goal whose errors the controls' whole range moves by at most this many tolerances (by the derivatives) is out
#: of the controls' reach at this plan: no Gauss-Newton step is taken
STILL_GOAL = 1e-9
#: what refine can lower
OBJECTIVES = ("path_duration", "pusher_path_length")


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
    the run's steps, those whose derivatives the one-sided differences gave (a switch at the state) and those the
    dual numbers gave (the one-sided differences failed too)."""
    from planar_lcp.derivatives import rollout_derivatives
    from planar_lcp.frames import frame_state
    q, v, qk, vk, segment = _run_inputs(tm, x0, controls, steps)
    r = rollout_derivatives(sim, q, v, qk, vk, len(vk), method="one_sided")
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
    return (_coords(tm, np.concatenate([r.q[-1, d], r.v[-1, d]])), G, r.exact,
            (len(vk), len(r.one_sided), len(r.fallbacks)))


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


def goal_weights(tm):
    """1 / the goal's tolerance for each of object_jacobian's rows (position_tol for x and y, angle_tol, speed_tol,
    omega_tol): the goal's error so divided is about 1 at its edge."""
    g = tm.task.goal
    return np.array([1.0 / g.position_tol] * 2 + [1.0 / g.angle_tol] + [1.0 / g.speed_tol] * 2 + [1.0 / g.omega_tol])


class _Judge:
    """The plan's start, the task's bounds, a simulator for the derivatives and the replay that judges candidates."""

    def __init__(self, plan, max_change):
        from planar_lcp.sim import SimOptions, Simulator
        self.tm = tm = plan.model
        self.cm = float(tm.task.control_max)
        self.dt = float(tm.task.step_duration)
        self.x0 = np.asarray(plan.data["start"], float)
        self.max_change = float(max_change)
        opts = tm.sim.options
        self.sim = Simulator(tm.model, SimOptions(h=opts.h, solver=opts.solver, formulation=opts.formulation))
        self.all_exact = True
        self.derivative_steps = self.one_sided_steps = self.dual_steps = 0
        self.replays = 0
        self.no_derivatives = ""

    def replay(self, controls, steps):
        """(states at the controls' ends, dense states), or None where a propagation step fails or a state is not
        admissible."""
        self.replays += 1
        bound, dense, ok = self.tm.execute(self.x0, controls, steps, valid=self.tm.admissible)
        return (bound, dense) if ok and len(bound) == len(controls) + 1 else None

    def jacobian(self, controls, steps):
        """object_jacobian's final coordinates and G, counting the derivatives; (None, None) where G is not finite
        or a cold step of the derivatives' run fails (the replay's steps are warm-started: a cold one at the same
        state may fail), why in `no_derivatives`."""
        from planar_lcp.sim import SimulationError
        try:
            final, G, exact, (n_steps, n_sided, n_dual) = object_jacobian(self.tm, self.sim, self.x0, controls,
                                                                          steps)
        except SimulationError as e:
            self.no_derivatives = str(e)
            return None, None
        self.all_exact &= bool(exact)
        self.derivative_steps += n_steps
        self.one_sided_steps += n_sided
        self.dual_steps += n_dual
        if not np.all(np.isfinite(G)):
            self.no_derivatives = "derivatives not finite"
            return None, None
        return final, G

    def cap(self, d):
        """d scaled down so that no control moves by more than max_change of the bound."""
        big = np.max(np.abs(d), initial=0.0)
        return d * (self.max_change * self.cm / big) if big > self.max_change * self.cm else d


def _one_step_fewer(tm, controls, steps, j):
    """The plan with one propagation step fewer in segment j, the segment dropped when it is at the task's fewest
    steps; None when nothing would be left."""
    if int(np.sum(steps)) <= 1:
        return None
    steps = steps.copy()
    if steps[j] - 1 >= int(tm.task.min_steps):
        steps[j] -= 1
        return controls.copy(), steps
    if len(steps) == 1:
        return None
    return np.delete(controls, j, axis=0), np.delete(steps, j)


def _pull_into_goal(judge, controls, steps, repairs, halvings, deadline):
    """Gauss-Newton steps on the controls towards the goal (module docstring): (controls, replay) whose replay
    holds the goal, None where it does not, or "time_limit" where the deadline passed before a derivative run."""
    tm = judge.tm
    run = judge.replay(controls, steps)
    if run is None:
        return None
    distance = tm.goal_distance(run[0][-1])
    named = goal_rows(tm)
    w = goal_weights(tm)[named]
    for _ in range(repairs):
        if distance <= 1.0:
            break
        if deadline is not None and time.perf_counter() > deadline:
            return "time_limit"
        final, G = judge.jacobian(controls, steps)
        if G is None:
            return None
        r = w * goal_error(tm, final)[named]
        J = w[:, None] * G[named]
        if not np.max(np.abs(J), initial=0.0) * judge.cm > STILL_GOAL:
            # the controls' whole range moves the goal's errors by less than STILL_GOAL tolerances (a box at rest
            # the pusher does not reach): no Gauss-Newton step pulls it (pinv would divide by round-off)
            return None
        d = judge.cap(-(np.linalg.pinv(J) @ r)).reshape(controls.shape)
        for k in range(halvings + 1):
            cand = np.clip(controls + d * 0.5 ** k, -judge.cm, judge.cm)
            got = judge.replay(cand, steps)
            if got is not None and tm.goal_distance(got[0][-1]) < distance:
                controls, run, distance = cand, got, tm.goal_distance(got[0][-1])
                break
        else:
            return None
    return (controls, run) if distance <= 1.0 else None


def _shorter_duration(judge, controls, steps, run, iterations, deadline, repairs, halvings):
    """objective="path_duration" (module docstring): (controls, steps, replay, propagation steps dropped, shortenings
    tried, why it stopped)."""
    accepted = tried = 0
    while iterations is None or accepted < iterations:
        for j in reversed(range(len(steps))):
            if deadline is not None and time.perf_counter() > deadline:
                return controls, steps, run, accepted, tried, "time_limit"
            fewer = _one_step_fewer(judge.tm, controls, steps, j)
            if fewer is None:
                continue
            tried += 1
            held = _pull_into_goal(judge, *fewer, repairs, halvings, deadline)
            if isinstance(held, str):
                return controls, steps, run, accepted, tried, held
            if held is not None:
                controls, steps, run = held[0], fewer[1], held[1]
                accepted += 1
                break
        else:
            return controls, steps, run, accepted, tried, "no step can be dropped"
    return controls, steps, run, accepted, tried, "iterations"


def _shorter_pusher_path(judge, controls, steps, run, iterations, deadline, halvings):
    """objective="pusher_path_length" (module docstring): (controls, replay, gradient steps kept, candidates tried,
    why it stopped, the last candidate replayed that missed the goal or None)."""
    from .tasks import wrap_angle
    tm = judge.tm
    dur = steps * judge.dt
    L = pusher_path_length(controls, dur)
    accepted = tried = 0
    last_miss = None
    named = goal_rows(tm)
    while iterations is None or accepted < iterations:
        if deadline is not None and time.perf_counter() > deadline:
            return controls, run, accepted, tried, "time_limit", last_miss
        final, G = judge.jacobian(controls, steps)
        if G is None:
            return controls, run, accepted, tried, judge.no_derivatives, last_miss
        e = goal_error(tm, final)
        Gp = np.linalg.pinv(G[named]) if named.any() else np.zeros((2 * len(controls), 0))
        speed = np.hypot(controls[:, 0], controls[:, 1])
        grad = np.zeros_like(controls)
        moving = speed > 0.0
        grad[moving] = (controls[moving] / speed[moving, None]) * dur[moving, None]
        g = grad.ravel()
        # down the path length's gradient within the controls that keep the goal's coordinates (G's null space),
        # scaled to at most max_change of the control bound, plus the Gauss-Newton step towards the goal's centre
        descent = -(g - Gp @ (G[named] @ g)) if named.any() else -g
        if not np.any(descent):
            return controls, run, accepted, tried, "no descent", last_miss
        descent *= judge.max_change * judge.cm / np.max(np.abs(descent))
        toward = judge.cap(-(Gp @ e[named])) if named.any() else np.zeros_like(g)
        d = (descent + toward).reshape(controls.shape)
        found = False
        now = _coords(tm, run[0][-1])
        for k in range(halvings + 1):
            tried += 1
            cand = np.clip(controls + d * 0.5 ** k, -judge.cm, judge.cm)
            Lc = pusher_path_length(cand, dur)
            if Lc >= L:
                continue
            bound, dense, ok = tm.execute(judge.x0, cand, steps, valid=tm.admissible)
            judge.replays += 1
            if ok and len(bound) == len(cand) + 1 and tm.goal_distance(bound[-1]) <= 1.0:
                controls, L, run, found = cand, Lc, (bound, dense), True
                break
            if len(bound) == len(cand) + 1:
                # what the derivatives predicted for the goal's coordinates against what the replay gave
                moved = _coords(tm, bound[-1]) - now
                moved[2] = wrap_angle(moved[2])
                last_miss = dict(control_change=float(np.max(np.abs(cand - controls))),
                                 predicted=(G[named] @ (cand - controls).ravel()).tolist(),
                                 replayed=moved[named].tolist())
        if not found:
            return controls, run, accepted, tried, "line search", last_miss
        accepted += 1
    return controls, run, accepted, tried, "iterations", last_miss


def refine(plan, iterations=None, objective="path_duration", max_change=MAX_CHANGE, halvings=HALVINGS,
           repairs=REPAIRS, time_limit=None):
    """A refined copy of an exact `plan` (a planners.Plan), the goal held (module docstring): shorter
    (`objective="path_duration"`: at most `iterations` propagation steps fewer) or with less pusher travel at the
    same steps (`"pusher_path_length"`: at most `iterations` gradient steps kept); None: until nothing more is kept.
    `time_limit` (s of wall time) stops it before the next derivative run or candidate past it (a run under way
    finishes: on a large task one takes minutes). Its data's `refine` entry: the objective before and
    after (s or m), the steps kept (`accepted`) and candidates tried, the replays, why it stopped (`stopped_by`),
    whether every derivative run was exact, the simulation steps differentiated, those the one-sided differences
    and those the dual numbers gave, the
    time, and, for the path length, `last_miss`: for the last candidate replayed that missed the goal, its largest
    control change and the goal's coordinates' change the derivatives predicted and the replay gave (None when every
    replay held it)."""
    from .plans import Plan
    from .shorten import costs
    if objective not in OBJECTIVES:
        raise ValueError(f"refine: objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
    if iterations is not None and int(iterations) < 0:
        raise ValueError(f"refine: iterations must be >= 0 or None, got {iterations!r}")
    if not plan.exact:
        raise ValueError("refine: the plan is not exact (it does not reach the goal)")
    judge = _Judge(plan, max_change)
    t0, c0 = time.perf_counter(), time.process_time()
    deadline = None if time_limit is None else t0 + float(time_limit)
    controls, steps = plan.controls.copy(), plan.steps.copy()
    run = judge.replay(controls, steps)
    if run is None or judge.tm.goal_distance(run[0][-1]) > 1.0:
        raise ValueError("refine: the plan's replay does not hold its goal")
    judge.replays = 0    # the candidates' replays only
    last_miss = None
    if objective == "path_duration":
        before = float(int(steps.sum()) * judge.dt)
        controls, steps, run, accepted, tried, stopped_by = _shorter_duration(
            judge, controls, steps, run, iterations, deadline, repairs, halvings)
        after = float(int(steps.sum()) * judge.dt)
    else:
        before = pusher_path_length(controls, steps * judge.dt)
        controls, run, accepted, tried, stopped_by, last_miss = _shorter_pusher_path(
            judge, controls, steps, run, iterations, deadline, halvings)
        after = pusher_path_length(controls, steps * judge.dt)
    bound, dense = run
    tm = judge.tm
    data = dict(plan.data)
    data.update(controls=controls.tolist(), steps=steps.tolist(), durations=(steps * judge.dt).tolist(),
                states=bound.tolist(), goal=tm.goal_report(bound[-1]))
    data.update(costs(tm, steps, dense))
    data["refine"] = dict(objective=objective, before=before, after=after, accepted=accepted, tried=tried,
                          replays=judge.replays, stopped_by=stopped_by, exact_derivatives=judge.all_exact,
                          derivative_steps=judge.derivative_steps, one_sided_steps=judge.one_sided_steps,
                          dual_steps=judge.dual_steps, last_miss=last_miss,
                          time=time.perf_counter() - t0, cpu_time=time.process_time() - c0)
    return Plan(data, plan.task, tm=tm, task_file=plan.task_file)
