"""Plan a task, save/load plans as JSON, replay them open loop, and draw them.

Only `plan_task` imports ompl (inside the function).
"""

import json
import math
from pathlib import Path

import numpy as np

from planar_lcp.spec.scene import display_source

from .tasks import TaskError, TaskModel, check_planner, get_task

PLAN_FORMAT = 1


def plan_task(task, planner="KPIECE1", seed=1, time_limit=None, iterations=None, tm=None):
    """Solve `task` with `planner`. Returns the plan as a dict (see `save_plan`); `tm` may reuse a TaskModel."""
    import gc

    from ompl import util as ou

    from .adapter import Problem

    check_planner(planner)
    if time_limit is None and iterations is None:
        raise TaskError("give a time limit (--time) or an iteration budget (--iterations)")
    if time_limit is not None and iterations is not None:
        raise TaskError("give either a time limit (--time) or an iteration budget (--iterations), not both")
    if time_limit is not None and not (math.isfinite(time_limit) and time_limit > 0):
        raise TaskError(f"the time limit must be > 0 s, got {time_limit}")
    if iterations is not None and int(iterations) < 1:
        raise TaskError(f"the iteration budget must be >= 1, got {iterations}")
    seed = int(seed)
    if seed < 1:
        raise TaskError(f"the seed must be >= 1, got {seed}")
    gc.disable()   # ompl 2.0.1: cyclic GC reads freed memory (see docs/planning.md)
    # re-seeding a worker that planned before logs "Random number generation already started" but does re-seed
    # (OMPL's RandomNumbers.cpp); keep that out of the output
    ou.setLogLevel(ou.LOG_NONE)
    ou.RNG.setSeed(seed)
    ou.setLogLevel(ou.LOG_ERROR)
    prob = Problem(task, planner, tm=tm)
    res = prob.solve(time_limit=time_limit, iterations=iterations)
    t = prob.task
    plan = dict(format=PLAN_FORMAT, task=t.name, scene=display_source(prob.tm.scene), planner=planner, seed=seed,
                time_limit=time_limit, iterations_budget=iterations, solve_time=res["solve_time"],
                iterations=res["iterations"], exact=res["exact"], approximate=res["approximate"],
                propagations=res["propagations"], sim_steps=res["sim_steps"],
                steps_per_second=res["sim_steps"] / max(res["solve_time"], 1e-9),
                h=prob.tm.h, step_duration=t.step_duration,
                state_names=t.state_names(),
                start=prob.tm.initial_state().tolist(), controls=[], steps=[], durations=[], states=[],
                path_duration=0.0)
    if res["exact"] or res["approximate"]:
        states, controls, steps = prob.solution()
        plan.update(controls=controls.tolist(), steps=steps.tolist(),
                    durations=(steps * t.step_duration).tolist(), states=states.tolist(),
                    path_duration=float(steps.sum() * t.step_duration),
                    goal=prob.tm.goal_report(states[-1]))
    return plan


def save_plan(plan, path):
    Path(path).write_text(json.dumps(plan, indent=1) + "\n")


