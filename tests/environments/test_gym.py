"""The Gymnasium environments (planners/environments/, docs/gym.md): planar_lcp/PushT-v0 and planar_lcp/Task-v0.

Checked by Gymnasium's own env_checker, against analytic oracles (gym-pusht's reset geometry, the PD law, the
coverage of shifted Ts, the table's deceleration bound, momentum without friction), against the planner's own
propagation (Task-v0), and side by side with gym-pusht itself in its own virtualenv (PLANAR_LCP_PUSHT_PYTHON).
"""

import json
import math
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
pytest.importorskip("shapely")

import planners  # noqa: E402  (registers the environments)
from planners.environments.push_t import GOAL_POSE, K_P, K_V, OBS_TYPES  # noqa: E402
from planners.environments.task_env import TASKS_DIR  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
ALL_TASKS = planners.shipped_tasks() + sorted(p.stem for p in TASKS_DIR.glob("*.toml"))


def check(env):
    from gymnasium.utils.env_checker import check_env
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=False)
    # the checker's advice that is a design choice (docs/gym.md): gym-pusht's [0, 512] action box; Task-v0's
    # unbounded state; anything else it warns about is a defect
    advice = ("symmetric and normalized", "minimum value is -infinity", "maximum value is infinity")
    return [str(w.message) for w in caught if not any(a in str(w.message) for a in advice)]


# ---- registration -------------------------------------------------------------------------------------------------
def test_import_planners_registers_both_ids_without_importing_ompl_or_the_envs():
    code = ("import sys, gymnasium, planners; "
            "assert 'planar_lcp/PushT-v0' in gymnasium.registry and 'planar_lcp/Task-v0' in gymnasium.registry; "
            "assert gymnasium.registry['planar_lcp/PushT-v0'].max_episode_steps == 300; "
            "assert 'ompl' not in sys.modules and 'planners.environments.push_t' not in sys.modules and 'planners.environments.task_env' not in sys.modules; print('ok')")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr


