"""Package-level contracts."""

import subprocess
import sys

import numpy as np

import planar_lcp


def test_import_does_not_pull_in_optional_libraries():
    code = ("import sys, planar_lcp\n"
            "bad = [m for m in ('matplotlib', 'pymunk', 'ompl', 'osqp') if m in sys.modules]\n"
            "print(','.join(bad))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"import planar_lcp imported {out}"


# the public API as planar_lcp's docstring and the README's "Python" section document it
PUBLIC_API = {"LCPResult", "Scene", "SceneError", "SimOptions", "SimulationError", "Simulator", "Trajectory", "lemke",
              "list_scenes", "load_scene", "simulate", "fit", "kinematic_velocities"}


def test_all_is_exactly_the_public_api():
    import inspect
    assert set(planar_lcp.__all__) == PUBLIC_API and len(planar_lcp.__all__) == len(PUBLIC_API)
    exported = {n for n, v in vars(planar_lcp).items() if not n.startswith("_") and not inspect.ismodule(v)}
    assert exported == PUBLIC_API, "a public name outside __all__, or one in __all__ that is not defined"


def test_free_fall_through_the_public_api_is_semi_implicit_euler():
    """Before its first contact (t = 0.385 s) Stewart & Trinkle's rod falls freely: v_n = v_0 + n h g and
    q_n = q_0 + h (v_1 + ... + v_n) = q_0 + n h v_0 + h^2 g n (n + 1) / 2, the angle turning at the constant 4 rad/s."""
    scene = planar_lcp.load_scene("falling_rod")
    tr = planar_lcp.simulate(scene, t_end=0.3)
    h, g = scene.sim.h, -9.81
    n = np.arange(len(tr.t))
    assert tr.body_names == ("rod",) and len(n) == 121
    np.testing.assert_allclose(tr.t, n * h, rtol=0, atol=1e-15)
    (x, y, th), (vx, vy, om) = tr.q[:, 0].T, tr.v[:, 0].T
    np.testing.assert_allclose(vy, n * h * g, rtol=0, atol=1e-12)
    np.testing.assert_allclose(y, 1.0 + h * h * g * n * (n + 1) / 2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(th, np.radians(30.0) + n * h * 4.0, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(x, 0.0)
    np.testing.assert_array_equal(vx, 0.0)
    np.testing.assert_array_equal(om, 4.0)


def test_numba_cache_is_keyed_on_the_kernel_sources(tmp_path):
    """A change in ANY engine file must start a fresh cache (numba alone only watches the defining file)."""
    import shutil

    from planar_lcp import engine
    src = tmp_path / "k"
    shutil.copytree(engine.__path__[0], src, ignore=shutil.ignore_patterns("__pycache__"))
    code = "import sys; sys.path.insert(0, %r); import k; print(k.kernel_source_hash())" % str(tmp_path)
    h1 = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    with open(src / "solvers" / "lemke.py", "a") as f:  # a file in a sub-folder counts too
        f.write("\n# edited\n")
    h2 = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert h1 != h2


def test_the_core_never_names_the_planners_and_they_still_register():
    """planners adds plan, replay and plan-bench through the entry-point group planar_lcp.commands (pyproject.toml);
    no module of planar_lcp imports or names the planners package."""
    import re
    from pathlib import Path

    from planar_lcp.cli import build_parser
    core = Path(__file__).resolve().parents[2] / "planar_lcp"
    for path in core.rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"^\s*(from|import)\s+planners\b|[\"']planners[.\"']", text, re.M), path
    import planners.cli
    parser = build_parser()
    for argv, func in ((["plan", "tip_box"], planners.cli.cmd_plan), (["replay", "p.json"], planners.cli.cmd_replay),
                       (["plan-bench", "tip_box"], planners.cli.cmd_bench)):
        assert parser.parse_args(argv).func is func, argv
