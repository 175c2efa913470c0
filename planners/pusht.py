"""A feedback policy for Push-T over our simulator: `PushTPolicy` (docs/closed_loop.md).

At every action it reads the observed state (the pusher's position and the T's pose, gym-pusht's "state"
observation) and decides the next PD target. Its plan is one push at a time, chosen with the simulator as the model
(PushT-v0's physics, `planners.environments.push_t.PushTEnv.advance`, set to the world the policy acts in):

- Candidates: points along the T's outline every `spacing` mm where the pusher's disk fits, each pushed along the
  inward normal of its edge; those whose first motion (a frictionless push's: along the push, turning by the moment
  arm over the radius of gyration squared) takes the T away from the goal are dropped, the others tried steepest
  first until `budget_s` of thread CPU time is spent. For each, the model pushes from there for up to `push_reach`
  mm (rollouts of PushT-v0's actions from the observed pose, the pusher starting at rest just off the point) and
  records the T's pose at every substep against how far the pusher has gone.
- Choice: each candidate's best stopping distance, in the distance |dp|^2 + (rho dtheta)^2 between centres of mass
  and the goal's (rho the T's radius of gyration about its centre of mass); among the pushes that bring the T
  nearer than it is now, the one with the most progress per action it costs (the way there, settling, the push).
- Execution: the pusher first moves straight off the T if it is against it, then goes to the point (straight, or
  round the T on a circle clear of it when the straight way would touch it), waits there until nearly at rest, then
  pushes along the line with targets that lead it by `push_step` mm per action and stop at the chosen distance.
  After each action the observed T pose is compared with the model's at the pusher's progress along the line:
  beyond `replan_mm` or `replan_deg` the push is dropped and a new one chosen from the observed state; so is a push
  whose pusher has stopped at its end.

With world="gym_pusht" the model has gym-pusht's physics (`PushTEnv(physics="gym_pusht")`: no table friction,
frictionless contacts, every velocity forgotten at each step, its T's mass properties): there, how far the T moves
depends on the pusher's path and not its speed, so a push is judged by its distance alone. With world="planar_lcp" it
is our PushT-v0's physics.
"""

import math
import time

import numpy as np

from .environments.push_t import ARENA, GOAL_POSE, PUSHT_COG, WALL_HALF, WALL_LINES, PushTEnv, pd_substeps

WORLDS = ("gym_pusht", "planar_lcp")
#: the pusher's centre stays this far inside the walls' inner faces beyond its radius, mm
WALL_CLEARANCE = 2.0


