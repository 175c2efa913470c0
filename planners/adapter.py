"""The OMPL side of a task: state and control spaces, the propagator, validity, goal, projection, planners.

The OMPL state is the full physics state, so propagation is a pure function of (state, control, duration):

    CompoundStateSpace = SE2 (object centre of mass x, y, theta)
                       + R^3 (object vx, vy, omega)
                       [+ SE2 + R^3 for each obstacle, in Task.obstacles order (push_clutter)]
                       + R^2 (pusher x, y)
                       [+ R^1 (time t) when a kinematic body follows a `path`: Task.moving]

with the task's distance weights `Task.weights = (w_pos, w_ang, w_vel, w_pus)` (derived from the object's size by
`planar_lcp.spec.task.derived_weights`, the reasons in docs/planning.md), so that OMPL's distance between two states is

    w_pos |dxy| + w_ang |dtheta| + w_vel |(dvx, dvy, domega)| + w_pus |dpusher|

(|.| Euclidean, dtheta the shorter way round), plus for each obstacle w_obs |dxy| + w_obs w_ang / w_pos |dtheta| +
w_vel |dv| (w_obs = Task.obstacle_weight), and Task.time_weight |dt| for a timed task. SE2 is itself compound (R^2
weight 1, SO2 weight 0.5): it enters with weight w_pos and its SO2 part with w_ang / w_pos. tests/planning/test_planning.py
checks this formula against OMPL.

Controls: R^2, the pusher velocity (m/s). Each propagate() call is ONE jitted rollout of
`duration / h` simulator steps (`TaskModel.advance`); the object angle is wrapped there and nowhere else.
A failed simulator step (e.g. the pusher jamming the object against a wall: the LCP has no solution) marks the
result invalid by putting the object outside the workspace bounds.

Every OMPL callback here deletes the state and control wrappers it was given before it returns (`del start, ...`).
Why: nanobind hands out the EXISTING Python wrapper when C++ passes a pointer that a live wrapper already refers
to. Planning runs with the cyclic GC off (the 2.0.1 bindings read freed memory during collection), so a reference
cycle that captures a frame is never freed, and with it every caller frame up the `f_back` chain and their locals.
numba's type inference makes such cycles (caught exceptions with their tracebacks) whenever it compiles, and with an
empty cache it compiles inside a propagate() call (the PGS fallback kernel, on Lemke's first failure). The frame of
that propagate() call then stayed alive holding `start`/`result`; OMPL freed those states, a state component was
allocated at the same address, and nanobind returned the stale CompoundState wrapper for it: read_state failed with
"CompoundState, slice". A leaked frame keeps the locals it has when it returns, so a callback whose
wrapper locals are deleted leaks no wrapper, whatever else leaks.
"""

import signal
import threading
import time

import numpy as np
from ompl import base as ob
from ompl import control as oc
from ompl import util as ou

from .tasks import TaskError, TaskModel, check_planner

INVALID_X = 1.0e9        # object x written for a state whose propagation failed (outside every workspace)
SYCLOP_GRID = 10         # Syclop's decomposition: SYCLOP_GRID x SYCLOP_GRID cells over the object's workspace


def read_state(s, nobj=1, timed=False):
    """The flat state (6 nobj + 2 [+ 1 timed],) of an OMPL state (planners.tasks); one slice per vector part, as
    each element read costs a binding call."""
    x = []
    for i in range(nobj):
        o = s[2 * i]
        x += [o.getX(), o.getY(), o.getYaw(), *s[2 * i + 1][0:3]]
    x += s[2 * nobj][0:2]
    if timed:
        x.append(s[2 * nobj + 1][0])
    return np.array(x)


def write_state(s, x, nobj=1, timed=False):
    """Write EVERY component of the flat state x (6 nobj + 2 [+ 1 timed],) into the OMPL state s (OMPL does not
    clear `result`)."""
    for i in range(nobj):
        o = s[2 * i]
        o.setXY(float(x[6 * i]), float(x[6 * i + 1]))
        o.setYaw(float(x[6 * i + 2]))
        s[2 * i + 1][0:3] = [float(x[6 * i + 3]), float(x[6 * i + 4]), float(x[6 * i + 5])]
    s[2 * nobj][0:2] = [float(x[6 * nobj]), float(x[6 * nobj + 1])]
    if timed:
        s[2 * nobj + 1][0] = float(x[6 * nobj + 2])


def bounds(low, high):
    """An ob.RealVectorBounds with the given per-dimension low and high values."""
    b = ob.RealVectorBounds(len(low))
    b.low = [float(v) for v in low]
    b.high = [float(v) for v in high]
    return b


