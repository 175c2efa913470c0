"""Installed like any package (README "Install"): the shipped scenes and task files travel in the wheel as package
data (planar_lcp/data/scenes, planar_lcp/data/tasks: setup.py) and are found with importlib.resources
(`planar_lcp.spec.scene.shipped_dir`), so that an installed wheel runs from any folder; a plan names a shipped file
as scenes/NAME.toml or tasks/NAME.toml wherever the package is installed, so plan files move between installations;
`planar-lcp --version` and `planar_lcp.__version__` name the installed version.

The slow test builds the wheel, installs it with its `plan` and `gym` extras in a fresh virtualenv in a temporary
folder (the versions of this environment's packages as constraints, so that pip takes what is already here) and
runs the commands from another folder, on an empty numba cache. With $PLANAR_LCP_WHEEL_VENV set (.ci/run, which has
just built the wheel, installed it in such a virtualenv and run the demo from another folder) it checks that
virtualenv instead of building another, on the numba cache its demo ran on ($PLANAR_LCP_WHEEL_CACHE).
"""

import csv
import importlib.metadata
import json
import os
import re
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import ROOT, run_cli

import planar_lcp
from planar_lcp.spec.scene import SHIPPED_FOLDERS, display_source, load_scene, read_document, shipped_dir

VERSION = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
#: what a wheel is built from (pyproject.toml, setup.py): the packages, the shipped files and the readme
BUILD_INPUTS = ("pyproject.toml", "setup.py", "README.md", "planar_lcp", "planners", *SHIPPED_FOLDERS)


def _copy_tree(dest):
    """The files a wheel is built from, copied to `dest` (no caches, no build folders)."""
    for name in BUILD_INPUTS:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc"))
        else:
            shutil.copy2(src, dest / name)


def _bare_env(**extra):
    """This environment without the checkout on the path: a subprocess imports what is installed."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env.update(MPLBACKEND="Agg", **extra)
    return env


# --- the version ------------------------------------------------------------------------------------------------


def test_version_is_the_installed_distributions():
    """`planar-lcp --version` prints planar_lcp.__version__: this tree's pyproject.toml version, which is also the
    installed distribution's (importlib.metadata) when the package is installed (editable here)."""
    r = run_cli("--version")
    assert r.returncode == 0 and r.stderr == "", r.stderr
    m = re.fullmatch(r"planar-lcp (\S+) \((.+), Python (\S+)\)\n", r.stdout)
    assert m, r.stdout
    assert m.group(1) == VERSION == planar_lcp.__version__
    assert Path(m.group(2)) == ROOT / "planar_lcp" and m.group(3) == sys.version.split()[0]
    try:
        installed = importlib.metadata.version("planar-lcp")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip("planar-lcp is not installed here (the tree runs from PYTHONPATH): nothing to compare")
    assert m.group(1) == installed


class _Dist:
    def __init__(self, root, version):
        self.root, self.version = Path(root), version

    def locate_file(self, path):
        return self.root / path


@pytest.mark.parametrize("found, expected", [("this package", "9.8.7"), ("another copy", VERSION),
                                             ("none", VERSION)])
def test_version_is_the_distributions_that_holds_this_package_else_the_trees(monkeypatch, tmp_path, found, expected):
    """A distribution whose files are this package (a wheel): its version; one installed elsewhere (an editable
    install's metadata, or another copy on the path) or none: this source tree's pyproject.toml."""
    def distribution(name):
        assert name == "planar-lcp"
        if found == "none":
            raise importlib.metadata.PackageNotFoundError(name)
        return _Dist(ROOT if found == "this package" else tmp_path, "9.8.7")
    monkeypatch.setattr(importlib.metadata, "distribution", distribution)
    assert planar_lcp.__version__ == expected
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        planar_lcp.no_such_name