class PushTPolicy:
    """A policy for obs_type "state" of `gym_pusht/PushT-v0` and `planar_lcp/PushT-v0`: `reset()`, then
    `policy(obs) -> action` (the pusher's target, x, y in mm) at every step.

    Parameters
    ----------
    world : "gym_pusht" | "planar_lcp"
        The physics the policy acts in, so that its model is that physics (module docstring).
    goal : (x, y mm, angle rad)
        The T's goal pose (gym-pusht's fixed one by default); an observation with 8 numbers (PushT-v0's
        random_goal) carries its own.
    spacing, push_reach, push_step : float, mm
        Candidate points' spacing along the outline, how far each candidate push is tried, the pusher's lead per
        action while pushing.
    approach_step : float, mm
        How far ahead of the pusher its target is put per action on the way to a push.
    replan_mm, replan_deg : float
        How far the observed T may drift from the model's prediction before the push is chosen again.
    budget_s : float
        Thread CPU seconds a choice of push may spend simulating candidates (the most promising first), so that
        every action is decided within the 0.1 s between actions.
    settle_mm, settle_speed : float
        The push starts once the pusher is this near its start point (mm) and this slow (mm/s).

    Notes
    -----
    Attributes (after each call): `compute_s`, the thread CPU time of the call; `replans`, the pushes chosen so far;
    `phase`, "approach" | "settle" | "push" | "idle".
    """

    def __init__(self, world="gym_pusht", goal=GOAL_POSE, spacing=6.0, push_reach=60.0, push_step=8.0,
                 approach_step=60.0, replan_mm=2.0, replan_deg=2.0, budget_s=0.07, settle_mm=1.0, settle_speed=10.0):
        if world not in WORLDS:
            raise ValueError(f"PushTPolicy: world must be one of {', '.join(WORLDS)}, got {world!r}")
        self.world = world
        self.model = PushTEnv(obs_type="state", render_mode=None, physics=world)
        self.goal = np.asarray(goal, dtype=np.float64)
        self.spacing, self.push_reach, self.push_step = float(spacing), float(push_reach), float(push_step)
        self.approach_step, self.replan_mm = float(approach_step), float(replan_mm)
        self.replan_rad = math.radians(float(replan_deg))
        self.budget_s = float(budget_s)
        self.settle_mm, self.settle_speed = float(settle_mm), float(settle_speed)
        self.radius = float(self.model.pusher_radius)
        self._boxes = _boxes_mm(self.model)
        self._com = np.array(PUSHT_COG, dtype=np.float64)
        self.rho = _gyration(self._boxes, self._com)
        # the model T's own radius of gyration (its inertia over its mass, mm): how a push's impulse turns it
        self.rho_m = math.sqrt(self.model.model.arrays.dyn_inertia[0] / self.model.model.arrays.dyn_mass[0]) * 1e3
        self._outline = _outline_points(self._boxes, self.spacing, self.radius)
        lo, hi = WALL_LINES[0] + WALL_HALF + self.radius + WALL_CLEARANCE, \
            WALL_LINES[1] - WALL_HALF - self.radius - WALL_CLEARANCE
        self._arena = (lo, hi)
        # load the model's kernels now (a first rollout), not in the first action's time
        self.model.set_state((100.0, 100.0), (0.0, 0.0), (256.0, 300.0, 0.0))
        self.model.advance((100.0, 100.0))
        self.reset()

    # ---- the interface ------------------------------------------------------------------------------------------
    def reset(self):
        """Forget the episode: the pusher is taken to be at rest, no push chosen."""
        self._agent_vel = np.zeros(2)
        self._last = None              # (observed agent, action) of the previous call
        self._push = None
        self.phase = "idle"
        self.replans = 0
        self.compute_s = 0.0

    def __call__(self, obs):
        c0 = time.thread_time()
        obs = np.asarray(obs, dtype=np.float64)
        agent, pose = obs[0:2], obs[2:5].copy()
        goal = obs[5:8] if len(obs) >= 8 else self.goal
        self._track_velocity(agent)
        action = np.clip(self._decide(agent, pose, goal), 0.0, ARENA)      # the action space
        self._last = (agent.copy(), action.copy())
        self.compute_s = time.thread_time() - c0
        return action

    # ---- the pusher's velocity ----------------------------------------------------------------------------------
    def _track_velocity(self, agent):
        """The PD law's velocity (not observed): the previous action's ten substeps from the previous observation,
        exactly as the environment computes them; where that does not end where the pusher is seen (a pusher
        stopped by a wall, another policy's step), the mean velocity of the last action."""
        if self._last is None:
            return
        p0, target = self._last
        ps, vs = pd_substeps(p0 * 1e-3, self._agent_vel * 1e-3, target * 1e-3)
        p, v = ps[-1], vs[-1]
        if np.abs(p * 1e3 - agent).max() < 1e-6:
            self._agent_vel = v * 1e3
        else:
            self._agent_vel = (agent - self._last[0]) / 0.1

    # ---- deciding -----------------------------------------------------------------------------------------------
    def _decide(self, agent, pose, goal):
        push = self._push
        if push is not None and not self._on_track(push, agent, pose):
            push = self._push = None
        if push is None:
            push = self._push = self._choose(agent, pose, goal)
            self.replans += 1
            if push is None:
                self.phase = "idle"
                return agent.copy()
        return self._follow(push, agent, pose)

    def _on_track(self, push, agent, pose):
        """Whether the T is where the model said it would be at the pusher's progress along the push, and the push
        is not over."""
        if push["phase"] in ("approach", "settle"):
            moved = push["start_pose"]
        else:
            s = float(np.dot(agent - push["c0"], push["d"]))
            if push["phase"] == "push" and s >= push["s_stop"] - 0.3 and np.hypot(*self._agent_vel) < 5.0:
                return False                    # pushed to its end and stopped: choose the next
            moved = _interp_pose(push["s_path"], push["poses"], max(s, 0.0))
        dp = math.hypot(pose[0] - moved[0], pose[1] - moved[1])
        da = abs(_wrap(pose[2] - moved[2]))
        return dp <= self.replan_mm and da <= self.replan_rad

    def _follow(self, push, agent, pose):
        c0, d = push["c0"], push["d"]
        speed = float(np.hypot(*self._agent_vel))
        if push["phase"] == "approach":
            dist = float(np.hypot(*(c0 - agent)))
            if dist < 1.0:
                push["phase"] = "settle"
            else:
                self.phase = "approach"
                return self._approach_target(push, agent, pose)
        if push["phase"] == "settle":
            if float(np.hypot(*(c0 - agent))) < self.settle_mm and speed < self.settle_speed:
                push["phase"] = "push"
                push["s_target"] = 0.0
            else:
                self.phase = "settle"
                return c0.copy()
        self.phase = "push"
        push["s_target"] = min(push["s_target"] + self.push_step, push["s_stop"])
        return c0 + d * push["s_target"]

    def _approach_target(self, push, agent, pose):
        """The next target on the way to the push's start point: approach_step further along the route (straight,
        or round the T) than the route's point nearest the pusher, the latest of the route's legs on a tie, so that
        the target never leads back; the start point itself when it is that near."""
        route = [agent.copy()] + self._route(agent, push["c0"], pose)
        near, leg = agent.copy(), 0
        best = math.inf
        for i in range(len(route) - 1):
            a, ab = route[i], route[i + 1] - route[i]
            L2 = float(ab @ ab)
            t = 0.0 if L2 == 0.0 else min(1.0, max(0.0, float((agent - a) @ ab) / L2))
            q = a + t * ab
            dist = float(np.hypot(*(agent - q)))
            if dist <= best + 1e-9:
                best, near, leg = dist, q, i
        left, p = self.approach_step, near
        for w in route[leg + 1:]:
            seg = w - p
            n = float(np.hypot(*seg))
            if n >= left:
                return p + seg * (left / n)
            left -= n
            p = w
        return p

    def _route(self, agent, c0, pose):
        """Waypoints (world, mm) from the pusher to c0 that keep its disk off the T at `pose`: [c0] when the straight
        segment is clear; else out to a circle about the T's centre of mass that clears it, along it the shorter way
        and in to c0. Points are kept inside the arena."""
        to_t, to_w = _frame_maps(pose)
        a, b = to_t(agent), to_t(c0)
        lo, hi = self._arena
        lead = []
        gap = float(_sdf(self._boxes, a))
        if gap < self.radius + 3.0:
            # the pusher against the T (a push just ended): first straight away from it, along the distance's
            # gradient, so that going round does not drag the T along
            e = 1e-3
            g = np.array([_sdf(self._boxes, a + [e, 0.0]) - _sdf(self._boxes, a - [e, 0.0]),
                          _sdf(self._boxes, a + [0.0, e]) - _sdf(self._boxes, a - [0.0, e])])
            if np.hypot(*g) > 0.0:
                a = a + g / np.hypot(*g) * (self.radius + 6.0 - gap)
                lead = [np.clip(to_w(a), lo, hi)]
                a = to_t(lead[0])
        # c0 is radius + 1 mm off the T: a way clear by radius + 0.5 mm may end there
        clear = self.radius + 0.5
        if _segment_clear(self._boxes, a, b, clear):
            return lead + [c0]
        com = self._com
        R = (_circumradius(self._boxes, com) + self.radius + 4.0) / math.cos(math.radians(15.0))
        a0 = math.atan2(a[1] - com[1], a[0] - com[0])
        da = _wrap(math.atan2(b[1] - com[1], b[0] - com[0]) - a0)
        n = max(1, int(math.ceil(abs(da) / math.radians(30.0))))
        pts = [com + R * np.array([math.cos(a0 + da * k / n), math.sin(a0 + da * k / n)]) for k in range(n + 1)]
        out = [np.clip(to_w(p), lo, hi) for p in pts]
        return lead + out + [c0]

    def _choose(self, agent, pose, goal):
        """The best push from the observed pose (module docstring), or None when no push brings the T nearer."""
        to_t, to_w = _frame_maps(pose)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        R = np.array([[c, -s], [s, c]])
        lo, hi = self._arena
        best = None
        j_now = self._cost(pose, goal)
        steps = int(math.ceil(self.push_reach / self.push_step))
        env = self.model
        grad = self._cost_gradient(pose, goal)
        # a frictionless push at p along -n moves the centre of mass along -n and turns the T by (p - c) x (-n) over
        # the radius of gyration^2 (per unit of impulse and mass): the cost's slope along that first motion. Pushes
        # that start uphill are not tried; the others in the order of their slope, the steepest first, until the
        # time budget is spent (so that a decision keeps to real time)
        tried = []
        for p_t, n_t in self._outline:
            c0 = to_w(p_t + (self.radius + 1.0) * n_t)
            if not (lo <= c0[0] <= hi and lo <= c0[1] <= hi):
                continue
            arm = p_t - self._com
            slope = float(grad @ np.array([-n_t[0], -n_t[1], -(arm[0] * n_t[1] - arm[1] * n_t[0]) / self.rho_m ** 2]))
            if slope < 0.0:
                tried.append((slope, len(tried), c0, n_t))
        tried.sort(key=lambda c: c[:2])
        t_start = time.thread_time()
        for _, _, c0, n_t in tried:
            if time.thread_time() - t_start > self.budget_s:
                break
            d = -(R @ n_t)
            env.set_state(c0, (0.0, 0.0), pose)
            s_path, poses, costs = [0.0], [pose.copy()], [j_now]
            rising = 0
            for k in range(1, steps + 1):
                env.advance(c0 + d * (self.push_step * k))
                rec = env.rec
                pk = rec.qk[1:, 0, :2] * 1e3
                fr = _frames(env, rec.q[1:, 0])
                s_path.extend(((pk - c0) @ d).tolist())
                poses.extend(fr)
                c = self._cost_many(fr, goal)
                rising = rising + 1 if c[-1] > min(costs) else 0
                costs.extend(c.tolist())
                if env.failed_steps or rising >= 2:
                    break                           # past its best for two actions: it only gets worse
            s_path, poses, costs = np.asarray(s_path), np.asarray(poses), np.asarray(costs)
            i = int(np.argmin(costs))
            if costs[i] < j_now - 1e-3:
                # the progress per action it takes to get there and push: the way round the T at about half an
                # approach step per action, a few to settle, the push at push_step per action
                way = _polyline_length([agent] + self._route(agent, c0, pose))
                actions = way / (0.5 * self.approach_step) + 3.0 + max(float(s_path[i]), 0.0) / self.push_step
                rate = (j_now - float(costs[i])) / actions
                if best is None or rate > best[0]:
                    best = (rate, c0, d, s_path, poses, float(s_path[i]))
        if best is None:
            return None
        _, c0, d, s_path, poses, s_stop = best
        return {"c0": c0, "d": d, "s_path": s_path, "poses": poses, "s_stop": s_stop, "phase": "approach",
                "start_pose": pose.copy(), "s_target": 0.0}

    def _cost_gradient(self, pose, goal):
        """The cost's gradient (module docstring) with respect to the T's centre of mass (x, y, mm; in the T's
        frame) and its angle, at `pose`."""
        com = self._com
        c, s = math.cos(pose[2]), math.sin(pose[2])
        px, py = pose[0] + c * com[0] - s * com[1], pose[1] + s * com[0] + c * com[1]
        cg, sg = math.cos(goal[2]), math.sin(goal[2])
        gx, gy = goal[0] + cg * com[0] - sg * com[1], goal[1] + sg * com[0] + cg * com[1]
        dw = np.array([px - gx, py - gy])
        dt = np.array([c * dw[0] + s * dw[1], -s * dw[0] + c * dw[1]])      # in the T's frame, as n_t and arm
        return np.array([2.0 * dt[0], 2.0 * dt[1], 2.0 * self.rho ** 2 * _wrap(pose[2] - goal[2])])

    def _cost(self, pose, goal):
        return float(self._cost_many(np.asarray(pose)[None], goal)[0])

    def _cost_many(self, poses, goal):
        """|dp|^2 + (rho dtheta)^2 between the centres of mass of the T at `poses` (n, 3) and at `goal`, mm^2."""
        com = self._com
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        px = poses[:, 0] + c * com[0] - s * com[1]
        py = poses[:, 1] + s * com[0] + c * com[1]
        cg, sg = math.cos(goal[2]), math.sin(goal[2])
        gx, gy = goal[0] + cg * com[0] - sg * com[1], goal[1] + sg * com[0] + cg * com[1]
        da = (poses[:, 2] - goal[2] + np.pi) % (2 * np.pi) - np.pi
        return (px - gx) ** 2 + (py - gy) ** 2 + (self.rho * da) ** 2


