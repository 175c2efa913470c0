"""Bad input to planning and to the environments: `plan`, `plan-bench` and `replay` refuse it in one line naming
the file or flag, the field, the bound and the value, with exit status 2, no traceback and nothing written; the
Python API raises a TaskError; PushT-v0 and Task-v0 raise a ValueError and leave their state as it was.

The CLI cases run `planar-lcp` in a subprocess (cli_helpers.run_cli) from an empty folder, as a user would; the
environment cases go through gymnasium.make."""

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import ROOT, run_cli

from planar_lcp.spec.scene import scenes_dir
from planar_lcp.spec.task import MAX_RUNS, MAX_SEED, MAX_TIME, TaskError

pytest.importorskip("shapely")

PUSH_BOX = (scenes_dir() / "push_box.toml").read_text()
PUSH_DISK = (ROOT / "tasks" / "push_disk.toml").read_text()


def refused(r, prog, quiet=True):
    """The one line of a refused command r: exit status 2, no traceback, one line on stderr starting with
    `planar-lcp PROG: error: `, nothing on stdout (no work started) when `quiet`. Returns the line after that
    prefix."""
    assert r.returncode == 2, r.stdout + r.stderr
    assert "Traceback" not in r.stderr, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith(f"planar-lcp {prog}: error: "), lines[0]
    assert r.stdout == "" or not quiet, r.stdout
    return lines[0][len(f"planar-lcp {prog}: error: "):]


def task_file(folder, name, text, old=None, new=None):
    """Write `text` (with `old` replaced by `new`, which must occur once) to folder/name; returns the path."""
    if old is not None:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = Path(folder) / name
    path.write_text(text)
    return path


def run_in(folder, *args, timeout=300):
    """Run the CLI in `folder` (the task file's folder, nothing else in it) and check that it wrote nothing there:
    no --out directory, no default bench_TASK folder, no file."""
    before = sorted(p.name for p in Path(folder).iterdir())
    r = run_cli(*args, cwd=folder, timeout=timeout)
    after = sorted(p.name for p in Path(folder).iterdir())
    assert after == before, f"the refused command wrote {set(after) - set(before)}"
    return r


PLAN_ARGS = ("--iterations", "10", "--out", "out")
BENCH_ARGS = ("--runs", "1", "--iterations", "10", "--out", "out")


# ---- task files ---------------------------------------------------------------------------------------------------


def test_a_pusher_inside_the_object_is_refused_by_plan_and_plan_bench_as_simulate_refuses_it(tmp_path):
    # the pusher moved onto the box: simulate's start-overlap check (planar_lcp.model), one definition for all three
    f = task_file(tmp_path, "inside.toml", PUSH_BOX, "position = [-0.08, 0.0]", "position = [0.0, 0.0]")
    msg = ("inside.toml: bodies[0].shapes[0] ('box') and bodies[2].shapes[0] ('pusher') must not overlap at the start "
           "by more than 1e-06 m, got an overlap of 0.065 m at (0, 0.0175)")
    # (simulate names the scene before it compiles it)
    assert refused(run_in(tmp_path, "simulate", f.name), "simulate", quiet=False) == msg
    assert refused(run_in(tmp_path, "plan", f.name, *PLAN_ARGS), "plan") == msg
    assert refused(run_in(tmp_path, "plan-bench", f.name, *BENCH_ARGS), "plan-bench") == msg


def test_the_task_model_refuses_a_start_overlap_with_a_task_error(tmp_path):
    from planners.tasks import TaskModel
    f = task_file(tmp_path, "inside.toml", PUSH_BOX, "position = [-0.08, 0.0]", "position = [0.0, 0.0]")
    with pytest.raises(TaskError, match=r"inside.toml: bodies\[0\].shapes\[0\] \('box'\) and bodies\[2\].shapes\[0\] "
                                        r"\('pusher'\) must not overlap at the start by more than 1e-06 m"):
        TaskModel(f)


