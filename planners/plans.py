"""Plans: planning a task, the self-contained plan file, open-loop replay, and drawing.

`plan(task, ...)` returns a `Plan`; `Plan.save` writes plan.json, `load_plan` reads one back. A plan file holds the
task's whole scene document (scene and [task] table, as parsed, with its SHA-256), so `replay` re-simulates it bit
for bit on any machine, after the task file was moved or edited (an edited file is reported, and the plan replays
from its own copy). Only `plan_task` imports ompl (inside the function).
"""

import contextlib
import json
import math
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np

from planar_lcp.spec.scene import SHIPPED_FOLDERS, SceneError, _is_real, read_document, shipped_dir
from planar_lcp.spec.task import MAX_TIME, check_seed, check_time_limit, document_sha256, parse_task

from .shorten import costs
from .tasks import TaskError, TaskModel, check_planner

#: 2: the plan holds its task's document (task files); 1 (before) named a built-in task only
PLAN_FORMAT = 2


class ShorteningInterrupted(KeyboardInterrupt):
    """Ctrl-C while `plan_task` shortened an exact plan. `data` is the plan file's contents with the best exact plan
    so far (still exact: every plan the shortening holds is one it judged whole), its `shorten` entry saying so
    (`status` "interrupted"); `plan` (the API) adds `plan`, that plan as a `Plan`."""

    def __init__(self, data):
        super().__init__("while shortening")
        self.data = data
        self.plan = None


@contextlib.contextmanager
def _sigint_flag():
    """During the block, SIGINT only appends to the yielded list (in the main thread; elsewhere signal handlers
    cannot be set and the list stays empty): the shortening reads it between candidates and stops with the best
    plan so far, instead of a KeyboardInterrupt raised wherever Python happens to be (or swallowed inside numba's
    dispatcher, planar_lcp/interrupt.py)."""
    flag = []
    main = threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGINT, lambda signum, frame: flag.append(signum)) if main else None
    try:
        yield flag
    finally:
        if main:
            signal.signal(signal.SIGINT, old if old is not None else signal.SIG_DFL)   # None: set outside Python