# --- the shipped files ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind, name", [("scenes", "push_box"), ("tasks", "push_l")])
def test_a_plan_names_a_shipped_file_the_same_from_any_installation(kind, name, monkeypatch, tmp_path):
    """A shipped file is shown (a plan's task_source) as KIND/NAME.toml whatever the working directory, and a plan
    naming it finds it again in this installation's shipped folder, from any working directory."""
    from planar_lcp.spec.task import document_sha256
    from planners.plans import _task_file_status
    monkeypatch.chdir(tmp_path)
    path = shipped_dir(kind) / f"{name}.toml"
    assert display_source(load_scene(path)) == f"{kind}/{name}.toml"
    sha = document_sha256(read_document(path)[0])
    assert _task_file_status(f"{kind}/{name}.toml", sha) == "unchanged"
    assert _task_file_status(f"{kind}/{name}.toml", "0" * 64) == "edited"
    assert _task_file_status(f"{kind}/no_such_file.toml", sha) == "missing"


def test_the_scenes_command_lists_an_added_folder_and_refuses_a_bad_one(tmp_path):
    """$PLANAR_LCP_SCENES through the command line: `scenes` names both folders and lists the added scene beside the
    shipped ones, its own falling_rod in place of the shipped one; a variable naming no folder is one line, exit 2."""
    rod = (shipped_dir("scenes") / "falling_rod.toml").read_text()
    assert 'description = "' in rod
    (tmp_path / "falling_rod.toml").write_text(re.sub(r'description = ".*"', 'description = "my own rod"', rod))
    (tmp_path / "my_rod.toml").write_text(rod.replace('name = "falling_rod"', 'name = "my_rod"'))
    r = run_cli("scenes", env={"PLANAR_LCP_SCENES": str(tmp_path)})
    assert r.returncode == 0 and r.stderr == "", r.stderr
    n = len(list(shipped_dir("scenes").glob("*.toml"))) + 1
    assert r.stdout.startswith(f"{n} scenes in $PLANAR_LCP_SCENES ({tmp_path}) and {shipped_dir('scenes')} (a name "
                               "in both: $PLANAR_LCP_SCENES's) "), r.stdout
    assert re.search(r"^  falling_rod +my own rod$", r.stdout, re.M) and re.search(r"^  my_rod ", r.stdout, re.M)
    assert re.search(r"^  push_box +\[task\] ", r.stdout, re.M), r.stdout
    r = run_cli("scenes", env={"PLANAR_LCP_SCENES": str(tmp_path / "nope")})
    assert r.returncode == 2 and r.stdout == "" and r.stderr == (
        f"planar-lcp scenes: error: $PLANAR_LCP_SCENES: must be a folder of scene files (NAME.toml), got "
        f"'{tmp_path / 'nope'}' (no such file or folder)\n"), r.stderr


WHEEL_LAYOUT_PROBE = """
import json, sys
import planar_lcp
from planar_lcp.spec.scene import display_source, list_scenes, load_scene, scene_dirs, shipped_dir
from planar_lcp.spec.task import document_sha256, load_task
from planners.plans import _task_file_status
from planar_lcp.spec.scene import read_document
out = dict(package=planar_lcp.__file__, scenes=str(shipped_dir("scenes")), tasks=str(shipped_dir("tasks")),
           dirs=[str(d) for d in scene_dirs()], names=[n for n, _ in list_scenes()],
           rod=load_scene("falling_rod").source, rod_shown=display_source(load_scene("falling_rod")),
           push_box=load_task("push_box").source,
           push_l=load_task(str(shipped_dir("tasks") / "push_l.toml")).source,
           status=[_task_file_status(f"{k}/{n}.toml", document_sha256(read_document(shipped_dir(k) / f"{n}.toml")[0]))
                   for k, n in (("scenes", "push_box"), ("tasks", "push_l"))])
try:
    from planners.environments.task_env import TASKS_DIR, task_source
    out.update(tasks_dir=str(TASKS_DIR), push_l_env=str(task_source("push_l")))
except ImportError:
    pass
print(json.dumps(out))
"""


