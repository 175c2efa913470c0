"""Shorter plans: randomised shortcutting of an exact plan, the simulator as the judge.

OMPL's control planners stop at the first exact plan, a chain of short random controls (SST, the near-optimal one,
cannot be built from the 2.0.1 wheel: docs/planning.md). `shorten` rewrites such a plan, keeping it exact:

- The plan is held per PROPAGATION STEP: one control per step (U, (K, 2)) and the states at every step (X, (K+1, d)),
  the dense states `TaskModel.execute` returns. Every propagation step is its own rollout starting from the full
  state (`TaskModel.advance`), so a control held k steps is bit for bit the same control held k1 then k - k1 steps:
  any step is a vertex where a stretch can start or end (Hauser and Ng-Thow-Hing 2010 pick random points along
  the path, OMPL's PathSimplifier::shortcutPath random states on it).
- A candidate replaces the stretch of steps [a, b) by something shorter:
  "straight": the pusher goes straight from its position at step a to the one at step b at the largest speed the
  control bounds allow (|v| <= control_max per axis), in ceil(max(|dx|, |dy|) / (control_max dt)) steps. Where
  nothing is touched the object is at rest and the rest of the plan is unchanged; where the stretch pushed, it is a
  merged, sustained push along the stretch's net pusher motion.
  "faster": the stretch's pusher path is kept and each control in it is sped up to the largest allowed speed (its
  displacement u k dt kept, its steps k cut to ceil(k |u|max / control_max)): pushing is nearly quasi-static.
  "retarget": a straight move from step a to the pusher's position at step b shifted by the object's error at the
  end (a local re-plan of the last push towards the goal pose: the pusher moves by what the object still lacks).
  "push": a local re-plan of the OBJECT's path from step a to the object's pose at step b (b = the plan's end, in
  half of them: the goal's pose, or its position when it has no angle), the only kind that can straighten the
  object's path. A point pusher moves a box without turning it only by pushing a face through its middle (within
  the contact's friction cone about the face's normal), so the primitive goes as a rook does: when the object's
  angle is off the target's it first turns it (pushing a face off its middle), then moves it in one or two straight
  legs along its faces' normals (the pair whose cone holds the way to the target, the shortest, in a random order),
  each a free approach to behind the object (straight segments, round the object on a circle clear of it) and a
  push re-aimed at the leg's end every step, the contact point shifted across the push line by the object's angle
  error to hold it. It waits for the object to come to rest and, for b < the end, moves free to the pusher's
  position at b. The controls are made by simulating the candidate from X[a] step by step (feedback on the
  simulated states); the result is still a list of per-step controls with their states, judged as the others; its
  parameters (gains, speed, the side it goes round, the order of the legs, b) are drawn from the shortener's
  Generator.
- A candidate is simulated from X[a] only: the states before a are unchanged and the simulator is deterministic, so
  this equals a re-simulation from the start bit for bit (tests/planning/test_shorten.py checks it on the final plan). It is
  accepted only when every propagation step succeeds, every state is admissible (`TaskModel.admissible`: the
  validity the planner checks after each propagation step), the goal holds at the end and the plan has fewer
  steps. A stretch that leaves the object farther from where the rest of the plan expects it than the goal's
  tolerances is rejected without simulating the rest (a pruning: what is kept is always judged whole). A plan whose
  goal holds before its end is cut there (checked at the start and after each acceptance).
- Bounded and deterministic: a numpy Generator seeded from the plan's seed draws the candidates; shortening stops
  after `max_candidates` simulated candidates, `patience` rejected ones in a row or `max_sim_steps` simulated steps
  (`default_rule`: counts, so that a plan made with --iterations is the same on any machine), at `deadline` (a
  wall-clock time: the rest of a --time budget, or `plan --shorten-time`), or when `stop` says so (Ctrl-C). A
  larger budget continues the same sequence of candidates: the rule only chooses where it ends.

The result is returned as controls and step counts (runs of equal per-step controls, split into the task's
min_steps..max_steps), which `replay` re-simulates bit for bit.
"""