def test_import_planners_works_without_gymnasium():
    code = ("import sys; sys.modules['gymnasium'] = None; import planners; "
            "t = planners.load_task('push_box'); print(t.name)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "push_box", r.stderr


# ---- PushT-v0: Gymnasium's checks and gym-pusht's interface --------------------------------------------------------
@pytest.mark.parametrize("obs_type", OBS_TYPES)
def test_pusht_passes_gymnasiums_env_checker(obs_type):
    env = gym.make("planar_lcp/PushT-v0", obs_type=obs_type)
    assert check(env) == []
    env.reset(seed=0)
    assert env.render().shape == (680, 680, 3)


@pytest.mark.parametrize("obs_type", ["state", "environment_state_agent_pos", "pixels_agent_pos"])
def test_pusht_random_goal_passes_the_checker_and_is_in_the_observation(obs_type):
    env = gym.make("planar_lcp/PushT-v0", obs_type=obs_type, random_goal=True)
    assert check(env) == []
    obs, info = env.reset(seed=4)
    goal = obs[5:] if obs_type == "state" else obs["goal"]
    assert np.allclose(goal[:2], info["goal_pose"][:2]) and not np.allclose(info["goal_pose"], GOAL_POSE)
    assert math.isclose(goal[2], info["goal_pose"][2] % (2 * math.pi))
    # the start is drawn before the goal: the same start as without a random goal
    _, plain = gym.make("planar_lcp/PushT-v0").reset(seed=4)
    assert np.array_equal(info["pos_agent"], plain["pos_agent"])
    assert np.array_equal(info["block_pose"], plain["block_pose"])


def test_pusht_spaces_are_gym_pushts():
    shapes = {"state": (5,), "pixels": (96, 96, 3)}
    for ot in OBS_TYPES:
        env = gym.make("planar_lcp/PushT-v0", obs_type=ot)
        sp = env.observation_space
        assert env.action_space.shape == (2,) and env.action_space.dtype == np.float32
        assert float(env.action_space.low[0]) == 0.0 and float(env.action_space.high[0]) == 512.0
        if ot in shapes:
            assert sp.shape == shapes[ot]
            assert sp.dtype == (np.uint8 if ot == "pixels" else np.float64)
        else:
            key = "environment_state" if ot == "environment_state_agent_pos" else "pixels"
            assert set(sp.spaces) == {key, "agent_pos"}
            assert sp[key].shape == ((16,) if key == "environment_state" else (96, 96, 3))
        assert env.spec.max_episode_steps == 300


def test_pusht_bad_input_is_one_clear_error():
    with pytest.raises(ValueError, match="obs_type must be one of state, environment_state_agent_pos"):
        gym.make("planar_lcp/PushT-v0", obs_type="keypoints")
    env = gym.make("planar_lcp/PushT-v0")
    with pytest.raises(ValueError, match=r"reset_to_state.*must be 5 finite numbers"):
        env.reset(options={"reset_to_state": [1, 2, 3]})
    with pytest.raises(ValueError, match="overlaps the T"):
        env.reset(options={"reset_to_state": [256, 260, 256, 256 - 45, 0.0]})
    with pytest.raises(ValueError, match="crosses the walls"):
        env.reset(options={"reset_to_state": [100, 100, 10, 300, 0.0]})
    with pytest.raises(ValueError, match="table_friction must be a finite number >= 0"):
        gym.make("planar_lcp/PushT-v0", table_friction=-1.0)


def test_reset_to_state_turns_the_t_about_gym_pushts_centre_of_gravity():
    # gym-pusht puts the T's frame at (x, y) at angle 0, then turns it about its frame point (0, 45) (pymunk keeps
    # the centre of gravity when the angle is set): the frame ends at (x + 45 sin a, y + 45 - 45 cos a)
    env = gym.make("planar_lcp/PushT-v0")
    a = 1.0
    obs, info = env.reset(options={"reset_to_state": [100.0, 100.0, 250.0, 250.0, a]})
    assert np.allclose(obs, [100.0, 100.0, 250.0 + 45 * math.sin(a), 250.0 + 45 - 45 * math.cos(a), a], atol=1e-9)
    # the keypoints: gym-pusht's order (bar 0-3 from its top left, then the stem's), at angle 0
    env = gym.make("planar_lcp/PushT-v0", obs_type="environment_state_agent_pos")
    obs, _ = env.reset(options={"reset_to_state": [100.0, 100.0, 256.0, 211.0, 0.0]})
    want = [[196, 211], [316, 211], [316, 241], [196, 241], [241, 241], [271, 241], [271, 331], [241, 331]]
    assert np.allclose(obs["environment_state"].reshape(8, 2), want, atol=1e-9)
    assert np.allclose(obs["agent_pos"], [100.0, 100.0])


def test_seeded_reset_draws_gym_pushts_start_states():
    # gymnasium seeds np_random with PCG64(SeedSequence(seed)), gym-pusht draws (integers(50, 450) x 2,
    # integers(100, 400) x 2, uniform(-pi, pi)): the same start as gym-pusht's for the same seed, unless the draw
    # overlaps (drawn again, docs/gym.md)
    env = gym.make("planar_lcp/PushT-v0")
    same = 0
    for seed in range(8):
        rng = np.random.default_rng(seed)
        s = [rng.integers(50, 450), rng.integers(50, 450), rng.integers(100, 400), rng.integers(100, 400),
             rng.uniform(-np.pi, np.pi)]
        obs, _ = env.reset(seed=seed)
        env2 = gym.make("planar_lcp/PushT-v0")
        try:
            want, _ = env2.reset(options={"reset_to_state": s})
        except ValueError:
            continue
        assert np.array_equal(obs, want)
        same += 1
    assert same >= 4


@pytest.mark.parametrize("obs_type", ["state", "pixels_agent_pos"])
def test_seeded_resets_reproduce_bit_for_bit(obs_type):
    def run(seed):
        env = gym.make("planar_lcp/PushT-v0", obs_type=obs_type, random_goal=True)
        out = [env.reset(seed=seed)[0]]
        env.action_space.seed(seed)
        for _ in range(12):
            out.append(env.step(env.action_space.sample())[0])
        return out

    def flat(o):
        return np.concatenate([np.ravel(v).astype(float) for v in (o.values() if isinstance(o, dict) else [o])])

    a, b, c = run(7), run(7), run(8)
    assert all(np.array_equal(flat(x), flat(y)) for x, y in zip(a, b))
    assert not np.array_equal(flat(a[0]), flat(c[0]))


def test_pusher_follows_gym_pushts_pd_law_away_from_the_t():
    # far from the T the pusher's path is the PD law's alone: v += (k_p (target - p) - k_v v) dt; p += dt v
    env = gym.make("planar_lcp/PushT-v0")
    obs, _ = env.reset(options={"reset_to_state": [60.0, 450.0, 300.0, 150.0, 0.0]})
    p, v = np.array([60.0, 450.0]), np.zeros(2)
    for target in ([120.0, 430.0], [150.0, 400.0], [150.0, 400.0]):
        obs, *_ = env.step(np.array(target, dtype=np.float32))
        for _ in range(10):
            v = v + (K_P * (np.array(target) - p) - K_V * v) * 0.01
            p = p + 0.01 * v
        assert np.allclose(obs[:2], p, atol=1e-9)
        assert np.array_equal(obs[2:4], [300.0, 150.0])      # the T untouched


def test_coverage_and_reward_of_a_shifted_t():
    # the T at the goal shifted by d mm along the bar (angle 0): the bar overlaps (120 - d) 30, the stem (30 - d) 90
    env = gym.make("planar_lcp/PushT-v0").unwrapped
    for d in (0.0, 3.0, 10.0, 25.0):
        env.reset(options={"goal": [250.0, 200.0, 0.0], "reset_to_state": [60.0, 60.0, 250.0 + d, 200.0, 0.0]})
        want = ((120 - d) * 30 + (30 - d) * 90) / (120 * 30 + 30 * 90)
        assert math.isclose(env.coverage(), want, rel_tol=1e-12)
        _, reward, terminated, _, info = env.step(np.array([60.0, 60.0], dtype=np.float32))
        assert math.isclose(info["coverage"], want, rel_tol=1e-12)
        assert math.isclose(reward, min(want / 0.95, 1.0), rel_tol=1e-12)
        assert terminated == (want > 0.95) == info["is_success"]


def test_the_table_stops_the_t_as_mu_g_says_and_without_it_the_t_coasts():
    # a push up the stem, then the pusher pulled away. Out of contact the table's force on the T is at most mu m g
    # (the limit surface), exactly mu m g against the velocity in pure translation (this straight push): each 0.01 s
    # step takes mu g h off the speed until it stops, so it slides h sum_k max(v0 - k mu g h, 0). Without table
    # friction the T keeps its velocity exactly.
    start = [256.0, 400.0, 256.0, 255.0, 0.0]           # the stem's tip at y = 375, the pusher 10 mm below it
    g, h = 9.81, 0.01
    for mu in (0.05, 0.0):
        env = gym.make("planar_lcp/PushT-v0", table_friction=mu).unwrapped
        env.reset(options={"reset_to_state": start})
        for _ in range(2):
            env.step(np.array([256.0, 330.0], dtype=np.float32))
        env.step(np.array([256.0, 505.0], dtype=np.float32))     # away: out of contact after this action
        assert env.agent_pos()[1] - env.t_world_corners(env.block_pose())[:, :, 1].max() > 15.0
        q0, v0 = env._q.copy(), env._v.copy()
        speed = math.hypot(*v0[0, :2])
        assert speed > 0.1
        for _ in range(5):
            env.step(np.array([256.0, 505.0], dtype=np.float32))
        dist = math.hypot(*(env._q[0, :2] - q0[0, :2]))
        if mu > 0:
            assert np.abs(env._v).max() < 1e-12
            slide = h * sum(max(speed - k * mu * g * h, 0.0) for k in range(1, 1000))
            assert math.isclose(dist, slide, rel_tol=1e-9)
        else:
            assert np.allclose(env._v, v0, rtol=0, atol=1e-15)
            assert math.isclose(dist, 0.5 * speed, rel_tol=1e-9)


def test_make_vec_sync_and_async_run():
    for mode in ("sync", "async"):
        envs = gym.make_vec("planar_lcp/PushT-v0", num_envs=2, vectorization_mode=mode)
        try:
            obs, _ = envs.reset(seed=3)
            assert obs.shape == (2, 5)
            for _ in range(3):
                obs, reward, term, trunc, info = envs.step(envs.action_space.sample())
            assert obs.shape == (2, 5) and reward.shape == (2,)
        finally:
            envs.close()
    envs = gym.make_vec("planar_lcp/Task-v0", num_envs=2, vectorization_mode="async", task="push_box")
    try:
        obs, _ = envs.reset(seed=0)
        obs, reward, *_ = envs.step(np.zeros((2, 2), dtype=np.float32))
        assert obs.shape == (2, 8) and np.array_equal(obs[0], obs[1])
    finally:
        envs.close()


# ---- Task-v0 ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("task", ALL_TASKS)
def test_task_env_passes_gymnasiums_env_checker_on_every_shipped_task(task):
    env = gym.make("planar_lcp/Task-v0", task=task)
    assert check(env) == []
    env.reset(seed=0)
    img = env.render()
    assert img.dtype == np.uint8 and img.shape[1] == 512 and img.shape[2] == 3 and len(np.unique(img)) > 3


def test_task_env_steps_are_the_planners_propagations():
    from planners.tasks import TaskModel
    env = gym.make("planar_lcp/Task-v0", task="push_t")
    tm = TaskModel("push_t")
    x, _ = env.reset(seed=0)
    assert np.array_equal(x, tm.initial_state())
    rng = np.random.default_rng(1)
    for _ in range(8):
        u = rng.uniform(-0.15, 0.15, 2).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(u)
        x, ok = tm.advance(x, np.asarray(u, dtype=np.float64), tm.steps_per_prop)
        assert ok and np.array_equal(obs, x)
        assert reward == -tm.goal_distance(x) and info["goal_distance"] == tm.goal_distance(x)


def test_task_env_terminates_at_the_goal_and_truncates_at_its_time_limit():
    from planners.tasks import TaskModel
    tm = TaskModel("push_box")
    rng = np.random.default_rng(0)
    x = tm.sample_goal(lambda lo, hi: rng.uniform(lo, hi))
    env = gym.make("planar_lcp/Task-v0", task="push_box")
    obs, info = env.reset(options={"state": x})
    assert info["is_success"]
    obs, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and info["is_success"] and reward >= -1.0
    env = gym.make("planar_lcp/Task-v0", task="push_box", time_limit=0.3)
    env.reset()
    flags = [env.step(np.zeros(2, dtype=np.float32))[3] for _ in range(3)]
    assert flags == [False, False, True]


def test_task_env_takes_a_path_and_a_tasks_folder_name():
    a = gym.make("planar_lcp/Task-v0", task="push_l").unwrapped
    b = gym.make("planar_lcp/Task-v0", task=str(TASKS_DIR / "push_l.toml")).unwrapped
    assert a.task.sha256 == b.task.sha256
    with pytest.raises(planners.TaskError, match="unknown task 'no_such_task'"):
        gym.make("planar_lcp/Task-v0", task="no_such_task")
    with pytest.raises(ValueError, match="time_limit must be a number of seconds > 0"):
        gym.make("planar_lcp/Task-v0", task="push_box", time_limit=0)


# ---- side by side with gym-pusht ----------------------------------------------------------------------------------
def pusht_python():
    exe = os.environ.get("PLANAR_LCP_PUSHT_PYTHON")
    if not exe or not Path(exe).is_file():
        pytest.skip("gym-pusht's interpreter not given: set PLANAR_LCP_PUSHT_PYTHON to the python of a virtualenv "
                    "with gym-pusht==0.1.8 (docs/gym.md)")
    return exe


def test_raster_fills_exactly_the_pixel_centres_inside_each_shape():
    # oracle: shapely's point-in-polygon at every pixel centre, and the disk's distance test
    import shapely
    from shapely.geometry import MultiPoint

    from planners.environments.raster import Raster
    rng = np.random.default_rng(0)
    for y_down in (True, False):
        r = Raster(37, 29, -1.0, 2.0, 0.5, 3.0, y_down=y_down)
        gx, gy = r.grid()
        X, Y = np.meshgrid(gx, gy)
        for _ in range(20):
            hull = MultiPoint(rng.uniform([-1.5, 0.0], [2.5, 3.5], (6, 2))).convex_hull
            verts = np.array(hull.exterior.coords)[:-1]
            if rng.random() < 0.5:
                verts = verts[::-1]                              # either winding
            img = r.blank((0, 0, 0))
            r.convex(img, verts, (255, 0, 0))
            want = shapely.contains_xy(hull, X, Y)
            # a centre within rounding of an edge may go either way; none does here
            assert np.all(shapely.distance(hull.exterior, shapely.points(X, Y)) > 1e-9)
            assert np.array_equal(img[..., 0] == 255, want)
        c, rad = rng.uniform([-0.5, 1.0], [1.5, 2.5]), 0.7
        img = r.blank((0, 0, 0))
        r.disk(img, c, rad, (0, 255, 0))
        assert np.array_equal(img[..., 1] == 255, (X - c[0]) ** 2 + (Y - c[1]) ** 2 <= rad ** 2)


# ---- docs/gym.md's commands, end to end -----------------------------------------------------------------------
GYM_MD = (ROOT / "docs" / "gym.md").read_text()


def run(args, python=sys.executable, timeout=600, **kw):
    return subprocess.run([python, *args], capture_output=True, text=True, cwd=ROOT, timeout=timeout, **kw)


def test_the_python_example_of_gym_md_runs(tmp_path):
    import re
    code = re.findall(r"```python\n(.*?)```", GYM_MD, re.S)[0]
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert r.returncode == 0, r.stderr


#: the numbers docs/gym.md quotes are the compiled kernels': without the JIT the steps round differently, and 300
#: actions of pushing carry a rounding difference into a different push (0.318 instead of 0.777 at the end)
COMPILED_NUMBERS = pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT", "0") == "1",
                                      reason="docs/gym.md quotes the compiled kernels' numbers; without the JIT the "
                                             "steps round differently and a long push ends elsewhere")


