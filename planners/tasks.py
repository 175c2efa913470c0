"""Planning tasks: a scene, the object, the pusher, control bounds and durations, a goal and validity rules.

Nothing here imports ompl: `planners.adapter` turns a `Task` into an OMPL problem. The goal tests are plain
functions of the flat physics state

    x = (qx, qy, qtheta, vx, vy, omega, px, py)      (8,)

with the object's CENTRE-OF-MASS pose and velocity (m, rad, m/s, rad/s) and the pusher's body-frame position (m),
so that `replay` and the tests use exactly the checks the planner used.
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
    """A planning problem over a scene with ONE dynamic body (the object) and one kinematic body (the pusher).

    Attributes
    ----------
    name : str
    scene : str
        A shipped scene name or a path.
    object, pusher : str
        Body names in the scene.
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
        Velocity bounds of the object (state bounds; faster states are invalid), m/s and rad/s.
    goal : dict
        kind "pose" (x, y, theta_deg of the object's body frame, pos_tol m, ang_tol_deg),
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
        # bias 0.3 solved seeds 1..20 within 24k iterations; with 0.1, 2 of seeds 1..10 took more than 140k
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
        if model.ndyn != 1 or task.object not in model.dyn_names:
            raise TaskError(f"task {task.name}: scene {src} must have exactly one dynamic body, the object "
                            f"{task.object!r}; it has {list(model.dyn_names)}")
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
        for lab, b in (("object_bounds", task.object_bounds), ("pusher_bounds", task.pusher_bounds)):
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
        self.com_local = self.model.com_local[0].copy()
        hull = np.asarray(self.object_poly_body.convex_hull.exterior.coords)
        self.object_radius = float(np.max(np.hypot(hull[:, 0] - self.com_local[0], hull[:, 1] - self.com_local[1])))
        g = self.task.goal
        if g.get("kind") in ("pose", "cover"):
            qf = np.array([[g["x"], g["y"], math.radians(g["theta_deg"])]])
            self.goal_com = self.model.frame_to_com(qf)[0]
            self.goal_poly = _place(self.object_poly_body, (g["x"], g["y"]), math.radians(g["theta_deg"]))
        if self.task.ledge_x is not None:
            self.object_hull = np.asarray(self.object_poly_body.convex_hull.exterior.coords)[:-1]

    # ---- state ---------------------------------------------------------------------------------------------
    def initial_state(self):
        m = self.model
        x = np.zeros(8)
        x[0:3] = m.q0[0]
        x[2] = wrap_angle(x[2])
        x[3:6] = m.v0[0]
        x[6:8] = m.qk0[self.ipusher, :2]
        return x

    def advance(self, x, u, nsteps):
        """Roll the physics out for `nsteps` steps with pusher velocity u = (vx, vy): ONE rollout call.

        Returns (x_new, ok); the object angle of x_new is wrapped to [-pi, pi)."""
        m = self.model
        q = np.array([[x[0], x[1], x[2]]])
        v = np.array([[x[3], x[4], x[5]]])
        qk = self.qk0.copy()
        qk[self.ipusher, 0] = x[6]
        qk[self.ipusher, 1] = x[7]
        vk = np.zeros((1, m.nkin, 3))
        vk[0, self.ipusher, 0] = u[0]
        vk[0, self.ipusher, 1] = u[1]
        out = self.sim.rollout(q, v, qk, vk, int(nsteps), stop_on_failure=True)
        done = out["steps_done"]
        self.nsteps_total += done
        ok = bool(done == nsteps and not np.any(out["status"][:done]))
        y = np.empty(8)
        y[0:3] = out["q"][done, 0]
        y[2] = wrap_angle(y[2])
        y[3:6] = out["v"][done, 0]
        y[6:8] = out["qk"][done, self.ipusher, :2]
        return y, ok and bool(np.all(np.isfinite(y)))

    def execute(self, x0, controls, steps):
        """Replay controls open loop exactly as the planner propagated them.

        controls (n, 2) m/s; steps (n,) propagation steps each. Returns (states at control boundaries (n+1, 8),
        dense states (1 + total sim steps / steps_per_prop, 8) at every propagation step, ok)."""
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
        t = self.task
        (ox0, ox1), (oy0, oy1) = t.object_bounds
        (px0, px1), (py0, py1) = t.pusher_bounds
        return (ox0 <= x[0] <= ox1 and oy0 <= x[1] <= oy1 and px0 <= x[6] <= px1 and py0 <= x[7] <= py1
                and math.hypot(x[3], x[4]) <= t.speed_max and abs(x[5]) <= t.omega_max)

    def valid(self, x):
        """Task rules beyond the state bounds: the pusher is not inside a static body; the object stays on the
        ledge (vertical tasks)."""
        import shapely
        if self.forbidden is not None and shapely.contains_xy(self.forbidden, x[6], x[7]):
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
        return self.model.com_to_frame(np.asarray(x[0:3], float)[None])[0]

    def goal_distance(self, x):
        """A goal distance with threshold 1.0: the goal holds iff goal_distance(x) <= 1."""
        g = self.task.goal
        kind = g["kind"]
        if kind == "pose":
            pe = math.hypot(x[0] - self.goal_com[0], x[1] - self.goal_com[1])
            ae = abs(wrap_angle(x[2] - self.goal_com[2]))
            return max(pe / g["pos_tol"], ae / math.radians(g["ang_tol_deg"]))
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
        if g["kind"] == "tip":
            r["angle_deg"] = float(math.degrees(x[2]))
            r["com_height_m"] = float(x[1])
            r["speed_m_s"] = float(math.hypot(x[3], x[4]))
            r["omega_rad_s"] = float(x[5])
        return r

    def sample_goal(self, rng):
        """A state in the goal region: object at the goal (within tolerance), at rest; pusher anywhere valid.

        rng(lo, hi) -> uniform float (OMPL's RNG in the planner, so sampling is seeded)."""
        g = self.task.goal
        kind = g["kind"]
        x = np.zeros(8)
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
            x[6] = min(max(x[0] + r * math.cos(a), px0), px1)
            x[7] = min(max(x[1] + r * math.sin(a), py0), py1)
        else:
            x[6], x[7] = rng(px0, px1), rng(py0, py1)
        return x


def _place(g, pos, angle):
    from shapely import affinity
    g = affinity.rotate(g, angle, origin=(0.0, 0.0), use_radians=True)
    return affinity.translate(g, float(pos[0]), float(pos[1]))
