"""Every command of the README's "Commands" table runs end to end, as a user types it, in a subprocess on small
settings: exit status 0 and its output files checked (they exist, are not empty and parse: CSV header and rows, PNG
and GIF magic bytes, JSON with the expected keys, SQLite header).

`test_every_readme_command_has_a_test` parses the table, so a new row without a test here fails.

They share the suite's numba cache, except `demo`, which runs on an EMPTY one as on a user's fresh machine
(tests/planning/test_planning_e2e.py does the same for `plan`)."""

import csv
import io
import json
import math
import os
import re
import textwrap
from pathlib import Path

import pytest
from cli_helpers import ROOT, cli_env, python_compiling, run_cli
from planar_lcp.compilation.kernel_sets import compilation_stages
from planar_lcp.compilation.notice import BACKGROUND_NOTICE, NOTICE

README = ROOT / "README.md"

PNG = b"\x89PNG\r\n\x1a\n"
SQLITE = b"SQLite format 3\x00"

#: README command -> the tests below that run it (the table check reads this)
COVERED = {}


def covers(*commands):
    """Register a test as running these README commands; it is slow-marked (compiled code for seconds to
    minutes; hours without the JIT)."""
    def mark(fn):
        for c in commands:
            COVERED.setdefault(c, []).append(fn.__name__)
        return pytest.mark.slow(fn)
    return mark


def ok(r):
    """Exit status 0 and no traceback; the output on failure."""
    assert r.returncode == 0, f"exit status {r.returncode}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    assert "Traceback" not in r.stderr, r.stderr[-3000:]


# --- file checks ------------------------------------------------------------------------------------------------


def check_png(p):
    b = Path(p).read_bytes()
    assert b[:8] == PNG and len(b) > 1000, p


def check_gif(p):
    b = Path(p).read_bytes()
    assert b[:6] in (b"GIF87a", b"GIF89a") and len(b) > 1000, p
    assert b.count(b"\x21\xf9\x04") > 1, f"{p}: one frame or none"   # graphic control extension per frame


def check_csv(p, first=None, numeric=None, min_rows=1):
    """A header row, at least `min_rows` rows of its width; `first`: the first header cell; `numeric`: columns
    whose non-empty cells all parse as finite floats (True: every column)."""
    text = Path(p).read_text()
    rows = list(csv.reader(io.StringIO(text)))
    assert rows and len(rows) - 1 >= min_rows, f"{p}: {len(rows) - 1} rows"
    header = rows[0]
    assert len(set(header)) == len(header) and all(h.strip() for h in header), f"{p}: header {header}"
    if first is not None:
        assert header[0] == first, f"{p}: header {header}"
    assert all(len(r) == len(header) for r in rows[1:]), f"{p}: ragged rows"
    cols = range(len(header)) if numeric is True else [header.index(c) for c in (numeric or [])]
    for r in rows[1:]:
        for j in cols:
            if r[j] != "":
                assert math.isfinite(float(r[j])), f"{p}: {header[j]} = {r[j]}"
    return header, rows[1:]


def check_text(p, contains=None):
    t = Path(p).read_text()
    assert t.strip(), f"{p} is empty"
    if contains:
        assert contains in t, f"{p} lacks {contains!r}"
    return t


def check_json(p, keys):
    d = json.loads(Path(p).read_text())
    missing = set(keys) - set(d)
    assert not missing, f"{p}: no {sorted(missing)}"
    return d


def check_dir(out, expected):
    """Every expected file exists, is not empty and parses by its extension; no other file was written empty."""
    out = Path(out)
    for name in expected:
        assert (out / name).is_file(), f"{out / name} not written; the directory holds {sorted(os.listdir(out))}"
    for p in out.iterdir():
        if not p.is_file():
            continue
        assert p.stat().st_size > 0, f"{p} is empty"
        ext = p.suffix
        if ext == ".png":
            check_png(p)
        elif ext == ".gif":
            check_gif(p)
        elif ext == ".csv":
            check_csv(p)
        elif ext == ".json":
            json.loads(p.read_text())
        elif ext == ".md":
            check_text(p, "|")
        elif ext == ".db":
            assert p.read_bytes()[:16] == SQLITE, p