# ---- geometry of the T (its frame, mm) ------------------------------------------------------------------------------
def _boxes_mm(env):
    """(k, 4) the T's boxes: centre x, y and half-widths, mm, in gym-pusht's T frame."""
    return np.array([[1e3 * ox, 1e3 * oy, 500.0 * w, 500.0 * h] for w, h, ox, oy in env.boxes])


def _sdf(boxes, p):
    """Signed distance (mm) from points p (..., 2) to the union of the boxes (negative inside)."""
    p = np.asarray(p, dtype=np.float64)
    out = None
    for cx, cy, hx, hy in boxes:
        qx, qy = np.abs(p[..., 0] - cx) - hx, np.abs(p[..., 1] - cy) - hy
        d = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0)) + np.minimum(np.maximum(qx, qy), 0.0)
        out = d if out is None else np.minimum(out, d)
    return out


def _segment_clear(boxes, a, b, clear):
    n = max(2, int(math.ceil(np.hypot(*(b - a)) / 2.0)) + 1)
    pts = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    return bool(np.all(_sdf(boxes, pts) >= clear))


def _circumradius(boxes, centre):
    corners = np.array([[cx + sx * hx, cy + sy * hy] for cx, cy, hx, hy in boxes for sx in (-1, 1) for sy in (-1, 1)])
    return float(np.max(np.hypot(*(corners - centre).T)))


