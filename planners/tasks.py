"""Planning tasks compiled with their scene: the forward model, goal tests and validity as numpy functions.

A task is a scene file with a `[task]` table (docs/scene-format.md, "Task files"), loaded and validated by
`planar_lcp.spec.task.load_task`; this module keeps no task definitions. Nothing here imports ompl:
`planners.adapter` turns a `TaskModel` into an OMPL problem. The goal tests are plain functions of the flat physics
state

    x = (qx, qy, qtheta, vx, vy, omega,              the object
         [qx, qy, qtheta, vx, vy, omega] per obstacle, in Task.obstacles order (the scene's other dynamic bodies)
         px, py,                                     the pusher        (6 (1 + n_obstacles) + 2,)
         [t])                                        the time, s: a timed task only

with each body's CENTRE-OF-MASS pose and velocity (m, rad, m/s, rad/s) and the pusher's body-frame position (m),
so that `replay` and the tests use exactly the checks the planner used. A task with one object has the 8 numbers
(qx, qy, qtheta, vx, vy, omega, px, py). The goal itself is stated on the object's body-frame pose.

A TIMED task (Task.moving: a kinematic body other than the pusher follows a `path`, e.g. a sliding gate or a
conveyor's carrier) holds the time as its last entry, a whole number of the scene's steps h, so that propagation is
still a pure function of the state: each rollout places the moving bodies at the path's pose at the state's time
and moves them with the path's velocities step by step, as `simulate` does. The time stops at Task.horizon (the last
path's end; the world holds still after it), so the state space stays bounded.
"""

import math

import numpy as np

from planar_lcp.spec.scene import SceneError
from planar_lcp.spec.task import PLANNERS, Task, TaskError, body_extent, load_task, shipped_tasks

__all__ = ["PLANNERS", "Task", "TaskError", "TaskModel", "check_planner", "load_task", "shipped_tasks", "wrap_angle"]


def check_planner(name):
    """`name` if it is one of PLANNERS; a TaskError that lists them otherwise."""
    if name not in PLANNERS:
        raise TaskError(f"unknown planner {name!r}; valid planners: {', '.join(PLANNERS)}")
    return name