def test_a_wheel_layout_finds_its_package_data(tmp_path):
    """The packages as a wheel installs them, the shipped files in planar_lcp/data/ and no scenes/ or tasks/ beside
    them, imported from another folder: every lookup finds the package data (the slow test below builds a real
    wheel)."""
    site = tmp_path / "site"
    site.mkdir()
    for name in ("planar_lcp", "planners"):
        shutil.copytree(ROOT / name, site / name, ignore=shutil.ignore_patterns("__pycache__"))
    for kind in SHIPPED_FOLDERS:
        shutil.copytree(ROOT / kind, site / "planar_lcp" / "data" / kind)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    r = subprocess.run([sys.executable, "-c", WHEEL_LAYOUT_PROBE], capture_output=True, text=True, cwd=elsewhere,
                       timeout=300, env=_bare_env(PYTHONPATH=str(site)))
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout)
    data = site / "planar_lcp" / "data"
    assert out["package"] == str(site / "planar_lcp" / "__init__.py")
    assert (out["scenes"], out["tasks"], out["dirs"]) == (str(data / "scenes"), str(data / "tasks"),
                                                          [str(data / "scenes")])
    assert out["names"] == sorted(p.stem for p in (ROOT / "scenes").glob("*.toml"))
    assert out["rod"] == str(data / "scenes" / "falling_rod.toml") and out["rod_shown"] == "scenes/falling_rod.toml"
    assert (out["push_box"], out["push_l"]) == ("scenes/push_box.toml", "tasks/push_l.toml")
    assert out["status"] == ["unchanged", "unchanged"]
    if "tasks_dir" in out:
        assert (out["tasks_dir"], out["push_l_env"]) == (str(data / "tasks"), str(data / "tasks" / "push_l.toml"))


# --- a wheel in a fresh virtualenv ------------------------------------------------------------------------------


def _build_and_install(tmp_path, timings):
    """Build the wheel from a copy of the tree, install it with its plan and gym extras in a fresh virtualenv;
    returns the virtualenv's folder."""
    src, dist, venv = tmp_path / "src", tmp_path / "dist", tmp_path / "venv"
    src.mkdir()
    _copy_tree(src)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(dist), str(src)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    wheels = list(dist.glob("planar_lcp-*.whl"))
    assert len(wheels) == 1, wheels
    timings["build"] = time.perf_counter() - t0
    import zipfile
    names = set(zipfile.ZipFile(wheels[0]).namelist())
    for kind in SHIPPED_FOLDERS:
        expected = {f"planar_lcp/data/{kind}/{p.name}" for p in (ROOT / kind).glob("*.toml")}
        assert expected and expected <= names, f"the wheel lacks {sorted(expected - names)}"
    assert not [n for n in names if n.split("/")[0] in SHIPPED_FOLDERS], "scenes/ or tasks/ at the wheel's top"
    # pip takes the versions this environment has (already downloaded, already tested with)
    here = {d.metadata["Name"].lower(): d.version for d in importlib.metadata.distributions() if d.metadata["Name"]}
    here.pop("planar-lcp", None)
    constraints = tmp_path / "constraints.txt"
    constraints.write_text("".join(f"{n}=={v}\n" for n, v in sorted(here.items())))
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300, env=_bare_env())
    r = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "-c", str(constraints),
                        f"{wheels[0]}[plan,gym]"], capture_output=True, text=True, timeout=1200, env=_bare_env())
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    timings["venv and install"] = time.perf_counter() - t0
    return venv


GYM_PROBE = """
import json, numpy as np, gymnasium as gym, planar_lcp, planners
task = gym.make("planar_lcp/Task-v0", task="push_disk").unwrapped
obs, _ = task.reset(seed=0)
obs, _, _, _, info = task.step(np.zeros(2, dtype=np.float32))
pusht = gym.make("planar_lcp/PushT-v0").unwrapped
obs_t, _ = pusht.reset(seed=0)
obs_t, *_ = pusht.step(np.array([300.0, 300.0]))
print(json.dumps(dict(package=planar_lcp.__file__, task=task.task.name, source=task.task.source, obs=len(obs),
                      sim_ok=bool(info["sim_ok"]), pusht=len(obs_t), finite=bool(np.isfinite(obs_t).all()))))
"""