def wrote_lines(stdout):
    return [line.split(None, 1)[1].strip() for line in stdout.splitlines() if line.startswith("wrote")]


# --- the table --------------------------------------------------------------------------------------------------


def readme_commands():
    """The commands of the README's Commands table: 'planar-lcp' and the lower-case words after it (the sub-
    command and any sub-sub-command), e.g. 'study falling-rod', 'bench'."""
    text = README.read_text()
    m = re.search(r"^## Commands\n(.*?)(?=^## )", text, re.M | re.S)
    assert m, "README.md has no '## Commands' section"
    cmds = []
    for line in m.group(1).splitlines():
        cell = re.match(r"\|\s*`planar-lcp ([^`]*)`", line)
        if not cell:
            continue
        words = []
        for w in cell.group(1).split():
            if not re.fullmatch(r"[a-z][a-z-]*", w):
                break
            words.append(w)
        cmds.append(" ".join(words))
    return cmds


def test_readme_table_is_parsed():
    cmds = readme_commands()
    # the parser finds the rows it must: if this breaks, the table's format changed, not the commands
    assert {"demo", "simulate", "study falling-rod", "bench"} <= set(cmds) and len(cmds) >= 11, cmds


def test_every_readme_command_has_a_test():
    missing = [c for c in readme_commands() if c not in COVERED]
    assert not missing, f"README commands without a test in {Path(__file__).name}: {missing}"
    # and the replay row is run with both simulators
    assert {"test_replay_lcp", "test_replay_pymunk"} <= set(COVERED["replay"])


# --- the commands -----------------------------------------------------------------------------------------------


@covers("demo")
@pytest.mark.xdist_group("cold_demo")
def test_demo(cold_demo):
    """On an EMPTY numba cache, as on a user's fresh machine (conftest.cold_demo): every kernel compiles during the
    demo, the planning part too."""
    r, out, cache = cold_demo
    ok(r)
    assert any(cache.iterdir()), "the demo did not use its own cache: it was not cold"
    assert "leaked" not in r.stderr, r.stderr
    # the one line that says what a cold cache does: part 1 runs as Python while the kernels compile in the
    # background (engine/interpreted.py), the same answer (checked below)
    assert r.stderr.count(f"planar-lcp demo: {BACKGROUND_NOTICE}\n") == 1 and NOTICE not in r.stderr, r.stderr
    assert "(as Python while the kernels compile in the background)" in r.stdout
    check_dir(out, ["falling_rod.csv", "falling_rod.png", "plan.json", "plan.png", "plan.gif"])
    assert (out / "falling_rod.png").stat().st_size > 10000
    header, rows = check_csv(out / "falling_rod.csv", first="t", numeric=True, min_rows=100)
    assert header == ["t", "rod.x", "rod.y", "rod.theta", "rod.vx", "rod.vy", "rod.omega"] and len(rows) == 401
    assert "first contact in the step ending at t = 0.3850 s" in r.stdout
    plan = check_json(out / "plan.json", ["task", "planner", "seed", "exact", "controls", "states"])
    assert plan["task"] == "push_box" and plan["exact"] is True
    assert "an exact plan in" in r.stdout
    # the demo's plan is the shortened one behind docs/planning.md's figure, bit for bit
    doc = json.loads((ROOT / "docs" / "figures" / "planning" / "push_box" / "plan.json").read_text())
    assert plan["shorten"]["enabled"] and plan["path_duration"] < plan["first_path_duration"]
    assert (plan["controls"], plan["steps"], plan["states"]) == (doc["controls"], doc["steps"], doc["states"])