def wrap_angle(a):
    """Wrap to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


#: a body whose points leave the workspace by less than this is still inside (rounding of the pose, m)
WORKSPACE_SLACK = 1e-9
#: the pusher's centre may come this close to a static body's surface (its shape less this slack), m
PUSHER_SLACK = 1e-3


class TaskModel:
    """A task compiled with its scene: the forward model, goal tests and validity as plain numpy functions.

    Everything the planner and `replay` do to a state goes through here, so both compute bit-identical results.
    Construction checks what needs the geometry (the goal's footprint against the static bodies, the start state's
    validity) and raises a TaskError naming the task's file.
    """

    def __init__(self, task):
        from planar_lcp.engine.layout import Stat
        from planar_lcp.model import compile_scene
        from planar_lcp.sim import SimOptions, Simulator

        self.task = task = load_task(task)
        self.scene = scene = task.scene
        try:
            # it refuses a start where bodies overlap, as `planar-lcp simulate` does
            self.model = model = compile_scene(scene)
        except TaskError:
            raise
        except SceneError as e:
            raise TaskError(str(e)) from None
        want = [task.object, *task.obstacles]
        # the scene's index of each body in the flat state's order (object first, then the obstacles)
        self.dyn_order = np.array([model.dyn_names.index(b) for b in want])
        self.nobj = len(want)
        self.ip = 6 * self.nobj                  # the pusher's position is x[ip:ip + 2]
        self.h = float(scene.sim.h)
        self.steps_per_prop = int(round(task.step_duration / self.h))
        # warm start: faster pushing steps (docs/performance.md, "Per step, against pymunk"); a rollout starts cold, so each
        # propagation is still a pure function of its inputs and replays bit for bit
        self.sim = Simulator(model, SimOptions(h=self.h, solver=scene.sim.solver if scene.sim.solver != "osqp"
                                               else "lemke", formulation=scene.sim.formulation, warm_start=True))
        self.ipusher = model.kin_names.index(task.pusher)
        self.qk0 = model.qk0.copy()
        # advance()'s inputs and its recordings (one per rollout length), reused from call to call
        self._q, self._v = np.empty((model.ndyn, 3)), np.empty((model.ndyn, 3))
        self._qk, self._vk = self.qk0.copy(), np.zeros((1, model.nkin, 3))
        self.timed = task.timed
        if self.timed:
            self._paths()
        self._recordings = {}
        self.nsteps_total = 0          # simulated steps (throughput)
        #: None, or a list to which each advance() appends its rollout's deepest penetration (m; replay_lcp)
        self.penetrations = None
        self._stat_penetration = int(Stat.PENETRATION)
        self._geometry()
        self._check_start_and_goal()

    def _paths(self):
        """A timed task's moving bodies: their kinematic indices, their poses at every step k h up to the horizon
        (path_q, (K + 1, n, 3)) and the velocities of those steps (path_v, (K, n, 3)); rollouts read both from the
        state's step index, so that a state's time places them exactly (no drift from propagation to
        propagation)."""
        from planar_lcp.spec.path import path_pose
        t = self.task
        self.moving_idx = np.array([self.model.kin_names.index(n) for n in t.moving])
        K = self.horizon_steps = int(math.ceil(t.horizon / self.h - 1e-9))
        steps = np.arange(K + 1) * self.h
        self.path_q = np.stack([path_pose(np.asarray(self.scene.body(n).path, float), steps) for n in t.moving],
                               axis=1)
        self.path_v = np.diff(self.path_q, axis=0) / self.h
        self._vk_timed = {}            # nsteps -> the rollout's (nsteps, nkin, 3) kinematic velocities, reused

    def step_index(self, x):
        """The step k of a timed state's time (x[-1] = k h, rounded), at most the horizon's."""
        return min(int(round(float(x[self.ip + 2]) / self.h)), self.horizon_steps)

    def moving_poses(self, x):
        """(n, 3) the body-frame poses of Task.moving at a timed state's time."""
        return self.path_q[self.step_index(x)]

    # ---- geometry ------------------------------------------------------------------------------------------
    def _geometry(self):
        import shapely
        from shapely.geometry import Polygon
        from shapely.ops import unary_union

        from planar_lcp.frames import frame_to_com
        from planar_lcp.geometry import shape_geometry
        from planar_lcp.spec.task import body_core_points, body_extent

        sc, t = self.scene, self.task
        obj = sc.body(t.object)
        self.object_poly_body = unary_union([shape_geometry(s, quad_segs=8) for s in obj.shapes])  # body frame
        self.object_area = self.object_poly_body.area
        pusher_extent = body_extent(sc.body(t.pusher), about_origin=True)
        self.pusher_radius, pusher_inner = pusher_extent["circumradius"], pusher_extent["min_support"]
        statics, self.static_bodies = [], []
        for b in sc.bodies:
            if b.type == "dynamic" or b.name == t.pusher or b.name in t.moving:
                continue              # a kinematic body other than the pusher stands still (spec.task): a static
            first = len(statics)
            for s in b.shapes:
                if s.type == "halfplane":
                    p, nrm = np.asarray(s.point, float), np.asarray(s.normal, float)
                    tan = np.array([-nrm[1], nrm[0]])
                    big = 1e3
                    statics.append(Polygon([p + big * tan, p - big * tan, p - big * tan - big * nrm,
                                            p + big * tan - big * nrm]))
                else:
                    statics.append(_place(shape_geometry(s, quad_segs=8), b.position, b.angle))
            self.static_bodies.append((b.name, unary_union(statics[first:])))
        self.statics = unary_union(statics) if statics else None
        # where the pusher's centre may not be: the statics grown by the pusher's least half-width (its radius for a
        # disk) less a slack, a necessary condition for the pusher not to overlap them
        self.forbidden = self.statics.buffer(max(pusher_inner - PUSHER_SLACK, 0.0)) if statics else None
        if self.forbidden is not None:
            shapely.prepare(self.forbidden)
        # the same for each moving body, in its own frame: `valid` takes the pusher's centre there at the state's time
        self.moving_forbidden = []
        for name in t.moving:
            b = sc.body(name)
            grown = unary_union([shape_geometry(s, quad_segs=8) for s in b.shapes]).buffer(
                max(pusher_inner - PUSHER_SLACK, 0.0))
            shapely.prepare(grown)
            self.moving_forbidden.append(grown)
        # per body in state order: its core points about its centre of mass (body frame) and their radii, for the
        # exact "no point leaves the workspace" test; its COM bounds (the workspace less its least half-width, a
        # necessary condition: OMPL's SE2 bounds) and the region where the COM keeps every point inside whatever the
        # angle (the workspace less its circumradius: the test's quick accept)
        (wx0, wx1), (wy0, wy1) = t.workspace
        self.body_points, self.com_bounds, self._sure = [], [], []
        for i, name in enumerate([t.object, *t.obstacles]):
            b = sc.body(name)
            pts, radii = body_core_points(b)
            ext = body_extent(b)
            com = np.asarray(ext["com"])
            self.body_points.append((pts - com, radii))
            m = ext["min_support"]
            self.com_bounds.append(((wx0 + m, wx1 - m), (wy0 + m, wy1 - m)))
            r = ext["circumradius"]
            self._sure.append((wx0 + r, wx1 - r, wy0 + r, wy1 - r))
        for i, ((a0, a1), (b0, b1)) in enumerate(self.com_bounds):
            if not (a0 < a1 and b0 < b1):
                name = [t.object, *t.obstacles][i]
                raise TaskError(f"{t.source}: task.workspace must be wider than body {name!r} in x and y "
                                f"(its least width is {2 * (a0 - wx0):.4g} m), got {[list(w) for w in t.workspace]}")
        # the object's centre of mass in its body frame, (1, 2) as planar_lcp.frames takes it
        self.com_local1 = self.model.com_local[self.dyn_order[:1]].copy()
        self.com_local = self.com_local1[0]
        self.object_radius = t.object_extent["circumradius"]
        g = t.goal
        self.goal_com = self.goal_poly = None
        if g.pose is not None:
            qf = np.array([[g.x, g.y, g.angle]])
            self.goal_com = frame_to_com(qf, self.com_local1)[0]
            self.goal_poly = _place(self.object_poly_body, (g.x, g.y), g.angle)
        if g.min_cover is not None:
            self.cover_com_bound = self._cover_bound()

    def _cover_bound(self):
        """How far (m) the object's centre of mass can be from the goal footprint's while the cover still reaches
        min_cover c: 2 L (1 - c) / c, L the object's circumradius about its centre of mass (the area centroid).

        Why: with A the footprint, A' the placed object (equal areas) and I their intersection, the centroids satisfy
        |A| (a' - a) = |A' - I| u' - |A - I| u with |A - I| = |A' - I| = (1 - cover) |A|, u, u' the centroids of the
        two differences, each within L of its body's centroid; so cover |a' - a| <= 2 L (1 - cover). A necessary
        condition, so the cheap test never rejects a pose the cover accepts."""
        c = self.task.goal.min_cover
        return max(2.0 * self.object_radius * (1.0 - c) / c, 1e-12)

    def _check_start_and_goal(self):
        t = self.task
        src = t.source
        if self.goal_poly is not None and self.statics is not None:
            overlap = self.goal_poly.intersection(self.statics).area
            if overlap > 1e-6 * self.goal_poly.area:
                raise TaskError(f"{src}: task.goal must not place the object inside a static body, got "
                                f"{overlap / self.goal_poly.area:.1%} of its area overlapping the static bodies at "
                                f"({t.goal.x:g}, {t.goal.y:g}, {math.degrees(t.goal.angle):g} deg)")
        g = t.goal
        if g.pose is None and g.x is not None and g.y is not None and self.statics is not None:
            p, tol = (g.x, g.y), g.position_tol
            R = body_extent(self.scene.body(t.object), about_origin=True)["circumradius"]
            if no_pose_fits(self.object_poly_body, self.statics, p, tol, R, 1e-6 * self.object_area):
                at0 = _place(self.object_poly_body, p, 0.0)
                names = [n for n, geom in self.static_bodies if geom.intersection(at0).area > 0.0]
                raise TaskError(f"{src}: task.goal must leave room for the object {t.object!r} at some angle with "
                                f"its position within task.goal.position_tol = {tol:g} m of ({g.x:g}, {g.y:g}), got "
                                f"every such pose overlapping static bod{'ies' if len(names) > 1 else 'y'} "
                                f"{', '.join(repr(n) for n in names)}")
        x0 = self.initial_state()
        why = self.why_invalid(x0)
        if why:
            raise TaskError(f"{src}: the start state is already invalid: {why}")

    # ---- state ---------------------------------------------------------------------------------------------
    def initial_state(self):
        m = self.model
        x = np.zeros(self.task.state_dim)        # a timed task's time 0 last
        for i, d in enumerate(self.dyn_order):
            x[6 * i:6 * i + 3] = m.q0[d]
            x[6 * i + 2] = wrap_angle(x[6 * i + 2])
            x[6 * i + 3:6 * i + 6] = m.v0[d]
        x[self.ip:self.ip + 2] = m.qk0[self.ipusher, :2]
        return x

    def advance(self, x, u, nsteps):
        """Roll the physics out for `nsteps` steps with pusher velocity u = (vx, vy): ONE rollout call.

        Returns (x_new, ok); the bodies' angles in x_new are wrapped to [-pi, pi). The planner calls this for every
        propagation, so it reuses its arrays (Simulator.rollout_into): 10 to 13 us less per call than `rollout`
        (examples/measurements/propagation_cost.py)."""
        n, ip, nsteps = self.nobj, self.ip, int(nsteps)
        rec = self._recordings.get(nsteps)
        if rec is None:
            rec = self._recordings[nsteps] = self.sim.recording(nsteps)
        q, v = self._q, self._v
        if n == 1:
            q[0] = x[0:3]
            v[0] = x[3:6]
        else:
            blocks = np.asarray(x[:ip], float).reshape(n, 6)
            q[self.dyn_order] = blocks[:, 0:3]
            v[self.dyn_order] = blocks[:, 3:6]
        qk, vk = self._qk, self._vk
        qk[self.ipusher, 0] = x[ip]
        qk[self.ipusher, 1] = x[ip + 1]
        if self.timed:
            vk, k0 = self._timed_velocities(nsteps), self.step_index(x)
            qk[self.moving_idx] = self.path_q[k0]
            K = self.horizon_steps
            on = max(0, min(nsteps, K - k0))            # steps still on the paths; the bodies rest after them
            vk[:on, self.moving_idx] = self.path_v[k0:k0 + on]
            vk[on:, self.moving_idx] = 0.0
        vk[:, self.ipusher, 0] = u[0]
        vk[:, self.ipusher, 1] = u[1]
        done = self.sim.rollout_into(rec, q, v, qk, vk, stop_on_failure=True)
        self.nsteps_total += done
        if self.penetrations is not None:
            self.penetrations.append(float(rec.stats[:done, self._stat_penetration].max()) if done else 0.0)
        ok = done == nsteps and not rec.status[:done].any()
        y = np.empty(len(x))
        if n == 1:
            y[0:3] = rec.q[done, 0]
            y[3:6] = rec.v[done, 0]
            y[2] = wrap_angle(y[2])
        else:
            yb = y[:ip].reshape(n, 6)
            yb[:, 0:3] = rec.q[done][self.dyn_order]
            yb[:, 2] = (yb[:, 2] + math.pi) % (2.0 * math.pi) - math.pi       # wrap_angle, elementwise
            yb[:, 3:6] = rec.v[done][self.dyn_order]
        y[ip] = rec.qk[done, self.ipusher, 0]
        y[ip + 1] = rec.qk[done, self.ipusher, 1]
        if self.timed:
            y[ip + 2] = min(self.step_index(x) + done, self.horizon_steps) * self.h
        return y, ok and bool(np.isfinite(y).all())

    def _timed_velocities(self, nsteps):
        """The (nsteps, nkin, 3) kinematic velocities of a timed task's rollout (reused per length): the bodies that
        stand still 0, the pusher's and the moving bodies' filled in by advance()."""
        vk = self._vk_timed.get(nsteps)
        if vk is None:
            vk = self._vk_timed[nsteps] = np.zeros((nsteps, self.model.nkin, 3))
        return vk

    def execute(self, x0, controls, steps, valid=None):
        """Replay controls open loop exactly as the planner propagated them.

        controls (n, 2) m/s; steps (n,) propagation steps each. Returns (states at control boundaries (n+1, d),
        dense states (1 + total sim steps / steps_per_prop, d) at every propagation step, ok); d = Task.state_dim.
        With `valid` (a function of a state, e.g. `admissible`: the planner's check after each propagation step) the
        replay stops at the first failed step or state `valid` rejects, with ok False (planners.shorten judges
        candidates so, without simulating the rest)."""
        x = np.asarray(x0, float).copy()
        bound, dense, ok = [x.copy()], [x.copy()], True
        for u, k in zip(np.asarray(controls, float), np.asarray(steps, int)):
            for _ in range(int(k)):
                x, good = self.advance(x, u, self.steps_per_prop)
                ok = ok and good
                dense.append(x.copy())
                if valid is not None and not (good and valid(x)):
                    return np.array(bound), np.array(dense), False
            bound.append(x.copy())
        return np.array(bound), np.array(dense), ok

    # ---- validity ------------------------------------------------------------------------------------------
    def in_bounds(self, x):
        """The state bounds (OMPL's too): every centre of mass within its body's COM bounds (the workspace less
        its least half-width), the pusher in task.pusher_workspace, speeds and spins within speed_max and
        omega_max."""
        t = self.task
        (px0, px1), (py0, py1) = t.pusher_workspace
        ip = self.ip
        if not (px0 <= x[ip] <= px1 and py0 <= x[ip + 1] <= py1):
            return False
        if self.timed and not 0.0 <= x[ip + 2] <= t.horizon:
            return False
        for i in range(self.nobj):
            (bx0, bx1), (by0, by1) = self.com_bounds[i]
            if not (bx0 <= x[6 * i] <= bx1 and by0 <= x[6 * i + 1] <= by1):
                return False
            if not (math.hypot(x[6 * i + 3], x[6 * i + 4]) <= t.speed_max and abs(x[6 * i + 5]) <= t.omega_max):
                return False
        return True

    def valid(self, x):
        """Task rules beyond the state bounds: no point of any dynamic body outside task.workspace; the pusher not
        inside a static body, nor inside a moving one where it is at the state's time (two kinematic bodies do not
        collide in the engine: the pusher would pass through it)."""
        import shapely
        if self.forbidden is not None and shapely.contains_xy(self.forbidden, x[self.ip], x[self.ip + 1]):
            return False
        if self.timed and self.pusher_in_moving_body(x) is not None:
            return False
        return all(self.inside_workspace(x, i) for i in range(self.nobj))

    def pusher_in_moving_body(self, x):
        """The name of the moving body whose outline, grown by the pusher's least half-width, holds the pusher's
        centre at a timed state's time; None when none does."""
        import shapely
        poses = self.moving_poses(x)
        for name, grown, (bx, by, ba) in zip(self.task.moving, self.moving_forbidden, poses):
            c, s = math.cos(ba), math.sin(ba)
            dx, dy = x[self.ip] - bx, x[self.ip + 1] - by
            if shapely.contains_xy(grown, c * dx + s * dy, -s * dx + c * dy):     # the centre in the body's frame
                return name
        return None

    def inside_workspace(self, x, i):
        """No point of body i (0: the object, then the obstacles) of state x is outside task.workspace (up to
        WORKSPACE_SLACK)."""
        cx, cy = x[6 * i], x[6 * i + 1]
        s0, s1, s2, s3 = self._sure[i]
        if s0 <= cx <= s1 and s2 <= cy <= s3:
            return True                        # every point inside at any angle
        (wx0, wx1), (wy0, wy1) = self.task.workspace
        pts, r = self.body_points[i]
        c, s = math.cos(x[6 * i + 2]), math.sin(x[6 * i + 2])
        wx = cx + c * pts[:, 0] - s * pts[:, 1]
        wy = cy + s * pts[:, 0] + c * pts[:, 1]
        return not (np.min(wx - r) < wx0 - WORKSPACE_SLACK or np.max(wx + r) > wx1 + WORKSPACE_SLACK
                    or np.min(wy - r) < wy0 - WORKSPACE_SLACK or np.max(wy + r) > wy1 + WORKSPACE_SLACK)

    def admissible(self, x):
        """in_bounds and valid: a state the planner may pass through."""
        return bool(self.in_bounds(x) and self.valid(x))

    def why_invalid(self, x):
        """"" for an admissible state, else what makes it invalid (for messages)."""
        import shapely
        t = self.task
        ws = [list(w) for w in t.workspace]
        (px0, px1), (py0, py1) = t.pusher_workspace
        px, py = x[self.ip], x[self.ip + 1]
        if not (px0 <= px <= px1 and py0 <= py <= py1):
            return (f"the pusher {t.pusher!r} at ({px:.4g}, {py:.4g}) is outside task.pusher_workspace = "
                    f"{[list(w) for w in t.pusher_workspace]}")
        if self.forbidden is not None and shapely.contains_xy(self.forbidden, px, py):
            return f"the pusher {t.pusher!r} at ({px:.4g}, {py:.4g}) overlaps a static body"
        if self.timed:
            tt = x[self.ip + 2]
            if not 0.0 <= tt <= t.horizon:
                return f"the time {tt:.6g} s is outside [0, {t.horizon:g}] s (the moving bodies' paths)"
            hit = self.pusher_in_moving_body(x)
            if hit is not None:
                return f"the pusher {t.pusher!r} at ({px:.4g}, {py:.4g}) overlaps body {hit!r} at t = {tt:.6g} s"
        for i, name in enumerate([t.object, *t.obstacles]):
            if not self.inside_workspace(x, i):
                return f"body {name!r} is not inside task.workspace = {ws}"
            sp, om = math.hypot(x[6 * i + 3], x[6 * i + 4]), abs(x[6 * i + 5])
            if not (sp <= t.speed_max and om <= t.omega_max):
                return (f"body {name!r} moves at {sp:.4g} m/s and {om:.4g} rad/s, beyond task.speed_max = "
                        f"{t.speed_max:g} or task.omega_max = {t.omega_max:g}")
        # a body inside the workspace has its centre of mass inside its bounds (the bounds are necessary)
        return ""

    # ---- goal ----------------------------------------------------------------------------------------------
    def object_frame_pose(self, x):
        from planar_lcp.frames import com_to_frame
        return com_to_frame(np.asarray(x[0:3], float)[None], self.com_local1)[0]

    def _position_error(self, x):
        """The object's body-frame position error over the goal's named coordinates (m), or None."""
        g = self.task.goal
        if g.x is None and g.y is None:
            return None
        c, s = math.cos(x[2]), math.sin(x[2])
        fx = x[0] - (c * self.com_local[0] - s * self.com_local[1])
        fy = x[1] - (s * self.com_local[0] + c * self.com_local[1])
        if g.x is not None and g.y is not None:
            return math.hypot(fx - g.x, fy - g.y)
        return abs(fx - g.x) if g.x is not None else abs(fy - g.y)

    def goal_distance(self, x):
        """A goal distance with threshold 1.0: the goal holds iff goal_distance(x) <= 1."""
        g = self.task.goal
        d = 0.0
        if g.min_cover is not None:
            # a cheap bound first (_cover_bound): farther, the cover cannot reach min_cover
            proxy = math.hypot(x[0] - self.goal_com[0], x[1] - self.goal_com[1]) / self.cover_com_bound
            if proxy > 1.0:
                return 1.0 + proxy
            d = (1.0 - self.cover(x)) / (1.0 - g.min_cover) if g.min_cover < 1.0 else \
                (0.0 if self.cover(x) >= 1.0 else 2.0)
        else:
            pe = self._position_error(x)
            if pe is not None:
                d = pe / g.position_tol
            if g.angle is not None:
                d = max(d, abs(wrap_angle(x[2] - g.angle)) / g.angle_tol)
        if g.at_rest:
            d = max(d, math.hypot(x[3], x[4]) / g.speed_tol, abs(x[5]) / g.omega_tol)
        return d

    def cover(self, x):
        """Fraction of the goal footprint's area covered by the object (goals with a full pose)."""
        pf = self.object_frame_pose(x)
        poly = _place(self.object_poly_body, pf[:2], pf[2])
        return poly.intersection(self.goal_poly).area / self.goal_poly.area

    def goal_report(self, x):
        """Human-readable goal errors of state x (a dict of floats and the verdict)."""
        g = self.task.goal
        d = self.goal_distance(x)
        r = {"goal_distance": float(d), "goal_holds": bool(d <= 1.0)}
        pe = self._position_error(x)
        if pe is not None:
            r["position_error_m"] = float(pe)
        if g.angle is not None:
            r["angle_error_deg"] = float(math.degrees(abs(wrap_angle(x[2] - g.angle))))
        if g.min_cover is not None:
            r["cover"] = float(self.cover(x))
        if g.at_rest:
            r["speed_m_s"] = float(math.hypot(x[3], x[4]))
            r["omega_rad_s"] = float(x[5])
        pf = self.object_frame_pose(x)
        r["object_pose"] = [float(pf[0]), float(pf[1]), float(math.degrees(wrap_angle(pf[2])))]
        return r

    def sample_goal(self, rng):
        """A state in the goal region: the object at the goal (the named coordinates within 0.7 of their
        tolerance, exactly at the goal pose for a cover goal; the free ones anywhere in its bounds), every body at
        rest, the obstacles anywhere in their bounds; in the horizontal plane the pusher on a ring around the
        object (where a push that just brought it there leaves it), in the vertical plane anywhere.

        rng(lo, hi) -> uniform float (OMPL's RNG in the planner, so sampling is seeded)."""
        g = self.task.goal
        x = np.zeros(self.task.state_dim)
        if self.timed:
            x[self.ip + 2] = round(rng(0.0, self.task.horizon) / self.h) * self.h
        for i in range(1, self.nobj):
            (bx0, bx1), (by0, by1) = self.com_bounds[i]
            x[6 * i] = rng(bx0, bx1)
            x[6 * i + 1] = rng(by0, by1)
            x[6 * i + 2] = rng(-math.pi, math.pi)
        (ox0, ox1), (oy0, oy1) = self.com_bounds[0]
        exact = g.min_cover is not None
        r = 0.7 * g.position_tol
        both = g.x is not None and g.y is not None
        dx = 0.0 if exact or g.x is None else rng(-r, r) / (math.sqrt(2) if both else 1.0)
        dy = 0.0 if exact or g.y is None else rng(-r, r) / (math.sqrt(2) if both else 1.0)
        if g.angle is None:
            a = rng(-math.pi, math.pi)
        else:
            a = wrap_angle(g.angle + (0.0 if exact else rng(-0.7, 0.7) * g.angle_tol))
        c, s = math.cos(a), math.sin(a)
        # the COM of the body frame at the named coordinates: frame + R(a) com_local
        x[0] = g.x + dx + c * self.com_local[0] - s * self.com_local[1] if g.x is not None else rng(ox0, ox1)
        x[1] = g.y + dy + s * self.com_local[0] + c * self.com_local[1] if g.y is not None else rng(oy0, oy1)
        x[2] = a
        (px0, px1), (py0, py1) = self.task.pusher_workspace
        if self.scene.world.plane == "horizontal":
            # a pusher anywhere in the workspace would make the nearest tree state to a goal sample mostly a
            # matter of the pusher's position
            a = rng(-math.pi, math.pi)
            rr = rng(0.8, 1.0) * self.object_radius + self.pusher_radius
            x[self.ip] = min(max(x[0] + rr * math.cos(a), px0), px1)
            x[self.ip + 1] = min(max(x[1] + rr * math.sin(a), py0), py1)
        else:
            x[self.ip], x[self.ip + 1] = rng(px0, px1), rng(py0, py1)
        return x


