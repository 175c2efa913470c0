"""Closed loop for any task: feedback controllers over a TaskModel, our simulator as their model.

`PlanTracker(plan)`: executes a plan with feedback (receding-horizon tracking). At every propagation step it
simulates the plan's controls from the observed state, each with one of a few constant offsets, for a few steps,
and keeps the one that ends nearest the plan's reference; off the plan or stalled it pushes the object back to
where the plan has it a little later; past the plan's end it pushes the object into the goal. docs/closed_loop.md,
"Any task".

`PushController(tm)`: for a horizontal-plane task, one push at a time, chosen from the observed flat state
(planners.tasks) by simulating candidate pushes with the task's own forward model (`TaskModel.advance`), scored by a
distance (the task's goal distance unless given) and the task's validity (`TaskModel.admissible`): the Push-T
policy's method (planners/pusht.py) with velocity controls held for the task's step duration. PlanTracker uses it
to recover and to finish.

Both are callables `controller(x) -> u` (the pusher's velocity, m/s, for the next propagation step) with `reset()`
and `compute_s` (the thread CPU seconds of the last call); planners.plans.replay_pymunk and run_closed_loop_lcp
execute them in pymunk or in our simulator (`planar-lcp replay --closed-loop`).
"""
import math
import time

import numpy as np


#: PushController._choose's answer when its budget ran out before the search ended
PENDING = object()


class _Timed:
    """A controller's call: `_decide(x)` on the observed state as float64, its thread CPU time kept in `compute_s`
    (what the closed-loop runs report per control step)."""

    compute_s = 0.0

    def __call__(self, x):
        c0 = time.thread_time()
        u = self._decide(np.asarray(x, dtype=np.float64))
        self.compute_s = time.thread_time() - c0
        return u


