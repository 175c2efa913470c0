"""Planning tasks: a scene, the object, the pusher, control bounds and durations, a goal and validity rules.

Nothing here imports ompl: `planners.adapter` turns a `Task` into an OMPL problem. The goal tests are plain
functions of the flat physics state

    x = (qx, qy, qtheta, vx, vy, omega,              the object
         [qx, qy, qtheta, vx, vy, omega] per obstacle, in Task.obstacles order (push_clutter)
         px, py)                                     the pusher        (6 (1 + n_obstacles) + 2,)

with each body's CENTRE-OF-MASS pose and velocity (m, rad, m/s, rad/s) and the pusher's body-frame position (m),
so that `replay` and the tests use exactly the checks the planner used. A task with one object has the 8 numbers
(qx, qy, qtheta, vx, vy, omega, px, py).
"""

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

SCENES_DIR = Path(__file__).resolve().parent.parent / "scenes"


class TaskError(ValueError):
    """A bad task name, task definition or plan file; the message says what was expected."""


#: The OMPL control planners that the 2.0.1 wheel can construct from Python (SST and PDST have no constructor
#: there, docs/planning.md). Kept here, not in planners.adapter, so that the CLI lists and checks them without
#: importing ompl.
PLANNERS = ("RRT", "EST", "KPIECE1", "SyclopRRT", "SyclopEST")


def check_planner(name):
    """`name` if it is one of PLANNERS; a TaskError that lists them otherwise."""
    if name not in PLANNERS:
        raise TaskError(f"unknown planner {name!r}; valid planners: {', '.join(PLANNERS)}")
    return name


