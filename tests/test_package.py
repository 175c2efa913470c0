"""Package-level contracts."""

import subprocess
import sys

import pytest

import planar_lcp


def test_import_does_not_pull_in_optional_libraries():
    code = ("import sys, planar_lcp\n"
            "bad = [m for m in ('matplotlib', 'pymunk', 'ompl', 'osqp') if m in sys.modules]\n"
            "print(','.join(bad))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"import planar_lcp imported {out}"


def test_public_names():
    for name in ("load_scene", "simulate", "lemke", "Trajectory", "Simulator", "list_scenes"):
        assert hasattr(planar_lcp, name)
    tr = planar_lcp.simulate(planar_lcp.load_scene("falling_rod"), t_end=0.01)
    assert tr.body_names == ("rod",)


def test_numba_cache_is_keyed_on_the_kernel_sources(tmp_path):
    """A change in ANY engine file must start a fresh cache (numba alone only watches the defining file)."""
    import shutil

    from planar_lcp import engine
    src = tmp_path / "k"
    shutil.copytree(engine.__path__[0], src, ignore=shutil.ignore_patterns("__pycache__"))
    code = "import sys; sys.path.insert(0, %r); import k; print(k._kernel_source_hash())" % str(tmp_path)
    h1 = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    with open(src / "solvers" / "lemke.py", "a") as f:  # a file in a sub-folder counts too
        f.write("\n# edited\n")
    h2 = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert h1 != h2


@pytest.mark.slow  # minutes without the JIT (NUMBA_DISABLE_JIT=1)
def test_demo_writes_its_files(tmp_path, capsys):
    from planar_lcp.cli import main
    assert main(["demo", "--out", str(tmp_path / "d")]) == 0
    out = capsys.readouterr().out
    assert (tmp_path / "d" / "falling_rod.png").stat().st_size > 10000
    lines = (tmp_path / "d" / "falling_rod.csv").read_text().splitlines()
    assert lines[0] == "t,rod.x,rod.y,rod.theta,rod.vx,rod.vy,rod.omega" and len(lines) == 402
    assert "first contact in the step ending at t = 0.3850 s" in out


def test_the_core_never_names_the_planners_and_they_still_register():
    """planners adds plan, replay and plan-bench through the entry-point group planar_lcp.commands (pyproject.toml);
    no module of planar_lcp imports or names the planners package."""
    import re
    from pathlib import Path

    from planar_lcp.cli import build_parser
    core = Path(__file__).resolve().parents[1] / "planar_lcp"
    for path in core.rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"^\s*(from|import)\s+planners\b|[\"']planners[.\"']", text, re.M), path
    commands = build_parser()._subparsers._group_actions[0].choices
    assert {"plan", "replay", "plan-bench", "simulate"} <= set(commands)