class PushController(_Timed):
    """One push at a time over a TaskModel (module docstring). `reset()`, then `controller(x) -> u` (the pusher's
    velocity, m/s, for one propagation step).

    spacing, gap, reach : m; candidate points along the object's outline, how far off it the pusher starts, how far
    a push is tried. push_speed : m/s (at most the task's control_max). budget_steps : propagation steps simulated
    per call at most (a deterministic budget: the same choices on any machine; a search it cuts short goes on at
    the next call while the pusher waits)."""

    def __init__(self, tm, spacing=None, gap=0.001, reach=None, push_speed=None, budget_steps=300, replan_tol=1.0,
                 distance=None, stall=4):
        import shapely  # noqa: F401 - the candidates' clearance and the approach's way are shapely's
        t = tm.task
        if tm.scene.world.plane != "horizontal":
            raise ValueError(f"PushController: task {t.name!r} is in the vertical plane; it pushes on a table only")
        self.tm = tm
        L = tm.object_radius
        self.spacing = float(spacing or L / 8.0)
        self.gap = float(gap)
        self.reach = float(reach or 1.5 * L)
        self.cm = float(t.control_max)
        self.push_speed = float(push_speed or 0.5 * self.cm)
        self.dt = float(t.step_duration)
        self.budget_steps = int(budget_steps)
        self.replan_tol = float(replan_tol)
        self.stall = int(stall)
        self.r = float(tm.pusher_radius)
        #: the distance a push must reduce, threshold 1: the task's goal distance unless given
        self.distance = distance if distance is not None else tm.goal_distance
        self._outline = self._outline_points()
        self.reset()

    def reset(self):
        self._push = None
        self._search = None
        self._banned = set()
        self.replans = 0
        self.compute_s = 0.0
        self.phase = "idle"

    # ---- candidates -------------------------------------------------------------------------------------------
    def _outline_points(self):
        """(point, outward normal) in the object's body frame along its outline, where the pusher's disk fits."""
        import shapely
        poly = self.tm.object_poly_body
        ring = np.asarray(poly.exterior.coords)
        if not poly.exterior.is_ccw:
            ring = ring[::-1]
        out = []
        for a, b in zip(ring[:-1], ring[1:]):
            e = b - a
            L = float(np.hypot(*e))
            if L < 1e-9:
                continue
            n = np.array([e[1], -e[0]]) / L
            k = max(1, int(math.floor(L / self.spacing)))
            for s in (np.arange(k) + 0.5) / k:
                p = a + s * e
                c = p + (self.r + self.gap) * n
                if shapely.distance(poly, shapely.points(*c)) >= self.r + 0.99 * self.gap:
                    out.append((p, n))
        return out

    def _frame(self, x):
        f = self.tm.object_frame_pose(x)
        c, s = math.cos(f[2]), math.sin(f[2])
        return f, np.array([[c, -s], [s, c]])

    # ---- deciding ---------------------------------------------------------------------------------------------
    def _decide(self, x):
        push = self._push
        if push is not None and not self._on_track(push, x):
            push = self._push = None
        u = None
        for _ in range(2):                     # a push given up while approaching (_follow) is replaced at once
            if push is None:
                push = self._choose(x)
                if push is PENDING:
                    self.phase = "thinking"
                    return np.zeros(2)
                self._push = push
                self.replans += 1
            if push is None:
                break
            u = self._follow(push, x)
            if u is not None:
                break
            push = self._push = None
        if u is None:
            self.phase = "idle"
            u = np.zeros(2)
        return u

    def _on_track(self, push, x):
        tm = self.tm
        if push["phase"] == "approach":
            ref = push["start"]
        else:
            k = push["k"]
            if k >= len(push["states"]) - 1:
                return False                               # the push is done: choose the next
            ref = push["states"][k]
        g = tm.task.goal
        dp = math.hypot(x[0] - ref[0], x[1] - ref[1])
        da = abs((x[2] - ref[2] + math.pi) % (2 * math.pi) - math.pi)
        # a goal without an angle (a disk) leaves the object free to spin: its angle is not tracked
        return dp <= self.replan_tol * g.position_tol and (g.angle is None or da <= self.replan_tol * g.angle_tol)

    def _follow(self, push, x):
        ip = self.tm.ip
        p = x[ip:ip + 2]
        if push["phase"] == "approach":
            route, push["side"] = self._route(x, push["c0"], push.get("side", 0))
            target = route[0]
            d = target - p
            dist = float(np.hypot(*d))
            # the way left; an approach that has not shortened it by a millimetre in `stall` steps (the route
            # flipping sides, the object moving away as fast) is given up: None, and that push is not chosen again
            # until one push has been made
            left = dist + sum(float(np.hypot(*(b - a))) for a, b in zip(route[:-1], route[1:]))
            if left < push.get("best_left", math.inf) - 1e-3:
                push["best_left"], push["since"] = left, 0
            else:
                push["since"] = push.get("since", 0) + 1
                if push["since"] >= self.stall:
                    self._banned.add(push["j"])
                    return None
            if dist < 1e-4 and len(route) == 1:
                push["phase"] = "push"
                push["k"] = 0
                self._banned.clear()
            else:
                self.phase = "approach"
                step = min(dist, self.cm * self.dt)
                return np.clip(d / max(dist, 1e-12) * step / self.dt, -self.cm, self.cm)
        self.phase = "push"
        push["k"] += 1
        return push["u"].copy()

    def _route(self, x, c0, side=0):
        """(waypoints for the pusher to c0 clear of the object, the side it goes round): [c0] when the straight way
        is clear, else round it on a circle about its centre of mass, anticlockwise (side +1), clockwise (-1) or the
        shorter way (0); a push keeps the side it started with, so that the way does not flip from step to step."""
        import shapely
        from shapely.geometry import LineString
        tm = self.tm
        f, R = self._frame(x)
        ip = tm.ip
        p = x[ip:ip + 2]
        from .tasks import _place
        body = _place(tm.object_poly_body, f[:2], f[2])
        if shapely.distance(body, LineString([p, c0])) >= self.r + 0.5 * self.gap or np.allclose(p, c0):
            return [np.asarray(c0, float)], side
        com = x[0:2]
        rad = (tm.object_radius + self.r + 4 * self.gap + 0.005) / math.cos(math.radians(15.0))
        a0 = math.atan2(p[1] - com[1], p[0] - com[0])
        da = (math.atan2(c0[1] - com[1], c0[0] - com[0]) - a0 + math.pi) % (2 * math.pi) - math.pi
        if side * da < 0:
            da += side * 2 * math.pi                     # round the way it started
        side = side or (1 if da >= 0 else -1)
        n = max(1, int(math.ceil(abs(da) / math.radians(30.0))))
        pts = [com + rad * np.array([math.cos(a0 + da * k / n), math.sin(a0 + da * k / n)]) for k in range(n + 1)]
        # the first waypoint not yet reached
        for i, w in enumerate(pts):
            if np.hypot(*(w - p)) > 1e-4:
                return pts[i:] + [np.asarray(c0, float)], side
        return [np.asarray(c0, float)], side

    def _choose(self, x):
        """The push with the most progress per step (approach included), or None when no push makes progress, or
        PENDING when the budget ran out first: the search goes on at the next call from where it stopped (the
        pusher waits meanwhile), unless the object has moved since. Pushes are tried at push_speed first, and only
        when none of those makes progress at a quarter and a sixteenth of it over as many steps (shorter pushes:
        near the goal a fast push overshoots it in its first step)."""
        tm = self.tm
        ip = tm.ip
        search = self._search
        # a search goes on while the bodies stay within a fifth of the goal's position tolerance of where it began
        # (their poses: the velocities of a body coming to rest change meanwhile)
        moved = None if search is None else np.abs((search["x"][:ip] - x[:ip]).reshape(-1, 6)[:, 0:2]).max()
        if search is None or moved > 0.2 * tm.task.goal.position_tol:
            order = np.random.default_rng(self.replans).permutation(len(self._outline))
            speeds = (self.push_speed, self.push_speed / 4.0, self.push_speed / 16.0)
            search = self._search = {"x": x.copy(), "todo": [(sp, j) for sp in speeds for j in order],
                                     "best": None, "speed": speeds[0]}
        f, R = self._frame(x)
        d_now = self.distance(x)
        steps = max(1, int(math.ceil(self.reach / (self.push_speed * self.dt))))
        spent = 0                              # propagation steps simulated in this call
        todo = search["todo"]
        while todo:
            speed, j = todo[0]
            if speed != search["speed"]:
                if search["best"] is not None:
                    break                      # a faster push makes progress: the slower ones are not tried
                search["speed"] = speed
            if spent >= self.budget_steps:
                return PENDING
            todo.pop(0)
            if j in self._banned:
                continue
            p_b, n_b = self._outline[j]
            c0 = f[:2] + R @ (p_b + (self.r + self.gap) * n_b)
            u = -(R @ n_b) * speed
            y = x.copy()
            y[3:6] = 0.0
            y[ip:ip + 2] = c0
            if not tm.admissible(y):
                continue
            states, dists = [y], [d_now]
            for _ in range(steps):
                y, ok = tm.advance(y, u, tm.steps_per_prop)
                spent += 1
                if not (ok and tm.admissible(y)):
                    break
                states.append(y)
                dists.append(self.distance(y))
            i = int(np.argmin(dists))
            if i == 0 or dists[i] >= d_now:
                continue
            way = float(np.hypot(*(c0 - x[ip:ip + 2])))
            cost_steps = way / (self.cm * self.dt) + i
            rate = (d_now - dists[i]) / cost_steps
            if search["best"] is None or rate > search["best"][0]:
                search["best"] = (rate, c0, u, states[:i + 1], j)
        best = search["best"]
        self._search = None
        if best is None:
            return None
        _, c0, u, states, j = best
        return {"phase": "approach", "c0": c0, "u": u, "states": states, "start": x.copy(), "k": 0, "j": j}