def wrap_angle(a):
    """Wrap to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class Task:
    """A planning problem over a scene with one kinematic body (the pusher), the object to bring to the goal, and
    optionally movable obstacles (the scene's other dynamic bodies).

    Attributes
    ----------
    name : str
    scene : str
        A shipped scene name or a path.
    object, pusher : str
        Body names in the scene.
    obstacles : tuple of str
        The scene's other dynamic bodies, movable obstacles: every dynamic body of the scene is the object or one of
        these (the OMPL state holds them all, so propagation stays a pure function of the state).
    obstacle_bounds : ((xlo, xhi), (ylo, yhi)) or None
        The table region: an obstacle's centre of mass outside it makes a state invalid (default: object_bounds).
    obstacle_weight : float
        OMPL distance weight of an obstacle's position (per m); its angle weighs obstacle_weight * w_ang / w_pos and
        its velocity w_vel, as the object's.
    control_max : float
        Pusher speed bound per axis, m/s: controls are (vx, vy) in [-control_max, control_max]^2.
    step_duration : float
        The OMPL propagation step, s (a multiple of the scene's h); each propagate() call rolls out this long.
    min_steps, max_steps : int
        A sampled control is held for min_steps..max_steps propagation steps.
    object_bounds : ((xlo, xhi), (ylo, yhi))
        Workspace of the object's centre of mass, m.
    pusher_bounds : ((xlo, xhi), (ylo, yhi))
        Workspace of the pusher, m.
    speed_max, omega_max : float
        Velocity bounds of every dynamic body (state bounds; faster states are invalid), m/s and rad/s.
    goal : dict
        kind "pose" (x, y, theta_deg of the object's body frame, pos_tol m, ang_tol_deg; with speed_tol m/s and
        omega_tol rad/s the object must also be at rest: its speed and spin within them),
        kind "cover" (pose of the goal, min_cover fraction of the goal's area covered),
        kind "tip" (angle_deg, ang_tol_deg, rest_height m of the COM, height_tol, speed_tol, omega_tol; with
        signed=True the angle's sign, i.e. the tipping direction, is required, otherwise +-angle_deg both count).
    ledge_x : float or None
        No part of the object may pass this x (the table's edge) - vertical tasks.
    weights : (position, angle, velocity, pusher)
        OMPL distance weights: the object's position (per m), its angle (per rad), its velocity (per m/s and
        rad/s) and the pusher's position (per m). Nearest-neighbour search (RRT) and goal distances in the tree use
        them; velocities should weigh little (pushing is nearly quasi-static), the object's pose most.
    goal_bias : float
        RRT's goal bias (the fraction of samples drawn from the goal region).
    kpiece_cell : float
        KPIECE1's cell size on the projection (the object's position), m.
    """

    name: str
    scene: str
    object: str
    pusher: str
    control_max: float
    step_duration: float
    min_steps: int
    max_steps: int
    object_bounds: tuple
    pusher_bounds: tuple
    speed_max: float
    omega_max: float
    goal: dict = field(default_factory=dict)
    ledge_x: float = None
    weights: tuple = (1.0, 0.5, 0.05, 0.2)
    goal_bias: float = 0.1
    kpiece_cell: float = 0.02
    description: str = ""
    obstacles: tuple = ()
    obstacle_bounds: tuple = None
    obstacle_weight: float = 0.1

    @property
    def table_region(self):
        """Where the obstacles' centres of mass must stay: obstacle_bounds, or object_bounds when it is None."""
        return self.obstacle_bounds if self.obstacle_bounds is not None else self.object_bounds

    @property
    def nobj(self):
        """Dynamic bodies in the state: the object and the obstacles."""
        return 1 + len(self.obstacles)

    @property
    def state_dim(self):
        return 6 * self.nobj + 2

    def state_names(self):
        """Names of the flat state's entries (module docstring)."""
        names = ["x", "y", "theta", "vx", "vy", "omega"]
        for b in self.obstacles:
            names += [f"{b}_{n}" for n in ("x", "y", "theta", "vx", "vy", "omega")]
        return names + ["pusher_x", "pusher_y"]

    def load_scene(self):
        from planar_lcp.spec.scene import load_scene
        p = Path(self.scene)
        if not p.suffix and (SCENES_DIR / f"{self.scene}.toml").exists():
            p = SCENES_DIR / f"{self.scene}.toml"
        return load_scene(str(p) if p.suffix else self.scene)


TASKS = {
    "push_box": Task(
        name="push_box", scene="push_box_task", object="box", pusher="pusher",
        control_max=0.15, step_duration=0.1, min_steps=1, max_steps=10,
        object_bounds=((-0.15, 0.40), (-0.20, 0.30)), pusher_bounds=((-0.25, 0.50), (-0.30, 0.40)),
        speed_max=1.0, omega_max=10.0, weights=(1.0, 0.06, 0.002, 0.1),
        goal=dict(kind="pose", x=0.25, y=0.08, theta_deg=0.0, pos_tol=0.01, ang_tol_deg=10.0),
        description="push the box around a static block to (0.25, 0.08, 0 deg) within 1 cm and 10 deg"),
    "push_t": Task(
        name="push_t", scene="push_t", object="T", pusher="pusher",
        control_max=0.15, step_duration=0.1, min_steps=1, max_steps=10,
        object_bounds=((-0.20, 0.25), (-0.20, 0.25)), pusher_bounds=((-0.30, 0.35), (-0.30, 0.35)),
        speed_max=1.0, omega_max=10.0, weights=(1.0, 0.06, 0.002, 0.1),
        # the 95% cover goal needs the pose within a few mm and degrees, which goal samples reach best: RRT with
        # bias 0.3 solves seeds 1..10 within 10.6k iterations; with 0.1, 2 of them took more than 140k
        # (docs/planning.md, "Faster planning")
        goal_bias=0.3,
        goal=dict(kind="cover", x=0.06, y=0.08, theta_deg=30.0, min_cover=0.95),
        description="push the T block until it covers >= 95% of the goal T at (0.06, 0.08, 30 deg)"),
    "tip_box": Task(
        name="tip_box", scene="tip_box_task", object="box", pusher="finger",
        control_max=0.2, step_duration=0.1, min_steps=1, max_steps=10,
        object_bounds=((-0.30, 0.30), (0.0, 0.25)), pusher_bounds=((-0.30, 0.40), (0.0, 0.35)),
        speed_max=2.0, omega_max=20.0, weights=(1.0, 0.1, 0.005, 0.1),
        goal=dict(kind="tip", angle_deg=-90.0, signed=True, ang_tol_deg=10.0, rest_height=0.05,
                  height_tol=0.005, speed_tol=0.02, omega_tol=0.2),
        ledge_x=0.27,
        description="tip the standing box onto its right side, towards the ledge (-90 +- 10 deg, at rest), "
                    "without any part of it passing the ledge"),
    "push_clutter": Task(
        name="push_clutter", scene="push_clutter_task", object="box", pusher="pusher",
        obstacles=("disk", "crate", "rod", "wedge"),
        control_max=0.15, step_duration=0.1, min_steps=1, max_steps=10,
        object_bounds=((-0.33, 0.33), (-0.18, 0.18)), pusher_bounds=((-0.40, 0.40), (-0.25, 0.25)),
        obstacle_bounds=((-0.35, 0.35), (-0.20, 0.20)),
        speed_max=1.0, omega_max=10.0, weights=(1.0, 0.06, 0.002, 0.1), obstacle_weight=0.05,
        goal=dict(kind="pose", x=0.22, y=0.0, theta_deg=0.0, pos_tol=0.01, ang_tol_deg=10.0,
                  speed_tol=0.005, omega_tol=0.05),
        description="push the box through four movable obstacles (disk, crate, rod, wedge) to (0.22, 0, 0 deg) "
                    "within 1 cm and 10 deg, at rest, every obstacle's centre of mass staying on the table"),
}


def get_task(name):
    """The task called `name`; a TaskError lists the valid names otherwise."""
    if isinstance(name, Task):
        return name
    try:
        return TASKS[name]
    except (KeyError, TypeError):
        raise TaskError(f"unknown task {name!r}; valid tasks: {', '.join(sorted(TASKS))}") from None


class TaskModel:
    """A task compiled with its scene: the forward model, goal tests and validity as plain numpy functions.

    Everything the planner and `replay` do to a state goes through here, so both compute bit-identical results.
    """

    def __init__(self, task):
        from planar_lcp.model import compile_scene
        from planar_lcp.sim import SimOptions, Simulator

        self.task = task = get_task(task)
        self.scene = scene = task.load_scene()
        self.model = model = compile_scene(scene)
        src = scene.source
        want = [task.object, *task.obstacles]
        if sorted(model.dyn_names) != sorted(want) or len(set(want)) != len(want):
            raise TaskError(f"task {task.name}: the dynamic bodies of scene {src} must be the object and the "
                            f"obstacles {want}; it has {list(model.dyn_names)}")
        # the scene's index of each body in the flat state's order (object first, then the obstacles)
        self.dyn_order = np.array([model.dyn_names.index(b) for b in want])
        self.nobj = len(want)
        self.ip = 6 * self.nobj                  # the pusher's position is x[ip:ip + 2]
        if task.pusher not in model.kin_names:
            raise TaskError(f"task {task.name}: scene {src} has no kinematic body {task.pusher!r} "
                            f"(kinematic bodies: {list(model.kin_names)})")
        self.h = float(scene.sim.h)
        n = task.step_duration / self.h
        if abs(n - round(n)) > 1e-9 or round(n) < 1:
            raise TaskError(f"task {task.name}: step_duration {task.step_duration} must be a multiple of the "
                            f"scene's h = {self.h}")
        if not (1 <= task.min_steps <= task.max_steps):
            raise TaskError(f"task {task.name}: need 1 <= min_steps <= max_steps, got {task.min_steps}, "
                            f"{task.max_steps}")
        for lab, b in (("object_bounds", task.object_bounds), ("pusher_bounds", task.pusher_bounds),
                       ("obstacle_bounds", task.table_region)):
            for lo, hi in b:
                if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                    raise TaskError(f"task {task.name}: {lab} must be finite with low < high, got {b}")
        if not task.control_max > 0:
            raise TaskError(f"task {task.name}: control_max must be > 0, got {task.control_max}")
        self.steps_per_prop = int(round(n))
        # warm start: 2.5 to 3.5 times faster pushing steps (docs/performance.md); a rollout starts cold, so each
        # propagation is still a pure function of its inputs and replays bit for bit
        self.sim = Simulator(model, SimOptions(h=self.h, solver=scene.sim.solver if scene.sim.solver != "osqp"
                                               else "lemke", formulation=scene.sim.formulation, warm_start=True))
        self.ipusher = model.kin_names.index(task.pusher)
        self.qk0 = model.qk0.copy()
        # advance()'s inputs and its recordings (one per rollout length), reused from call to call
        self._q, self._v = np.empty((model.ndyn, 3)), np.empty((model.ndyn, 3))
        self._qk, self._vk = self.qk0.copy(), np.zeros((1, model.nkin, 3))
        self._recordings = {}
        self.nsteps_total = 0          # simulated steps (throughput)
        self._geometry()
        x0 = self.initial_state()
        if not self.in_bounds(x0):
            raise TaskError(f"task {task.name}: the start state {x0.round(4).tolist()} is outside the task bounds")

    # ---- geometry ------------------------------------------------------------------------------------------
    def _geometry(self):
        import shapely
        from shapely.geometry import Polygon
        from shapely.ops import unary_union

        from planar_lcp.frames import frame_to_com
        from planar_lcp.geometry import shape_geometry

        sc = self.scene
        obj = sc.body(self.task.object)
        self.object_poly_body = unary_union([shape_geometry(s, quad_segs=8) for s in obj.shapes])  # body frame
        self.object_area = self.object_poly_body.area
        pb = sc.body(self.task.pusher)
        radii = [s.radius for s in pb.shapes if s.type == "disk"]
        self.pusher_radius = max(radii) if radii else 0.0
        statics = []
        for b in sc.bodies:
            if b.type != "static":
                continue
            for s in b.shapes:
                if s.type == "halfplane":
                    p, nrm = np.asarray(s.point, float), np.asarray(s.normal, float)
                    t = np.array([-nrm[1], nrm[0]])
                    big = 1e3
                    statics.append(Polygon([p + big * t, p - big * t, p - big * t - big * nrm,
                                            p + big * t - big * nrm]))
                else:
                    g = shape_geometry(s, quad_segs=8)
                    statics.append(_place(g, b.position, b.angle))
        # where the pusher's centre may not be (statics inflated by the pusher radius less 1 mm of slack)
        self.forbidden = unary_union(statics).buffer(max(self.pusher_radius - 1e-3, 0.0)) if statics else None
        if self.forbidden is not None:
            shapely.prepare(self.forbidden)
        # the object's centre of mass in its body frame, (1, 2) as planar_lcp.frames takes it
        self.com_local1 = self.model.com_local[self.dyn_order[:1]].copy()
        self.com_local = self.com_local1[0]
        hull = np.asarray(self.object_poly_body.convex_hull.exterior.coords)
        self.object_radius = float(np.max(np.hypot(hull[:, 0] - self.com_local[0], hull[:, 1] - self.com_local[1])))
        g = self.task.goal
        if g.get("kind") in ("pose", "cover"):
            qf = np.array([[g["x"], g["y"], math.radians(g["theta_deg"])]])
            self.goal_com = frame_to_com(qf, self.com_local1)[0]
            self.goal_poly = _place(self.object_poly_body, (g["x"], g["y"]), math.radians(g["theta_deg"]))
        if self.task.ledge_x is not None:
            self.object_hull = np.asarray(self.object_poly_body.convex_hull.exterior.coords)[:-1]

    # ---- state ---------------------------------------------------------------------------------------------
    def initial_state(self):
        m = self.model
        x = np.zeros(self.ip + 2)
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
        (examples/propagation_cost.py)."""
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
        vk[0, self.ipusher, 0] = u[0]
        vk[0, self.ipusher, 1] = u[1]
        done = self.sim.rollout_into(rec, q, v, qk, vk, stop_on_failure=True)
        self.nsteps_total += done
        ok = done == nsteps and not rec.status[:done].any()
        y = np.empty(ip + 2)
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
        return y, ok and bool(np.isfinite(y).all())

    def execute(self, x0, controls, steps):
        """Replay controls open loop exactly as the planner propagated them.

        controls (n, 2) m/s; steps (n,) propagation steps each. Returns (states at control boundaries (n+1, d),
        dense states (1 + total sim steps / steps_per_prop, d) at every propagation step, ok); d = Task.state_dim."""
        x = np.asarray(x0, float).copy()
        bound, dense, ok = [x.copy()], [x.copy()], True
        for u, k in zip(np.asarray(controls, float), np.asarray(steps, int)):
            for _ in range(int(k)):
                x, good = self.advance(x, u, self.steps_per_prop)
                ok = ok and good
                dense.append(x.copy())
            bound.append(x.copy())
        return np.array(bound), np.array(dense), ok

    # ---- validity ------------------------------------------------------------------------------------------
    def in_bounds(self, x):
        """The state bounds (OMPL's too): positions in their regions (the obstacles' centres of mass on the table
        region), speeds and spins within speed_max and omega_max."""
        t = self.task
        (ox0, ox1), (oy0, oy1) = t.object_bounds
        (px0, px1), (py0, py1) = t.pusher_bounds
        ip = self.ip
        if not (ox0 <= x[0] <= ox1 and oy0 <= x[1] <= oy1 and px0 <= x[ip] <= px1 and py0 <= x[ip + 1] <= py1):
            return False
        (bx0, bx1), (by0, by1) = self.task.table_region
        for i in range(self.nobj):
            if i and not (bx0 <= x[6 * i] <= bx1 and by0 <= x[6 * i + 1] <= by1):
                return False
            if not (math.hypot(x[6 * i + 3], x[6 * i + 4]) <= t.speed_max and abs(x[6 * i + 5]) <= t.omega_max):
                return False
        return True

    def valid(self, x):
        """Task rules beyond the state bounds: the pusher is not inside a static body; the object stays on the
        ledge (vertical tasks)."""
        import shapely
        if self.forbidden is not None and shapely.contains_xy(self.forbidden, x[self.ip], x[self.ip + 1]):
            return False
        if self.task.ledge_x is not None:
            c, s = math.cos(x[2]), math.sin(x[2])
            # body-frame origin = COM - R com_local; hull points are body frame
            ox = x[0] - (c * self.com_local[0] - s * self.com_local[1])
            xs = ox + c * self.object_hull[:, 0] - s * self.object_hull[:, 1]
            if np.max(xs) > self.task.ledge_x:
                return False
        return True

    # ---- goal ----------------------------------------------------------------------------------------------
    def object_frame_pose(self, x):
        from planar_lcp.frames import com_to_frame
        return com_to_frame(np.asarray(x[0:3], float)[None], self.com_local1)[0]

    def goal_distance(self, x):
        """A goal distance with threshold 1.0: the goal holds iff goal_distance(x) <= 1."""
        g = self.task.goal
        kind = g["kind"]
        if kind == "pose":
            pe = math.hypot(x[0] - self.goal_com[0], x[1] - self.goal_com[1])
            ae = abs(wrap_angle(x[2] - self.goal_com[2]))
            d = max(pe / g["pos_tol"], ae / math.radians(g["ang_tol_deg"]))
            if "speed_tol" in g:                 # at rest
                d = max(d, math.hypot(x[3], x[4]) / g["speed_tol"], abs(x[5]) / g["omega_tol"])
            return d
        if kind == "cover":
            # cheap pose bound first: 95% cover needs the COM within a few mm and the angle within a few degrees
            pe = math.hypot(x[0] - self.goal_com[0], x[1] - self.goal_com[1])
            ae = abs(wrap_angle(x[2] - self.goal_com[2]))
            proxy = max(pe / 0.02, ae / math.radians(15.0))
            if proxy > 1.0:
                return 1.0 + proxy
            miss = 1.0 - self.cover(x)
            return miss / (1.0 - g["min_cover"])
        if kind == "tip":
            if g.get("signed", False):      # the tipping direction is part of the goal
                ae = abs(wrap_angle(x[2] - math.radians(g["angle_deg"])))
            else:
                ae = abs(abs(x[2]) - math.radians(g["angle_deg"]))
            he = abs(x[1] - g["rest_height"])
            return max(ae / math.radians(g["ang_tol_deg"]), he / g["height_tol"],
                       math.hypot(x[3], x[4]) / g["speed_tol"], abs(x[5]) / g["omega_tol"])
        raise TaskError(f"task {self.task.name}: unknown goal kind {kind!r}")

    def cover(self, x):
        """Fraction of the goal shape's area covered by the object (cover goals)."""
        pf = self.object_frame_pose(x)
        poly = _place(self.object_poly_body, pf[:2], pf[2])
        return poly.intersection(self.goal_poly).area / self.goal_poly.area

    def goal_report(self, x):
        """Human-readable goal errors of state x (a dict of floats and the verdict)."""
        g = self.task.goal
        d = self.goal_distance(x)
        r = {"goal_distance": float(d), "goal_holds": bool(d <= 1.0)}
        if g["kind"] in ("pose", "cover"):
            r["position_error_m"] = float(math.hypot(x[0] - self.goal_com[0], x[1] - self.goal_com[1]))
            r["angle_error_deg"] = float(math.degrees(abs(wrap_angle(x[2] - self.goal_com[2]))))
        if g["kind"] == "cover":
            r["cover"] = float(self.cover(x))
        if g["kind"] == "tip" or "speed_tol" in g:
            r["speed_m_s"] = float(math.hypot(x[3], x[4]))
            r["omega_rad_s"] = float(x[5])
        if g["kind"] == "tip":
            r["angle_deg"] = float(math.degrees(x[2]))
            r["com_height_m"] = float(x[1])
        return r

    def sample_goal(self, rng):
        """A state in the goal region: object at the goal (within tolerance), at rest; pusher anywhere valid;
        obstacles at rest anywhere on the table region.

        rng(lo, hi) -> uniform float (OMPL's RNG in the planner, so sampling is seeded)."""
        g = self.task.goal
        kind = g["kind"]
        x = np.zeros(self.ip + 2)
        (bx0, bx1), (by0, by1) = self.task.table_region
        for i in range(1, self.nobj):
            x[6 * i] = rng(bx0, bx1)
            x[6 * i + 1] = rng(by0, by1)
            x[6 * i + 2] = rng(-math.pi, math.pi)
        if kind in ("pose", "cover"):
            x[0:3] = self.goal_com
            if kind == "pose":
                r = 0.7 * g["pos_tol"]
                x[0] += rng(-r, r) / math.sqrt(2)
                x[1] += rng(-r, r) / math.sqrt(2)
                x[2] = wrap_angle(x[2] + math.radians(rng(-0.7, 0.7) * g["ang_tol_deg"]))
        else:
            sgn = 1.0 if (g.get("signed", False) or rng(-1.0, 1.0) > 0) else -1.0
            x[2] = wrap_angle(sgn * math.radians(g["angle_deg"] + rng(-0.7, 0.7) * g["ang_tol_deg"]))
            (ox0, ox1), _ = self.task.object_bounds
            x[0] = rng(ox0, ox1)
            x[1] = g["rest_height"]
        (px0, px1), (py0, py1) = self.task.pusher_bounds
        if kind in ("pose", "cover"):
            # the pusher next to the object (a ring around its centre of mass), where a plan that just pushed the
            # object there leaves it; a pusher anywhere in the workspace would make the nearest tree state to a
            # goal sample mostly a matter of the pusher's position
            a = rng(-math.pi, math.pi)
            r = rng(0.8, 1.0) * self.object_radius + self.pusher_radius
            x[self.ip] = min(max(x[0] + r * math.cos(a), px0), px1)
            x[self.ip + 1] = min(max(x[1] + r * math.sin(a), py0), py1)
        else:
            x[self.ip], x[self.ip + 1] = rng(px0, px1), rng(py0, py1)
        return x


def _place(g, pos, angle):
    from shapely import affinity
    g = affinity.rotate(g, angle, origin=(0.0, 0.0), use_radians=True)
    return affinity.translate(g, float(pos[0]), float(pos[1]))