class Propagator:
    """The state propagator (a callable: OMPL 2.0.1 has no StatePropagator trampoline)."""

    def __init__(self, tm: TaskModel):
        self.tm = tm
        self.calls = 0

    def __call__(self, start, control, duration, result):
        # read all of start before writing result (they may alias)
        x = read_state(start, self.tm.nobj, self.tm.timed)
        u = (control[0], control[1])
        del start, control                       # no wrapper may outlive this call (module docstring)
        n = int(round(duration / self.tm.h))
        y, ok = self.tm.advance(x, u, n)
        if not ok:
            y = x.copy()
            y[0] = INVALID_X
        self.calls += 1
        write_state(result, y, self.tm.nobj, self.tm.timed)
        del result


class TaskGoal(ob.GoalSampleableRegion):
    """The task's goal region (threshold 1 on TaskModel.goal_distance); sampleable, so RRT's goal bias works (a
    plain GoalRegion cannot be sampled and the bias would do nothing)."""

    def __init__(self, si, tm):
        super().__init__(si)
        self.tm = tm
        self.setThreshold(1.0)
        self.rng = ou.RNG()                      # seeded by ou.RNG.setSeed like the planner's: plans reproduce

    def distanceGoal(self, state):
        x = read_state(state, self.tm.nobj, self.tm.timed)
        del state                                # no wrapper may outlive this call (module docstring)
        return float(self.tm.goal_distance(x))

    def sampleGoal(self, state):
        write_state(state, self.tm.sample_goal(self.rng.uniformReal), self.tm.nobj, self.tm.timed)
        del state

    def maxSampleCount(self):
        return 1 << 30                           # a continuous region: no finite set of goal states

    def couldSample(self):
        return True


class ObjectXY(ob.ProjectionEvaluator):
    """KPIECE1's projection: the object's position, in square cells of `cell` m (a CompoundStateSpace has no
    default projection and KPIECE1 refuses to run without one)."""

    def __init__(self, space, cell):
        super().__init__(space)
        self.cell = cell

    def getDimension(self):
        return 2

    def defaultCellSizes(self):
        self.setCellSizes([self.cell, self.cell])

    def project(self, state, out):
        o = state[0]
        out[0] = o.getX()
        out[1] = o.getY()
        del state, out, o                        # no wrapper may outlive this call (module docstring)


class ObjectGrid(oc.GridDecomposition):
    """Syclop's decomposition: a grid over the object's position."""

    def __init__(self, length, grid_bounds):
        super().__init__(length, 2, grid_bounds)

    def project(self, s, coord):
        coord[0] = s[0].getX()
        coord[1] = s[0].getY()
        del s, coord                             # no wrapper may outlive this call (module docstring)

    def sampleFullState(self, sampler, coord, s):
        sampler.sampleUniform(s)
        s[0].setXY(coord[0], coord[1])
        del sampler, coord, s


def state_space(tm):
    """The weighted CompoundStateSpace of a TaskModel (module docstring: SE2 + R^3 per body, R^2, [R^1,] the
    distance formula); each body's SE2 bounds are its centre-of-mass bounds (`TaskModel.com_bounds`), a timed
    task's time is in [0, Task.horizon]."""
    t = tm.task
    (px0, px1), (py0, py1) = t.pusher_workspace
    w_pos, w_ang, w_vel, w_pus = t.weights
    space = ob.CompoundStateSpace()
    for i, ((x0, x1), (y0, y1)) in enumerate(tm.com_bounds):
        se2 = ob.SE2StateSpace()
        se2.setBounds(bounds([x0, y0], [x1, y1]))
        se2.setSubspaceWeight(1, w_ang / w_pos)  # SE2 is scaled by w_pos (w_obs) below: its angle then weighs w_ang
        vel = ob.RealVectorStateSpace(3)
        vel.setBounds(bounds([-t.speed_max, -t.speed_max, -t.omega_max], [t.speed_max, t.speed_max, t.omega_max]))
        space.addSubspace(se2, w_pos if i == 0 else t.obstacle_weight)
        space.addSubspace(vel, w_vel)
    pusher = ob.RealVectorStateSpace(2)
    pusher.setBounds(bounds([px0, py0], [px1, py1]))
    space.addSubspace(pusher, w_pus)
    if tm.timed:
        clock = ob.RealVectorStateSpace(1)
        clock.setBounds(bounds([0.0], [t.horizon]))
        space.addSubspace(clock, t.time_weight)
    return space