@pytest.mark.slow
def test_a_wheel_installed_in_a_fresh_virtualenv_runs_from_any_folder(tmp_path):
    timings = {}
    reuse = os.environ.get("PLANAR_LCP_WHEEL_VENV")
    if reuse:
        # the cache its demo ran on (.ci/run), where its kernels are compiled
        venv = Path(reuse)
        cache = os.environ.get("PLANAR_LCP_WHEEL_CACHE") or os.environ.get("NUMBA_CACHE_DIR") or str(tmp_path / "numba")
    else:
        venv, cache = _build_and_install(tmp_path, timings), str(tmp_path / "numba")
    bin_ = venv / "bin"
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = _bare_env(NUMBA_CACHE_DIR=cache)

    def run(*args, timeout=900):
        t0 = time.perf_counter()
        r = subprocess.run([str(a) for a in args], capture_output=True, text=True, cwd=work, timeout=timeout, env=env)
        timings[" ".join([Path(args[0]).name, str(args[1])])] = time.perf_counter() - t0
        assert r.returncode == 0 and "Traceback" not in r.stderr, f"{args}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
        return r

    # the installed package, not the checkout
    r = run(bin_ / "planar-lcp", "--version")
    m = re.fullmatch(r"planar-lcp (\S+) \((.+), Python \S+\)\n", r.stdout)
    assert m and m.group(1) == VERSION, r.stdout
    package = Path(m.group(2))
    assert package.is_relative_to(venv) and package.name == "planar_lcp", package
    data = package / "data"

    r = run(bin_ / "planar-lcp", "scenes")
    assert r.stdout.startswith(f"{len(list((ROOT / 'scenes').glob('*.toml')))} scenes in {data / 'scenes'} "), r.stdout
    for p in (ROOT / "scenes").glob("*.toml"):
        mark = r"\[task\]" if "[task]" in p.read_text() else ""
        assert re.search(rf"^  {p.stem}\s+{mark}\s*\S", r.stdout, re.M), (p.stem, r.stdout)

    r = run(bin_ / "planar-lcp", "simulate", "falling_rod", "--t-end", "0.2", "--csv", "out.csv")
    assert f"falling_rod ({data / 'scenes' / 'falling_rod.toml'})" in r.stdout, r.stdout
    rows = list(csv.reader((work / "out.csv").read_text().splitlines()))
    assert rows[0] == ["t", "rod.x", "rod.y", "rod.theta", "rod.vx", "rod.vy", "rod.omega"] and len(rows) == 82
    here = planar_lcp.simulate("falling_rod", t_end=0.2)
    got = np.array(rows[1:], dtype=float)
    np.testing.assert_allclose(got[:, 0], here.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[:, 1:4], here.q[:, 0], rtol=0, atol=1e-12)

    from planar_lcp.cli import DEMO_PLAN
    d = DEMO_PLAN
    r = run(bin_ / "planar-lcp", "plan", d["task"], "--planner", d["planner"], "--seed", d["seed"], "--iterations",
            d["iterations"], "--no-gif", "--no-shorten", "--out", "plan")
    assert re.search(r"^solution +exact after", r.stdout, re.M), r.stdout
    plan = json.loads((work / "plan" / "plan.json").read_text())
    assert plan["exact"] and (plan["task"], plan["task_source"]) == ("push_box", "scenes/push_box.toml")
    r = run(bin_ / "planar-lcp", "replay", "plan/plan.json")
    assert "task file      scenes/push_box.toml (unchanged since planning)" in r.stdout, r.stdout
    assert re.search(r"^goal_holds +True$", r.stdout, re.M), r.stdout
    # the wheel's plan file in this checkout: the same task file, and the goal reached bit for bit
    import planners
    mine = planners.load_plan(work / "plan" / "plan.json")
    assert mine.task_file == "unchanged"
    assert mine.replay()["report"]["goal_holds"]

    r = run(bin_ / "python", "-c", GYM_PROBE)
    out = json.loads(r.stdout)
    assert Path(out["package"]).is_relative_to(package)
    assert (out["task"], out["source"], out["obs"], out["sim_ok"]) == ("push_disk", "tasks/push_disk.toml", 8, True)
    assert out["pusht"] == 5 and out["finite"]
    print("\nwheel test timings (s): " + ", ".join(f"{k}: {v:.1f}" for k, v in timings.items()))
