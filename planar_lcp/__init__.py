"""planar_lcp: planar rigid bodies with frictional contact, Stewart-Trinkle time-stepping solved by Lemke.

    import planar_lcp
    traj = planar_lcp.simulate("falling_rod")          # a shipped scene name or a .toml path
    traj.to_csv("rod.csv")
"""

from planar_lcp.fitting import fit
from planar_lcp.lcp import LCPResult, lemke
from planar_lcp.spec.path import kinematic_velocities
from planar_lcp.spec.scene import Scene, SceneError, list_scenes, load_scene
from planar_lcp.sim import SimOptions, SimulationError, Simulator, simulate
from planar_lcp.trajectory import Trajectory

__all__ = ["LCPResult", "Scene", "SceneError", "SimOptions", "SimulationError", "Simulator", "Trajectory",
           "fit", "kinematic_velocities", "lemke", "list_scenes", "load_scene", "simulate"]


def _version():
    """The version of the installed planar-lcp distribution this package came from (importlib.metadata); run from a
    source tree (an editable install, or the tree on PYTHONPATH), that of the tree's pyproject.toml."""
    import importlib.metadata
    import tomllib
    from pathlib import Path

    here = Path(__file__).resolve()
    try:
        dist = importlib.metadata.distribution("planar-lcp")
    except importlib.metadata.PackageNotFoundError:
        dist = None
    if dist is not None and Path(dist.locate_file("planar_lcp/__init__.py")).resolve() == here:
        return dist.version
    try:
        project = tomllib.loads((here.parents[1] / "pyproject.toml").read_text())["project"]
        if project["name"] == "planar-lcp":
            return project["version"]
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return dist.version if dist is not None else "unknown"


def __getattr__(name):
    # __version__ is looked up when asked for, not at import
    if name == "__version__":
        return _version()
    raise AttributeError(f"module 'planar_lcp' has no attribute {name!r}")
