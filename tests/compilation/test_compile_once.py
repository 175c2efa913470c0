"""One compilation serves every scene (planar_lcp/compilation/background.py): no kernel's type depends on a scene's layout, the
first run on an empty cache compiles what every later run with the defaults reaches, and `planar-lcp warmup` what
any run reaches. Measured with numba's compile events, in subprocesses with caches of their own."""

import json
import os
import re
import textwrap
import time
from pathlib import Path

import pytest

from cli_helpers import python_compiling, run_cli
from planar_lcp.compilation import background
from planar_lcp.compilation.notice import BACKGROUND_NOTICE

pytestmark = pytest.mark.needs_jit

ROOT = Path(__file__).resolve().parents[2]

# Every kind of scene a user can write, with the defaults and with options: both planes, every shipped scene and task,
# the piles (large islands), force-limited and turning kinematic bodies, the velocity and fixed-point forms, the warm
# start, failed islands (PGS's fallback, the jam certificates), random scenes of both planes and a planner's
# propagations on tasks of two to eight bodies. Prints the number of runs last but one.
_EVERY_SCENE = textwrap.dedent("""
    import numpy as np
    from planar_lcp import simulate
    from planar_lcp.model import compile_scene
    from planar_lcp.sim import SimOptions, Simulator
    from planar_lcp.spec.random_scenes import jam_scene, random_scene, random_task
    from planar_lcp.spec.scene import list_scenes, load_scene, parse_scene
    from planners.tasks import TaskModel
    runs = 0

    def run(scene, n=20, **options):
        global runs
        sim = Simulator(compile_scene(scene), SimOptions(h=scene.sim.h, **options))
        q, v, qk, vk = sim.initial_state()
        sim.rollout(q, v, qk, vk[None], n, stop_on_failure=False, record_contacts=True, trajectory_rows=True)
        sim.step(q, v, qk, vk)
        runs += 1

    for name, _ in list_scenes():
        scene = load_scene(name)
        simulate(scene, t_end=min(scene.sim.t_end, 25 * scene.sim.h), on_failure="record")
        for options in ({"formulation": "velocity"}, {"formulation": "fixed_point"}, {"warm_start": True},
                        {"res_tol": 0.0}):
            run(scene, **options)
    for seed in range(NRANDOM):
        run(parse_scene(random_scene(seed), source=f"random {seed}"), n=60)
        run(parse_scene(jam_scene(seed), source=f"jam {seed}"), n=60)
    tasks = ["push_box", "push_clutter", "push_table", "tip_box", "push_t"] + sorted(TASKS_DIR.glob("*.toml"))
    tasks += [random_task(seed) for seed in range(NTASKS)] + [SIX_BODIES]
    for task in tasks:
        tm = TaskModel(task)
        x = tm.initial_state()
        for u in ((0.1, 0.0), (0.0, 0.1), (-0.05, 0.05)):
            x, ok = tm.advance(x, u, tm.steps_per_prop)
        runs += 1
    print(runs)
""")

# A top-down task of six bodies: an object, three movable obstacles, a pusher and a static wall.
SIX_BODIES = {
    "name": "six_bodies", "world": {"plane": "horizontal", "support_gravity": 9.81, "friction": 0.4},
    "sim": {"h": 0.01, "t_end": 1.0},
    "bodies": [
        {"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.0], "support_friction": 0.3,
         "shapes": [{"type": "box", "width": 0.1, "height": 0.1}]},
        *({"name": f"ob{i}", "type": "dynamic", "mass": 0.5, "position": [0.12, 0.12 * (i - 1)],
           "support_friction": 0.3, "shapes": [{"type": "disk", "radius": 0.04}]} for i in range(3)),
        {"name": "pusher", "type": "kinematic", "position": [-0.1, 0.0],
         "shapes": [{"type": "disk", "radius": 0.02}]},
        {"name": "wall", "type": "static", "position": [0.4, 0.0],
         "shapes": [{"type": "box", "width": 0.05, "height": 1.0}]},
    ],
    "task": {"object": "box", "pusher": "pusher", "goal": {"x": 0.3, "y": 0.25, "angle_deg": 30.0}},
}


def _every_scene(nrandom, ntasks):
    return (f"from pathlib import Path\nNRANDOM, NTASKS = {nrandom}, {ntasks}\n"
            f"TASKS_DIR = Path({str(ROOT / 'tasks')!r})\nSIX_BODIES = {SIX_BODIES!r}\n" + _EVERY_SCENE
            + "print(json.dumps(compiled))\n")


def _runs(nrandom, ntasks):
    """The runs _EVERY_SCENE makes."""
    from planar_lcp.spec.scene import list_scenes
    return 4 * len(list_scenes()) + 2 * nrandom + 5 + len(list((ROOT / "tasks").glob("*.toml"))) + ntasks + 1


