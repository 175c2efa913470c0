"""`planar_lcp/PushT-v0` (docs/gym.md): gym-pusht's Push-T on our physics.

It keeps gym-pusht's interface (its arena, units, action, observations, reward, goal and episode length) over the
push_t scene's T on a table with limit-surface friction, the pusher a kinematic disk of our simulator. `import
planners` registers the id when gymnasium is installed (the `gym` extra); the registration names this module by
string, so importing planners never imports it.
"""

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from planar_lcp.frames import com_to_frame, frame_to_com
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec.scene import load_scene, parse_scene, shipped_dir

from .inputs import checked_action, finite_array, options_dict, shown
from .raster import Raster

#: 1 gym-pusht unit = 1 mm
MM = 1e-3
ARENA = 512.0                        # the arena's side, gym-pusht units (mm)
#: gym-pusht's walls: segments of radius 2 along x = 5, x = 506, y = 5, y = 506 (mm), as static boxes 4 mm thick
WALL_LINES, WALL_HALF = (5.0, 506.0), 2.0
GOAL_POSE = (256.0, 256.0, math.pi / 4)        # gym-pusht's goal: the T's frame at (256, 256) mm, 45 degrees
#: the point of the T's frame about which gym-pusht's reset turns the T (its centre of gravity: the mean of the two
#: boxes' centroids, not the area centroid (0, 40.71)); `reset_to_state` is read with it, as gym-pusht reads it
PUSHT_COG = (0.0, 45.0)
K_P, K_V = 100.0, 20.0               # gym-pusht's PD gains (1/s^2, 1/s)
DT, SUBSTEPS = 0.01, 10              # its physics step (s) and steps per action (10 Hz actions)
SUCCESS_COVER = 0.95
#: PushT-v0's models of the world (PushTEnv's `physics`)
PHYSICS = ("planar_lcp", "gym_pusht")
#: gym-pusht's T inertia per unit mass, mm^2: pymunk's moment_for_poly of the 120 x 30 bar about the frame origin
#: ((120^2 + 30^2) / 12 + 15^2 = 1500), taken twice (its source computes the bar's moment for both boxes)
GYM_PUSHT_INERTIA = 3000.0
#: the pusher is a force-limited velocity servo (a kinematic body with max_force, docs/method.md): far above what a
#: push needs (the T's 0.1 kg at the PD law's accelerations: a few N), so that it binds only where a push into a
#: wall has no rigid solution, and stalls there as a robot would instead of failing the step. N
PUSHER_MAX_FORCE = 50.0
OBS_TYPES = ("state", "environment_state_agent_pos", "pixels", "pixels_agent_pos")
# gym-pusht's colours, read off its images (the fills of its LightSlateGray T and RoyalBlue pusher are lighter
# than the named colours: pymunk's drawing)
WHITE, LIGHT_GREEN, LIGHT_GRAY = (255, 255, 255), (144, 238, 144), (211, 211, 211)
SLATE_GRAY, ROYAL_BLUE, RED = (143, 163, 184), (78, 126, 255), (255, 0, 0)


def pd_substeps(p, v, target):
    """gym-pusht's PD law over one action: from the pusher's position p and velocity v (m, m/s) towards `target`
    (m), SUBSTEPS steps of DT, each v += (K_P (target - p) - K_V v) DT, then p += DT v (the kernel's q + h v).
    Returns the positions and velocities after each substep, (SUBSTEPS, 2) each."""
    p, v = np.asarray(p, dtype=np.float64), np.asarray(v, dtype=np.float64)
    ps, vs = np.empty((SUBSTEPS, 2)), np.empty((SUBSTEPS, 2))
    for i in range(SUBSTEPS):
        v = v + (K_P * (target - p) - K_V * v) * DT
        p = p + DT * v
        ps[i], vs[i] = p, v
    return ps, vs


