"""Closed loop for task files: a feedback controller over a TaskModel, and its runs in pymunk (work in progress).

`PushController(tm)`: for a horizontal-plane task with a disk pusher, one push at a time, chosen from the observed
flat state (planners.tasks) by simulating candidate pushes with the task's own forward model (`TaskModel.advance`),
scored by the task's own goal distance (`TaskModel.goal_distance`) and validity (`TaskModel.admissible`): the Push-T
policy's method (planners/pusht.py) with velocity controls held for the task's step duration.

`run_pymunk(tm, controller, ...)`: the task executed in pymunk through the bridge, the controller deciding each
propagation step's pusher velocity from pymunk's state.
"""

import math
import time

import numpy as np


class PushController:
    """One push at a time over a TaskModel (module docstring). `reset()`, then `controller(x) -> u` (the pusher's
    velocity, m/s, for one propagation step).

    spacing, gap, reach : m; candidate points along the object's outline, how far off it the pusher starts, how far
    a push is tried. push_speed : m/s (at most the task's control_max). budget_s : thread CPU seconds per choice."""

    def __init__(self, tm, spacing=None, gap=0.001, reach=None, push_speed=None, budget_s=0.2, replan_tol=1.0):
        from shapely.geometry import Point  # noqa: F401  (shapely needed)
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
        self.budget_s = float(budget_s)
        self.replan_tol = float(replan_tol)
        self.r = float(tm.pusher_radius)
        self._outline = self._outline_points()
        self.reset()

    def reset(self):
        self._push = None
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
    def __call__(self, x):
        c0 = time.thread_time()
        x = np.asarray(x, dtype=np.float64)
        push = self._push
        if push is not None and not self._on_track(push, x):
            push = self._push = None
        if push is None:
            push = self._push = self._choose(x)
            self.replans += 1
        if push is None:
            self.phase = "idle"
            u = np.zeros(2)
        else:
            u = self._follow(push, x)
        self.compute_s = time.thread_time() - c0
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
            if dist < 1e-4 and len(route) == 1:
                push["phase"] = "push"
                push["k"] = 0
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
        tm = self.tm
        ip = tm.ip
        f, R = self._frame(x)
        d_now = tm.goal_distance(x)
        steps = max(1, int(math.ceil(self.reach / (self.push_speed * self.dt))))
        start = time.thread_time()
        best = None
        order = np.random.default_rng(self.replans).permutation(len(self._outline))
        for j in order:
            if time.thread_time() - start > self.budget_s:
                break
            p_b, n_b = self._outline[j]
            c0 = f[:2] + R @ (p_b + (self.r + self.gap) * n_b)
            u = -(R @ n_b) * self.push_speed
            y = x.copy()
            y[3:6] = 0.0
            y[ip:ip + 2] = c0
            if not tm.admissible(y):
                continue
            states, dists = [y], [d_now]
            for _ in range(steps):
                y, ok = tm.advance(y, u, tm.steps_per_prop)
                if not (ok and tm.admissible(y)):
                    break
                states.append(y)
                dists.append(tm.goal_distance(y))
            i = int(np.argmin(dists))
            if i == 0 or dists[i] >= d_now:
                continue
            way = float(np.hypot(*(c0 - x[ip:ip + 2])))
            cost_steps = way / (self.cm * self.dt) + i
            rate = (d_now - dists[i]) / cost_steps
            if best is None or rate > best[0]:
                best = (rate, c0, u, states[:i + 1])
        if best is None:
            return None
        _, c0, u, states = best
        return {"phase": "approach", "c0": c0, "u": u, "states": states, "start": x.copy(), "k": 0}


def run_pymunk(tm, controller, max_steps=600, scene=None):
    """The task in pymunk through the bridge, the controller choosing every propagation step's pusher velocity from
    pymunk's state (converted to the flat state). Returns dict(goal_holds, steps, report, compute per step)."""
    from planar_lcp.experiments.pymunk_bridge import build_space, read_state
    sc = scene if scene is not None else tm.scene
    space, hd = build_space(sc, h=tm.h)
    pusher = hd.bodies[tm.task.pusher]

    def flat():
        q, _, qk, vc = read_state(hd)
        qc = tm.model.frame_to_com(q)
        x = np.empty(tm.task.state_dim)
        for i, d in enumerate(tm.dyn_order):
            x[6 * i:6 * i + 3] = qc[d]
            x[6 * i + 2] = math.atan2(math.sin(qc[d, 2]), math.cos(qc[d, 2]))
            x[6 * i + 3:6 * i + 6] = vc[d]
        x[tm.ip:tm.ip + 2] = qk[hd.kinematic_names.index(tm.task.pusher), 0:2]
        return x

    controller.reset()
    compute = []
    x = flat()
    for k in range(max_steps):
        if tm.goal_distance(x) <= 1.0 and tm.admissible(x):
            return {"goal_holds": True, "steps": k, "report": tm.goal_report(x), "compute_s": compute}
        u = controller(x)
        compute.append(controller.compute_s)
        pusher.velocity = (float(u[0]), float(u[1]))
        pusher.angular_velocity = 0.0
        for _ in range(tm.steps_per_prop):
            space.step(tm.h)
        x = flat()
    return {"goal_holds": bool(tm.goal_distance(x) <= 1.0), "steps": max_steps, "report": tm.goal_report(x),
            "compute_s": compute}