def load_plan(path):
    """Read and check a plan file; a TaskError says what is wrong."""
    p = Path(path)
    try:
        plan = json.loads(p.read_text())
    except FileNotFoundError:
        raise TaskError(f"{path}: no such plan file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise TaskError(f"{path}: cannot read: {e}") from None
    except json.JSONDecodeError as e:
        raise TaskError(f"{path}: not a JSON plan file ({e})") from None
    if not isinstance(plan, dict):
        raise TaskError(f"{path}: a plan file holds a JSON object, got {type(plan).__name__}")
    for key in ("format", "task", "controls", "steps", "start"):
        if key not in plan:
            raise TaskError(f"{path}: missing key {key!r}")
    if plan["format"] != PLAN_FORMAT or isinstance(plan["format"], bool):
        raise TaskError(f"{path}: format must be {PLAN_FORMAT}, got {plan['format']!r}")
    try:
        task = get_task(plan["task"])
    except TaskError as e:
        raise TaskError(f"{path}: task: {e}") from None
    try:
        u = np.asarray(plan["controls"], float).reshape(-1, 2)
        k = np.asarray(plan["steps"], float)
        x0 = np.asarray(plan["start"], float)
    except (TypeError, ValueError):
        raise TaskError(f"{path}: controls must be [[vx, vy], ...], steps a list of integers, start "
                        f"{task.state_dim} numbers")
    if len(u) != len(k) or k.ndim != 1 or x0.shape != (task.state_dim,):
        raise TaskError(f"{path}: need one positive integer step count per control and a {task.state_dim}-number "
                        f"start, got {len(u)} controls, {len(k)} step counts, start of shape {x0.shape}")
    # a control is held for min_steps..max_steps propagation steps (the task's control durations, the only ones
    # the planner samples): more would be a plan no planner wrote, and 1e9 steps a replay of days
    for i, ki in enumerate(plan["steps"]):
        if isinstance(ki, bool) or not isinstance(ki, (int, float)) or ki != k[i] or k[i] != np.rint(k[i]) \
                or not task.min_steps <= k[i] <= task.max_steps:
            raise TaskError(f"{path}: steps[{i}] must be an integer in {task.min_steps}..{task.max_steps} (the task's "
                            f"control durations, in propagation steps), got {ki!r}")
    cm = task.control_max
    for (i, j) in zip(*np.nonzero(~(np.abs(u) <= cm))):
        raise TaskError(f"{path}: controls[{i}][{j}] must be a number in [-{cm:g}, {cm:g}] m/s (the task's control "
                        f"bounds), got {plan['controls'][i][j]!r}")
    if not np.all(np.isfinite(x0)):
        raise TaskError(f"{path}: start must be {task.state_dim} finite numbers, got {plan['start']!r}")
    if "step_duration" in plan:
        sd = plan["step_duration"]
        if isinstance(sd, bool) or not isinstance(sd, (int, float)) or abs(sd - task.step_duration) > 1e-12:
            raise TaskError(f"{path}: step_duration must be the task's {task.step_duration:g} s, got {sd!r}")
    return plan


def replay_lcp(plan, tm=None):
    """Re-simulate the plan's controls open loop with our simulator, exactly as the planner propagated them.

    Returns dict(final state, report, dense states)."""
    tm = tm if tm is not None else TaskModel(plan["task"])
    step_duration = float(plan.get("step_duration", tm.task.step_duration))
    if abs(step_duration - tm.task.step_duration) > 1e-12:
        raise TaskError(f"the plan's step_duration {step_duration} differs from the task's "
                        f"{tm.task.step_duration}")
    bound, dense, ok = tm.execute(plan["start"], plan["controls"], plan["steps"])
    x = dense[-1]
    rep = tm.goal_report(x)
    rep["simulation_ok"] = bool(ok)
    rep["goal_holds"] = bool(rep["goal_holds"] and ok and tm.in_bounds(x))
    return dict(final=x, report=rep, dense=dense, bound=bound, tm=tm)


def _frame_poses(tm, X):
    """Body-frame poses of the dynamic bodies (n, ndyn, 3), in the scene's order, and kinematic poses (n, nkin, 3)
    of flat states X (n, d)."""
    X = np.asarray(X, float)
    qc = np.empty((len(X), tm.nobj, 3))
    qc[:, tm.dyn_order] = X[:, :tm.ip].reshape(len(X), tm.nobj, 6)[:, :, 0:3]
    qf = tm.model.com_to_frame(qc)
    qk = np.repeat(tm.qk0[None], len(X), axis=0)
    qk[:, tm.ipusher, 0:2] = X[:, tm.ip:tm.ip + 2]
    return qf, qk


def plot_plan(tm, X, path, title="", goal_state=None):
    """A strobe of object and pusher along the states X (n, 8) over the scene, with the goal outline."""
    from planar_lcp.viz import draw_scene, new_figure

    qf, qk = _frame_poses(tm, X)
    fig = new_figure((7, 5.5), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    n = len(X)
    idx = np.unique(np.linspace(0, n - 1, min(n, 14)).round().astype(int))
    # fix the view first: the workspace
    (ox0, ox1), (oy0, oy1) = tm.task.object_bounds
    (px0, px1), (py0, py1) = tm.task.pusher_bounds
    x0, x1 = min(ox0, px0), max(ox1, px1)
    y0, y1 = min(oy0, py0), max(oy1, py1)
    if tm.scene.world.plane == "vertical":
        y0 = min(y0, -0.05)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_autoscale_on(False)
    for j, i in enumerate(idx):
        a = 0.15 + 0.85 * (j + 1) / len(idx)
        draw_scene(ax, tm.scene, qf[i], qk[i], alpha=a)
    ax.plot(X[:, 0], X[:, 1], "-", color="tab:blue", lw=1, label="object COM")
    for i in range(1, tm.nobj):
        ax.plot(X[:, 6 * i], X[:, 6 * i + 1], ":", color="tab:gray", lw=1,
                label="obstacles' COM" if i == 1 else None)
    ax.plot(X[:, tm.ip], X[:, tm.ip + 1], "-", color="tab:red", lw=1, label="pusher")
    g = tm.task.goal
    if g["kind"] in ("pose", "cover"):
        xs, ys = tm.goal_poly.exterior.xy
        ax.plot(xs, ys, "--", color="tab:green", lw=1.5, label="goal")
    elif tm.task.ledge_x is not None:
        ax.axvline(tm.task.ledge_x, color="tab:green", ls="--", lw=1, label="ledge")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    fig.savefig(path)


def animate_plan(tm, X, path, fps=20, max_frames=120):
    from matplotlib.animation import PillowWriter

    from planar_lcp.viz import draw_scene, new_figure

    qf, qk = _frame_poses(tm, X)
    idx = np.unique(np.linspace(0, len(X) - 1, min(len(X), max_frames)).round().astype(int))
    fig = new_figure((5, 4), dpi=80)
    ax = fig.add_subplot(1, 1, 1)
    (ox0, ox1), (oy0, oy1) = tm.task.object_bounds
    (px0, px1), (py0, py1) = tm.task.pusher_bounds
    y0 = min(oy0, py0) if tm.scene.world.plane != "vertical" else min(oy0, py0, -0.05)
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(path), dpi=80):
        for i in idx:
            ax.clear()
            ax.set_xlim(min(ox0, px0), max(ox1, px1))
            ax.set_ylim(y0, max(oy1, py1))
            ax.set_autoscale_on(False)
            if tm.task.goal["kind"] in ("pose", "cover"):
                xs, ys = tm.goal_poly.exterior.xy
                ax.plot(xs, ys, "--", color="tab:green", lw=1.5)
            draw_scene(ax, tm.scene, qf[i], qk[i])
            ax.set_title(f"{tm.task.name}  t = {i * tm.task.step_duration:.2f} s", fontsize=9)
            writer.grab_frame()


def replay_pymunk(plan, tm=None):
    """Re-simulate the plan's controls open loop in pymunk (planar_lcp.experiments.pymunk_bridge), from the scene's
    start.

    The pusher's velocity is set to each control in turn; the space is stepped with the scene's h. Returns the
    same dict as `replay_lcp` (the goal is judged by the same task test)."""
    try:
        from planar_lcp.experiments.pymunk_bridge import build_space, read_state
    except ImportError as e:  # the bridge, or pymunk itself
        raise ImportError(f"planar_lcp.experiments.pymunk_bridge cannot be used ({e})") from None
    tm = tm if tm is not None else TaskModel(plan["task"])
    space, hd = build_space(tm.scene, h=tm.h)
    pusher = hd.bodies[tm.task.pusher]

    def flat():
        q, _, qk, vc = read_state(hd)        # vc: the centre-of-mass velocities, as the flat state holds them
        qc = tm.model.frame_to_com(q)
        x = np.empty(tm.ip + 2)
        for i, d in enumerate(tm.dyn_order):
            x[6 * i:6 * i + 3] = qc[d]
            x[6 * i + 2] = math.atan2(math.sin(qc[d, 2]), math.cos(qc[d, 2]))
            x[6 * i + 3:6 * i + 6] = vc[d]
        x[tm.ip:tm.ip + 2] = qk[hd.kinematic_names.index(tm.task.pusher), 0:2]
        return x

    dense = [flat()]
    for u, k in zip(np.asarray(plan["controls"], float), np.asarray(plan["steps"], int)):
        pusher.velocity = (float(u[0]), float(u[1]))
        pusher.angular_velocity = 0.0
        for _ in range(int(k)):
            for _ in range(tm.steps_per_prop):
                space.step(tm.h)
            dense.append(flat())
    dense = np.array(dense)
    x = dense[-1]
    rep = tm.goal_report(x)
    rep["simulation_ok"] = bool(np.all(np.isfinite(dense)))
    rep["goal_holds"] = bool(rep["goal_holds"] and tm.in_bounds(x))
    return dict(final=x, report=rep, dense=dense, bound=None, tm=tm)
