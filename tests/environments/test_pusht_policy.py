"""PushTPolicy (planners/pusht.py, docs/closed_loop.md) and `planar-lcp pusht-eval`.

Oracles: the policy's velocity estimate is the environment's own PD state; its candidate pushes start where the
pusher's disk fits against the T; episodes in our PushT-v0 with gym-pusht's physics and in ours with the world's
friction changed reach gym-pusht's success test (coverage > 0.95, as the environment says); `pusht-eval` writes one
row per episode that agrees with its summary, and refuses bad input in one line. With gym-pusht's virtualenv
(PLANAR_LCP_PUSHT_PYTHON) the same command runs in gym-pusht's own environment.
"""

import csv
import json
import math

import numpy as np
import pytest

from cli_helpers import run_cli

gym = pytest.importorskip("gymnasium")
pytest.importorskip("shapely")

from planners.environments.push_t import PushTEnv  # noqa: E402
from planners.environments.pusht_eval import run_episode  # noqa: E402
from planners.pusht import PushTPolicy, _outline_points, _sdf  # noqa: E402


def test_the_policy_tracks_the_pushers_velocity_as_the_environment_does():
    """The observation has no velocity; the policy's (the PD law's state, from its own last action) is the env's."""
    env = PushTEnv(obs_type="state", render_mode=None, physics="gym_pusht")
    policy = PushTPolicy("gym_pusht")
    obs, _ = env.reset(seed=3)
    policy.reset()
    moving = 0
    for _ in range(25):
        action = policy(obs)                           # reads obs: its estimate is of the state the env is in
        assert np.abs(policy._agent_vel - env._agent_vel * 1e3).max() < 1e-6
        moving += np.hypot(*policy._agent_vel) > 10.0
        obs, *_ = env.step(action)
    assert moving > 5


def test_candidate_points_are_on_the_outline_and_the_disk_fits_there():
    policy = PushTPolicy("gym_pusht")
    pts = policy._outline
    assert len(pts) > 40
    for p, n in pts:
        assert abs(_sdf(policy._boxes, p)) < 1e-9                          # on the outline
        assert abs(np.hypot(*n) - 1.0) < 1e-12
        c = p + (policy.radius + 1.0) * n
        assert _sdf(policy._boxes, c) >= policy.radius + 0.99             # the disk there touches nothing else
    # the inner corners' neighbourhoods are left out: no point within the radius of (+-15, 30) on the bar's underside
    under = [p for p, n in pts if abs(p[1] - 30.0) < 1e-9]
    assert under and min(abs(abs(p[0]) - 15.0) for p in under) >= 15.0
    assert _outline_points(policy._boxes, 6.0, 15.0)[0][0].shape == (2,)


@pytest.mark.parametrize("seed", [11, 12])
def test_episodes_reach_the_goal_in_our_push_t_with_gym_pushts_physics(seed):
    env = PushTEnv(obs_type="state", render_mode=None, physics="gym_pusht")
    r = run_episode(gym.wrappers.TimeLimit(env, 300), PushTPolicy("gym_pusht"), seed=seed)
    assert r["success"] and r["coverage"] > 0.95 and r["actions"] < 300, r


def test_an_episode_reaches_the_goal_when_the_worlds_friction_is_not_the_models():
    env = PushTEnv(obs_type="state", render_mode=None, table_friction=0.45, contact_friction=0.45)
    policy = PushTPolicy("planar_lcp")
    assert policy.model.table_friction == 0.3 and policy.model.contact_friction == 0.3
    r = run_episode(gym.wrappers.TimeLimit(env, 300), policy, seed=21)
    assert r["success"], r