class PlanTracker(_Timed):
    """Track a plan with feedback: receding-horizon control over our simulator (module docstring). `reset()`, then
    `tracker(x) -> u`, the pusher's velocity (m/s) for the next propagation step from the observed flat state x.

    The reference is the plan replayed in our model (TaskModel.execute: the states at every propagation step and
    the control of each). At each step the tracker finds where along the reference the observed state is (the
    nearest reference state, never going back), then simulates `horizon` propagation steps for each candidate, the
    plan's controls from there plus one constant offset (none; eight directions at two speeds; the offset that puts
    the pusher back where the plan has it), and keeps the candidate whose end is nearest the reference state
    `horizon` steps on (nearest the goal, by the task's goal distance, once the reference has ended). Candidates
    that fail a step or leave the task's valid states are dropped. The distance weighs every dynamic body's position
    error by the goal's position tolerance and its angle error by the angle tolerance, the object's fully, the
    obstacles' by `obstacle_weight`, and the pusher's position by `pusher_weight`.

    Off the plan (the object's pose farther than `lost` from the reference's, in goal tolerances) or stalled (no
    progress along the reference for `stall` steps), on a table: a PushController brings the object to the
    reference's pose `lookahead` steps on (at most `recover_max` steps), and tracking resumes there; when the object
    is already there (the plan only moves the pusher meanwhile) tracking skips ahead; when no push brings it there,
    the plan is given up for the finisher's pushes into the goal. Past the plan's end, when no
    candidate brings the goal nearer: a PushController on the task's goal (`finisher`; "auto": on a table, none in
    the vertical plane). Every choice is deterministic: the push searches' budget is `budget_steps` simulated
    propagation steps per call, not seconds.

    horizon : int, propagation steps each candidate is simulated. window : int, how far ahead of the last index the
    search for the nearest reference state looks. offsets : (fractions of the task's control_max) of the candidates'
    offsets."""

    def __init__(self, plan, horizon=4, window=10, offsets=(0.25, 0.6), obstacle_weight=0.3, pusher_weight=0.2,
                 finisher="auto", lost=3.0, stall=8, lookahead=10, recover_max=100, budget_steps=150):
        self.plan = plan
        self.tm = tm = plan.model
        # past the plan's end, when no candidate brings the goal nearer: one push at a time (PushController) on a
        # table; "auto": for a horizontal-plane task, else none
        if finisher == "auto":
            finisher = None
            if tm.scene.world.plane == "horizontal":
                finisher = PushController(tm, budget_steps=budget_steps)
        self.finisher = finisher
        # off the plan or stalled: pushes that bring the object to the reference's pose a little later, then
        # tracking again; on a table only, as the finisher
        self.lost = float(lost)
        self.stall, self.lookahead, self.recover_max = int(stall), int(lookahead), int(recover_max)
        self.recoverer = None
        if tm.scene.world.plane == "horizontal":
            self.recoverer = PushController(tm, budget_steps=budget_steps, distance=self._to_target)
        self._target = None
        self.horizon, self.window = int(horizon), int(window)
        t = tm.task
        self.cm = float(t.control_max)
        self.dt = float(t.step_duration)
        _, dense, ok = tm.execute(plan.states[0], plan.controls, plan.steps)
        self.ref = dense
        self.uref = np.repeat(plan.controls, plan.steps, axis=0)          # (N, 2): the control of each step
        g = t.goal
        self.pos_scale = float(g.position_tol)
        self.ang_scale = float(g.angle_tol)
        w = np.zeros(t.state_dim)
        for i in range(tm.nobj):
            wi = 1.0 if i == 0 else float(obstacle_weight)
            w[6 * i:6 * i + 2] = wi / self.pos_scale
            w[6 * i + 2] = wi / self.ang_scale
        w[tm.ip:tm.ip + 2] = float(pusher_weight) / self.pos_scale
        if g.angle is None:
            w[2] = 0.0                        # a goal that leaves the angle free (a disk): the object may spin
        self._w = w
        self._angle_cols = np.array([6 * i + 2 for i in range(tm.nobj)])
        self._w_object = np.zeros_like(w)
        self._w_object[0:3] = w[0:3]
        dirs = [np.array([math.cos(a), math.sin(a)]) for a in np.arange(8) * math.pi / 4]
        self._offsets = [np.zeros(2)] + [f * self.cm * d for f in offsets for d in dirs]
        self.reset()

    def reset(self):
        self.k = 0
        self.compute_s = 0.0
        self.phase = "track"
        self.finishing = False
        self.recoveries = 0
        self._target = None
        self._target_index = 0
        self._recover_steps = 0
        self._best_k, self._since_progress = 0, 0
        if self.finisher is not None:
            self.finisher.reset()

    def distance(self, x, r, w=None):
        """The weighted distance (class docstring) of state x from reference state r; `w` other weights."""
        e = np.asarray(x, float) - r
        e[self._angle_cols] = (e[self._angle_cols] + math.pi) % (2.0 * math.pi) - math.pi
        e *= self._w if w is None else w
        return float(np.sqrt(e @ e))

    def object_distance(self, x, r):
        """The object's pose error from reference state r (position by the goal's position tolerance, angle by its
        angle tolerance): 1 where the goal's tolerances would hold."""
        return self.distance(x, r, self._w_object)

    def _to_target(self, x):
        return self.object_distance(x, self._target)

    def _u(self, j, offset):
        base = self.uref[j] if j < len(self.uref) else np.zeros(2)
        return np.clip(base + offset, -self.cm, self.cm)

    def _decide(self, x):
        """The control for observed state x, and self.phase set (the class docstring's steps)."""
        tm = self.tm
        if self.finishing:
            u = self.finisher(x)
            self.phase = "finish: " + self.finisher.phase
            return u
        N = len(self.uref)
        if self._target is not None:
            if self._to_target(x) > 1.0 and self._recover_steps < self.recover_max:
                self._recover_steps += 1
                u = self.recoverer(x)
                self.phase = "recover: " + self.recoverer.phase
                if self.recoverer.phase == "idle" and self.finisher is not None:
                    # no push brings the object back to the plan: the plan is given up for pushes into the goal
                    self.finishing = True
                    u = self.finisher(x)
                    self.phase = "finish: " + self.finisher.phase
                return u
            # back on the plan (or the recovery took too long): tracking resumes at the target's index
            self._target = None
            self.k = self._target_index
            self._best_k, self._since_progress = self.k, 0
        lo, hi = self.k, min(self.k + self.window, N)
        d = [self.distance(x, self.ref[j]) for j in range(lo, hi + 1)]
        self.k = j = lo + int(np.argmin(d))
        if j > self._best_k:
            self._best_k, self._since_progress = j, 0
        else:
            self._since_progress += 1
        # off the plan (the object too far from the reference) or stalled (no progress along it for `stall`
        # steps): pushes that bring the object to the reference's pose `lookahead` steps on
        if self.recoverer is not None and j < N and (self.object_distance(x, self.ref[j]) > self.lost
                                                     or self._since_progress >= self.stall):
            self._target_index = min(j + self.lookahead, N)
            self._target = self.ref[self._target_index]
        if self._target is not None and self._to_target(x) <= 1.0:
            # stalled where the plan moves the pusher only (the object already where the plan has it `lookahead`
            # steps on): tracking skips there
            self._target = None
            self.k = j = self._target_index
            self._best_k, self._since_progress = j, 0
        elif self._target is not None:
            self._recover_steps = 0
            self.recoverer.reset()
            self.recoveries += 1
            u = self.recoverer(x)
            self.phase = "recover: " + self.recoverer.phase
            return u
        end = min(j + self.horizon, N)
        at_end = j + self.horizon >= N
        self.phase = "track" if not at_end else "finish"
        ip = tm.ip
        # the offset that brings the pusher to the plan's position at the next step
        back = (self.ref[min(j + 1, N), ip:ip + 2] - self._u(j, 0.0) * self.dt - x[ip:ip + 2]) / self.dt
        best = None
        for off in self._offsets + [back]:
            y, good = x, True
            for i in range(self.horizon):
                y, ok = tm.advance(y, self._u(j + i, off), tm.steps_per_prop)
                if not (ok and tm.admissible(y)):
                    good = False
                    break
            if not good:
                continue
            cost = self.distance(y, self.ref[end])
            if at_end:
                cost = tm.goal_distance(y) + 1e-3 * cost
            if best is None or cost < best[0]:
                best = (cost, off)
        if at_end and self.finisher is not None and (best is None or best[0] >= tm.goal_distance(x)):
            # the finisher starts at the next step: its search and this step's candidates in one step would be
            # twice a step's compute
            self.finishing = True
            u = np.zeros(2)
            self.phase = "finish: thinking"
        else:
            u = self._u(j, best[1] if best is not None else 0.0)
        return u


class OpenLoop:
    """The plan's controls in turn, one per propagation step, whatever the state (zero after the plan's end): the
    open-loop execution as a controller, for the runners of closed loops."""

    def __init__(self, plan):
        self.uref = np.repeat(plan.controls, plan.steps, axis=0)
        self.reset()

    def reset(self):
        self.k = 0
        self.compute_s = 0.0

    def __call__(self, x):
        u = self.uref[self.k] if self.k < len(self.uref) else np.zeros(2)
        self.k += 1
        return u