def _push_t_bodies():
    """The push_t scene's T and pusher, in gym-pusht's T frame: the bar's top edge's midpoint at the origin, the bar
    y in [0, 30] mm, the stem y in [30, 120] mm (push_t's frame turned by 180 degrees and moved 15 mm)."""
    scene = load_scene(shipped_dir("scenes") / "push_t.toml")   # the shipped T, whatever $PLANAR_LCP_SCENES holds
    t, pusher = scene.body("T"), scene.body("pusher")
    boxes = []
    for s in t.shapes:
        w, h = np.ptp(np.asarray(s.core_vertices_body()), axis=0) + 2.0 * s.radius
        boxes.append((float(w), float(h), -float(s.offset[0]), -float(s.offset[1]) + 0.015))
    return scene, t, boxes, float(pusher.shapes[0].radius)


def t_box_corners():
    """(2, 4, 2) corners (mm) of the T's two boxes in its frame (gym-pusht's), in gym-pusht's keypoint order."""
    _, _, boxes, _ = _push_t_bodies()
    out = []
    for w, h, ox, oy in boxes:
        hw, hh, cx, cy = 500.0 * w, 500.0 * h, 1000.0 * ox, 1000.0 * oy
        out.append([(cx - hw, cy - hh), (cx + hw, cy - hh), (cx + hw, cy + hh), (cx - hw, cy + hh)])
    return np.array(out)


def place_corners(corners, pose):
    """corners (..., 2) of a body frame placed at pose (x, y, angle rad)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    p = corners
    return np.stack([pose[0] + c * p[..., 0] - s * p[..., 1], pose[1] + s * p[..., 0] + c * p[..., 1]], axis=-1)


def coverage(corners, pose, goal):
    """gym-pusht's coverage: the fraction of the goal T's area (at frame pose `goal`) that the T at `pose` covers.
    The two boxes of each T meet only on an edge, so the overlap of the unions is the sum of the boxes' overlaps."""
    import shapely
    t = shapely.polygons(place_corners(corners, pose))
    g = shapely.polygons(place_corners(corners, goal))
    return float(shapely.area(shapely.intersection(t[:, None], g[None, :])).sum() / shapely.area(g).sum())