@COMPILED_NUMBERS
def test_the_scripted_policy_command_prints_what_gym_md_says(tmp_path):
    out = tmp_path / "pusht_policy.gif"
    r = run(["examples/gym_pusht_policy.py", "--seed", "0", "--steps", "300", "--out", str(out)])
    assert r.returncode == 0, r.stderr
    documented = ("seed 0: cover 0.266 at the start, 0.777 after 300 actions (no success); wrote "
                  "docs/figures/gym/pusht_policy.gif (301 frames)")
    assert "python examples/gym_pusht_policy.py --seed 0 --steps 300 --out docs/figures/gym/pusht_policy.gif" in GYM_MD
    assert " ".join(GYM_MD.split()).count(documented) == 1
    assert r.stdout.strip() == documented.replace("docs/figures/gym/pusht_policy.gif", str(out))
    from PIL import Image, ImageSequence
    with Image.open(out) as im:
        # Pillow merges repeated frames into one of the summed duration: 301 frames of 0.1 s
        assert im.size == (256, 256) and im.n_frames > 100
        assert sum(f.info["duration"] for f in ImageSequence.Iterator(im)) == 301 * 100


def test_the_gym_commands_fail_in_one_line_without_gym_pusht():
    env = {k: v for k, v in os.environ.items() if k != "PLANAR_LCP_PUSHT_PYTHON"}
    r = run(["examples/measurements/gym_side_by_side.py"], env=env)
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "--pusht-python (or $PLANAR_LCP_PUSHT_PYTHON) must name the python" in r.stderr
    try:
        import gym_pusht  # noqa: F401
    except ImportError:
        r = run(["examples/measurements/gym_speed.py", "--rounds", "1"])
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and "gym_pusht is not importable" in r.stderr