@pytest.mark.parametrize("key, old, new, msg", [
    ("goal.x", "goal = { x = 0.2, y = 0.0 }", "goal = { x = 1e300, y = 0.0 }",
     "task.goal.x must be within +-10000 m (a physical bound, as for positions), got 1e+300"),
    ("goal.y", "goal = { x = 0.2, y = 0.0 }", "goal = { x = 0.2, y = -2e4 }",
     "task.goal.y must be within +-10000 m (a physical bound, as for positions), got -20000.0"),
    ("workspace", 'pusher = "pusher"\n', 'pusher = "pusher"\nworkspace = [[-1e9, 1], [-1, 1]]\n',
     "task.workspace[0][0] must be within +-10000 m (a physical bound, as for positions), got -1000000000.0"),
])
def test_goal_and_workspace_coordinates_are_bounded_like_positions(tmp_path, key, old, new, msg):
    f = task_file(tmp_path, "far.toml", PUSH_DISK, old, new)
    assert refused(run_in(tmp_path, "plan", f.name, *PLAN_ARGS), "plan") == f"far.toml: {msg}"
    assert refused(run_in(tmp_path, "plan-bench", f.name, *BENCH_ARGS), "plan-bench") == f"far.toml: {msg}"


def test_a_goal_at_the_bound_is_accepted(tmp_path):
    from planar_lcp.spec.task import load_task
    f = task_file(tmp_path, "edge.toml", PUSH_DISK, "goal = { x = 0.2, y = 0.0 }", "goal = { x = 1e4, y = -1e4 }")
    assert (load_task(f).goal.x, load_task(f).goal.y) == (1e4, -1e4)


def test_a_position_goal_where_no_pose_of_the_object_fits_is_refused(tmp_path):
    # push_disk's puck (radius 35 mm) with its goal in the middle of the wall (20 x 140 mm): at every angle, and
    # anywhere within the 1 cm tolerance, the puck overlaps the wall
    f = task_file(tmp_path, "nofit.toml", PUSH_DISK, "goal = { x = 0.2, y = 0.0 }", "goal = { x = 0.1, y = -0.02 }")
    msg = ("nofit.toml: task.goal must leave room for the object 'puck' at some angle with its position within "
           "task.goal.position_tol = 0.01 m of (0.1, -0.02), got every such pose overlapping static body 'wall'")
    assert refused(run_in(tmp_path, "plan", f.name, *PLAN_ARGS), "plan") == msg
    assert refused(run_in(tmp_path, "plan-bench", f.name, *BENCH_ARGS), "plan-bench") == msg


def test_a_position_goal_next_to_a_static_body_is_accepted(tmp_path):
    # the puck touching the wall's side, and overlapping it by 5 mm at the goal: within the 1 cm tolerance it fits
    from planners.tasks import TaskModel
    for x in (0.09 - 0.035, 0.09 - 0.030):
        f = task_file(tmp_path, "near.toml", PUSH_DISK, "goal = { x = 0.2, y = 0.0 }",
                      f"goal = {{ x = {x!r}, y = 0.0 }}")
        assert TaskModel(f).task.goal.x == x


def test_no_pose_fits_proves_only_what_holds():
    # a 200 x 40 mm bar in a corridor between two half-infinite walls, its centre on the corridor's axis: it fits
    # (lying along the corridor, within a degree or so of it) exactly when the corridor is at least 40 mm wide
    from shapely.geometry import box
    from shapely.ops import unary_union

    from planners.tasks import no_pose_fits
    bar = box(-0.1, -0.02, 0.1, 0.02)
    radius = math.hypot(0.1, 0.02)

    def corridor(gap):
        return unary_union([box(-1, gap / 2, 1, 1), box(-1, -1, 1, -gap / 2)])

    for gap, fits in ((0.030, False), (0.0399, False), (0.0401, True), (0.045, True), (0.3, True)):
        assert no_pose_fits(bar, corridor(gap), (0.0, 0.0), 0.0, radius, 1e-6 * bar.area) is (not fits), gap
    # a square in a square hole, any angle: fits only when the hole is as large
    sq = box(-0.05, -0.05, 0.05, 0.05)
    for hole, fits in ((0.099, False), (0.1005, True)):
        walls = box(-1, -1, 1, 1).difference(box(-hole / 2, -hole / 2, hole / 2, hole / 2))
        assert no_pose_fits(sq, walls, (0.0, 0.0), 0.0, math.hypot(0.05, 0.05), 1e-6 * sq.area) is (not fits)
    # a wall 15 mm from the bar's centre: at every angle the bar (20 mm half-width) pokes into it, unless the
    # tolerance lets it move away
    wall = box(0.015, -1, 1, 1)
    assert no_pose_fits(bar, wall, (0.0, 0.0), 0.0, radius, 1e-6 * bar.area)
    assert not no_pose_fits(bar, wall, (0.0, 0.0), 0.01, radius, 1e-6 * bar.area)     # 1 cm to the left: free


