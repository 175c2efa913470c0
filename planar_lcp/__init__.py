"""planar_lcp: planar rigid bodies with frictional contact, Stewart-Trinkle time-stepping solved by Lemke.

    import planar_lcp
    traj = planar_lcp.simulate("falling_rod")          # a shipped scene name or a .toml path
    traj.to_csv("rod.csv")
"""

from planar_lcp.lcp import LCPResult, lemke
from planar_lcp.spec.scene import Scene, SceneError, list_scenes, load_scene
from planar_lcp.sim import SimOptions, SimulationError, Simulator, simulate
from planar_lcp.trajectory import Trajectory

__all__ = ["LCPResult", "Scene", "SceneError", "SimOptions", "SimulationError", "Simulator", "Trajectory",
           "lemke", "list_scenes", "load_scene", "simulate"]
__version__ = "0.1.0"