def check_shorten_time(value, name="shorten_time"):
    """A shortening time budget: a number of seconds in [0, MAX_TIME] (None: the default rule). Returns it as a
    float; raises TaskError naming `name`."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or not 0 <= value <= MAX_TIME:
        raise TaskError(f"{name} must be a number of seconds in [0, {MAX_TIME:g}], got {value!r}")
    return float(value)


def plan_task(task, planner=None, seed=1, time_limit=None, iterations=None, tm=None, shorten=True,
              shorten_time=None, on_first=None):
    """Solve `task` (a Task, a shipped task's name or a task file) with `planner` (default: the task's). Returns
    the plan as a dict (the plan file's contents, `Plan.data`); `tm` may reuse a TaskModel of the task.

    `shorten`: an exact plan is then shortened (planners.shorten); the planner's own plan's costs are kept as
    first_path_duration, first_pusher_path_length, first_object_path_length and its controls as first_plan.
    False: the planner's plan as it is, bit for bit. How long: `shorten_time` None, the default rule
    (`planners.shorten.default_rule`: counts of candidates and simulated steps, the same on every machine, and
    under a time limit no later than the budget's end); a number of seconds, that long by the wall clock (0: no
    candidate), whatever the time limit.

    `on_first(data)`: called after the search with the plan file's contents as they are before any shortening
    (the planner's plan; `shorten.status` "running" when it is about to be shortened), e.g. to write it at once.

    Ctrl-C while shortening (in the main thread) stops it between two candidates and raises ShorteningInterrupted,
    whose `data` holds the best exact plan so far; Ctrl-C during the search raises KeyboardInterrupt."""
    import gc

    from ompl import util as ou

    from .adapter import Problem

    tm = tm if tm is not None else TaskModel(task)
    t = tm.task
    planner = check_planner(planner if planner is not None else t.planner)
    if time_limit is None and iterations is None:
        raise TaskError("give a time limit (--time) or an iteration budget (--iterations)")
    if time_limit is not None and iterations is not None:
        raise TaskError("give either a time limit (--time) or an iteration budget (--iterations), not both")
    if time_limit is not None:
        time_limit = check_time_limit(time_limit)
    if iterations is not None and int(iterations) < 1:
        raise TaskError(f"the iteration budget must be >= 1, got {iterations}")
    shorten_time = check_shorten_time(shorten_time)
    seed = check_seed(seed)
    gc.disable()   # ompl 2.0.1: cyclic GC reads freed memory (see docs/planning.md)
    # re-seeding a worker that planned before logs "Random number generation already started" but does re-seed
    # (OMPL's RandomNumbers.cpp); keep that out of the output
    ou.setLogLevel(ou.LOG_NONE)
    ou.RNG.setSeed(seed)
    ou.setLogLevel(ou.LOG_ERROR)
    prob = Problem(t, planner, tm=tm)
    # a cold numba cache: wait here, where Ctrl-C stops the wait, for the kernels the propagations run
    tm.sim.wait_for_kernel()
    res = prob.solve(time_limit=time_limit, iterations=iterations)
    # the rest of a time budget bounds the default shortening too (an iteration budget: the counts alone)
    deadline = None if time_limit is None else time.perf_counter() + max(time_limit - res["solve_time"], 0.0)
    plan = dict(format=PLAN_FORMAT, task=t.name, task_source=t.source, task_sha256=t.sha256,
                task_document=t.document, planner=planner, seed=seed,
                time_limit=time_limit, iterations_budget=iterations, solve_time=res["solve_time"],
                iterations=res["iterations"], exact=res["exact"], approximate=res["approximate"],
                propagations=res["propagations"], sim_steps=res["sim_steps"],
                steps_per_second=res["sim_steps"] / max(res["solve_time"], 1e-9),
                h=tm.h, step_duration=t.step_duration,
                state_names=t.state_names(),
                start=tm.initial_state().tolist(), controls=[], steps=[], durations=[], states=[],
                path_duration=0.0)
    if res["exact"] or res["approximate"]:
        states, controls, steps = prob.solution()
        plan.update(controls=controls.tolist(), steps=steps.tolist(),
                    durations=(steps * t.step_duration).tolist(), states=states.tolist(),
                    path_duration=float(steps.sum() * t.step_duration),
                    goal=tm.goal_report(states[-1]))
    # the planner's plan replayed once: its costs, and the shortening's starting states
    _, first_dense, first_ok = tm.execute(plan["start"], plan["controls"], plan["steps"])
    first = costs(tm, plan["steps"], first_dense)
    plan.update(pusher_path_length=first["pusher_path_length"], object_path_length=first["object_path_length"])
    plan.update({f"first_{k}": v for k, v in first.items()})
    plan["shorten"] = dict(enabled=bool(shorten), candidates=0, accepted=0, time=0.0)
    if not (shorten and res["exact"]):
        if on_first is not None:
            on_first(plan)
        return plan

    from .shorten import default_rule
    from .shorten import shorten as shorten_plan
    if shorten_time is None:
        rule = default_rule(res["sim_steps"])
        limits = dict(rule, shorten_time=None)
    else:
        rule = dict(max_candidates=None, patience=None, max_sim_steps=None)
        limits = dict(rule, shorten_time=shorten_time)
    plan["first_plan"] = dict(controls=plan["controls"], steps=plan["steps"])
    plan["shorten"] = dict(enabled=True, status="running", candidates=0, accepted=0, time=0.0, **limits)
    if on_first is not None:
        on_first(plan)
    if shorten_time is not None:
        deadline = time.perf_counter() + shorten_time
    with _sigint_flag() as flag:
        r = shorten_plan(tm, plan["start"], controls, steps, seed, deadline=deadline,
                         replayed=(first_dense, first_ok), stop=lambda: bool(flag), **rule)
    bound, dense, _ = tm.execute(plan["start"], r["controls"], r["steps"])    # the replay's states
    plan.update(controls=r["controls"].tolist(), steps=r["steps"].tolist(),
                durations=(r["steps"] * t.step_duration).tolist(), states=bound.tolist(),
                goal=tm.goal_report(bound[-1]))
    plan.update(costs(tm, r["steps"], dense))
    stopped_by = r["stopped_by"]
    if stopped_by == "deadline":
        stopped_by = "time_limit" if shorten_time is None else "shorten_time"
    plan["shorten"] = dict(enabled=True, status="interrupted" if stopped_by == "interrupted" else "done",
                           stopped_by=stopped_by, candidates=r["candidates"], accepted=r["accepted"],
                           accepted_by_kind=r["accepted_by_kind"], truncated=r["truncated"], time=r["time"],
                           cpu_time=r["cpu_time"], sim_steps=r["sim_steps"], **limits,
                           stopped_by_deadline=r["stopped_by_deadline"])
    if flag:
        # a Ctrl-C after the last candidate was judged is still the user's interrupt: the plan is whole, and says
        # why the shortening stopped
        raise ShorteningInterrupted(plan)
    return plan


class Plan:
    """A plan: the task it solves, the controls, the states the planner reached, and how it was found.

    Attributes
    ----------
    data : dict
        The plan file's contents (module docstring; docs/planning.md, "Plan files").
    task : planar_lcp.spec.task.Task
        The task as planned (rebuilt from the plan's own copy of its document when loaded).
    task_file : str
        For a loaded plan, whether the task's file still matches the plan's copy: "unchanged", "edited",
        "missing", or "none" (the task was given as text or a dict); "as planned" for a new plan.
    """

    def __init__(self, data, task, tm=None, task_file="as planned"):
        self.data, self.task, self.task_file = data, task, task_file
        self._tm = tm

    @property
    def exact(self):
        """True when the planner found a plan that reaches the goal exactly."""
        return bool(self.data["exact"])

    @property
    def controls(self):
        """(n, 2) pusher velocities, m/s, each held for `durations` s."""
        return np.asarray(self.data["controls"], float).reshape(-1, 2)

    @property
    def steps(self):
        """(n,) propagation steps each control is held."""
        return np.asarray(self.data["steps"], int)

    @property
    def durations(self):
        """(n,) seconds each control is held."""
        return np.asarray(self.data["durations"], float)

    @property
    def states(self):
        """(n + 1, d) flat planning states (planners.tasks) at the control boundaries, as the planner reached them."""
        return np.asarray(self.data["states"], float).reshape(-1, self.task.state_dim)

    @property
    def goal_report(self):
        """The goal errors at the plan's last state (TaskModel.goal_report); {} without a path."""
        return dict(self.data.get("goal", {}))

    @property
    def path_duration(self):
        return float(self.data["path_duration"])

    @property
    def model(self):
        """The TaskModel of the plan's task (built once)."""
        if self._tm is None:
            self._tm = TaskModel(self.task)
        return self._tm

    def save(self, path):
        """Write the plan file (JSON)."""
        save_plan(self.data, path)

    def replay(self, simulator="lcp", closed_loop=False, perturb=None):
        """Re-simulate the plan: its controls open loop, or closed loop in pymunk.

        Parameters
        ----------
        simulator : {"lcp", "pymunk"}
            "lcp": ours, exactly as the planner propagated them (bit for bit); "pymunk": through
            planar_lcp.bridges.pymunk, from the scene's start (another contact model: expect drift).
        closed_loop : bool
            A planners.closed_loop.PlanTracker chooses every propagation step's control from the simulator's
            state (docs/closed_loop.md, "Any task in pymunk"); the run stops when the goal holds.
        perturb : dict, optional
            {"mu": f, "mass": g}, factors on every friction coefficient and every dynamic body's mass of the world
            executed in (spec.scene.perturbed_scene); the plan and the tracker's model keep the task's.

        Returns
        -------
        dict
            final : (d,) the last state; report : the goal report with simulation_ok and goal_holds; dense :
            (k, d) the states at every propagation step; bound : (n + 1, d) those at the control boundaries
            ("lcp" only, else None); tm : the TaskModel; pymunk: steps, and closed loop compute_s (per step).
        """
        if simulator not in ("lcp", "pymunk"):
            raise TaskError(f"simulator must be 'lcp' or 'pymunk', got {simulator!r}")
        if simulator == "lcp" and not (closed_loop or perturb):
            return replay_lcp(self.data, tm=self.model)
        scene = None
        if perturb:
            from planar_lcp.spec.scene import perturbed_scene
            unknown = sorted(set(perturb) - {"mu", "mass"})
            if unknown:
                raise TaskError(f"perturb takes mu and mass, got {', '.join(unknown)}")
            scene = perturbed_scene(self.model.scene, friction=perturb.get("mu", 1.0), mass=perturb.get("mass", 1.0))
        controller = None
        if closed_loop:
            from .closed_loop import PlanTracker
            controller = PlanTracker(self)
        if simulator == "lcp":
            if controller is None:            # the plan's controls in a perturbed world, judged at their end
                from .closed_loop import OpenLoop
                return run_closed_loop_lcp(self.data, OpenLoop(self), tm=self.model, scene=scene,
                                           max_steps=int(self.steps.sum()), stop_at_goal=False)
            return run_closed_loop_lcp(self.data, controller, tm=self.model, scene=scene)
        return replay_pymunk(self.data, tm=self.model, controller=controller, scene=scene)

    def plot(self, path, title=None):
        """A strobe of the replayed plan over the scene (plan.png)."""
        rep = self.replay()
        plot_plan(self.model, rep["dense"], path, title=title if title is not None else self.title())

    def animate(self, path):
        """The replayed plan as a GIF (plan.gif)."""
        animate_plan(self.model, self.replay()["dense"], path)

    def title(self):
        status = "exact" if self.exact else ("approximate" if self.data["approximate"] else "no")
        return (f"{self.task.name}, {self.data['planner']}, seed {self.data['seed']}: {status} solution, "
                f"{self.path_duration:.2f} s of pushing")


def plan(task, planner=None, time=None, iterations=None, seed=1, shorten=True, shorten_time=None):
    """Plan a task with OMPL, our simulator as the forward model.

    Parameters
    ----------
    task : str, os.PathLike, dict or Task
        A shipped task's name, a task file, its text or its document (`planar_lcp.spec.task.load_task`).
    planner : str, optional
        One of PLANNERS; default the task's `planner` ("RRT" unless the file says otherwise).
    time : float, optional
        Wall-clock budget, s, at most 86400 (as a task file's `time`). Default: the task's `time` (60 s unless the
        file says otherwise), unless `iterations` is given.
    iterations : int, optional
        An iteration budget instead of a time limit: with `seed`, the plan is the same on any machine.
    seed : int
        OMPL's random seed, 1 to 2**32 - 1 (spec.task.MAX_SEED; it seeds the shortening too).
    shorten : bool
        Shorten the first exact plan (planners.shorten, docs/planning.md "Shorter plans"); False: the planner's
        first exact plan as it is.
    shorten_time : float, optional
        Shorten for this many seconds of wall time instead of the default stopping rule (docs/planning.md "When
        shortening stops"); 0: no candidate.

    Returns
    -------
    Plan
        `.exact` is True when the goal is reached; the planner stops at the first exact solution, which is then
        shortened (`.data["first_path_duration"]` is its duration).

    Raises
    ------
    ShorteningInterrupted
        Ctrl-C while shortening (a KeyboardInterrupt): its `plan` is the best exact plan so far.
    """
    seed = check_seed(seed)                  # before any work: the task model compiles the scene
    if time is not None:
        time = check_time_limit(time)
    tm = TaskModel(task)
    if time is None and iterations is None:
        time = tm.task.time
    try:
        data = plan_task(tm.task, planner, seed=seed, time_limit=time, iterations=iterations, tm=tm,
                         shorten=shorten, shorten_time=shorten_time)
    except ShorteningInterrupted as e:
        e.plan = Plan(e.data, tm.task, tm=tm)
        raise
    return Plan(data, tm.task, tm=tm)


def save_plan(plan, path):
    """Write a plan file. Written whole or not at all: into PATH.part, then renamed over PATH (a Ctrl-C or a crash
    while writing leaves the file as it was)."""
    path = Path(path)
    part = path.with_name(path.name + ".part")
    part.write_text(json.dumps(plan, indent=1) + "\n")
    os.replace(part, path)


def _task_file_status(source, sha):
    """Whether the task file a plan names still holds the document the plan holds."""
    if source.startswith("<"):
        return "none"
    p = Path(source)
    candidates = [p]
    # scenes/NAME.toml, tasks/NAME.toml: a shipped file (display_source), wherever this installation keeps it
    if not p.is_absolute() and len(p.parts) > 1 and p.parts[0] in SHIPPED_FOLDERS:
        candidates.insert(0, shipped_dir(p.parts[0]).joinpath(*p.parts[1:]))
    for c in candidates:
        if c.is_file():
            try:
                doc, _ = read_document(c)
            except SceneError:
                return "edited"
            return "unchanged" if document_sha256(doc) == sha else "edited"
    return "missing"


def load_plan(path):
    """Read and check a plan file (`Plan.save`, `planar-lcp plan`).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Plan
        Its task rebuilt from the plan's own copy (`task_document`), never from the task file; `Plan.task_file`
        says whether that file still holds the same document.

    Raises
    ------
    TaskError
        One line naming the file and the field: not a plan, format 1, a hash that does not match the document, a
        bad document (the task file's own messages), controls, steps or start that the task could not have made.
    """
    p = Path(path)
    try:
        plan = json.loads(p.read_text())
    except FileNotFoundError:
        raise TaskError(f"{path}: no such plan file") from None
    except IsADirectoryError:
        raise TaskError(f"{path}: is a directory, not a plan file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise TaskError(f"{path}: cannot read: {e}") from None
    except json.JSONDecodeError as e:
        raise TaskError(f"{path}: not a JSON plan file ({e})") from None
    if not isinstance(plan, dict):
        raise TaskError(f"{path}: a plan file holds a JSON object, got {type(plan).__name__}")
    if "format" in plan and plan["format"] == 1 and not isinstance(plan["format"], bool):
        raise TaskError(f"{path}: format must be {PLAN_FORMAT}, got 1 (a plan made before task files, which names "
                        "its task only): plan it again with `planar-lcp plan`")
    for key in ("format", "task", "task_source", "task_sha256", "task_document", "controls", "steps", "start"):
        if key not in plan:
            raise TaskError(f"{path}: missing key {key!r}")
    if plan["format"] != PLAN_FORMAT or isinstance(plan["format"], bool):
        raise TaskError(f"{path}: format must be {PLAN_FORMAT}, got {plan['format']!r}")
    doc, src, sha = plan["task_document"], plan["task_source"], plan["task_sha256"]
    if not isinstance(doc, dict) or not isinstance(src, str) or not isinstance(plan["task"], str):
        raise TaskError(f"{path}: task_document must be an object and task, task_source strings, got "
                        f"{type(doc).__name__}, {type(plan['task']).__name__}, {type(src).__name__}")
    try:
        own = document_sha256(doc)
    except (TypeError, ValueError) as e:
        raise TaskError(f"{path}: task_document is not a scene document ({e})") from None
    if own != sha:
        raise TaskError(f"{path}: task_sha256 must be the hash of task_document, {own}, got {sha!r} (the plan file "
                        "was edited)")
    try:
        task = parse_task(doc, source=src, name=plan["task"], display=f"{path}: task_document ({src})")
    except SceneError as e:
        raise TaskError(str(e)) from None
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
    # what the plan file says of its durations is what its steps make (the report and the drawings read them)
    sd = task.step_duration
    want = k * sd
    if "durations" in plan:
        d = plan["durations"]
        if not isinstance(d, list) or len(d) != len(k):
            raise TaskError(f"{path}: durations must be one number per control (steps[i] * step_duration), got "
                            f"{len(d) if isinstance(d, list) else type(d).__name__} for {len(k)} controls")
        for i, di in enumerate(d):
            if not _is_real(di) or not abs(di - want[i]) <= 1e-9 * max(1.0, want[i]):
                raise TaskError(f"{path}: durations[{i}] must be steps[{i}] * step_duration = {int(k[i])} * {sd:g} "
                                f"= {want[i]:.6g} s, got {di!r}")
    if "path_duration" in plan:
        pd, total = plan["path_duration"], float(k.sum() * sd)
        if not _is_real(pd) or not abs(pd - total) <= 1e-9 * max(1.0, total):
            raise TaskError(f"{path}: path_duration must be the sum of steps * step_duration = {total:.6g} s, got "
                            f"{pd!r}")
    for key in ("exact", "approximate"):
        plan.setdefault(key, False)
    plan.setdefault("durations", want.tolist())
    plan.setdefault("path_duration", float(k.sum() * sd))
    return Plan(plan, task, task_file=_task_file_status(src, sha))


def replay_lcp(plan, tm=None):
    """Re-simulate the plan's controls open loop with our simulator, exactly as the planner propagated them.

    `plan` is a plan dict (Plan.data). Returns dict(final state, report, dense states, bound states, tm,
    penetration: the deepest penetration of any two bodies at the end of any simulated step, m, penetration_time:
    the end of the propagation step it happened in, s)."""
    tm = tm if tm is not None else TaskModel(plan["task_document"])
    tm.penetrations = []          # each propagation step's deepest penetration (at the end of any of its steps)
    try:
        bound, dense, ok = tm.execute(plan["start"], plan["controls"], plan["steps"])
        pen = np.asarray(tm.penetrations)
    finally:
        tm.penetrations = None
    x = dense[-1]
    rep = tm.goal_report(x)
    rep["simulation_ok"] = bool(ok)
    rep["goal_holds"] = bool(rep["goal_holds"] and ok and tm.admissible(x))
    i = int(np.argmax(pen)) if len(pen) else -1
    return dict(final=x, report=rep, dense=dense, bound=bound, tm=tm,
                penetration=float(pen[i]) if len(pen) else 0.0,
                penetration_time=(i + 1) * tm.task.step_duration if len(pen) else 0.0)


def run_closed_loop_lcp(plan, controller, tm=None, scene=None, max_steps=None, stop_at_goal=True):
    """Execute a plan closed loop in our simulator: `controller(x) -> u` chooses every propagation step's pusher
    velocity from the state, the world being the task's scene or `scene` (e.g. spec.scene.perturbed_scene of it).
    Stops as replay_pymunk does (the goal holds, or `max_steps`, default three times the plan's steps plus 100; without
    `stop_at_goal`, after `max_steps` only, as an open loop is judged at the plan's end). Returns
    replay_pymunk's dict (steps, compute_s; no penetration is measured: 0)."""
    import dataclasses
    tm = tm if tm is not None else TaskModel(plan["task_document"])
    world = tm if scene is None else TaskModel(dataclasses.replace(tm.task, scene=scene))
    n_steps = int(max_steps) if max_steps is not None else 3 * int(np.sum(plan["steps"])) + 100
    controller.reset()
    x, ok, compute = np.asarray(plan["start"], float), True, []
    dense = [x]
    for _ in range(n_steps):
        if stop_at_goal and tm.goal_distance(x) <= 1.0 and tm.admissible(x):
            break
        u = controller(x)
        compute.append(float(getattr(controller, "compute_s", float("nan"))))
        x, good = world.advance(x, u, tm.steps_per_prop)
        dense.append(x)
        if not good:
            ok = False
            break
    dense = np.array(dense)
    rep = tm.goal_report(x)
    rep["simulation_ok"] = bool(ok)
    rep["goal_holds"] = bool(rep["goal_holds"] and ok and tm.admissible(x))
    return dict(final=x, report=rep, dense=dense, bound=None, tm=tm, penetration=0.0, penetration_time=0.0,
                steps=len(dense) - 1, compute_s=np.array(compute))


def _frame_poses(tm, X):
    """Body-frame poses of the dynamic bodies (n, ndyn, 3), in the scene's order, and kinematic poses (n, nkin, 3)
    of flat states X (n, d)."""
    X = np.asarray(X, float)
    qc = np.empty((len(X), tm.nobj, 3))
    qc[:, tm.dyn_order] = X[:, :tm.ip].reshape(len(X), tm.nobj, 6)[:, :, 0:3]
    qf = tm.model.com_to_frame(qc)
    qk = np.repeat(tm.qk0[None], len(X), axis=0)
    qk[:, tm.ipusher, 0:2] = X[:, tm.ip:tm.ip + 2]
    if tm.timed:
        for j, x in enumerate(X):
            qk[j, tm.moving_idx] = tm.moving_poses(x)
    return qf, qk


def _view(tm):
    """The drawing's limits: the workspace and the pusher's together."""
    (ox0, ox1), (oy0, oy1) = tm.task.workspace
    (px0, px1), (py0, py1) = tm.task.pusher_workspace
    return (min(ox0, px0), max(ox1, px1)), (min(oy0, py0), max(oy1, py1))


def _draw_goal(ax, tm, label=False):
    """The workspace's outline, and the goal: the object's outline at a full goal pose, else a line at each named
    coordinate."""
    (x0, x1), (y0, y1) = tm.task.workspace
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], ":", color="tab:gray", lw=1,
            label="workspace" if label else None)
    g = tm.task.goal
    if tm.goal_poly is not None:
        xs, ys = tm.goal_poly.exterior.xy
        ax.plot(xs, ys, "--", color="tab:green", lw=1.5, label="goal" if label else None)
        return
    if g.x is not None:
        ax.axvline(g.x, color="tab:green", ls="--", lw=1, label="goal x" if label else None)
    if g.y is not None:
        ax.axhline(g.y, color="tab:green", ls="--", lw=1, label="goal y" if label else None)


def plot_plan(tm, X, path, title="", goal_state=None):
    """A strobe of object and pusher along the states X (n, 8) over the scene, with the goal outline."""
    from planar_lcp.viz import draw_scene, new_figure

    qf, qk = _frame_poses(tm, X)
    fig = new_figure((7, 5.5), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    n = len(X)
    idx = np.unique(np.linspace(0, n - 1, min(n, 14)).round().astype(int))
    # fix the view first: the workspaces
    (x0, x1), (y0, y1) = _view(tm)
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
    _draw_goal(ax, tm, label=True)
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
    (x0, x1), (y0, y1) = _view(tm)
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(path), dpi=80):
        for i in idx:
            ax.clear()
            ax.set_xlim(x0, x1)
            ax.set_ylim(y0, y1)
            ax.set_autoscale_on(False)
            _draw_goal(ax, tm)
            draw_scene(ax, tm.scene, qf[i], qk[i])
            ax.set_title(f"{tm.task.name}  t = {i * tm.task.step_duration:.2f} s", fontsize=9)
            writer.grab_frame()


def replay_pymunk(plan, tm=None, controller=None, scene=None, max_steps=None):
    """Execute a plan in pymunk (planar_lcp.bridges.pymunk), from the scene's start: open loop (the
    plan's controls in turn) or, with `controller`, closed loop.

    controller : callable, optional
        `controller(x) -> u`: the pusher's velocity (m/s) for the next propagation step from pymunk's state as a
        flat planning state x (planners.tasks), e.g. planners.closed_loop.PlanTracker; `reset()` is called first.
        The run stops at the first propagation step whose state meets the goal (TaskModel.goal_distance <= 1 and
        admissible), or after `max_steps` steps (default: three times the plan's, plus 100).
    scene : Scene, optional
        The world to execute in, default the task's scene (e.g. spec.scene.perturbed_scene of it).

    The pusher's velocity is set to each control; the space is stepped with the scene's h. Returns the same dict as
    `replay_lcp` (the goal is judged by the same task test; the penetration is the deepest of any contact point of
    pymunk's arbiters after any step), with `steps` (propagation steps executed) and, closed loop, `compute_s`
    (the controller's thread CPU seconds of each step)."""
    try:
        from planar_lcp.bridges.pymunk import build_space, read_state, set_kinematic_velocity
    except ImportError as e:  # the bridge, or pymunk itself
        raise ImportError(f"planar_lcp.bridges.pymunk cannot be used ({e})") from None
    tm = tm if tm is not None else TaskModel(plan["task_document"])
    space, hd = build_space(scene if scene is not None else tm.scene, h=tm.h)
    pusher = hd.bodies[tm.task.pusher]
    step = [0]                       # pymunk steps taken

    def flat():
        q, _, qk, vc = read_state(hd)        # vc: the centre-of-mass velocities, as the flat state holds them
        qc = tm.model.frame_to_com(q)
        x = np.empty(tm.task.state_dim)
        for i, d in enumerate(tm.dyn_order):
            x[6 * i:6 * i + 3] = qc[d]
            x[6 * i + 2] = math.atan2(math.sin(qc[d, 2]), math.cos(qc[d, 2]))
            x[6 * i + 3:6 * i + 6] = vc[d]
        x[tm.ip:tm.ip + 2] = qk[hd.kinematic_names.index(tm.task.pusher), 0:2]
        if tm.timed:
            x[tm.ip + 2] = min(step[0], tm.horizon_steps) * tm.h
        return x

    # a timed task's moving bodies follow their paths, their velocities set before each step as TaskModel.advance
    # takes them (the path's from step 0; at rest after the horizon)
    moving = list(enumerate(tm.task.moving))
    deepest = [0.0, 0.0]              # the deepest penetration (m) and the end of its propagation step (s)

    def overlap(arb):
        for p in arb.contact_point_set.points:
            if -p.distance > deepest[0]:
                deepest[0], deepest[1] = -p.distance, (len(dense)) * tm.task.step_duration

    controls = np.repeat(np.asarray(plan["controls"], float).reshape(-1, 2), np.asarray(plan["steps"], int), axis=0)
    if controller is None:
        n_steps = len(controls)
    else:
        n_steps = int(max_steps) if max_steps is not None else 3 * len(controls) + 100
        controller.reset()
    compute = []
    dense = [flat()]
    for n in range(n_steps):
        if controller is None:
            u = controls[n]
        else:
            x = dense[-1]
            if tm.goal_distance(x) <= 1.0 and tm.admissible(x):
                break
            u = controller(x)
            compute.append(float(getattr(controller, "compute_s", float("nan"))))
        pusher.velocity = (float(u[0]), float(u[1]))
        pusher.angular_velocity = 0.0
        for _ in range(tm.steps_per_prop):
            for m, name in moving:
                vk = tm.path_v[step[0], m] if step[0] < tm.horizon_steps else (0.0, 0.0, 0.0)
                set_kinematic_velocity(hd, name, vk)
            space.step(tm.h)
            step[0] += 1
            for name in hd.dynamic_names:
                hd.bodies[name].each_arbiter(overlap)
        dense.append(flat())
    dense = np.array(dense)
    x = dense[-1]
    rep = tm.goal_report(x)
    rep["simulation_ok"] = bool(np.all(np.isfinite(dense)))
    rep["goal_holds"] = bool(rep["goal_holds"] and tm.admissible(x))
    out = dict(final=x, report=rep, dense=dense, bound=None, tm=tm, penetration=deepest[0],
               penetration_time=deepest[1], steps=len(dense) - 1)
    if controller is not None:
        out["compute_s"] = np.array(compute)
    return out