def test_every_shipped_and_benchmark_position_goal_still_fits():
    from planners.tasks import TaskModel
    from planar_lcp.spec.task import load_task, shipped_tasks
    files = [scenes_dir() / f"{n}.toml" for n in shipped_tasks()] + sorted((ROOT / "tasks").glob("*.toml"))
    checked = 0
    for f in files:
        g = load_task(f).goal
        if g.pose is None and g.x is not None and g.y is not None:
            TaskModel(f)
            checked += 1
    assert checked >= 1


# ---- flags and the Python API -------------------------------------------------------------------------------------


@pytest.mark.parametrize("cmd, flag, value, msg", [
    ("plan", "--seed", str(2**64), f"argument --seed: must be <= {MAX_SEED} (OMPL's seed), got '{2**64}'"),
    ("plan", "--seed", str(MAX_SEED + 1), f"argument --seed: must be <= {MAX_SEED} (OMPL's seed), got "
                                          f"'{MAX_SEED + 1}'"),
    ("plan-bench", "--runs", str(MAX_RUNS + 1), f"argument --runs: must be <= {MAX_RUNS}, got '{MAX_RUNS + 1}'"),
    ("plan-bench", "--runs", str(2**64), f"argument --runs: must be <= {MAX_RUNS}, got '{2**64}'"),
    ("plan", "--time", "1e12", "argument --time: must be <= 86400 s (as a task file's time), got '1e12'"),
    ("plan-bench", "--time", "86400.5", "argument --time: must be <= 86400 s (as a task file's time), got "
                                        "'86400.5'"),
])
def test_seeds_and_time_limits_are_bounded_on_the_command_line(tmp_path, cmd, flag, value, msg):
    small = ("--planners", "RRT", "--runs", "1") if cmd == "plan-bench" else ()    # short, were it not refused
    assert refused(run_in(tmp_path, cmd, "tip_box", *small, flag, value, "--out", "out"), cmd) == msg


def test_the_largest_seed_plans():
    pytest.importorskip("ompl")
    from planners.plans import plan_task
    from planners.tasks import TaskModel
    tm = TaskModel("tip_box")
    data = plan_task(tm.task, "RRT", seed=MAX_SEED, iterations=3, tm=tm, shorten=False)
    assert data["seed"] == MAX_SEED


@pytest.mark.parametrize("kw, msg", [
    (dict(seed=2**64), f"the seed must be from 1 to {MAX_SEED} (OMPL's seed), got {2**64}"),
    (dict(seed=0), f"the seed must be from 1 to {MAX_SEED} (OMPL's seed), got 0"),
    (dict(seed=1.5), f"the seed must be an integer from 1 to {MAX_SEED} (OMPL's seed), got 1.5"),
    (dict(time=1e12), "the time limit must be > 0 and <= 86400 s (as a task file's time), got 1000000000000.0"),
    (dict(time=float("nan")), "the time limit must be > 0 and <= 86400 s (as a task file's time), got nan"),
])
def test_the_planning_api_bounds_seeds_and_time_limits_before_any_work(kw, msg, monkeypatch):
    import planners
    import planners.plans

    def no_work(*a, **k):
        raise AssertionError("the task model was built before the arguments were checked")

    monkeypatch.setattr(planners.plans, "TaskModel", no_work)
    with pytest.raises(TaskError) as e:
        planners.plan("tip_box", **kw)
    assert str(e.value) == msg


def test_run_bench_bounds_its_runs_and_time_limit(tmp_path):
    pytest.importorskip("ompl")
    from planners.bench import run_bench
    with pytest.raises(TaskError, match=rf"runs must be an integer from 1 to {MAX_RUNS} \(seeds 1..runs\), got "
                                        rf"{MAX_RUNS + 1}"):
        run_bench("tip_box", ["RRT"], runs=MAX_RUNS + 1, out=tmp_path / "b")
    with pytest.raises(TaskError, match=r"the time limit must be > 0 and <= 86400 s"):
        run_bench("tip_box", ["RRT"], runs=1, time_limit=MAX_TIME * 2, out=tmp_path / "b")
    assert not (tmp_path / "b").exists()


@pytest.mark.parametrize("cmd", ["simulate", "plan", "plan-bench", "replay"])
def test_a_directory_given_as_the_file_is_named_a_directory(tmp_path, cmd):
    d = tmp_path / "mytask.toml"
    d.mkdir()
    what = "plan file" if cmd == "replay" else "scene file"
    extra = {"plan": PLAN_ARGS, "plan-bench": BENCH_ARGS}.get(cmd, ())
    assert refused(run_in(tmp_path, cmd, d.name, *extra), cmd) == f"mytask.toml: is a directory, not a {what}"


