"""The core installs with numpy and numba only (pyproject.toml); a command that needs an optional package that is
missing stops before any work with one line naming the package and the extra that installs it, exit status 2, no
traceback. A missing package is simulated by setting sys.modules[name] = None in the child process."""

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from planar_lcp.cli_support import OPTIONAL_PACKAGES

ROOT = Path(__file__).resolve().parents[2]


def run_without(packages, argv, cwd):
    code = ("import sys\n"
            f"for name in {list(packages)!r}:\n"
            "    sys.modules[name] = None\n"
            "from planar_lcp.cli import main\n"
            f"sys.exit(main({[str(a) for a in argv]!r}))\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=cwd, timeout=600, env=env)


@pytest.mark.parametrize("missing, argv, package, extra", [
    (["matplotlib"], ["simulate", "falling_rod", "--plot", "x.png"], "matplotlib", "plot"),
    (["shapely"], ["simulate", "falling_rod", "--animate", "x.gif"], "shapely", "plot"),
    (["ompl", "matplotlib"], ["demo", "--out", "d"], "ompl", "plan"),
    (["matplotlib"], ["demo", "--out", "d"], "matplotlib", "plot"),
])
def test_a_missing_optional_package_is_one_line_naming_its_extra(tmp_path, missing, argv, package, extra):
    r = run_without(missing, argv, tmp_path)
    assert r.returncode == 2, r.stderr
    assert r.stdout == ""                       # checked before any work
    prog = f"planar-lcp {argv[0]}"
    assert r.stderr == (f"{prog}: error: {package} is not installed; it comes with the extra '{extra}': "
                        f"pip install \"planar-lcp[{extra}]\" (in a checkout: pip install -e \".[{extra}]\"; the "
                        "extra 'dev' installs every extra)\n")
    assert list(tmp_path.iterdir()) == []      # nothing written


def test_an_optional_import_deep_in_a_command_is_reported_the_same_way(tmp_path):
    # `study` imports tqdm only when its sweep starts: main() turns the ModuleNotFoundError into the same line
    r = run_without(["tqdm"], ["study", "falling-rod", "--quick", "--out", tmp_path / "s"], tmp_path)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    assert r.stderr.splitlines() == ["planar-lcp study: error: tqdm is not installed; it comes with the extra "
                                     "'studies': pip install \"planar-lcp[studies]\" (in a checkout: pip install -e "
                                     "\".[studies]\"; the extra 'dev' installs every extra)"]


def test_every_optional_package_is_in_the_extra_the_cli_names_and_not_in_the_core():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]

    def names(reqs):
        out = set()
        for r in reqs:
            name = r.split("[")[0].split(">")[0].split("=")[0].split("<")[0].strip()
            if name == "planar-lcp":                  # a self-reference: planar-lcp[plot,osqp]
                for e in r.split("[")[1].rstrip("]").split(","):
                    out |= names(extras[e.strip()])
            else:
                out.add(name)
        return out

    assert names(project["dependencies"]) == {"numpy", "numba"}
    for package, extra in OPTIONAL_PACKAGES.items():
        assert package in names(extras[extra]), (package, extra)
        assert package in names(extras["dev"]), package