import math
import time

import numpy as np

#: The default stopping rule (`default_rule`; docs/planning.md, "When shortening stops"): shortening stops after
#: PATIENCE rejected candidates in a row (it has stopped paying), or once its candidates have simulated EFFORT_SHARE
#: times the steps the planner simulated to find the plan, and at least EFFORT_MIN (a share of the time already
#: spent, counted in simulated steps: the same on every machine), or after MAX_CANDIDATES simulated candidates (each
#: re-simulates the plan from its change point)
MAX_CANDIDATES = 4000
PATIENCE = 500
EFFORT_SHARE = 2.0
EFFORT_MIN = 100_000
#: with no bound on the candidates (a time budget only, `plan --shorten-time`): stop after this many draws in a row
#: that gave nothing to simulate (a plan so short that no stretch can be replaced by a shorter one)
IDLE_DRAWS = 10000
#: the share of each kind of candidate (straight, faster, retarget, push)
KINDS = ("straight", "faster", "retarget", "push")
KIND_P = (0.5, 0.25, 0.1, 0.15)
#: ... where no push applies (the vertical plane, tip_box; a goal without x and y, turn_box): the shares of the first
#: three kinds before "push" existed, drawn as then, so those tasks' shortened plans are the same as before it
KIND_P_NO_PUSH = (0.6, 0.3, 0.1)
#: the push primitive's free moves keep the pusher's disk this far (m) from the object's outline
PUSH_CLEARANCE = 0.005
#: ... and its push ends when the object's centre of mass is within this share of position_tol of the target's
PUSH_STOP = 0.3
#: ... and keeps its direction once the object is within this share of its least half-width of a leg's end (re-aimed
#: so close, a small sideways error would swing the push across the face)
PUSH_FREEZE = 1.0
#: ... and turns the object first when its angle is farther than this share of angle_tol from the target's, pushing
#: a face this share of the object's least half-width off its middle
PUSH_TURN = 0.5
PUSH_TURN_OFFSET = 0.7
#: ... and waits at most this many propagation steps for the object to come to rest
PUSH_SETTLE = 5


def default_rule(planner_sim_steps):
    """The default stopping rule of `plan`'s shortening, as keyword arguments of `shorten`: at most MAX_CANDIDATES
    candidates, PATIENCE rejected in a row, and simulated steps at most EFFORT_SHARE times the planner's
    `planner_sim_steps` (what finding the plan cost), at least EFFORT_MIN. Counts, not seconds: a plan made with an
    iteration budget and a seed is the same on every machine."""
    return dict(max_candidates=MAX_CANDIDATES, patience=PATIENCE,
                max_sim_steps=int(max(EFFORT_MIN, EFFORT_SHARE * int(planner_sim_steps))))


def per_step(controls, steps):
    """(K, 2) one control per propagation step of controls (n, 2) held steps (n,) each."""
    u = np.asarray(controls, float).reshape(-1, 2)
    return np.repeat(u, np.asarray(steps, int), axis=0)