def _gyration(boxes, centre):
    """The radius of gyration (mm) of the boxes' area about `centre`."""
    area = polar = 0.0
    for cx, cy, hx, hy in boxes:
        a = 4 * hx * hy
        area += a
        polar += a * ((4 * hx * hx + 4 * hy * hy) / 12.0 + (cx - centre[0]) ** 2 + (cy - centre[1]) ** 2)
    return math.sqrt(polar / area)


def _outline_points(boxes, spacing, radius):
    """(point, outward unit normal) pairs along the outline of the union of the boxes, every `spacing` mm, where the
    pusher's disk fits against the point (its centre radius + 1 mm out along the normal clears every box)."""
    from shapely.geometry import box
    from shapely.ops import unary_union
    poly = unary_union([box(cx - hx, cy - hy, cx + hx, cy + hy) for cx, cy, hx, hy in boxes]).simplify(0.0)
    ring = np.asarray(poly.exterior.coords)
    if poly.exterior.is_ccw is False:
        ring = ring[::-1]
    out = []
    for a, b in zip(ring[:-1], ring[1:]):
        e = b - a
        L = float(np.hypot(*e))
        n = np.array([e[1], -e[0]]) / L                     # outward for a counter-clockwise ring
        k = max(1, int(math.floor(L / spacing)))
        for t in (np.arange(k) + 0.5) / k:
            p = a + t * e
            if _sdf(boxes, p + (radius + 1.0) * n) >= radius + 0.99:
                out.append((p, n))
    return out