@pytest.mark.slow
def test_the_readme_commands_in_order_in_a_fresh_checkout(tmp_path):
    """The README's two commands in order, as a user runs them in a fresh clone: the demo from the checkout's root
    (its files go to ./planar_lcp_demo/, as the README says), then the tests, twice. The whole suite is CI's
    (.ci/run runs the same commands in this order, and says so: PLANAR_LCP_README_RUN_HERE); here the tests that read
    the checkout (tests/package/test_docs.py: its layout test failed on the demo's folder) run in a copy of the repository's
    files made a git checkout."""
    if os.environ.get("PLANAR_LCP_README_RUN_HERE"):
        pytest.skip(".ci/run ran the README's commands in this checkout itself: the demo, then these tests")
    import shutil
    import subprocess
    import sys
    from test_docs import FILES
    clone = tmp_path / "clone"
    for rel in FILES:
        (clone / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / rel, clone / rel)
    subprocess.run(["git", "init", "-q"], cwd=clone, check=True)
    env = dict(PYTHONPATH=str(clone))
    r = run_cli("demo", cwd=clone, timeout=900, env=env)
    ok(r)
    demo = clone / "planar_lcp_demo"
    assert (demo / "plan.json").is_file() and (demo / "falling_rod.csv").is_file()
    for _ in range(2):
        t = subprocess.run([sys.executable, "-m", "pytest", "-q", "tests/package/test_docs.py"], cwd=clone, capture_output=True,
                           text=True, timeout=900, env=cli_env(**env))
        assert t.returncode == 0, t.stdout[-3000:] + t.stderr[-3000:]


@covers("scenes")
def test_scenes(tmp_path):
    r = run_cli("scenes", cwd=tmp_path)
    ok(r)
    for name in ("falling_rod", "four_disks", "box_push", "box_tip", "push_t"):
        assert re.search(rf"^\s+{name}\s+\S", r.stdout, re.M), r.stdout


@covers("simulate")
def test_simulate_with_csv_plot_and_animation(tmp_path):
    f = tmp_path / "rod"
    r = run_cli("simulate", "falling_rod", "--t-end", "0.2", "--csv", f"{f}.csv", "--plot", f"{f}.png",
             "--animate", f"{f}.gif", cwd=tmp_path)
    ok(r)
    header, rows = check_csv(f"{f}.csv", first="t", numeric=True, min_rows=80)
    assert header == ["t", "rod.x", "rod.y", "rod.theta", "rod.vx", "rod.vy", "rod.omega"]
    assert float(rows[-1][0]) == pytest.approx(0.2)
    check_png(f"{f}.png")
    check_gif(f"{f}.gif")
    assert sorted(wrote_lines(r.stdout)) == sorted([f"{f}.csv", f"{f}.png", f"{f}.gif"])


@covers("simulate")
def test_simulate_with_contacts_csv(tmp_path):
    """--contacts-csv as a user types it: a row per contact per step, the pair named, the stack's weight carried."""
    f = tmp_path / "stack_contacts.csv"
    r = run_cli("simulate", "box_stack", "--t-end", "0.1", "--contacts-csv", f, cwd=tmp_path)
    ok(r)
    header, rows = check_csv(f, first="t", numeric=["t", "step", "contact", "cn", "ft", "gap", "vt", "point.x",
                                                    "point.y", "normal.x", "normal.y"], min_rows=120)
    assert header[3:5] == ["pair", "cn"] and {row[3] for row in rows} == {"box1|table", "box1|box2", "box2|box3"}
    on_table = sum(float(row[4]) for row in rows if row[1] == "0" and row[3] == "box1|table")
    assert on_table == pytest.approx(3 * 9.81 * 0.005, rel=1e-9)
    assert wrote_lines(r.stdout) == [str(f)]


@covers("simulate")
def test_simulate_with_the_solver_and_formulation_options(tmp_path):
    f = tmp_path / "push.csv"
    r = run_cli("simulate", "box_push", "--h", "0.01", "--t-end", "0.3", "--solver", "lemke", "--formulation",
             "fixed_point", "--fixed-point-iterations", "2", "--support-model", "points", "--friction-directions", "6",
             "--on-failure", "record", "--csv", f, cwd=tmp_path)
    ok(r)
    assert re.search(r"^formulation\s+fixed_point$", r.stdout, re.M) and re.search(r"^steps\s+30 ", r.stdout, re.M)
    check_csv(f, first="t", numeric=True, min_rows=30)