@COMPILED_NUMBERS
def test_side_by_side_with_gym_pusht_prints_gym_mds_table(tmp_path):
    """The same start states and actions in gym-pusht (its own virtualenv) and here: the pusher paths agree to
    rounding, the starts exactly, and the table in docs/gym.md is this command's output."""
    py = pusht_python()
    js = tmp_path / "sbs.json"
    r = run(["examples/measurements/gym_side_by_side.py", "--pusht-python", py, "--json", str(js)])
    assert r.returncode == 0, r.stderr
    start = GYM_MD.index("<!-- side-by-side table: the command's output (tests/environments/test_gym.py checks it) -->\n")
    start = GYM_MD.index("\n", start) + 1
    documented = GYM_MD[start:GYM_MD.index("<!-- end of the side-by-side table -->")]
    assert r.stdout.strip() == documented.strip()
    data = json.loads(js.read_text())
    for ep in data["episodes"]:
        theirs = np.array(ep["gym_pusht"]["state"])
        for setting, mine in ep["ours"].items():
            mine = np.array(mine["state"])
            assert np.array_equal(mine[0], theirs[0]) or np.allclose(mine[0], theirs[0], rtol=0, atol=1e-9)
            assert np.abs(mine[:, :2] - theirs[:, :2]).max() < 1e-9        # the pusher: the same PD law
        # gym-pusht's physics in our engine follows its T along every episode
        mine = np.array(ep["ours"]["ours, gym-pusht's physics"]["state"])
        assert np.abs(mine[:, 2:4] - theirs[:, 2:4]).max() < 2.0, ep["name"]            # mm
        assert np.abs(mine[:, 4] - theirs[:, 4]).max() < np.radians(1.0), ep["name"]