class Problem:
    """An OMPL SimpleSetup for a task with a named planner. Call `ou.RNG.setSeed` before building it."""

    def __init__(self, task, planner=None, tm=None):
        self.tm = tm = tm if tm is not None else TaskModel(task)
        t = tm.task
        self.task = t
        self.planner_name = planner = check_planner(planner if planner is not None else t.planner)
        space = state_space(tm)
        self.projection = ObjectXY(space, t.kpiece_cell)
        space.registerDefaultProjection(self.projection)     # before setup(): KPIECE1 reads it there
        cspace = oc.RealVectorControlSpace(space, 2)
        cspace.setBounds(bounds([-t.control_max] * 2, [t.control_max] * 2))
        ss = oc.SimpleSetup(cspace)
        si = ss.getSpaceInformation()
        self.propagator = Propagator(tm)
        ss.setStatePropagator(self.propagator)

        # the space, not `si`: a checker that held the SpaceInformation that holds the checker would be a
        # reference cycle through C++ that nothing frees (nanobind's "leaked instances" at exit)
        def is_valid(state):
            inside = space.satisfiesBounds(state)
            x = read_state(state, tm.nobj, tm.timed) if inside else None
            del state                            # no wrapper may outlive this call, on either path (module docstring)
            return inside and tm.valid(x)

        self._is_valid = is_valid
        ss.setStateValidityChecker(is_valid)
        si.setPropagationStepSize(t.step_duration)
        si.setMinMaxControlDuration(t.min_steps, t.max_steps)
        start = space.allocState()
        write_state(start, tm.initial_state(), tm.nobj, tm.timed)
        ss.setStartState(start)
        self.goal = TaskGoal(si, tm)
        ss.setGoal(self.goal)
        p = self._planner(planner, si)
        ss.setPlanner(p)
        # keep every Python object OMPL refers to alive as long as the setup (the bindings do not own them)
        self.space, self.cspace, self.ss, self.si, self.planner, self._start = space, cspace, ss, si, p, start
        ss.setup()

    def _planner(self, name, si):
        """The named planner; RRT and Syclop get their settings from the task (the others have no setters in
        the 2.0.1 bindings)."""
        if name == "RRT":
            p = oc.RRT(si)
            p.setGoalBias(self.task.goal_bias)
            return p
        if name == "EST":
            return oc.EST(si)
        if name == "KPIECE1":
            return oc.KPIECE1(si)
        (ox0, ox1), (oy0, oy1) = self.tm.com_bounds[0]
        self.decomposition = ObjectGrid(SYCLOP_GRID, bounds([ox0, oy0], [ox1, oy1]))
        return (oc.SyclopRRT if name == "SyclopRRT" else oc.SyclopEST)(si, self.decomposition)

    def solve(self, time_limit=None, iterations=None):
        """Solve with a wall-clock limit or an iteration budget (reproducible); stops at the first exact solution.

        Returns a dict: exact, approximate, solve_time, iterations, propagations, sim_steps."""
        if (time_limit is None) == (iterations is None):
            raise TaskError("give exactly one of a time limit and an iteration budget")
        pdef = self.ss.getProblemDefinition()
        count = [0]
        t_end = [None]
        if iterations is not None:
            n = int(iterations)

            def limit():
                count[0] += 1
                return count[0] > n
        else:
            tl = float(time_limit)

            def limit():
                count[0] += 1
                return time.perf_counter() > t_end[0]
        # Ctrl-C: a KeyboardInterrupt raised inside a callback would have to unwind through OMPL's C++ planner, so
        # during solve() SIGINT only sets a flag that the termination condition reads once per planner iteration
        # (milliseconds apart); solve() then returns normally and the interrupt is raised here
        interrupted = []
        stop = lambda: bool(interrupted) or bool(limit())  # noqa: E731
        ptc = ob.plannerOrTerminationCondition(ob.PlannerTerminationCondition(stop),
                                               ob.exactSolnPlannerTerminationCondition(pdef))
        steps0 = self.tm.nsteps_total
        calls0 = self.propagator.calls
        t0 = time.perf_counter()
        if iterations is None:
            t_end[0] = t0 + tl
        main_thread = threading.current_thread() is threading.main_thread()
        if main_thread:
            old = signal.signal(signal.SIGINT, lambda signum, frame: interrupted.append(signum))
        try:
            self.ss.solve(ptc)
        finally:
            if main_thread:
                signal.signal(signal.SIGINT, old)
        if interrupted:
            raise KeyboardInterrupt
        dt = time.perf_counter() - t0
        exact = bool(self.ss.haveExactSolutionPath())
        approx = (not exact) and bool(self.ss.haveSolutionPath())
        return dict(exact=exact, approximate=approx, solve_time=dt, iterations=count[0],
                    propagations=self.propagator.calls - calls0, sim_steps=self.tm.nsteps_total - steps0)

    def solution(self):
        """(states (n+1, d), controls (n, 2), steps (n,) propagation steps per control) of the found path."""
        path = self.ss.getSolutionPath()
        states = np.array([read_state(s, self.tm.nobj, self.tm.timed) for s in path.getStates()])
        controls = np.array([[c[0], c[1]] for c in path.getControls()]).reshape(-1, 2)
        durs = np.array(path.getControlDurations(), float)
        steps = np.rint(durs / self.task.step_duration).astype(int)
        return states, controls, steps