@covers("simulate")
def test_simulate_with_the_limit_surface_knobs(tmp_path):
    f = tmp_path / "push.csv"
    r = run_cli("simulate", "box_push", "--t-end", "0.3", "--support-model", "limit_surface",
             "--limit-surface-twists", "14", "--limit-surface-resolution", "4", "--csv", f, cwd=tmp_path)
    ok(r)
    assert re.search(r"^steps\s+30 ", r.stdout, re.M)
    check_csv(f, first="t", numeric=True, min_rows=30)


@covers("study falling-rod")
def test_study_falling_rod(tmp_path):
    out = tmp_path / "rod"
    r = run_cli("study", "falling-rod", "--out", out, "--quick", cwd=tmp_path)
    ok(r)
    check_dir(out, ["strobe.png", "vx.png", "vy.png", "omega.png", "events.csv", "events.md", "convergence.csv",
                    "convergence.md"])
    check_csv(out / "events.csv", first="h", min_rows=2)
    check_csv(out / "convergence.csv", min_rows=1)


@covers("study falling-rod")
def test_study_falling_rod_with_restitution(tmp_path):
    """The README's [--restitution E] as a user types it: the study states E in its tables."""
    out = tmp_path / "rod_e"
    r = run_cli("study", "falling-rod", "--out", out, "--quick", "--restitution", "0.5", cwd=tmp_path)
    ok(r)
    check_dir(out, ["strobe.png", "vy.png", "events.csv", "events.md", "convergence.md"])
    check_csv(out / "events.csv", first="h", min_rows=2)
    assert "e = 0.5 in every run" in (out / "events.md").read_text()


@covers("study four-disks")
def test_study_four_disks(tmp_path):
    out = tmp_path / "disks"
    r = run_cli("study", "four-disks", "--out", out, "--quick", cwd=tmp_path)
    ok(r)
    check_dir(out, ["trajectories.png", "velocity.png", "impulses.png", "cascade.csv", "events.csv",
                    "convergence.csv"])
    check_csv(out / "cascade.csv", min_rows=1)


@covers("compare")
def test_compare(tmp_path):
    out = tmp_path / "cmp"
    r = run_cli("compare", "falling_rod", "--out", out, "--t-end", "0.6", cwd=tmp_path)
    ok(r)
    check_dir(out, ["report.csv", "report.md", "trajectories.png", "frames.png", "side_by_side.gif"])
    header, rows = check_csv(out / "report.csv", first="scene", numeric=["max_penetration_m", "us_per_step"])
    assert {row[header.index("simulator")] for row in rows} == {"planar_lcp", "pymunk"}


PLAN_KEYS = ["format", "task", "planner", "seed", "exact", "start", "controls", "steps", "durations", "states", "goal",
             "path_duration", "pusher_path_length", "object_path_length", "first_path_duration",
             "first_pusher_path_length", "first_object_path_length", "solve_time", "shorten"]


def check_plan_dir(out, task):
    check_dir(out, ["plan.json", "plan.png"])
    plan = check_json(out / "plan.json", PLAN_KEYS)
    assert plan["task"] == task and plan["exact"] is True
    assert len(plan["controls"]) == len(plan["steps"]) == len(plan["durations"]) == len(plan["states"]) - 1 > 0
    return plan


@covers("plan")
def test_plan(tmp_path):
    out = tmp_path / "plan"
    r = run_cli("plan", "tip_box", "--planner", "RRT", "--iterations", "400", "--seed", "1", "--out", out,
            cwd=tmp_path)
    ok(r)
    plan = check_plan_dir(out, "tip_box")
    check_gif(out / "plan.gif")
    assert plan["shorten"]["enabled"] and plan["path_duration"] < plan["first_path_duration"]
    # [--no-shorten]: the planner's first exact plan, the one the default shortened
    r = run_cli("plan", "tip_box", "--planner", "RRT", "--iterations", "400", "--seed", "1", "--no-shorten", "--out",
                tmp_path / "first", "--no-gif", cwd=tmp_path)
    ok(r)
    first = check_plan_dir(tmp_path / "first", "tip_box")
    assert not first["shorten"]["enabled"] and first["path_duration"] == plan["first_path_duration"]
    assert dict(controls=first["controls"], steps=first["steps"]) == plan["first_plan"]