# ---- replay -------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("edit, msg", [
    (lambda d: d["durations"].__setitem__(0, d["durations"][0] + 1.0),
     lambda d: f"durations[0] must be steps[0] * step_duration = {d['steps'][0]} * 0.1 = "
               f"{d['steps'][0] * 0.1:.6g} s, got {d['steps'][0] * 0.1 + 1.0!r}"),
    (lambda d: d.__setitem__("durations", d["durations"][:-1]),
     lambda d: f"durations must be one number per control (steps[i] * step_duration), got "
               f"{len(d['steps']) - 1} for {len(d['steps'])} controls"),
    (lambda d: d.__setitem__("path_duration", 99.0),
     lambda d: f"path_duration must be the sum of steps * step_duration = {sum(d['steps']) * 0.1:.6g} s, got 99.0"),
])
def test_replay_checks_durations_against_steps(tip_plan, tmp_path, edit, msg):
    r, out = tip_plan
    data = json.loads((out / "plan.json").read_text())
    assert data["step_duration"] == 0.1
    want = msg(data)
    edit(data)
    (tmp_path / "edited.json").write_text(json.dumps(data))
    assert refused(run_in(tmp_path, "replay", "edited.json", "--out", "rep"), "replay") == f"edited.json: {want}"


def test_an_unedited_plan_still_replays(tip_plan, tmp_path):
    r, out = tip_plan
    (tmp_path / "plan.json").write_text((out / "plan.json").read_text())
    rr = run_cli("replay", "plan.json", "--out", "rep", cwd=tmp_path)
    assert rr.returncode == 0 and (tmp_path / "rep" / "replay_lcp.png").is_file(), rr.stdout + rr.stderr


# ---- the environments ---------------------------------------------------------------------------------------------


gym = pytest.importorskip("gymnasium")
import planners  # noqa: E402,F401  (registers the environments)


def pusht_state(env):
    """Everything a refused call must leave as it was, as bytes."""
    e = env.unwrapped
    parts = [e._q, e._v, e._qk, e._agent_vel, e._goal, np.asarray(e._last_action, float),
             np.asarray(e.failed_steps)]
    return [np.asarray(p).tobytes() for p in parts] + [repr(e.np_random.bit_generator.state)]


def task_state(env):
    e = env.unwrapped
    return [e._x.tobytes(), repr(e._n), repr(e.np_random.bit_generator.state)]


BAD_ACTIONS = [
    ([np.nan, 100.0], "[nan, 100.0]"),
    ([100.0, np.inf], "[100.0, inf]"),
    ([1.0, 2.0, 3.0], "[1.0, 2.0, 3.0] of shape (3,)"),
    ([[1.0, 2.0]], "[[1.0, 2.0]] of shape (1, 2)"),
    (5.0, "5.0 of shape ()"),
    ("ab", "'ab' of shape ()"),
]


@pytest.mark.parametrize("action, shown", BAD_ACTIONS, ids=[s for _, s in BAD_ACTIONS])
def test_pusht_refuses_a_bad_action_and_keeps_its_state(action, shown):
    env = gym.make("planar_lcp/PushT-v0")
    env.reset(seed=3)
    env.step(np.array([200.0, 200.0], dtype=np.float32))          # a moving pusher: a velocity state to keep
    before = pusht_state(env)
    with pytest.raises(ValueError) as e:
        env.step(action)
    assert str(e.value) == ("PushT-v0: the action (the pusher's target x, y in mm) must be 2 finite numbers, got "
                            + shown)
    assert pusht_state(env) == before
    env.render()                                                   # still drawable


@pytest.mark.parametrize("action, shown", BAD_ACTIONS, ids=[s for _, s in BAD_ACTIONS])
def test_task_env_refuses_a_bad_action_and_keeps_its_state(action, shown):
    env = gym.make("planar_lcp/Task-v0", task="push_box")
    env.reset(seed=0)
    env.step(np.array([0.1, 0.0], dtype=np.float32))
    before = task_state(env)
    with pytest.raises(ValueError) as e:
        env.step(action)
    assert str(e.value) == ("Task-v0: the action (the pusher's velocity vx, vy in m/s) must be 2 finite numbers, got "
                            + shown)
    assert task_state(env) == before


