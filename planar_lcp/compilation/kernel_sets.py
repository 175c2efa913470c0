"""What the kernels compile on, by set, and the process that compiles them (`python -m
planar_lcp.compilation.kernel_sets SET`, started by background.py on a cold cache; `planar-lcp warmup` runs
`compile_kernels("all")` in its own process). The kernel sets are described in background.py's docstring.
"""

import os
import sys

import numpy as np

from planar_lcp.compilation import background
from planar_lcp.compilation.precompile import start_helper
from planar_lcp.engine import cache_dir as engine_cache_dir, copying_inlined_ir_once
from planar_lcp.engine.contacts import contacts_at
from planar_lcp.engine.limit_surface import unit_load_wrench
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec.scene import parse_scene

#: the kernel sets of `compile_kernels`
KERNEL_SETS = ("default", "all")

#: The built-in scene the kernels compile on (a run's kernels are typed alike for every scene): a box pushed on a
#: table (limit surface) by a force-limited disk against a wall, so that every stage of the step runs.
SAMPLE_SCENE = {
    "name": "compile_sample",
    "world": {"plane": "horizontal", "support_gravity": 9.81, "friction": 0.3},
    "sim": {"h": 0.01, "t_end": 0.05},
    "bodies": [
        {"name": "box", "type": "dynamic", "mass": 1.0, "position": [0.0, 0.0], "support_friction": 0.35,
         "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]},
        {"name": "pusher", "type": "kinematic", "position": [-0.12, 0.02], "velocity": [0.1, 0.0],
         "max_force": 50.0, "shapes": [{"type": "disk", "radius": 0.02}]},
        {"name": "wall", "type": "static", "position": [0.3, 0.0],
         "shapes": [{"type": "box", "width": 0.05, "height": 0.5}]},
    ],
}


def sample_model():
    """The built-in scene's Model (SAMPLE_SCENE)."""
    return compile_scene(parse_scene(SAMPLE_SCENE, source="planar_lcp.compilation.kernel_sets.SAMPLE_SCENE"))


def compilation_stages(kernel_set="default"):
    """The stages of `compile_kernels(kernel_set)`, in order: (label, function of no arguments)."""
    if kernel_set not in KERNEL_SETS:
        raise ValueError(f"kernel_set must be one of {', '.join(KERNEL_SETS)}, got {kernel_set!r}")

    state = {}

    def structs():
        model = state["model"] = sample_model()
        model.struct
        Simulator(model, SimOptions(h=0.01)).kwork

    def contacts():
        model = state["model"]
        contacts_at(model.arrays, model.q0, model.qk0, 0.0, m=model.struct)
        unit_load_wrench(model.struct, 0, 1.0, 0.0, 0.0, np.zeros(3))

    def run(solver, formulations=("position",)):
        def stage():
            model = state["model"]
            for formulation in formulations:
                sim = Simulator(model, SimOptions(h=0.01, solver=solver, formulation=formulation))
                sim.rollout(model.q0, model.v0, model.qk0, model.vk0[None], 1, record_contacts=True,
                            trajectory_rows=True)
        return stage

    def checks():
        from planar_lcp.engine.solvers.certificate import lcp_scale
        from planar_lcp.lcp import lemke
        A, b = np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0])
        lcp_scale(A, b)
        lemke(A, b)

    stages = [("structs", structs), ("contacts", contacts), ("step (lemke)", run("lemke")), ("checks", checks)]
    def differences():
        # the step's checked differences (step_derivatives(method="differences"): fit by derivatives) and its
        # one-sided differences at a switch (method="one_sided": refine), which the state here need not reach
        from planar_lcp.derivatives.differences import one_sided_differences
        model = state["model"]
        sim = Simulator(model, SimOptions(h=0.01))
        sim.step_derivatives(model.q0, model.v0, model.qk0, model.vk0, method="differences")
        one_sided_differences(sim, *(np.ascontiguousarray(a, dtype=np.float64)
                                     for a in (model.q0, model.v0, model.qk0, model.vk0)))

    if kernel_set == "all":
        stages.append(("step (pgs)", run("pgs")))
        stages.append(("derivatives (differences)", differences))
        try:
            import osqp  # noqa: F401
        except ImportError:
            pass
        else:
            # its step is Python calling kernels: the velocity form's projection among them
            stages.append(("step (osqp)", run("osqp", ("position", "velocity"))))
    return stages


def compile_kernels(kernel_set="default", progress=None, helper=True):
    """Compile `kernel_set` (module docstring) into numba's cache in this process, the helper process compiling the
    island solvers meanwhile (`helper`: where it may start). progress: called as progress(label, done, total) after
    each stage."""
    background.compiling_here = True
    try:
        if helper:
            start_helper()
        stages = compilation_stages(kernel_set)
        # the kernels compiled for every later run: numba's inliner copying a callee's IR once (planar_lcp.engine)
        with copying_inlined_ir_once():
            for i, (label, stage) in enumerate(stages):
                stage()
                if progress is not None:
                    progress(label, i + 1, len(stages))
    finally:
        background.compiling_here = False


def _compile_in_background(kernel_set):
    """The background process: `compile_kernels(kernel_set)` under the lock."""
    lock = background.lock_file(engine_cache_dir())
    if not background.take_lock(lock, os.getpid()):
        return
    try:
        compile_kernels(kernel_set)
    finally:
        os.unlink(lock)


if __name__ == "__main__":
    _compile_in_background(sys.argv[1] if len(sys.argv) > 1 else "default")