@pytest.fixture
def plan_file(tip_plan):
    """The plan file of the suite's small plan (conftest.tip_plan, made by `plan`), checked as `test_plan` checks."""
    r, out = tip_plan
    ok(r)
    check_plan_dir(out, "tip_box")
    return out / "plan.json"


def check_replay(r, out, simulator):
    """`replay` exits 0 exactly when it reports that the goal holds, reports the deepest penetration, and draws and
    animates the replay."""
    m = re.search(r"^goal_holds\s+(True|False)$", r.stdout, re.M)
    assert m, f"no goal_holds line:\n{r.stdout}\n{r.stderr[-3000:]}"
    assert re.search(rf"^simulator\s+{simulator}$", r.stdout, re.M), r.stdout
    assert re.search(r"^max_penetration\s+\S+ m ", r.stdout, re.M), r.stdout
    check_png(out / f"replay_{simulator}.png")
    check_gif(out / f"replay_{simulator}.gif")
    return m.group(1) == "True"


@covers("replay")
def test_replay_lcp(plan_file, tmp_path):
    r = run_cli("replay", plan_file, "--simulator", "lcp", "--out", tmp_path, cwd=tmp_path)
    ok(r)
    assert check_replay(r, tmp_path, "lcp")   # our simulator replays the plan it made: the goal holds


@covers("replay")
def test_replay_pymunk(plan_file, tmp_path):
    r = run_cli("replay", plan_file, "--simulator", "pymunk", "--out", tmp_path, cwd=tmp_path)
    assert "Traceback" not in r.stderr, r.stderr[-3000:]
    # pymunk is another simulator: the open-loop plan may miss the goal there (exit 1), but it must say which
    assert r.returncode in (0, 1), f"exit status {r.returncode}\n{r.stdout}\n{r.stderr[-3000:]}"
    holds = check_replay(r, tmp_path, "pymunk")
    assert r.returncode == (0 if holds else 1)


def check_records(p, runs):
    """A record file (planar_lcp.parallel.records): every line JSON, a header first, `runs` runs."""
    lines = [json.loads(line) for line in Path(p).read_text().splitlines()]
    assert "header" in lines[0] and sum(1 for line in lines if "run" in line) == runs, p
    return lines


@covers("plan-bench")
def test_plan_bench(tmp_path):
    out = tmp_path / "pb"
    argv = ["plan-bench", "tip_box", "--planners", "RRT", "--runs", "1", "--time", "3", "--jobs", "1", "--out", out]
    r = run_cli(*argv, cwd=tmp_path)
    ok(r)
    check_dir(out, ["tip_box.log", "tip_box.db", "summary.md", "summary.json", "boxplots.png", "records.jsonl"])
    d = check_json(out / "summary.json", ["task", "runs", "time_limit", "summary", "records"])
    assert d["task"] == "tip_box" and d["runs"] == 1 and len(d["records"]) == 1
    assert [s["planner"] for s in d["summary"]] == ["RRT"]
    rec = d["records"][0]
    assert rec["exact"] and rec["path_duration"] <= rec["first_path_duration"]    # the first and the shortened plan
    check_text(out / "summary.md", "first path duration [s]")
    check_text(out / "summary.md", "final path duration [s]")
    check_text(out / "tip_box.log", "RRT")
    check_records(out / "records.jsonl", 1)
    # [--resume]: the benchmark is finished, so nothing runs and the outputs are written again from its records
    r = run_cli(*argv, "--resume", cwd=tmp_path)
    ok(r)
    assert "1 of 1 runs finished before; nothing left to run" in r.stdout and "cluster" not in r.stdout
    assert check_json(out / "summary.json", ["records"])["records"] == d["records"]
    check_dir(out, ["tip_box.log", "tip_box.db", "summary.md", "summary.json", "boxplots.png", "records.jsonl"])


