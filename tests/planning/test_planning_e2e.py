"""Planning commands end to end in subprocesses: a first run on a cold numba cache, the demo's failure path, replay
in both simulators, bad plan files and Ctrl-C. Skipped when ompl is not installed.

The cold-cache test gives its subprocess its OWN EMPTY NUMBA_CACHE_DIR: the suite's cache is warm by the time it
runs, and the crash it guards against (state wrappers outliving an OMPL callback while numba compiles inside it)
only happened when the kernels were compiled during planning (tests/commands/test_readme_commands.py runs the demo, whose
part 3 plans, on an empty cache too)."""

import json
import time

import numpy as np
import pytest

pytest.importorskip("ompl")
pytest.importorskip("shapely")

from cli_helpers import interrupt_cli, run_cli  # noqa: E402
from planar_lcp.compilation.notice import BACKGROUND_NOTICE, NOTICE  # noqa: E402

pytestmark = pytest.mark.needs_jit     # cold compiles and timing


def test_demo_fails_loudly_when_its_plan_fails(tmp_path, monkeypatch, capsys):
    import planar_lcp.cli as cli
    monkeypatch.setattr(cli, "DEMO_PLAN", dict(cli.DEMO_PLAN, iterations=1))   # too small to reach the goal
    written = []
    assert cli.demo_plan(tmp_path, written) == 1
    err = capsys.readouterr().err
    assert "planar-lcp demo: error: part 3" in err and "no exact plan within the budget" in err, err


@pytest.fixture
def small_plan(tip_plan):
    """The suite's small plan (conftest.tip_plan): (the finished `plan` process, its --out directory)."""
    r, out = tip_plan
    assert r.returncode == 0, r.stdout + r.stderr
    return r, out


def test_plan_prints_no_binding_leaks(small_plan):
    r, _ = small_plan
    # nothing on stderr but, if the suite's numba cache was still cold for a kernel of the plan, the one notice
    assert "leaked" not in r.stderr and r.stderr in ("", f"planar-lcp plan: {NOTICE}\n",
                                                     f"planar-lcp plan: {BACKGROUND_NOTICE}\n"), r.stderr