def _signatures():
    """A process's body printing, as its last line, {dispatcher: number of compiled signatures} of every numba
    dispatcher of planar_lcp."""
    return textwrap.dedent("""
        import importlib, pkgutil, planar_lcp
        from numba.core.dispatcher import Dispatcher
        counts = {}
        for info in pkgutil.walk_packages(planar_lcp.__path__, "planar_lcp."):
            module = importlib.import_module(info.name)
            for obj in vars(module).values():
                if isinstance(obj, Dispatcher) and obj.py_func.__module__ == info.name:
                    counts[info.name + "." + obj.py_func.__qualname__] = len(obj.signatures)
        print(json.dumps(counts))
    """)


def test_no_kernel_type_depends_on_the_scene(tmp_path):
    """After runs of every kind of scene and option (_EVERY_SCENE, 10 random scenes of each kind), every kernel of
    planar_lcp was compiled (or loaded) for one signature: none depends on the number of bodies, shapes, contacts or
    kinematic bodies, the plane, or the options. The struct constructor is the one function with two (the model's
    and the work buffers' structs, the same for every scene)."""
    lines, counts = python_compiling(_every_scene(10, 4).replace("print(json.dumps(compiled))\n", "") + _signatures(),
                            os.environ.get("NUMBA_CACHE_DIR") or tmp_path / "cache", PLANAR_LCP_PRECOMPILE="0")
    assert int(lines[-1]) == _runs(10, 4)                           # none was skipped
    assert counts["planar_lcp.engine.rollout.rollout_lemke"] == 1
    several = {name: n for name, n in counts.items() if n > 1}
    assert several == {"planar_lcp.engine.layout._new_struct": 2}, several


@pytest.mark.slow
@pytest.mark.xdist_group("cold_demo")
def test_after_the_first_run_nothing_compiles(cold_demo):
    """The README's first command's main job (`planar-lcp demo`) on an empty cache (conftest.cold_demo), then every
    shipped scene and task (with the defaults and options), 50 random scenes of both planes, 50 jam scenes, 12 random
    tasks and a task of six bodies on that cache: not one function compiles (the background compilation the demo
    started compiled it all)."""
    demo, _, cache = cold_demo
    assert demo.returncode == 0, demo.stderr
    lines, compiled = python_compiling(_every_scene(50, 12), cache)
    assert compiled == [], sorted(set(compiled))
    assert int(lines[-1]) == _runs(50, 12)                          # none was skipped


@pytest.mark.slow
def test_a_users_first_minute_on_a_cold_cache(tmp_path):
    """One empty cache, commands run one after another as a user runs them:
    1. `simulate falling_rod` answers at once, as Python, with the one line that says the kernels compile in a
       background process;
    2. `plan push_box` while that compilation runs joins it (the same line) and waits; Ctrl-C (SIGINT to its process
       group, as a terminal sends it) stops it within 2 s, exit status 130, one line, while the compilation, in a
       process group of its own, goes on;
    3. `plan push_box` again joins it, waits and plans (the same line; an exact plan);
    4. once the compilation has ended, `simulate falling_rod` says nothing and prints what the first run printed."""
    from cli_helpers import ctrl_c_cli
    cache = tmp_path / "cache"
    env = {"NUMBA_CACHE_DIR": str(cache)}
    lock = Path(background.lock_file(str(cache)))
    notice = f"{BACKGROUND_NOTICE}\n"

    first = run_cli("simulate", "falling_rod", cwd=tmp_path, env=env)
    assert first.returncode == 0, first.stderr
    assert first.stderr == f"planar-lcp simulate: {notice}"
    assert lock.exists(), "no background compilation runs"

    t0 = time.monotonic()
    plan = ["plan", "push_box", "--seed", "5", "--iterations", "15000", "--no-gif"]
    r = ctrl_c_cli([*plan, "--out", tmp_path / "interrupted"], lambda: time.monotonic() - t0 > 4.0, tmp_path, env=env)
    assert r.returncode == 130, r.stderr
    assert r.seconds < 2.0, r.seconds
    assert r.stderr == f"planar-lcp plan: {notice}planar-lcp plan: error: interrupted (Ctrl-C); stopped\n"
    assert lock.exists(), "the compilation stopped with the command"

    out = tmp_path / "out"
    second = run_cli(*plan, "--out", out, cwd=tmp_path, env=env, timeout=900)
    assert second.returncode == 0, second.stdout + second.stderr
    assert second.stderr == f"planar-lcp plan: {notice}", second.stderr
    data = json.loads((out / "plan.json").read_text())
    assert data["exact"] and data["goal"]["goal_holds"] and len(data["controls"]) > 0

    assert background.Background(None, str(lock), 0.0).wait(timeout=900)
    third = run_cli("simulate", "falling_rod", cwd=tmp_path, env=env)
    assert third.returncode == 0 and third.stderr == "", third.stderr
    wall = re.compile(r"wall time .*\n")
    assert wall.sub("", third.stdout) == wall.sub("", first.stdout)