def test_speed_command_runs_beside_gym_pusht():
    py = pusht_python()
    probe = run(["-c", "import planners, gym_pusht"], python=py)
    if probe.returncode != 0:
        pytest.skip(f"planar_lcp is not installed in gym-pusht's virtualenv {py} (docs/gym.md, 'Speed')")
    r = run(["examples/measurements/gym_speed.py", "--rounds", "2", "--steps", "20"], python=py)
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("ours / gym-pusht steps per second: median") == 2
    assert "/work/venv_pusht/bin/python examples/measurements/gym_speed.py" in GYM_MD


@pytest.mark.slow
def test_the_push_t_plan_of_gym_md_is_the_command_s(tmp_path):
    """docs/figures/gym/push_t_plan/plan.json is what the documented `planar-lcp plan` command writes: the same
    controls and states (a seeded run with an iteration budget is reproducible)."""
    from cli_helpers import run_cli
    assert ("planar-lcp plan push_t --seed 1 --iterations 3000 --no-shorten --out docs/figures/gym/push_t_plan"
            in " ".join(GYM_MD.split()))
    r = run_cli("plan", "push_t", "--seed", "1", "--iterations", "3000", "--no-shorten", "--no-gif", "--out",
                tmp_path)
    assert r.returncode == 0, r.stderr
    new = json.loads((tmp_path / "plan.json").read_text())
    old = json.loads((ROOT / "docs" / "figures" / "gym" / "push_t_plan" / "plan.json").read_text())
    assert new["exact"] and new["goal"]["cover"] == old["goal"]["cover"]
    for key in ("controls", "steps", "states", "task_sha256"):
        assert new[key] == old[key]