def test_replay_lcp_reproduces_the_plan_bit_for_bit(small_plan, tmp_path):
    _, out = small_plan
    r = run_cli("replay", out / "plan.json", "--simulator", "lcp", "--out", tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "goal_holds       True" in r.stdout and r.stderr.strip() == "", r.stderr
    assert (tmp_path / "replay_lcp.png").stat().st_size > 1000
    from planners import load_plan
    plan = load_plan(out / "plan.json")
    np.testing.assert_array_equal(plan.replay()["bound"], plan.states)


def test_replay_pymunk_runs_and_judges_the_goal(small_plan, tmp_path):
    pytest.importorskip("pymunk")
    _, out = small_plan
    r = run_cli("replay", out / "plan.json", "--simulator", "pymunk", "--out", tmp_path)
    # open loop in another simulator the goal may be missed (exit 1), but it must be judged, not crash
    assert r.returncode in (0, 1) and r.stderr.strip() == "", r.stdout + r.stderr
    holds = "goal_holds       True" in r.stdout
    assert holds == (r.returncode == 0) and ("goal_holds       False" in r.stdout) == (not holds), r.stdout
    assert "simulation_ok    True" in r.stdout
    assert (tmp_path / "replay_pymunk.png").stat().st_size > 1000
    assert (tmp_path / "replay_pymunk.gif").stat().st_size > 1000
    pen = next(x for x in r.stdout.splitlines() if x.startswith("max_penetration  "))
    assert float(pen.split()[1]) >= 0.0, pen


def test_replay_reports_the_deepest_penetration_and_writes_a_gif(small_plan, tmp_path):
    """`replay` prints the deepest penetration over the replay (any two bodies, after any simulated step) and writes
    replay_lcp.gif beside replay_lcp.png; --no-gif skips it. Oracle for the number: the box's deepest corner below
    the table top (y = 0) at every propagation step's end, computed here from the states' geometry, is a lower bound
    of it (the reported one also sees the steps in between), and it is far below a millimetre."""
    _, out = small_plan
    r = run_cli("replay", out / "plan.json", "--out", tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    line = next(x for x in r.stdout.splitlines() if x.startswith("max_penetration  "))
    reported = float(line.split()[1])
    from planners import load_plan
    plan = load_plan(out / "plan.json")
    res = plan.replay()
    assert f"{res['penetration']:.3g}" == line.split()[1] and f"t = {res['penetration_time']:.2f} s" in line, line
    tm = plan.model
    deepest = 0.0
    for x in res["dense"]:
        px, py, th = tm.object_frame_pose(x)
        c, s = np.cos(th), np.sin(th)
        corners_y = [py + s * dx + c * dy for dx in (-0.05, 0.05) for dy in (-0.1, 0.1)]
        deepest = max(deepest, -min(corners_y))
    assert 0.0 < deepest <= reported * (1 + 1e-9) + 1e-15 < 1e-3, (deepest, reported)
    assert (tmp_path / "replay_lcp.gif").stat().st_size > 1000 and (tmp_path / "replay_lcp.png").is_file()
    assert f"wrote          {tmp_path / 'replay_lcp.gif'}" in r.stdout
    r2 = run_cli("replay", out / "plan.json", "--out", tmp_path / "nogif", "--no-gif")
    assert r2.returncode == 0 and not (tmp_path / "nogif" / "replay_lcp.gif").exists(), r2.stdout + r2.stderr
    assert (tmp_path / "nogif" / "replay_lcp.png").is_file()


@pytest.mark.parametrize("field, value, expected", [
    ("format", 99, "format must be 2, got 99"),
    ("steps", 10**9, "steps[0] must be an integer in 1..10 (the task's control durations, in propagation steps), "
                     "got 1000000000"),
    ("steps", 2.5, "steps[0] must be an integer in 1..10"),
    ("controls", 7.0, "controls[0][1] must be a number in [-0.2, 0.2] m/s (the task's control bounds), got 7.0"),
    ("step_duration", 0.2, "step_duration must be the task's 0.1 s, got 0.2"),
    ("task_sha256", "0" * 64, "task_sha256 must be the hash of task_document"),
    ("task_document", {"name": "x"}, "task_sha256 must be the hash of task_document"),
    ("task_document", [1], "task_document must be an object"),
    ("doc_goal", {"y": 0.05, "angle_deg": -90.0, "position_tol": -1.0},
     "task_document (scenes/tip_box.toml): task.goal.position_tol must be > 0, got -1.0"),
])
def test_bad_plan_fields_give_one_line_errors(small_plan, tmp_path, field, value, expected):
    _, out = small_plan
    plan = json.loads((out / "plan.json").read_text())
    if field == "doc_goal":             # an edited copy of the task, its hash made to match
        from planar_lcp.spec.task import document_sha256
        plan["task_document"]["task"]["goal"] = value
        plan["task_sha256"] = document_sha256(plan["task_document"])
    elif field == "steps":
        plan["steps"][0] = value
    elif field == "controls":
        plan["controls"][0][1] = value
    else:
        plan[field] = value
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(plan))
    t0 = time.perf_counter()
    r = run_cli("replay", bad, "--out", tmp_path, timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    assert r.stderr.startswith(f"planar-lcp replay: error: {bad}: {expected}"), r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stdout == "" and not (tmp_path / "replay_lcp.png").exists()   # no work started
    assert time.perf_counter() - t0 < 30


def test_ctrl_c_stops_plan_cleanly(tmp_path):
    # EST: RRT solves push_t within seconds now, EST not within a minute (docs/planning.md): still planning at Ctrl-C
    rc, err, dt = interrupt_cli(["plan", "push_t", "--planner", "EST", "--time", "120", "--out", tmp_path, "--no-gif"],
                                "planner", tmp_path)
    assert rc == 130 and err == "planar-lcp plan: error: interrupted (Ctrl-C); stopped\n", err
    assert dt < 2.0, dt


def test_ctrl_c_stops_replay_cleanly(small_plan, tmp_path):
    _, out = small_plan
    plan = json.loads((out / "plan.json").read_text())
    # a long but valid plan: the pusher standing still for 40000 controls of the task's longest duration (seconds of
    # replay, no contact: no kernel is compiled during it, which would hold the signal until the compile returns to
    # Python, see test_ctrl_c_during_a_compile_is_still_an_interrupt)
    plan["controls"] = [[0.0, 0.0]] * 40000
    plan["steps"] = [10] * 40000
    plan["durations"] = [10 * plan["step_duration"]] * 40000          # what the steps make (load_plan checks it)
    plan["path_duration"] = 40000 * 10 * plan["step_duration"]
    long_plan = tmp_path / "long.json"
    long_plan.write_text(json.dumps(plan))
    # the plan's own replay first: it compiles whatever kernel of the task the suite's cache does not hold yet (a
    # fresh CI cache, where this test once ran before any test had compiled the fallback variant the replay needs)
    warm = run_cli("replay", out / "plan.json", "--out", tmp_path / "warm")
    assert warm.returncode == 0, warm.stderr
    rc, err, dt = interrupt_cli(["replay", long_plan, "--out", tmp_path], "simulator", tmp_path)
    assert rc == 130 and err == "planar-lcp replay: error: interrupted (Ctrl-C); stopped\n", err
    assert dt < 2.0, dt


def _plan_then_ctrl_c(tmp_path, until, wait, *extra):
    """`planar-lcp plan push_box` (seed 5: an exact plan of 13.2 s found in 2034 iterations) in a process group of
    its own, as a terminal runs it; once its stdout has printed a line starting with each of `until` in turn, and
    `wait` seconds more, Ctrl-C as a terminal sends it: SIGINT to the whole group. Returns (exit status, stdout,
    stderr, the --out directory)."""
    import os
    import signal
    import subprocess

    from cli_helpers import CLI, cli_env
    out = tmp_path / "out"
    args = ["plan", "push_box", "--seed", "5", "--iterations", "15000", "--no-gif", "--out", str(out), *extra]
    p = subprocess.Popen(CLI + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                         env=cli_env(PYTHONUNBUFFERED="1"), start_new_session=True)
    try:
        seen, todo = [], list(until)
        for line in p.stdout:
            seen.append(line)
            if todo and line.startswith(todo[0]):
                todo.pop(0)
                if not todo:
                    break
        assert not todo, "".join(seen) + p.stderr.read()
        time.sleep(wait)
        assert p.poll() is None, "the command finished before it could be interrupted"
        os.killpg(p.pid, signal.SIGINT)
        rest, err = p.communicate(timeout=120)
        return p.returncode, "".join(seen) + rest, err, out
    finally:
        if p.poll() is None:
            p.kill()


def _check_kept_plan(out, status):
    """plan.json after a Ctrl-C: an exact plan that loads, replays to the goal bit for bit, with the first plan's
    costs kept and its shortening marked `status`."""
    from planners import load_plan
    plan = load_plan(out / "plan.json")
    d = plan.data
    assert plan.exact and d["shorten"]["status"] == status, d["shorten"]
    assert d["first_path_duration"] == pytest.approx(13.2) and d["path_duration"] <= d["first_path_duration"]
    assert "first_plan" in d and d["first_pusher_path_length"] > 0
    res = plan.replay()
    assert res["report"]["goal_holds"], res["report"]
    np.testing.assert_array_equal(res["bound"], plan.states)
    assert (out / "plan.png").stat().st_size > 1000
    assert not (out / "plan.json.part").exists()
    return d


def test_ctrl_c_while_shortening_keeps_the_best_exact_plan_so_far(tmp_path):
    """The first exact plan is written and announced before the shortening starts; Ctrl-C during the shortening
    (given a minute: --shorten-time 60) keeps the best exact plan so far in plan.json, marked interrupted, says so
    in one line and exits 130."""
    rc, stdout, err, out = _plan_then_ctrl_c(tmp_path, ["solution       exact", "shortening     "], 2.0,
                                             "--shorten-time", "60")
    assert rc == 130, stdout + err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("planar-lcp plan: error: interrupted (Ctrl-C); stopped shortening: kept the best exact "
                          "plan so far ("), err
    assert f"in {out / 'plan.json'} and its plan.png" in err, err
    # announced in this order, before the shortening: the first plan, where it was saved
    i = [stdout.find(s) for s in ("solution       exact", "first plan     30 controls, 13.20 s", "saved          ",
                                  "shortening     ")]
    assert min(i) >= 0 and i == sorted(i), stdout
    assert "shortened      " not in stdout
    d = _check_kept_plan(out, "interrupted")
    assert d["shorten"]["stopped_by"] == "interrupted" and d["shorten"]["candidates"] > 0
    assert d["shorten"]["shorten_time"] == 60.0 and d["shorten"]["time"] < 50
    # the message's numbers are the file's
    assert f"({d['path_duration']:.2f} s; the first plan 13.20 s; {d['shorten']['accepted']} of " \
           f"{d['shorten']['candidates']} candidates accepted)" in err, err
    # and `replay` says which plan it replays
    r = run_cli("replay", out / "plan.json", "--no-gif", "--out", tmp_path / "replay")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "shortening     interrupted (Ctrl-C): the best exact plan it had\n" in r.stdout, r.stdout


def test_ctrl_c_as_soon_as_the_first_plan_is_announced_keeps_it(tmp_path):
    """Ctrl-C at once after "solution exact" (the shortening may not have started): plan.json holds an exact plan,
    the one line says which, exit status 130."""
    rc, stdout, err, out = _plan_then_ctrl_c(tmp_path, ["solution       exact"], 0.0, "--shorten-time", "60")
    assert rc == 130, stdout + err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("planar-lcp plan: error: interrupted (Ctrl-C); stopped shortening: kept the "), err
    assert f"{out / 'plan.json'}" in err, err
    d = _check_kept_plan(out, "interrupted")
    assert d["shorten"]["stopped_by"] == "interrupted"
