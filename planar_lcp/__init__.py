"""planar_lcp: planar rigid bodies with frictional contact, Stewart-Trinkle time-stepping solved by Lemke."""

from .lcp import LCPResult, lemke

__all__ = ["LCPResult", "lemke"]
__version__ = "0.1.0"