def compress(U, min_steps, max_steps):
    """(controls (n, 2), steps (n,)) of per-step controls U (K, 2): runs of equal controls, each split into as few
    chunks of min_steps..max_steps steps as it can; None when a run cannot be split so (shorter than min_steps)."""
    controls, steps = [], []
    i, K = 0, len(U)
    while i < K:
        j = i + 1
        while j < K and U[j, 0] == U[i, 0] and U[j, 1] == U[i, 1]:
            j += 1
        r = j - i
        c = -(-r // max_steps)
        if c * min_steps > r:
            return None
        base, extra = divmod(r, c)
        for m in range(c):
            controls.append(U[i].copy())
            steps.append(base + (1 if m < extra else 0))
        i = j
    return np.array(controls).reshape(-1, 2), np.array(steps, int)


def path_lengths(tm, dense):
    """(pusher path length, object path length) in m of the states at every propagation step (d,) each: the
    polylines through the pusher's position and the object's centre of mass."""
    X = np.asarray(dense, float)
    if len(X) < 2:
        return 0.0, 0.0
    ip = tm.ip
    pusher = float(np.hypot(*np.diff(X[:, ip:ip + 2], axis=0).T).sum())
    obj = float(np.hypot(*np.diff(X[:, 0:2], axis=0).T).sum())
    return pusher, obj


def costs(tm, steps, dense):
    """The costs a plan is reported with: path duration (s), pusher and object path lengths (m)."""
    pusher, obj = path_lengths(tm, dense)
    return dict(path_duration=float(int(np.sum(steps)) * tm.task.step_duration), pusher_path_length=pusher,
                object_path_length=obj)


class Shortener:
    """The plan being shortened (per-step controls U and states X) and its judge (a TaskModel)."""

    def __init__(self, tm, x0, controls, steps, replayed=None):
        self.tm = tm
        t = tm.task
        self.cm, self.dt = float(t.control_max), float(t.step_duration)
        self.min_steps, self.max_steps = int(t.min_steps), int(t.max_steps)
        self.U = per_step(controls, steps)
        # replayed: (dense states, ok) of tm.execute(x0, controls, steps) when the caller has them already
        _, dense, ok = (None, *replayed) if replayed is not None else tm.execute(x0, controls, steps)
        self.X = dense
        self.ok = bool(ok) and all(tm.admissible(x) for x in dense) and self._goal(dense[-1])
        #: a time.perf_counter() value at which a push candidate being built stops (shorten's deadline)
        self.deadline = None
        #: a function that says the shortening must stop now (Ctrl-C: shorten's `stop`); a push being built stops too
        self.stop = None
        #: whether "push" candidates apply: a goal with a position (x and y), in the horizontal plane
        g = t.goal
        self.can_push = tm.scene.world.plane == "horizontal" and g.x is not None and g.y is not None

    def _goal(self, x):
        return self.tm.goal_distance(x) <= 1.0 and self.tm.admissible(x)

    def expired(self):
        """Whether the deadline has passed or `stop` says to stop: a push candidate being built is then abandoned."""
        return ((self.deadline is not None and time.perf_counter() > self.deadline)
                or (self.stop is not None and bool(self.stop())))

    def simulate(self, x, U_new):
        """States from x under the per-step controls U_new (`TaskModel.execute`, stopping at the first failed step
        or inadmissible state); (states (k+1, d), whole) with whole False when it stopped early."""
        _, dense, ok = self.tm.execute(x, U_new, np.ones(len(U_new), int), valid=self.tm.admissible)
        return dense, ok

    def diverged(self, x, y):
        """Whether the object's pose in x is farther from y's than the goal's tolerances (position_tol, angle_tol):
        the rest of the plan, open loop, would then rarely still reach the goal."""
        g = self.tm.task.goal
        return (math.hypot(x[0] - y[0], x[1] - y[1]) > g.position_tol
                or abs((x[2] - y[2] + math.pi) % (2 * math.pi) - math.pi) > g.angle_tol)

    def truncate_at_goal(self, start=1):
        """Cut the plan at its first state from `start` on where the goal holds (if its controls still split into
        the task's durations); True when it was cut."""
        for k in range(max(start, 1), len(self.X) - 1):
            if self._goal(self.X[k]) and compress(self.U[:k], self.min_steps, self.max_steps) is not None:
                self.U, self.X = self.U[:k], self.X[:k + 1]
                return True
        return False

    def straight(self, p0, p1):
        """Per-step controls moving the pusher from p0 to p1 in a straight line at the largest allowed speed, or
        None for no motion."""
        d = np.asarray(p1, float) - np.asarray(p0, float)
        n = int(math.ceil(max(abs(d[0]), abs(d[1])) / (self.cm * self.dt) - 1e-9))
        if n < 1:
            return None
        v = np.clip(d / (n * self.dt), -self.cm, self.cm)
        return np.repeat(v[None], n, axis=0)

    def faster(self, a, b):
        """The per-step controls of [a, b) with each run of equal controls sped up to the largest allowed speed,
        its displacement kept."""
        out, i = [], a
        while i < b:
            j = i + 1
            while j < b and self.U[j, 0] == self.U[i, 0] and self.U[j, 1] == self.U[i, 1]:
                j += 1
            u, k = self.U[i], j - i
            umax = max(abs(u[0]), abs(u[1]))
            k2 = max(1, int(math.ceil(k * umax / self.cm - 1e-9))) if umax > 0 else 1
            v = np.clip(u * k / k2, -self.cm, self.cm) if umax > 0 else u
            out.append(np.repeat(v[None], k2, axis=0))
            i = j
        return np.concatenate(out)

    def goal_shift(self):
        """What the object's centre of mass still lacks at the plan's end towards the goal's, (2,) m, or None when
        the goal names no position."""
        tm = self.tm
        if tm.goal_com is not None:
            return tm.goal_com[:2] - self.X[-1, 0:2]
        return None

    def candidate(self, kind, a, b):
        """Per-step controls replacing [a, b), or None."""
        ip = self.tm.ip
        if kind == "straight":
            return self.straight(self.X[a, ip:ip + 2], self.X[b, ip:ip + 2])
        if kind == "faster":
            return self.faster(a, b)
        shift = self.goal_shift()
        if shift is None:
            return None
        return self.straight(self.X[a, ip:ip + 2], self.X[b, ip:ip + 2] + shift)

    # ---- the push primitive ("push": a local re-plan of the object's path) ---------------------------------
    def _outline(self, x, grow):
        """The object's outline at state x grown by `grow` (m): a shapely polygon in the world frame."""
        from .tasks import _place
        pf = self.tm.object_frame_pose(x)
        return _place(self.tm.object_poly_body, pf[:2], pf[2]).buffer(grow, quad_segs=4)

    def _behind(self, x, o, e, grow):
        """How far (m) from the point o against the unit direction e the object's outline at x, grown by `grow`,
        ends (its farthest crossing by the ray from o along -e), or None when the ray misses it."""
        import shapely
        from shapely.geometry import LineString
        far = 4.0 * self.tm.object_radius + grow
        hit = LineString([o, o - far * e]).intersection(self._outline(x, grow).exterior)
        pts = shapely.get_coordinates(hit)
        if len(pts) == 0:
            return None
        return float(np.max((o - pts) @ e))

    def _route(self, x, p, q, side):
        """Waypoints for the pusher from p to q that keep its disk off the object at state x: [q] when the straight
        segment is clear of the outline grown by the pusher's radius; else out to the circle about the object's
        centre of mass whose 30-degree chords clear it, along it (side +1 anticlockwise, -1 clockwise, 0 the
        shorter way) and in to q (radial moves: clear of a convex object)."""
        from shapely.geometry import LineString
        tm = self.tm
        c = x[0:2]
        if not LineString([p, q]).intersects(self._outline(x, tm.pusher_radius + 0.5 * PUSH_CLEARANCE)):
            return [np.asarray(q, float)]
        R = (tm.object_radius + tm.pusher_radius + PUSH_CLEARANCE) / math.cos(math.radians(15.0))
        a0 = math.atan2(p[1] - c[1], p[0] - c[0])
        da = (math.atan2(q[1] - c[1], q[0] - c[0]) - a0 + math.pi) % (2 * math.pi) - math.pi
        if side * da < 0:
            da += side * 2 * math.pi                   # round the other way
        n = max(1, int(math.ceil(abs(da) / math.radians(30.0))))
        return [c + R * np.array([math.cos(a0 + da * k / n), math.sin(a0 + da * k / n)]) for k in range(n + 1)] \
            + [np.asarray(q, float)]

    def _legs(self, x, target, first):
        """The object's centre-of-mass waypoints from x to `target`: one or two straight legs, each along a push
        direction (_push_directions) or, when the object has none, straight; first 0 or 1: which of the two
        directions goes first."""
        c = x[0:2]
        d = np.asarray(target, float) - c
        F = self._push_directions(x)
        best = None
        for i in range(len(F)):
            for j in range(i + 1, len(F)):
                A = np.column_stack([F[i], F[j]])
                if abs(np.linalg.det(A)) < 1e-6:
                    continue
                ab = np.linalg.solve(A, d)
                if ab.min() >= -1e-9 and (best is None or ab.sum() < best[0]):
                    best = (ab.sum(), ab, (F[i], F[j]))
        if best is None:
            return [np.asarray(target, float)]
        _, ab, (fi, fj) = best
        lead = ab[0] * fi if first == 0 else ab[1] * fj
        if min(ab) < PUSH_STOP * self.tm.task.goal.position_tol:
            return [np.asarray(target, float)]          # one leg does it
        return [c + lead, np.asarray(target, float)]

    def _push_directions(self, x):
        """World-frame unit directions that push the object at state x through the middle of a face: the inward
        normals of its convex hull's edges at least half its least half-width long (none for a round object). A
        point pusher can move a box without turning it only so (within the contact's friction cone about a face's
        normal), so a move in any other direction is two legs: a box goes as a rook does."""
        from .tasks import _place
        tm = self.tm
        pf = tm.object_frame_pose(x)
        hull = _place(tm.object_poly_body, pf[:2], pf[2]).convex_hull
        P = np.asarray(hull.exterior.coords)
        D = np.diff(P, axis=0)
        L = np.hypot(D[:, 0], D[:, 1])
        keep = L >= 0.5 * tm.task.object_extent["min_support"]
        N = np.column_stack([-D[keep, 1], D[keep, 0]]) / L[keep, None]
        mid = 0.5 * (P[:-1] + P[1:])[keep]
        inward = np.sign(np.sum((x[0:2] - mid) * N, axis=1))
        return N * inward[:, None]

    def _turn(self, S, run, goto, target, error, speed):
        """The push primitive's turn (its states S, extended by run and goto): push the face whose inward normal
        points most towards the target at a point PUSH_TURN_OFFSET of its least half-width off its middle, along
        the face's normal as it turns, until the object's angle error is within PUSH_STOP of the goal's
        angle_tol (the sign of the offset as in `push`: l n with l of the error's sign turns it back). False when
        a step failed."""
        tm = self.tm
        ip, tol = tm.ip, PUSH_STOP * tm.task.goal.angle_tol
        x = S[-1]
        F = self._push_directions(x)
        if len(F) == 0:
            return True
        f = F[int(np.argmax(F @ (np.asarray(target) - x[0:2])))]
        c, s_ = math.cos(x[2]), math.sin(x[2])
        f_body = np.array([c * f[0] + s_ * f[1], -s_ * f[0] + c * f[1]])
        sign = 1.0 if error(x) > 0 else -1.0
        l = sign * PUSH_TURN_OFFSET * tm.task.object_extent["min_support"]
        approach = True
        while sign * error(S[-1]) > tol:
            x = S[-1]
            c, s_ = math.cos(x[2]), math.sin(x[2])
            f = np.array([c * f_body[0] - s_ * f_body[1], s_ * f_body[0] + c * f_body[1]])
            o = x[0:2] + l * np.array([-f[1], f[0]])
            behind = self._behind(x, o, f, tm.pusher_radius)
            if behind is None:
                return False
            p_star = o - behind * f
            if approach:
                if not goto(p_star - PUSH_CLEARANCE * f):
                    return False
                approach = False
                continue
            v = (p_star + speed * self.cm * self.dt * f - x[ip:ip + 2]) / self.dt
            if not run([v / max(1.0, float(np.max(np.abs(v))) / self.cm)]):
                return False
        return True

    def push(self, a, b, k_angle, lateral_gain, speed, side, first):
        """The "push" candidate replacing [a, b) (module docstring), built by simulating it from X[a]: (per-step
        controls, their states from X[a], whole) with whole False when it failed (a failed or inadmissible step,
        a lost contact, or no fewer steps than b - a); None when the task has no position goal in the horizontal
        plane (nothing simulated).

        Each leg (_legs) is a free approach to behind the object and a push re-aimed at the leg's end every step.
        k_angle (m/rad): the contact point's shift across the push line per radian of the object's angle error
        (a push off the line through the centre of mass turns the object: the torque of a force f e at l n from
        it, n = e turned +90 deg, is -l f, so l = k_angle (angle - target angle) turns it back); lateral_gain: the
        share of the pusher's offset across the line corrected per step; speed: the push's share of
        control_max; side: how the free moves go round the object (_route); first: which leg goes first."""
        tm = self.tm
        if not self.can_push:
            return None
        g = tm.task.goal
        K, ip, r = len(self.U), tm.ip, tm.pusher_radius
        if b == K and tm.goal_com is not None:
            target, angle = tm.goal_com[:2], (tm.goal_com[2] if g.angle is not None else None)
        elif b == K:
            # a goal position without an angle: the centre of mass where the body frame's origin is at (x, y) if the
            # object keeps its angle at a (exactly the goal for a round object, whose centre of mass is its origin)
            th = self.X[a, 2]
            cl = tm.com_local
            target = np.array([g.x + math.cos(th) * cl[0] - math.sin(th) * cl[1],
                               g.y + math.sin(th) * cl[0] + math.cos(th) * cl[1]])
            angle = None
        else:
            target, angle = self.X[b, 0:2], self.X[b, 2]
        budget = b - a - 1
        U, S = [], [self.X[a]]

        def run(controls):
            for u in controls:
                if len(U) >= budget or self.expired():
                    return False
                y, good = tm.advance(S[-1], u, tm.steps_per_prop)
                U.append(u)
                S.append(y)
                if not (good and tm.admissible(y)):
                    return False
            return True

        def goto(q):
            for w in self._route(S[-1], S[-1][ip:ip + 2], q, side):
                u = self.straight(S[-1][ip:ip + 2], w)
                if u is not None and not run(u):
                    return False
            return True

        def failed():
            return np.array(U).reshape(-1, 2), np.array(S), False

        lmax = 0.5 * tm.task.object_extent["min_support"]

        def aim(x, to, e=None):
            """(e, n, the pusher's place behind the object on the line to `to`, distance to go) at state x; with e
            given (the direction frozen near the leg's end), the distance to go along e."""
            d = to - x[0:2]
            if e is None:
                dist = math.hypot(d[0], d[1])
                e = d / max(dist, 1e-12)
            else:
                dist = float(d @ e)
            n = np.array([-e[1], e[0]])
            o = x[0:2] + min(max(k_angle * error(x), -lmax), lmax) * n
            s = self._behind(x, o, e, r)
            return e, n, (None if s is None else o - s * e), dist

        def error(x):
            return 0.0 if angle is None else (x[2] - angle + math.pi) % (2 * math.pi) - math.pi

        if abs(error(S[-1])) > PUSH_TURN * g.angle_tol and not self._turn(S, run, goto, target, error, speed):
            return failed()
        stop = PUSH_STOP * g.position_tol
        for to in self._legs(S[-1], target, first):
            e, n, p_star, dist = aim(S[-1], to)
            if dist <= stop:
                continue
            if p_star is None or not goto(p_star - PUSH_CLEARANCE * e):      # the approach, free
                return failed()
            frozen = None
            while True:              # the push, re-aimed every step until the object is near the leg's end
                e, n, p_star, dist = aim(S[-1], to, frozen)
                if dist <= PUSH_FREEZE * tm.task.object_extent["min_support"]:
                    frozen = e
                if dist <= stop:
                    break
                if p_star is None:
                    return failed()
                D = p_star + min(speed * self.cm * self.dt, dist) * e - S[-1][ip:ip + 2]
                v = (float(D @ e) * e + lateral_gain * float(D @ n) * n) / self.dt
                v = v / max(1.0, float(np.max(np.abs(v))) / self.cm)
                if not run([v]):
                    return failed()
        for _ in range(PUSH_SETTLE):                         # wait for the object to come to rest
            x = S[-1]
            if math.hypot(x[3], x[4]) <= 0.5 * g.speed_tol and abs(x[5]) <= 0.5 * g.omega_tol:
                break
            if not run([np.zeros(2)]):
                return failed()
        if b < K and not goto(self.X[b, ip:ip + 2]):          # back to where the rest of the plan starts
            return failed()
        return np.array(U).reshape(-1, 2), np.array(S), len(U) < b - a

    def try_candidate(self, a, b, new, seg=None):
        """Simulate U[:a] + new + U[b:] from X[a] (seg: new's states from X[a] when the candidate was built by
        simulating it, the same rollouts); keep it when it is valid, reaches the goal and is shorter.
        Returns True when kept."""
        U_new = np.concatenate([self.U[:a], new, self.U[b:]])
        if len(U_new) >= len(self.U) or compress(U_new, self.min_steps, self.max_steps) is None:
            return False
        if seg is None:
            seg, whole = self.simulate(self.X[a], new)
            if not whole:
                return False
        if b < len(self.U):
            # a stretch that leaves the object far from where the rest of the plan expects it is rejected without
            # simulating the rest (a pruning only: what is kept is judged by the whole simulation below)
            if self.diverged(seg[-1], self.X[b]):
                return False
            rest, whole = self.simulate(seg[-1], self.U[b:])
            if not whole:
                return False
            seg = np.concatenate([seg, rest[1:]])
        if not self._goal(seg[-1]):
            return False
        self.U, self.X = U_new, np.concatenate([self.X[:a], seg])
        self.truncate_at_goal(a + 1)
        return True


def shorten(tm, x0, controls, steps, seed, max_candidates=MAX_CANDIDATES, patience=PATIENCE, deadline=None,
            replayed=None, max_sim_steps=None, stop=None, trace=None):
    """Shorten an exact plan by randomised shortcutting (module docstring).

    Parameters
    ----------
    tm : planners.tasks.TaskModel
        The task: forward model, validity and goal.
    x0 : (d,) array
        The plan's start state.
    controls, steps : (n, 2) m/s and (n,) propagation steps
        The exact plan.
    seed : int
        Seeds the candidates' numpy Generator: the same plan and seed give the same result.
    max_candidates, patience : int or None
        Stop after this many simulated candidates, or this many rejected in a row (None: no such bound).
    deadline : float, optional
        A time.perf_counter() value after which no candidate is started (and a push candidate being built stops,
        rejected: building one simulates as many steps as it replaces at most).
    replayed : (dense states, ok), optional
        What `tm.execute(x0, controls, steps)` returns (its dense states and ok), when the caller replayed the plan
        already (`plan` does, for its costs): the plan is then not replayed again.
    max_sim_steps : int, optional
        Stop once the candidates have simulated this many steps (of the scene's h, as `TaskModel.nsteps_total`
        counts them): a bound on the work that is the same on every machine (`effort_bound`).
    stop : callable, optional
        Called between candidates (and while a push candidate is built): True stops the shortening at once with the
        best plan so far, `stopped_by` "interrupted" (`plan` passes its Ctrl-C flag).
    trace : callable, optional
        Called as trace(kind, accepted, shortener) after every simulated candidate (examples/measurements/shorten_rule.py).

    Returns
    -------
    dict
        controls (m, 2), steps (m,): the best plan so far (always exact when the input was); the counts
        `candidates`, `accepted` (and by kind), `sim_steps` (the steps the shortening simulated), `time` and `cpu_time`
        (s: wall and the process's CPU time),
        `truncated` (the plan reached the goal before its end and was cut there, before any candidate),
        `stopped_by` (why it stopped: "patience", "effort", "candidates", "deadline", "interrupted", or "nothing
        left": no stretch left to replace, or no candidate to draw), `stopped_by_deadline`, and `exact_input`
        (False when the given plan did not reach the goal: it is returned unchanged).
    """
    t0, c0 = time.perf_counter(), time.process_time()
    steps0 = tm.nsteps_total
    s = Shortener(tm, x0, controls, steps, replayed)
    s.deadline, s.stop = deadline, stop
    stats = dict(candidates=0, accepted=0, accepted_by_kind={k: 0 for k in KINDS}, truncated=False,
                 stopped_by=None, stopped_by_deadline=False, exact_input=s.ok)
    if not s.ok:
        stats.update(controls=np.asarray(controls, float).reshape(-1, 2), steps=np.asarray(steps, int),
                     time=time.perf_counter() - t0, cpu_time=time.process_time() - c0,
                     sim_steps=tm.nsteps_total - steps0, stopped_by="not exact")
        return stats
    stats["truncated"] = s.truncate_at_goal()
    rng = np.random.default_rng([int(seed), 25])        # 25: a stream apart from other uses of the seed
    rejected = draws = idle = 0
    while True:
        # the stopping rule, checked before each draw (the draws themselves do not depend on it: a larger budget
        # continues the same sequence of candidates)
        if stop is not None and stop():
            stats["stopped_by"] = "interrupted"
        elif max_candidates is not None and stats["candidates"] >= max_candidates:
            stats["stopped_by"] = "candidates"
        elif patience is not None and rejected >= patience:
            stats["stopped_by"] = "patience"
        elif max_sim_steps is not None and tm.nsteps_total - steps0 >= max_sim_steps:
            stats["stopped_by"] = "effort"
        elif deadline is not None and time.perf_counter() > deadline:
            stats["stopped_by"] = "deadline"
        elif len(s.U) < 2 or (draws >= 20 * max_candidates if max_candidates is not None else idle >= IDLE_DRAWS):
            stats["stopped_by"] = "nothing left"
        if stats["stopped_by"] is not None:
            break
        draws += 1
        idle += 1
        K = len(s.U)
        kind = KINDS[rng.choice(4, p=KIND_P)] if s.can_push else KINDS[rng.choice(3, p=KIND_P_NO_PUSH)]
        a, b = sorted(rng.choice(K + 1, size=2, replace=False).tolist())
        if kind == "retarget":
            b = K                                     # the last push, towards the goal
            a = int(rng.integers(0, K))
        seg = None
        if kind == "push":
            if rng.random() < 0.5:
                b = K                                 # to the goal
            k_angle, lateral_gain, speed = rng.uniform(0.01, 0.06), rng.uniform(0.5, 1.0), rng.uniform(0.6, 0.95)
            side, first = int(rng.integers(-1, 2)), int(rng.integers(0, 2))
            if b - a < 2:
                continue
            built = s.push(a, b, k_angle, lateral_gain, speed, side, first)
            if built is None:
                continue                              # not a pushing task: nothing simulated
            stats["candidates"] += 1
            idle = 0
            new, seg, whole = built
            if not whole:
                rejected += 1
                if trace is not None:
                    trace(kind, False, s)
                continue
        else:
            if b - a < 2:
                continue
            new = s.candidate(kind, a, b)
            if new is None or len(new) >= b - a:
                continue                              # no shorter: nothing to simulate
            stats["candidates"] += 1
            idle = 0
        if s.try_candidate(a, b, new, seg):
            stats["accepted"] += 1
            stats["accepted_by_kind"][kind] += 1
            rejected = 0
            if trace is not None:
                trace(kind, True, s)
        else:
            rejected += 1
            if trace is not None:
                trace(kind, False, s)
    stats["stopped_by_deadline"] = stats["stopped_by"] == "deadline"
    c, k = compress(s.U, s.min_steps, s.max_steps)
    stats.update(controls=c, steps=k, dense=s.X, time=time.perf_counter() - t0, cpu_time=time.process_time() - c0,
                 sim_steps=tm.nsteps_total - steps0)
    return stats
