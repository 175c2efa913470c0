"""Golden trajectories: the behaviour of the simulator recorded before restructuring it (issue 11), and a test that the
code still reproduces it: every shipped scene, each formulation, the default solver (Lemke) and settings, over the
scene's own duration. Recorded per step: the COM poses and velocities of the dynamic bodies, the kinematic poses, the
pivot count and the step status. The code must reproduce them to 1e-12 (m, rad, m/s, rad/s) with identical pivot
counts and statuses.

The files in tests/golden/ are made by `python tests/test_golden.py` (it overwrites them): do that only for a change
that is MEANT to change behaviour, and say so in the commit.

Horizontal-plane scenes are also run with support_model = "points" (files `*__points.npz`): the table-friction model
that was the default before issue H, whose runs were recorded before it and are kept as they were. The default runs
of those scenes (the limit surface) were recorded when issue H made it the default.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from planar_lcp.model import compile_scene
from planar_lcp.spec.scene import list_scenes, load_scene
from planar_lcp.sim import STEP_OK, SimOptions, Simulator
from planar_lcp.engine.layout import Stat

GOLDEN_DIR = Path(__file__).resolve().parent / "golden"
FORMULATIONS = ("position", "fixed_point", "velocity")
TOL = 1e-12
HORIZONTAL = {name for name, _ in list_scenes() if load_scene(name).world.plane == "horizontal"}
CASES = [(name, f, None) for name, _ in list_scenes() for f in FORMULATIONS] + \
    [(name, f, "points") for name in sorted(HORIZONTAL) for f in FORMULATIONS]


def record(name, formulation, support_model=None):
    """The run of a shipped scene with the defaults and this formulation (and support model), as arrays."""
    sc = load_scene(name)
    s = sc.sim
    sim = Simulator(compile_scene(sc, support_model=support_model), SimOptions(
        h=s.h, solver=s.solver, formulation=formulation, fixed_point_iterations=s.fixed_point_iterations,
        pgs_iterations=s.pgs_iterations))
    q, v, qk, vk = sim.initial_state()
    out = sim.rollout(q, v, qk, vk[None], int(round(s.t_end / s.h)), stop_on_failure=False)
    return dict(q=out["q"], v=out["v"], qk=out["qk"], pivots=out["stats"][:, Stat.PIVOTS].astype(np.int64),
                status=out["status"])


def golden_path(name, formulation, support_model=None):
    return GOLDEN_DIR / f"{name}__{formulation}{'__' + support_model if support_model else ''}.npz"


@pytest.mark.parametrize("name, formulation, support_model", CASES)
def test_the_code_reproduces_the_golden_trajectory(name, formulation, support_model):
    path = golden_path(name, formulation, support_model)
    assert path.is_file(), f"{path} is missing: run `python tests/test_golden.py` (see the module docstring)"
    gold = np.load(path)
    now = record(name, formulation, support_model)
    assert np.all(gold["status"] == STEP_OK), "a golden run must not contain failed steps"
    for key in ("q", "v", "qk"):
        assert now[key].shape == gold[key].shape, key
        diff = float(np.max(np.abs(now[key] - gold[key]))) if now[key].size else 0.0
        assert diff <= TOL, f"{name}/{formulation}: {key} differs from the golden run by {diff:.3e}"
    assert np.array_equal(now["status"], gold["status"])
    first = np.flatnonzero(now["pivots"] != gold["pivots"])
    assert first.size == 0, (f"{name}/{formulation}: pivot counts differ from step {first[0]} on "
                             f"({now['pivots'][first[0]]} against {gold['pivots'][first[0]]})" if first.size else "")


def test_every_shipped_scene_has_golden_runs():
    names = {p.name.split("__")[0] for p in GOLDEN_DIR.glob("*.npz")}
    assert names == {name for name, _ in list_scenes()}


if __name__ == "__main__":
    # python tests/test_golden.py [NAME ...]: (re)record all cases, or those of the named scenes
    GOLDEN_DIR.mkdir(exist_ok=True)
    for name, formulation, support_model in CASES:
        if sys.argv[1:] and name not in sys.argv[1:]:
            continue
        rec = record(name, formulation, support_model)
        if np.any(rec["status"] != STEP_OK):
            sys.exit(f"{name}/{formulation}: the run has failed steps; a golden run must not")
        path = golden_path(name, formulation, support_model)
        np.savez_compressed(path, **rec)
        print(f"wrote {path} ({len(rec['pivots'])} steps)")