class PushTEnv(gym.Env):
    """gym-pusht's Push-T (docs/gym.md) on our physics: the T on a table with limit-surface friction.

    Parameters
    ----------
    obs_type : "state" | "environment_state_agent_pos" | "pixels" | "pixels_agent_pos"
    render_mode : "rgb_array"
    table_friction : float
        The T's support friction coefficient (the limit surface of its uniform pressure); push_t's 0.3 by default;
        0 leaves it sliding until it meets something.
    contact_friction : float
        Pusher-T and T-wall Coulomb coefficient; push_t's 0.3 by default (gym-pusht's shapes have 0).
    pusher_max_force : float or None
        The pusher servo's force limit (N; PUSHER_MAX_FORCE); None: a purely prescribed pusher, whose push of the T
        into a wall has no rigid solution (that step takes PGS's uncertified answer, counted in info).
    physics : "planar_lcp" | "gym_pusht"
        The world's model. "planar_lcp" (default): the T on a table with limit-surface friction, velocities kept
        from step to step. "gym_pusht": gym-pusht's own, as its source sets it up: no table friction, frictionless
        contacts, every velocity forgotten at each step (`world.damping = 0`, Chipmunk's `space.damping`), and its
        T's mass properties (the centre of mass at the mean of the two boxes' centroids, PUSHT_COG, and twice the
        bar's moment about the frame origin as the inertia, GYM_PUSHT_INERTIA); table_friction and
        contact_friction default to 0 there.
    random_goal : bool
        Draw the goal pose at every reset (seeded) and put it in the observation (docs/gym.md).
    observation_width, observation_height, visualization_width, visualization_height : int
        The observation image's size (96 x 96) and render()'s (680 x 680), gym-pusht's defaults.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, obs_type="state", render_mode="rgb_array", table_friction=None, contact_friction=None,
                 random_goal=False, pusher_max_force=PUSHER_MAX_FORCE, observation_width=96, observation_height=96,
                 visualization_width=680, visualization_height=680, physics="planar_lcp"):
        super().__init__()
        if physics not in PHYSICS:
            raise ValueError(f"PushT-v0: physics must be one of {', '.join(PHYSICS)}, got {physics!r}")
        self.physics = physics
        gym_world = physics == "gym_pusht"
        if obs_type not in OBS_TYPES:
            raise ValueError(f"PushT-v0: obs_type must be one of {', '.join(OBS_TYPES)}, got {obs_type!r}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"PushT-v0: render_mode must be 'rgb_array' or None, got {render_mode!r}")
        self.obs_type, self.render_mode, self.random_goal = obs_type, render_mode, bool(random_goal)
        scene, t, self.boxes, self.pusher_radius_m = _push_t_bodies()
        self.table_friction = float((0.0 if gym_world else t.support_friction) if table_friction is None
                                    else table_friction)
        self.contact_friction = float((0.0 if gym_world else scene.world.friction) if contact_friction is None
                                      else contact_friction)
        for name, val in (("table_friction", self.table_friction), ("contact_friction", self.contact_friction)):
            if not (math.isfinite(val) and val >= 0.0):
                raise ValueError(f"PushT-v0: {name} must be a finite number >= 0, got {val!r}")
        self.t_mass = float(t.mass)
        self.pusher_max_force = None if pusher_max_force is None else float(pusher_max_force)
        self.model = compile_scene(parse_scene(self._scene_document(), source="PushT-v0"))
        # warm start: each action's ten steps are one rollout, which starts cold, so a step is a pure function of
        # the state and the action (seeded resets reproduce)
        self.sim = Simulator(self.model, SimOptions(h=DT, warm_start=True))
        self.rec = self.sim.recording(SUBSTEPS)
        self.vk_seq = np.zeros((SUBSTEPS, self.model.nkin, 3))
        self.com_local1 = self.model.com_local[:1].copy()
        self.t_corners = t_box_corners()
        self.pusher_radius = 1000.0 * self.pusher_radius_m
        self.obs_raster = Raster(observation_width, observation_height, 0.0, ARENA, 0.0, ARENA)
        self.vis_raster = Raster(visualization_width, visualization_height, 0.0, ARENA, 0.0, ARENA)
        self.action_space = spaces.Box(low=0.0, high=ARENA, shape=(2,), dtype=np.float32)
        self.observation_space = self._observation_space(observation_width, observation_height)
        self._goal = np.array(GOAL_POSE)
        self._last_action = None
        self._background = {}
        self._q = self._v = self._qk = None

    # ---- the scene ----------------------------------------------------------------------------------------------
    def _scene_document(self):
        lo, hi = (WALL_LINES[0] * MM, WALL_LINES[1] * MM)
        th, span = 2 * WALL_HALF * MM, (WALL_LINES[1] - WALL_LINES[0] + 2 * WALL_HALF) * MM
        mid = 0.5 * (lo + hi)
        walls = [{"type": "box", "width": th, "height": span, "offset": [lo, mid]},
                 {"type": "box", "width": th, "height": span, "offset": [hi, mid]},
                 {"type": "box", "width": span, "height": th, "offset": [mid, lo]},
                 {"type": "box", "width": span, "height": th, "offset": [mid, hi]}]
        t_body = {"name": "T", "type": "dynamic", "mass": self.t_mass, "position": [0.256, 0.300],
                  "support_friction": self.table_friction,
                  "shapes": [{"type": "box", "width": w, "height": h, "offset": [ox, oy]} for w, h, ox, oy in
                             self.boxes]}
        world = {"plane": "horizontal", "friction": self.contact_friction}
        if self.physics == "gym_pusht":
            world["damping"] = 0.0
            t_body["center_of_mass"] = [PUSHT_COG[0] * MM, PUSHT_COG[1] * MM]
            t_body["inertia"] = self.t_mass * GYM_PUSHT_INERTIA * MM * MM
        return {
            "name": "push_t_gym", "description": "gym-pusht's arena with the push_t T and pusher (mm -> m)",
            "world": world,
            "sim": {"h": DT},
            "bodies": [
                t_body,
                {"name": "pusher", "type": "kinematic", "position": [0.100, 0.100],
                 "shapes": [{"type": "disk", "radius": self.pusher_radius_m}],
                 **({} if self.pusher_max_force is None else {"max_force": self.pusher_max_force})},
                {"name": "walls", "type": "static", "shapes": walls},
            ]}

    def _observation_space(self, width, height):
        pos = spaces.Box(low=0.0, high=ARENA, shape=(2,), dtype=np.float64)
        goal = spaces.Box(low=np.array([0.0, 0.0, 0.0]), high=np.array([ARENA, ARENA, 2 * np.pi]), dtype=np.float64)
        pixels = spaces.Box(low=0, high=255, shape=(height, width, 3), dtype=np.uint8)
        if self.obs_type == "state":
            hi = [ARENA, ARENA, ARENA, ARENA, 2 * np.pi] + ([ARENA, ARENA, 2 * np.pi] if self.random_goal else [])
            return spaces.Box(low=np.zeros(len(hi)), high=np.array(hi), dtype=np.float64)
        if self.obs_type == "pixels":
            return pixels
        d = {"environment_state": spaces.Box(low=0.0, high=ARENA, shape=(16,), dtype=np.float64)} \
            if self.obs_type == "environment_state_agent_pos" else {"pixels": pixels}
        d["agent_pos"] = pos
        if self.random_goal:
            d["goal"] = goal
        return spaces.Dict(d)

    # ---- state --------------------------------------------------------------------------------------------------
    def block_pose(self):
        """The T's frame pose (x, y mm, angle rad, unwrapped)."""
        f = com_to_frame(self._q[:1], self.com_local1)[0]
        return np.array([f[0] / MM, f[1] / MM, f[2]])

    def agent_pos(self):
        return self._qk[0, :2] / MM

    @staticmethod
    def frame_pose(block):
        """The T's frame pose (x, y mm, angle rad) of `block` = (x, y, angle) read as gym-pusht reads
        reset_to_state: the T's frame put at (x, y) at angle 0, then turned about PUSHT_COG."""
        x, y, a = (float(b) for b in block)
        cx, cy = x + PUSHT_COG[0], y + PUSHT_COG[1]
        c, s = math.cos(a), math.sin(a)
        return np.array([cx - (c * PUSHT_COG[0] - s * PUSHT_COG[1]), cy - (s * PUSHT_COG[0] + c * PUSHT_COG[1]), a])

    def _set_state(self, agent, pose):
        """Place the pusher at `agent` (mm) and the T's frame at `pose` (x, y mm, angle rad). Velocities zero."""
        x, y, a = pose
        self._q = frame_to_com(np.array([[x * MM, y * MM, a]]), self.com_local1)
        self._v = np.zeros((1, 3))
        self._qk = self.model.qk0.copy()
        self._qk[0, :2] = np.asarray(agent, dtype=np.float64) * MM
        self._agent_vel = np.zeros(2)             # the PD law's velocity state, m/s

    def t_world_corners(self, pose):
        """(2, 4, 2) corners (mm) of the T's boxes at frame pose (x, y mm, angle rad)."""
        return place_corners(self.t_corners, pose)

    def why_not_start(self, agent, pose):
        """'' if the pusher is in the arena and the T at these poses overlaps neither it nor the walls, else why."""
        import shapely
        if not (0.0 <= min(agent) and max(agent) <= ARENA):
            return f"the pusher at {np.round(agent, 3).tolist()} is outside the arena (0..{ARENA:g} mm)"
        corners = self.t_world_corners(pose)
        inner0, inner1 = WALL_LINES[0] + WALL_HALF, WALL_LINES[1] - WALL_HALF
        if corners.min() < inner0 or corners.max() > inner1:
            return f"the T at {np.round(pose, 3).tolist()} crosses the walls (inside is {inner0:g}..{inner1:g} mm)"
        t = shapely.union_all(shapely.polygons(corners))
        if shapely.distance(t, shapely.points(*agent)) < self.pusher_radius:
            return f"the pusher at {np.round(agent, 3).tolist()} overlaps the T at {np.round(pose, 3).tolist()}"
        return ""

    def coverage(self):
        """The fraction of the goal T's area that the T covers (gym-pusht's coverage)."""
        return coverage(self.t_corners, self.block_pose(), self._goal)

    # ---- gymnasium ----------------------------------------------------------------------------------------------
    #: reset(options=...)'s keys
    RESET_OPTIONS = ("reset_to_state", "goal")

    def _reset_options(self, options):
        """The start (agent mm, T frame pose) and the goal of reset's options, each None when not given, checked
        before anything changes: a ValueError names the option, what it must be and what it got."""
        options = options_dict("PushT-v0", options, self.RESET_OPTIONS)
        start = goal = None
        if options.get("reset_to_state") is not None:
            state = finite_array(options["reset_to_state"])
            if state is None or state.shape != (5,):
                raise ValueError("PushT-v0: options['reset_to_state'] must be 5 finite numbers (agent x, y, block x, "
                                 f"y mm, angle rad), got {shown(options['reset_to_state'])}")
            start = (state[:2], self.frame_pose(state[2:]))
            why = self.why_not_start(*start)
            if why:
                raise ValueError(f"PushT-v0: options['reset_to_state'] = {state.tolist()} is not a start state: "
                                 f"{why}")
        if options.get("goal") is not None:
            goal = finite_array(options["goal"])
            if goal is None or goal.shape != (3,):
                raise ValueError(f"PushT-v0: options['goal'] must be 3 finite numbers (x, y mm, angle rad), got "
                                 f"{shown(options['goal'])}")
            c = self.t_world_corners(goal)
            inner0, inner1 = WALL_LINES[0] + WALL_HALF, WALL_LINES[1] - WALL_HALF
            if c.min() < inner0 or c.max() > inner1:
                raise ValueError(f"PushT-v0: options['goal'] must place the T inside the walls (its corners within "
                                 f"{inner0:g}..{inner1:g} mm), got {goal.tolist()} (corners within "
                                 f"{c.min():.4g}..{c.max():.4g} mm)")
        return start, goal

    def reset(self, *, seed=None, options=None):
        start, goal = self._reset_options(options)           # before anything changes
        super().reset(seed=seed)
        rng = self.np_random
        # the start first: gym-pusht's draws in its order, so that a seed gives its start state (random goal or not)
        if start is not None:
            self._set_state(*start)
        else:
            while True:           # gym-pusht's draws; a draw with overlaps is drawn again (docs/gym.md)
                state = np.array([rng.integers(50, 450), rng.integers(50, 450), rng.integers(100, 400),
                                  rng.integers(100, 400), rng.uniform(-np.pi, np.pi)], dtype=np.float64)
                pose = self.frame_pose(state[2:])
                if not self.why_not_start(state[:2], pose):
                    self._set_state(state[:2], pose)
                    break
        if goal is None and self.random_goal:
            while True:
                goal = np.array([rng.uniform(100, 400), rng.uniform(100, 400), rng.uniform(-np.pi, np.pi)])
                c = self.t_world_corners(goal)
                if c.min() >= WALL_LINES[0] + WALL_HALF and c.max() <= WALL_LINES[1] - WALL_HALF:
                    break
        elif goal is None:
            goal = np.array(GOAL_POSE)
        self._goal = goal
        self._last_action = None
        self.failed_steps = 0
        info = self._info()
        info["is_success"] = False
        return self._obs(), info

    def step(self, action):
        # checked before anything changes; a target outside the action space is clipped to it (the arena)
        target = np.clip(checked_action("PushT-v0", action, "the pusher's target x, y in mm"), 0.0, ARENA)
        self._last_action = target
        self.advance(target)
        cover = self.coverage()
        reward = float(np.clip(cover / SUCCESS_COVER, 0.0, 1.0))
        success = cover > SUCCESS_COVER
        info = self._info()
        info["is_success"], info["coverage"] = success, cover
        return self._obs(), reward, success, False, info

    def advance(self, target):
        """The physics of one action: the PD law's ten substeps towards `target` (x, y mm, unchecked), one rollout.
        What step() does before it scores and observes; a policy's model calls it directly (planners.pusht)."""
        target = np.asarray(target, dtype=np.float64) * MM
        # the pusher is kinematic, so its path over the ten substeps follows from the PD law alone: computed here,
        # then the ten steps are one rollout. Position update as the kernel's (q + h v), so the PD law sees the
        # positions the simulation has
        _, vs = pd_substeps(self._qk[0, :2], self._agent_vel, target)
        vk = self.vk_seq
        vk[:, 0, 0:2] = vs
        v = vs[-1].copy()
        rec = self.rec
        done = self.sim.rollout_into(rec, self._q, self._v, self._qk, vk, stop_on_failure=False)
        self.failed_steps = int(np.count_nonzero(rec.status))
        if not np.isfinite(rec.q[done]).all():
            from planar_lcp.sim import SimulationError
            raise SimulationError(f"PushT-v0: the physics gave a non-finite state from {self._state_summary()}")
        self._q, self._v, self._qk = rec.q[done].copy(), rec.v[done].copy(), rec.qk[done].copy()
        self._agent_vel = v

    def set_state(self, agent, agent_velocity, pose):
        """Put the pusher at `agent` (mm) moving at `agent_velocity` (mm/s, the PD law's state) and the T's frame at
        `pose` (x, y mm, angle rad), the T at rest; no checks (a policy's model: planners.pusht)."""
        self._set_state(agent, pose)
        self._agent_vel = np.asarray(agent_velocity, dtype=np.float64) * MM

    def _state_summary(self):
        return f"agent {np.round(self.agent_pos(), 3).tolist()} mm, block {np.round(self.block_pose(), 4).tolist()}"

    def _info(self):
        return {"pos_agent": self.agent_pos(), "vel_agent": self._agent_vel / MM, "block_pose": self.block_pose(),
                "goal_pose": self._goal.copy(), "failed_physics_steps": self.failed_steps}

    def _goal_obs(self):
        return np.array([self._goal[0], self._goal[1], self._goal[2] % (2 * np.pi)])

    def _obs(self):
        if self.obs_type == "state":
            b = self.block_pose()
            obs = [self.agent_pos(), b[:2], [b[2] % (2 * np.pi)]] + ([self._goal_obs()] if self.random_goal else [])
            return np.concatenate(obs).astype(np.float64)
        if self.obs_type == "pixels":
            return self._draw(self.obs_raster)
        d = {"environment_state": self.t_world_corners(self.block_pose()).reshape(16)} \
            if self.obs_type == "environment_state_agent_pos" else {"pixels": self._draw(self.obs_raster)}
        d["agent_pos"] = self.agent_pos()
        if self.random_goal:
            d["goal"] = self._goal_obs()
        return d

    def _draw(self, r, action=False):
        # the goal and the walls change only at a reset: drawn once per reset and raster
        key = (id(r), self._goal.tobytes())
        if self._background.get(id(r), (None,))[0] != key:
            self._background[id(r)] = (key, self._draw_background(r))
        img = self._background[id(r)][1].copy()
        r.disk(img, self.agent_pos(), self.pusher_radius, ROYAL_BLUE)
        for box in self.t_world_corners(self.block_pose()):     # the T over the pusher, as gym-pusht draws them
            r.convex(img, box, SLATE_GRAY)
        if action and self._last_action is not None:
            r.cross(img, self._last_action, 8 / 96 * min(r.width, r.height), RED)
        return img

    def _draw_background(self, r):
        img = r.blank(WHITE)
        for box in self.t_world_corners(self._goal):
            r.convex(img, box, LIGHT_GREEN)
        # the walls at least a pixel thick, so that a 96-pixel image shows them as gym-pusht's (resized) does
        w = max(WALL_HALF, 0.5 * ARENA / min(r.width, r.height))
        lo, hi = WALL_LINES[0] - w, WALL_LINES[1] + w
        for a, b in (((lo, lo), (hi, lo + 2 * w)), ((lo, hi - 2 * w), (hi, hi)),
                     ((lo, lo), (lo + 2 * w, hi)), ((hi - 2 * w, lo), (hi, hi))):
            r.convex(img, [a, (b[0], a[1]), b, (a[0], b[1])], LIGHT_GRAY)
        return img

    def render(self):
        if self.render_mode is None:
            return None
        return self._draw(self.vis_raster, action=True)