def test_pusht_clips_targets_to_its_action_space_so_the_pusher_stays_in_the_arena():
    def run(targets):
        env = gym.make("planar_lcp/PushT-v0")
        env.reset(options={"reset_to_state": [256.0, 100.0, 256.0, 300.0, 0.0]})
        return np.array([env.step(np.asarray(t, dtype=np.float32))[0][:2] for t in targets])

    far = run([[5000.0, 256.0]] * 15 + [[-5000.0, -1e6]] * 15)
    clipped = run([[512.0, 256.0]] * 15 + [[0.0, 0.0]] * 15)
    assert np.array_equal(far, clipped)                      # clipped to the box: the same steps bit for bit
    assert far.min() >= 0.0 and far.max() <= 512.0            # the pusher in the arena (it was at 4796 mm)
    # extreme targets at random, the PD law's overshoot included
    rng = np.random.default_rng(0)
    pos = run(rng.choice([-1e4, 0.0, 512.0, 1e4], size=(60, 2)))
    assert pos.min() >= 0.0 and pos.max() <= 512.0


@pytest.mark.parametrize("options, msg", [
    ({"goal": [1e9, 256.0, 0.0]}, "PushT-v0: options['goal'] must place the T inside the walls (its corners within "
                                  "7..504 mm), got [1000000000.0, 256.0, 0.0] (corners within 256..1e+09 mm)"),
    ({"goal": [256.0, 500.0, 0.0]}, "PushT-v0: options['goal'] must place the T inside the walls (its corners "
                                    "within 7..504 mm), got [256.0, 500.0, 0.0] (corners within 196..620 mm)"),
    ({"goal": [256.0, 256.0, np.nan]}, "PushT-v0: options['goal'] must be 3 finite numbers (x, y mm, angle rad), "
                                       "got [256.0, 256.0, nan]"),
    ({"goal": [256.0, 256.0]}, "PushT-v0: options['goal'] must be 3 finite numbers (x, y mm, angle rad), got "
                               "[256.0, 256.0]"),
    ({"goal_pose": [256.0, 256.0, 0.0]}, "PushT-v0: unknown reset option 'goal_pose' (the options are "
                                         "reset_to_state, goal)"),
    ({"reset_to_state": [1e9, 100.0, 256.0, 300.0, 0.0]},
     "PushT-v0: options['reset_to_state'] = [1000000000.0, 100.0, 256.0, 300.0, 0.0] is not a start state: the "
     "pusher at [1000000000.0, 100.0] is outside the arena (0..512 mm)"),
    ([1, 2], "PushT-v0: reset's options must be a dict (keys: reset_to_state, goal), got list"),
])
def test_pusht_refuses_bad_reset_options_before_anything_changes(options, msg):
    env = gym.make("planar_lcp/PushT-v0", random_goal=True)
    env.reset(seed=5)
    env.step(np.array([300.0, 300.0], dtype=np.float32))
    before = pusht_state(env)
    with pytest.raises(ValueError) as e:
        env.reset(seed=6, options=options)
    assert str(e.value) == msg
    assert pusht_state(env) == before


def test_pusht_takes_a_goal_inside_the_walls():
    env = gym.make("planar_lcp/PushT-v0", random_goal=True)
    obs, info = env.reset(options={"goal": [150.0, 350.0, 1.0]})
    assert np.array_equal(info["goal_pose"], [150.0, 350.0, 1.0]) and np.allclose(obs[5:], [150.0, 350.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")                     # nothing outside the observation space
        env.step(np.array([5000.0, 5000.0], dtype=np.float32))


@pytest.mark.parametrize("options, msg", [
    ({"start": [0.0] * 8}, "Task-v0: unknown reset option 'start' (the options are state)"),
    ({"state": [0.0] * 7}, "Task-v0: options['state'] must be 8 finite numbers (x, y, theta, vx, vy, omega, "
                           "pusher_x, pusher_y), got [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]"),
    ("state", "Task-v0: reset's options must be a dict (keys: state), got str"),
])
def test_task_env_refuses_unknown_and_bad_reset_options(options, msg):
    env = gym.make("planar_lcp/Task-v0", task="push_box")
    env.reset(seed=0)
    env.step(np.array([0.1, 0.0], dtype=np.float32))
    before = task_state(env)
    with pytest.raises(ValueError) as e:
        env.reset(seed=1, options=options)
    assert str(e.value) == msg
    assert task_state(env) == before