@covers("pusht-eval")
def test_pusht_eval(tmp_path):
    """Our PushT-v0 with the world's friction changed (gym-pusht's own needs its virtualenv:
    tests/environments/test_pusht_policy.py runs it there when PLANAR_LCP_PUSHT_PYTHON is set); with --jobs on a local cluster."""
    out = tmp_path / "pe"
    r = run_cli("pusht-eval", "--env", "planar_lcp/PushT-v0", "--episodes", "2", "--seed", "3", "--table-friction",
                "0.45", "--contact-friction", "0.45", "--jobs", "1", "--out", out, cwd=tmp_path)
    ok(r)
    check_dir(out, ["episodes.csv", "summary.json"])
    header, rows = check_csv(out / "episodes.csv", first="episode", min_rows=2)
    assert header[:3] == ["episode", "seed", "success"] and len(rows) == 2
    d = check_json(out / "summary.json", ["env", "world", "episodes", "successes", "success_rate",
                                          "compute_median_ms", "compute_max_ms", "failures"])
    assert d["env_kwargs"] == {"table_friction": 0.45, "contact_friction": 0.45} and d["world"] == "planar_lcp"
    assert "cluster" not in r.stderr and f"success        {d['successes']}/2" in r.stdout


@pytest.fixture(scope="module")
def push_root(tmp_path_factory):
    """A small data root in the MIT pushing data set's layout made by our simulator (tests/pushdata_synthetic.py):
    the pushdata commands run without the data."""
    pytest.importorskip("h5py")
    from pushdata_synthetic import make_root
    root = tmp_path_factory.mktemp("mit_push")
    return root, make_root(root)


@covers("pushdata predict")
def test_pushdata_predict(push_root, tmp_path):
    from pushdata_synthetic import TRUE
    root, files = push_root
    model = tmp_path / "model.json"
    model.write_text(json.dumps({"format": "planar_lcp.push_model", "version": 1, "parameters": TRUE}))
    out, plots = tmp_path / "pred.csv", tmp_path / "plots"
    r = run_cli("pushdata", "predict", *files, "--model", model, "--csv", out, "--plots", plots, cwd=tmp_path,
                env={"PLANAR_LCP_MIT_PUSH": str(root)})
    ok(r)
    header, rows = check_csv(out, first="file", numeric=["t", "x", "y", "theta"], min_rows=100)
    assert header == ["file", "t", "x", "y", "theta"] and {row[0] for row in rows} == {f.name for f in files}
    check_dir(plots, [f"{f.stem}.png" for f in files])
    assert sorted(wrote_lines(r.stdout)) == sorted([str(out)] + [str(plots / f"{f.stem}.png") for f in files])
    assert "median error   0.00 mm, 0.00 deg at the end of the push" in r.stdout


@covers("pushdata fit")
def test_pushdata_fit(push_root, tmp_path):
    from pushdata_synthetic import TRUE
    root, files = push_root
    out = tmp_path / "model.json"
    r = run_cli("pushdata", "fit", root, "--out", out, "--params", "support_friction,pusher_friction", "--every",
                "2", "--jobs", "2", "--exclude-shape", "ellip1", cwd=tmp_path, env={"PLANAR_LCP_MIT_PUSH": str(root)})
    assert r.returncode == 2 and r.stderr == "planar-lcp pushdata fit: error: --exclude-shape leaves no push to fit " \
                                             "(objects: ellip1)\n", r.stderr
    r = run_cli("pushdata", "fit", root, "--out", out, "--params", "support_friction,pusher_friction", "--every",
                "2", "--jobs", "2", cwd=tmp_path, env={"PLANAR_LCP_MIT_PUSH": str(root)})
    ok(r)
    d = check_json(out, ["format", "version", "parameters", "stderr", "stderr_by_run", "fitted_on", "objects",
                         "cost", "per_push", "settings", "command"])
    for name in ("support_friction", "pusher_friction"):
        assert abs(d["parameters"][name] - TRUE[name]) < 1e-6
    assert d["fitted_on"] == [f.name for f in files] and wrote_lines(r.stdout) == [str(out)]


