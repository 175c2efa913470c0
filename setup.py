"""Package layout for setuptools; everything else is in pyproject.toml.

The repository keeps the shipped scene and task files at its top (scenes/*.toml, tasks/*.toml); a wheel (and an
sdist) carries them as package data, planar_lcp/data/scenes and planar_lcp/data/tasks, where
planar_lcp.spec.scene.shipped_dir finds them with importlib.resources. pyproject.toml cannot map a folder outside the
packages into one while it also finds the packages, hence this file.
"""

from setuptools import find_packages, setup

#: the package each top-level folder of shipped files becomes in a wheel -> the folder
SHIPPED = {"planar_lcp.data.scenes": "scenes", "planar_lcp.data.tasks": "tasks"}

setup(
    packages=find_packages(include=["planar_lcp", "planar_lcp.*", "planners", "planners.*"]) + list(SHIPPED),
    package_dir=SHIPPED,
    package_data={package: ["*.toml"] for package in SHIPPED},
)