def test_actions_stay_in_the_action_space():
    env = PushTEnv(obs_type="state", render_mode=None, physics="gym_pusht")
    policy = PushTPolicy("gym_pusht")
    obs, _ = env.reset(seed=4, options={"reset_to_state": [30.0, 30.0, 75.0, 330.0, 0.0]})
    policy.reset()
    for _ in range(60):
        a = policy(obs)
        assert env.action_space.contains(a.astype(np.float32)) and a.dtype == np.float64
        obs, _, term, _, _ = env.step(a)
        if term:
            break


def test_a_bad_world_is_refused():
    with pytest.raises(ValueError, match="PushTPolicy: world must be one of gym_pusht, planar_lcp, got 'mujoco'"):
        PushTPolicy("mujoco")
    with pytest.raises(ValueError, match="PushT-v0: physics must be one of planar_lcp, gym_pusht, got 'x'"):
        PushTEnv(physics="x")


def test_pusht_eval_writes_a_row_per_episode_and_its_summary(tmp_path):
    r = run_cli("pusht-eval", "--env", "planar_lcp/PushT-v0", "--episodes", 2, "--seed", 31, "--out", tmp_path,
                "--world", "planar_lcp")
    assert r.returncode == 0, r.stdout + r.stderr
    with open(tmp_path / "episodes.csv") as f:
        rows = list(csv.DictReader(f))
    assert [int(x["seed"]) for x in rows] == [31, 32] and [int(x["episode"]) for x in rows] == [0, 1]
    assert list(rows[0]) == ["episode", "seed", "success", "coverage", "best_coverage", "actions",
                             "compute_median_ms", "compute_max_ms", "replans", "wall_s"]
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["episodes"] == 2 and s["successes"] == sum(x["success"] == "True" for x in rows)
    assert s["env"] == "planar_lcp/PushT-v0" and s["world"] == "planar_lcp"
    assert math.isclose(s["compute_max_ms"], max(float(x["compute_max_ms"]) for x in rows))
    for x in rows:
        assert (x["success"] == "True") == (float(x["coverage"]) > 0.95)
    assert f"success        {s['successes']}/2" in r.stdout


@pytest.mark.parametrize("args, message", [
    (["--env", "gym_pusht/PushT-v0", "--episodes", "1", "--table-friction", "0.4"],
     "--table-friction changes our PushT-v0's world: only with --env planar_lcp/PushT-v0, got --env "
     "gym_pusht/PushT-v0"),
    (["--env", "planar_lcp/PushT-v0", "--episodes", "0"], "argument --episodes: must be >= 1, got '0'"),
    (["--env", "planar_lcp/PushT-v0", "--episodes", "1", "--jobs", "2", "--scheduler", "tcp://127.0.0.1:1"],
     "--jobs sizes the local cluster: not with --scheduler tcp://127.0.0.1:1"),
    (["--env", "gym_pusht/PushT-v0", "--episodes", "1", "--pusht-python", "/nonexistent/python"],
     "--pusht-python /nonexistent/python: no such file"),
    (["--env", "nope", "--episodes", "1"], "argument --env: invalid choice: 'nope'"),
])
def test_pusht_eval_refuses_bad_input_in_one_line(tmp_path, args, message):
    r = run_cli("pusht-eval", *args, "--out", tmp_path / "out")
    assert r.returncode == 2, r.stdout + r.stderr
    assert message in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp_path / "out" / "episodes.csv").exists()


def test_pusht_eval_without_gym_pusht_says_how_to_give_it(tmp_path):
    import os
    env = {k: v for k, v in os.environ.items() if k != "PLANAR_LCP_PUSHT_PYTHON"}
    import importlib.util
    if importlib.util.find_spec("gym_pusht") is not None:
        pytest.skip("gym_pusht imports in this python")
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-m", "planar_lcp.cli", "pusht-eval", "--env", "gym_pusht/PushT-v0",
                        "--episodes", "1", "--out", str(tmp_path)], capture_output=True, text=True, env=env,
                       timeout=300)
    assert r.returncode == 2 and "gym_pusht does not import here; give --pusht-python PY" in r.stderr, r.stderr