def no_pose_fits(body_poly, statics, position, tol, radius, area_tol, n0=64, max_placements=4096):
    """True when the body (`body_poly`, its body frame) overlaps `statics` by more than `area_tol` (m^2) at EVERY
    pose with its origin within `tol` of `position`, at any angle; False when some pose fits, or when that could not
    be shown within `max_placements` (it refuses only what it proves). `radius`: the farthest point of the body from
    its origin (m).

    The proof, over angle intervals [c - w, c + w]: turning by at most w about the origin and moving it by at most
    tol moves no point of the body by more than d = radius w + tol, so the body at (position, c) shrunk by d (a
    negative buffer) lies inside the body at every pose of the interval; its overlap with the statics then bounds
    theirs from below. An interval whose shrunk body does not overlap is halved; the body placed at
    (position, c) itself overlapping no more than area_tol is a pose that fits."""
    cores = {}

    def core(d):
        if d not in cores:
            cores[d] = body_poly.buffer(-1.01 * d, quad_segs=8)     # 1 %: the arcs' chords at inner corners
        return cores[d]

    w = math.pi / n0
    centres = [-math.pi + (2 * i + 1) * w for i in range(n0)]
    placements = 0
    while centres:
        shrunk, least = core(radius * w + tol), core(tol)
        halves = []
        for c in centres:
            placements += 1
            if placements > max_placements:
                return False
            if _place(body_poly, position, c).intersection(statics).area <= area_tol:
                return False                                   # a pose at the position fits
            if not shrunk.is_empty and _place(shrunk, position, c).intersection(statics).area > area_tol:
                continue                                       # every pose of this interval overlaps
            if least.is_empty or _place(least, position, c).intersection(statics).area <= area_tol:
                return False                 # no interval about c can be shown to overlap: not proven
            halves += [c - w / 2, c + w / 2]
        centres, w = halves, w / 2
    return True


def _place(g, pos, angle):
    from shapely import affinity
    g = affinity.rotate(g, angle, origin=(0.0, 0.0), use_radians=True)
    return affinity.translate(g, float(pos[0]), float(pos[1]))