def _frame_maps(pose):
    """(world -> T frame, T frame -> world) point maps for the T's frame at pose (x, y mm, angle rad)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    o = np.array([pose[0], pose[1]])

    def to_t(p):
        d = np.asarray(p, dtype=np.float64) - o
        return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])

    def to_w(p):
        p = np.asarray(p, dtype=np.float64)
        return o + np.array([c * p[0] - s * p[1], s * p[0] + c * p[1]])
    return to_t, to_w


def _frames(env, q_com):
    """The T's frame poses (n, 3; x, y mm, angle rad) of its centre-of-mass poses q_com (n, 3; m, rad)."""
    from planar_lcp.frames import com_to_frame
    f = com_to_frame(np.asarray(q_com), np.repeat(env.com_local1, len(q_com), axis=0))
    return np.column_stack([f[:, 0] * 1e3, f[:, 1] * 1e3, f[:, 2]])


def _interp_pose(s_path, poses, s):
    """The T's pose at pusher progress s along a push (linear between the model's substeps; the angle as is)."""
    i = int(np.searchsorted(s_path, s))
    if i <= 0:
        return poses[0]
    if i >= len(s_path):
        return poses[-1]
    s0, s1 = s_path[i - 1], s_path[i]
    w = 0.0 if s1 <= s0 else (s - s0) / (s1 - s0)
    return poses[i - 1] + w * (poses[i] - poses[i - 1])


def _polyline_length(points):
    return float(sum(np.hypot(*(b - a)) for a, b in zip(points[:-1], points[1:])))


def _wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


__all__ = ["PushTPolicy", "WORLDS", "ARENA"]