@covers("tradeoff")
def test_tradeoff_quick(tmp_path):
    out = tmp_path / "to"
    argv = ["tradeoff", "--quick", "--scenes", "falling_rod", "--out", out, "--no-progress"]
    r = run_cli(*argv, cwd=tmp_path)
    ok(r)
    check_dir(out, ["tradeoff.csv", "pareto_falling_rod.png", "summary.json", "records.jsonl"])
    header, rows = check_csv(out / "tradeoff.csv", first="scene",
                             numeric=["h", "velocity_error", "max_penetration", "cpu_s_per_sim_s"])
    assert {row[0] for row in rows} == {"falling_rod"} and len(rows) >= 2
    check_records(out / "records.jsonl", len(rows))
    assert check_json(out / "summary.json", ["complete"])["complete"] is True
    # [--resume]: the sweep is finished, so nothing runs and the same CSV is written again from its records
    csv_before = (out / "tradeoff.csv").read_bytes()
    r = run_cli(*argv, "--resume", cwd=tmp_path)
    ok(r)
    assert "nothing left to run" in r.stdout and (out / "tradeoff.csv").read_bytes() == csv_before


@covers("bench")
def test_bench_scaling_json(tmp_path):
    """`bench scaling` of the small layouts, docs/performance.md's Scaling table, the cheapest sub-command (about 10 s
    of CPU; `step` and `lcp` also time cold-cache compiles in child processes)."""
    path = tmp_path / "bench.json"
    r = run_cli("bench", "scaling", "--kinds", "pile", "islands", "--json", path, cwd=tmp_path)
    ok(r)
    assert "thread CPU time" in r.stdout and "fitted growth exponent" in r.stdout
    d = check_json(path, ["scaling"])["scaling"]
    assert d["clock"] == "thread_time" and set(d["fits"]) == set(d["fit_spread"]) == {"pile", "islands"}
    assert {(row["kind"], row["bodies"]) for row in d["rows"]} == {(k, n) for k in ("pile", "islands")
                                                                  for n in (1, 2, 4, 8, 16, 32, 64)}
    for row in d["rows"]:
        assert 0 < row["us_min"] <= row["us_per_step"] <= row["us_max"] and math.isfinite(row["us_max"])
        assert row["solved_sparse"] == 0        # the dense path, as the table of record (a tower of 64: 512 unknowns)


PILE_ROW_FIELDS = {"kind", "scene", "bodies", "h", "steps", "rounds", "settle_steps", "settle_max_speed", "lcp_max",
                   "islands", "solved_sparse", "sparse_fallbacks", "sparse_share", "failed_steps", "speedup",
                   "speedup_min", "speedup_max"} | {p + f for p in ("", "dense_") for f in (
                       "timing", "us_per_step", "us_min", "us_max", "pivots_per_step", "runs_per_round", "note")}


@covers("bench")
def test_bench_scaling_large_piles_json(tmp_path):
    """`bench scaling` of the large piles at small sizes: a tower of 16 (128 unknowns: the sparse solver's) beside
    the dense path, a pyramid and a settled bin, each with its exponent per path."""
    path = tmp_path / "piles.json"
    r = run_cli("bench", "scaling", "--kinds", "tower", "pyramid", "bin", "--sizes", "8", "16", "--steps", "2",
                "--rounds", "3", "--json", path, cwd=tmp_path)
    ok(r)
    assert "thread CPU time" in r.stdout and "fitted growth exponent of tower" in r.stdout
    d = check_json(path, ["scaling_piles"])["scaling_piles"]
    assert d["clock"] == "thread_time" and set(d["fits"]) == {"tower", "pyramid", "bin"}
    assert [(row["kind"], row["bodies"]) for row in d["rows"]] == [("tower", 8), ("tower", 16), ("pyramid", 10),
                                                                  ("pyramid", 15), ("bin", 8), ("bin", 16)]
    for row in d["rows"]:
        assert PILE_ROW_FIELDS <= set(row), PILE_ROW_FIELDS - set(row)
        assert row["timing"] == row["dense_timing"] == "rounds"
        for pre in ("", "dense_"):
            assert 0 < row[pre + "us_min"] <= row[pre + "us_per_step"] <= row[pre + "us_max"]
    tower16 = d["rows"][1]
    assert tower16["solved_sparse"] == 2 and tower16["sparse_share"] == 1.0 and tower16["dense_solved_sparse"] == 0
    for kind in d["fits"]:
        for path in ("defaults", "dense"):
            assert math.isfinite(d["fits"][kind][path]) and len(d["fit_bodies"][kind][path]) == 2


