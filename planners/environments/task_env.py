"""`planar_lcp/Task-v0` (docs/gym.md, "Task-v0"): any task file as a Gymnasium environment, the planner's state as
the observation and the pusher's velocity as the action, held for the task's step duration exactly as the planner
propagates it (TaskModel.advance)."""

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from planar_lcp.spec.scene import shipped_dir

from .inputs import checked_action, finite_array, options_dict, shown
from .push_t import LIGHT_GREEN, ROYAL_BLUE, SLATE_GRAY, WHITE
from .raster import Raster

#: where the benchmark's task files live (tasks/*.toml, shipped with the package), so that Task-v0 takes their names as
#: well as the shipped tasks'
TASKS_DIR = shipped_dir("tasks")


def task_source(task):
    """A shipped task's name, a tasks/ file's name (tasks/NAME.toml), a path, TOML text, a dict or a Task: what
    load_task takes."""
    from planar_lcp.spec.task import shipped_tasks
    if isinstance(task, str) and "\n" not in task and not task.endswith(".toml") and "/" not in task \
            and task not in shipped_tasks() and (TASKS_DIR / f"{task}.toml").is_file():
        return TASKS_DIR / f"{task}.toml"
    return task


class TaskEnv(gym.Env):
    """Any task file as an environment (docs/gym.md, "Task-v0").

    Observation: the planner's flat state (planners.tasks: the object's and each obstacle's centre-of-mass pose and
    velocity, then the pusher's position; m, rad, m/s, rad/s). Action: the pusher's velocity (vx, vy) m/s within the
    task's control_max per axis, held for task.step_duration (TaskModel.advance, as the planner propagates it).
    Reward: -goal_distance (the task's own metric, <= 1 where the goal holds). Terminated when the goal holds (or a
    physics step fails: info["sim_ok"] False); truncated at `time_limit` seconds of simulated time.

    Parameters
    ----------
    task : str, path, dict or Task
        A shipped task's name, a name in tasks/, a path to a task file, its TOML text or a dict.
    time_limit : float
        Seconds of simulated time per episode (default 20 s).
    render_mode : "rgb_array" or None
    render_size : int
        render()'s width in pixels (the height follows the drawn region's aspect).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, task, time_limit=20.0, render_mode="rgb_array", render_size=512):
        super().__init__()
        from ..tasks import TaskModel
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"Task-v0: render_mode must be 'rgb_array' or None, got {render_mode!r}")
        if not (isinstance(time_limit, (int, float)) and math.isfinite(time_limit) and time_limit > 0):
            raise ValueError(f"Task-v0: time_limit must be a number of seconds > 0, got {time_limit!r}")
        self.tm = tm = TaskModel(task_source(task))
        self.task = tm.task
        self.render_mode = render_mode
        self.max_steps = max(1, int(math.ceil(time_limit / self.task.step_duration - 1e-9)))
        self.metadata = {**self.metadata, "render_fps": max(1, int(round(1.0 / self.task.step_duration)))}
        cm = self.task.control_max
        self.action_space = spaces.Box(low=-cm, high=cm, shape=(2,), dtype=np.float32)
        self.observation_space = spaces.Box(low=-np.inf, high=np.inf, shape=(self.task.state_dim,), dtype=np.float64)
        self._x0 = tm.initial_state()
        self._x = self._x0.copy()
        self._n = 0
        self._render_size = int(render_size)
        self._drawing = None

    def reset(self, *, seed=None, options=None):
        state = options_dict("Task-v0", options, ("state",)).get("state")       # checked before anything changes
        if state is not None:
            x = finite_array(state)
            if x is None or x.shape != self._x0.shape:
                raise ValueError(f"Task-v0: options['state'] must be {self._x0.size} finite numbers "
                                 f"({', '.join(self.task.state_names())}), got {shown(state, 400)}")
        super().reset(seed=seed)
        self._x = self._x0.copy() if state is None else x.copy()
        self._n = 0
        d = self.tm.goal_distance(self._x)
        return self._x.copy(), {"goal_distance": d, "is_success": d <= 1.0, "sim_ok": True,
                                "admissible": self.tm.admissible(self._x)}

    def step(self, action):
        cm = self.task.control_max
        # checked before anything changes; beyond the action space clipped to it
        u = np.clip(checked_action("Task-v0", action, "the pusher's velocity vx, vy in m/s"), -cm, cm)
        x, ok = self.tm.advance(self._x, u, self.tm.steps_per_prop)
        self._n += 1
        if ok:
            self._x = x
        d = self.tm.goal_distance(self._x)
        success = ok and d <= 1.0
        info = {"goal_distance": d, "is_success": success, "sim_ok": ok, "admissible": self.tm.admissible(self._x)}
        return self._x.copy(), -float(d), bool(success or not ok), bool(self._n >= self.max_steps), info

    # ---- drawing ------------------------------------------------------------------------------------------------
    def _setup_drawing(self):
        import shapely
        from shapely.ops import unary_union

        from planar_lcp.geometry import shape_geometry
        tm, t = self.tm, self.task
        (wx0, wx1), (wy0, wy1) = t.workspace
        (px0, px1), (py0, py1) = t.pusher_workspace
        x0, x1, y0, y1 = min(wx0, px0), max(wx1, px1), min(wy0, py0), max(wy1, py1)
        width = self._render_size
        height = max(1, int(round(width * (y1 - y0) / (x1 - x0))))
        r = Raster(width, height, x0, x1, y0, y1, y_down=False)
        gx, gy = r.grid()
        X, Y = np.meshgrid(gx, gy)
        bodies = [unary_union([shape_geometry(s, quad_segs=8) for s in t.scene.body(n).shapes])
                  for n in (t.object, *t.obstacles)]
        statics = np.zeros(X.shape, dtype=bool)
        if tm.statics is not None:
            shapely.prepare(tm.statics)
            statics = shapely.contains_xy(tm.statics, X, Y)
        goal = np.zeros(X.shape, dtype=bool)
        if tm.goal_poly is not None:
            goal = shapely.contains_xy(tm.goal_poly, X, Y)
        # a timed task's moving bodies (body frame), drawn where they are at the state's time
        moving = [unary_union([shape_geometry(s, quad_segs=8) for s in t.scene.body(n).shapes]) for n in t.moving]
        self._drawing = (r, X, Y, bodies, statics, goal, moving)

    def render(self):
        if self.render_mode is None:
            return None
        import shapely

        from planar_lcp.frames import com_to_frame as to_frame
        from ..tasks import _place
        if self._drawing is None:
            self._setup_drawing()
        r, X, Y, bodies, statics, goal, moving = self._drawing
        tm, x = self.tm, self._x
        img = r.blank(WHITE)
        img[goal] = LIGHT_GREEN
        img[statics] = (90, 90, 90)
        if moving:
            for g, (bx, by, ba) in zip(moving, tm.moving_poses(x)):
                img[shapely.contains_xy(_place(g, (bx, by), ba), X, Y)] = (90, 90, 90)
        for i, g in enumerate(bodies):
            d = tm.dyn_order[i]
            pf = to_frame(x[6 * i:6 * i + 3][None], tm.model.com_local[d:d + 1])[0]
            color = SLATE_GRAY if i == 0 else (205, 133, 63)
            img[shapely.contains_xy(_place(g, pf[:2], pf[2]), X, Y)] = color
        g = self.task.goal
        if tm.goal_poly is None and g.x is not None and g.y is not None:
            r.cross(img, (g.x, g.y), max(5, r.width // 40), (0, 150, 0))
        r.disk(img, x[tm.ip:tm.ip + 2], tm.pusher_radius, ROYAL_BLUE)
        return img