def test_pusht_eval_in_gym_pushts_own_environment(tmp_path):
    from test_gym import pusht_python
    py = pusht_python()
    r = run_cli("pusht-eval", "--env", "gym_pusht/PushT-v0", "--episodes", 2, "--seed", 7, "--out", tmp_path,
                "--pusht-python", py)
    assert r.returncode == 0, r.stdout + r.stderr
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["gym_pusht"] == "0.1.8" and s["world"] == "gym_pusht" and s["successes"] == 2, s


def test_a_python_without_gym_pusht_cannot_serve_it():
    import sys

    from planners.environments.gym_pusht_process import SubprocessEnv
    import importlib.util
    if importlib.util.find_spec("gym_pusht") is not None:
        pytest.skip("gym_pusht imports in this python")
    with pytest.raises(RuntimeError, match=r"could not serve gym_pusht/PushT-v0: .*No module named 'gym_pusht'"):
        SubprocessEnv(sys.executable)


def test_the_python_example_of_closed_loop_md_runs(tmp_path):
    import re
    import subprocess
    import sys
    from pathlib import Path
    md = (Path(__file__).resolve().parents[2] / "docs" / "closed_loop.md").read_text()
    code = re.findall(r"```python\n(.*?)```", md, re.S)[0]
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("True "), r.stdout            # seed 0 succeeds: is_success, coverage, compute


@pytest.mark.parametrize("env_id", ["planar_lcp/PushT-v0", "gym_pusht/PushT-v0"])
def test_the_episode_gif_command_runs(tmp_path, env_id):
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    args = [sys.executable, str(root / "examples" / "measurements" / "pusht_episode_gif.py"), "--env", env_id, "--seed", "5000",
            "--every", "10", "--out", str(tmp_path / "e.gif")]
    if env_id.startswith("gym_pusht"):
        from test_gym import pusht_python
        args += ["--pusht-python", pusht_python()]
    r = subprocess.run(args, capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "seed 5000: success after" in r.stdout and (tmp_path / "e.gif").stat().st_size > 5000
    from PIL import Image
    im = Image.open(tmp_path / "e.gif")
    assert im.n_frames >= 5 and im.size == (340, 340)          # (identical frames at the end are merged)


def test_closed_loop_mds_table_is_the_commands_output():
    """docs/closed_loop.md's table is examples/measurements/closed_loop_table.py's output over the committed runs."""
    import re
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    md = (root / "docs" / "closed_loop.md").read_text()
    cmd = re.search(r"python (examples/measurements/closed_loop_table\.py [^`\n]*)", md).group(1)
    args = cmd.split()
    r = subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=root, timeout=120)
    assert r.returncode == 0, r.stderr
    start = md.index("<!-- closed-loop table -->\n") + len("<!-- closed-loop table -->\n")
    assert r.stdout.strip() == md[start:md.index("<!-- end of the closed-loop table -->")].strip()


def test_gym_pushts_t_is_identified_from_its_transitions():
    """examples/measurements/identify_gym_pusht.py on two episodes of gym-pusht (its virtualenv): the fitted inertia and centre of
    mass are gym-pusht's source's (3000 mm^2, 45 mm) within 2 % and 0.5 mm, from a start at 1500 and 35."""
    import re
    import subprocess
    import sys
    from pathlib import Path

    from test_gym import pusht_python
    root = Path(__file__).resolve().parents[2]
    r = subprocess.run([sys.executable, str(root / "examples" / "measurements" / "identify_gym_pusht.py"), "--pusht-python",
                        pusht_python(), "--episodes", "2", "--actions", "100"], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    inertia = float(re.search(r"inertia_mm2  = ([\d.]+)", r.stdout).group(1))
    com = float(re.search(r"com_y_mm     = ([\d.]+)", r.stdout).group(1))
    assert abs(inertia - 3000.0) < 60.0 and abs(com - 45.0) < 0.5, r.stdout