@covers("bench")
def test_bench_pile_json(tmp_path):
    """`bench pile` (ours against Box2D v3) on its smallest scene and a short run."""
    pytest.importorskip("pyb2d3")
    path = tmp_path / "pile.json"
    r = run_cli("bench", "pile", "--scenes", "tower_16", "--steps", "10", "--rounds", "2", "--json", path,
                cwd=tmp_path)
    ok(r)
    assert r.stdout.startswith("| scene | bodies | Box2D substeps |") and "thread CPU time" in r.stdout
    d = check_json(path, ["pile"])["pile"]
    assert d["clock"] == "thread_time" and {row["scene"] for row in d["rows"]} == {"tower_16"}
    assert 4 in {row["box2d_substeps"] for row in d["rows"]}
    for row in d["rows"]:
        assert row["steps"] == 10 and row["rounds"] == 2 and row["bodies"] == 16
        assert 0 < row["ours_us_min"] <= row["ours_us"] <= row["ours_us_max"] and row["box2d_us"] > 0
        assert row["solved_sparse"] == 10 and row["sparse_fallbacks"] == 0    # 128 unknowns: the sparse solver's
        assert row["ours_top_drift"] < 1e-6


@covers("warmup")
@pytest.mark.xdist_group("cold_demo")
def test_warmup(tmp_path, cold_demo):
    """`planar-lcp warmup` on what the demo left (a copy of conftest.cold_demo's cache), one line per stage; then runs
    of every solver (lemke, pgs, osqp) and formulation, `planar_lcp.lemke` and the step's checked differences
    compile nothing, and neither does a second warmup."""
    import shutil
    cache = tmp_path / "cache"
    shutil.copytree(cold_demo[2], cache)
    env = {"NUMBA_CACHE_DIR": str(cache)}
    first = run_cli("warmup", cwd=tmp_path, env=env, timeout=1800)
    assert first.returncode == 0, first.stderr
    stages = [line for line in first.stdout.splitlines() if line.lstrip().startswith("[")]
    assert len(stages) == len(compilation_stages("all")) and stages[-1].lstrip().startswith(
        f"[{len(stages)}/{len(stages)}]")
    _, compiled = python_compiling(textwrap.dedent("""
        import numpy as np
        from planar_lcp import lemke, simulate
        for solver in ("lemke", "pgs", "osqp"):
            for formulation in ("position", "fixed_point", "velocity"):
                for name in ("falling_rod", "box_push", "four_disks"):
                    simulate(name, t_end=0.05, solver=solver, formulation=formulation, on_failure="record")
        lemke(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0]))
        from planar_lcp import SimOptions, Simulator
        from planar_lcp.model import compile_scene
        from planar_lcp.spec.scene import load_scene
        sim = Simulator(compile_scene(load_scene("box_push")), SimOptions())
        sim.step_derivatives(*sim.initial_state(), method="differences")
        from planar_lcp.derivatives.differences import one_sided_differences
        one_sided_differences(sim, *(np.ascontiguousarray(a, dtype=float) for a in sim.initial_state()))
        print(json.dumps(compiled))
    """), cache)
    assert compiled == [], sorted(set(compiled))
    # a second warmup: every stage loads what the first compiled
    lines, compiled = python_compiling("from planar_lcp.cli import main\nassert main(['warmup']) == 0\n"
                                       "print(json.dumps(compiled))", cache)
    assert compiled == [] and lines[-1].startswith("planar-lcp warmup: done in"), (compiled, lines)
