"""A cold cache's first run as Python (planar_lcp/engine/interpreted.py, planar_lcp/compilation/background.py): the
same results as the compiled kernels bit for bit, the switch to them mid-run, the wait for them on a long run (the
cold command line in a subprocess with its own empty cache: tests/compilation/test_compile_once.py)."""

from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest
from numba.core.dispatcher import Dispatcher

import planar_lcp.sim as sim_module
from planar_lcp import simulate
from planar_lcp.engine.interpreted import python_version
from planar_lcp.engine.rollout import rollout_lemke
from planar_lcp.model import compile_scene
from planar_lcp.spec.scene import load_scene

pytestmark = pytest.mark.needs_jit

SCENES = sorted(p.stem for p in (Path(__file__).resolve().parents[2] / "scenes").glob("*.toml"))
# Python takes minutes for the piles bin (40 bodies) and pyramid (66) and 10 to 20 s for push_clutter and tower: the
# last two are compared in the slow suite, the piles were once under NUMBA_DISABLE_JIT=1 (docs/method.md, "Numba")
SLOW_PYTHON = ("push_clutter", "tower")
PYTHON_SCENES = [pytest.param(s, marks=pytest.mark.slow) if s in SLOW_PYTHON else s for s in SCENES
                 if s not in ("bin", "pyramid")]


class _Compiling:
    """A background compilation that runs with `seconds_left` expected (a stand-in for background.Background)."""

    def __init__(self, seconds_left=1e9):
        self.left = seconds_left

    def running(self):
        return True

    def seconds_left(self):
        return self.left


def _go_cold(monkeypatch, ready_after=None, seconds_left=1e9):
    """From here on this process sees a cold cache: no kernel is compiled (or, with `ready_after`, the rollout
    kernels are from the ready_after-th question on), a background compilation is 'running', and simulate's kept
    set-ups, models and simulators are fresh. Returns the kernels run as Python, one entry per chunk."""
    ran, asked = [], []

    def spy(kernel):
        ran.append(kernel)
        return python_version(kernel)

    def rollout_compiled(kernel):
        asked.append(kernel)
        return ready_after is not None and len(asked) > ready_after
    monkeypatch.setattr(sim_module, "compiled", rollout_compiled)
    monkeypatch.setattr("planar_lcp.model.compiled", lambda kernel: False)        # compile_scene's kernels
    monkeypatch.setattr(sim_module, "start_background", lambda *args: _Compiling(seconds_left))
    monkeypatch.setattr(sim_module, "python_version", spy)
    monkeypatch.setattr(sim_module, "_run_setups", OrderedDict())
    monkeypatch.setattr(sim_module, "_idle_simulators", OrderedDict())
    sim_module._compiled_scene.cache_clear()
    return ran


@pytest.fixture(autouse=True)
def _forget_compiled_scenes():
    yield
    sim_module._compiled_scene.cache_clear()


def _same(x, y):
    x, y = np.asarray(x), np.asarray(y)
    return x.dtype == y.dtype and np.array_equal(x, y, equal_nan=x.dtype.kind == "f")


def _assert_same_trajectory(a, b):
    for name in ("t", "q", "v", "q_com", "v_com", "qk"):
        assert _same(getattr(a, name), getattr(b, name)), name
    for group in ("stats", "contacts"):
        ga, gb = getattr(a, group), getattr(b, group)
        assert ga.keys() == gb.keys()
        for k in ga:
            assert _same(ga[k], gb[k]), f"{group}[{k}]"
    assert a.failures == b.failures


def test_the_python_version_calls_no_dispatcher():
    """Every function the Python rollouts reach is Python: no numba dispatcher is left in their globals."""
    seen, todo = set(), [python_version(rollout_lemke)]
    made = {id(f) for f in python_version.__globals__["_python"].values()}   # by identity: globals hold arrays too
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        for name in f.__code__.co_names:
            value = f.__globals__.get(name)
            assert not isinstance(value, Dispatcher), f"{f.__name__} calls the dispatcher {name}"
            if id(value) in made:
                todo.append(value)
    assert len(seen) > 40  # the whole step: collision, islands, assembly, Lemke and its certification


@pytest.mark.parametrize("name", PYTHON_SCENES)
def test_a_cold_simulate_runs_python_with_the_compiled_results_bit_for_bit(name, monkeypatch):
    """simulate() on a cold cache runs its steps as Python, and compile_scene its kernels (the start-overlap check,
    the limit surfaces' fixed columns) on the arrays without making the model's struct; the model's arrays and every
    array of the Trajectory equal the compiled run's bit for bit."""
    scene = load_scene(name)
    warm_model, warm = compile_scene(scene), simulate(scene)
    ran = _go_cold(monkeypatch)
    model = compile_scene(scene)
    assert "struct" not in model.__dict__
    for field, x, y in zip(model.arrays._fields, model.arrays, warm_model.arrays):
        assert np.array_equal(x, y), field
    cold = simulate(scene)
    assert ran and all(k is ran[0] for k in ran)
    _assert_same_trajectory(cold, warm)


@pytest.mark.parametrize("name", ["box_tip", "push_t"])
def test_a_run_switches_to_the_compiled_kernel_when_it_is_ready(name, monkeypatch):
    """Python for the first chunks, then the compiled kernel from the moment it is 'ready': the rollout is resumable,
    so the stitched run equals the compiled run bit for bit."""
    scene = load_scene(name)
    warm = simulate(scene)
    ran = _go_cold(monkeypatch, ready_after=3)
    sim_module.Simulator.CHUNK_SECONDS, chunk = 1e-4, sim_module.Simulator.CHUNK_SECONDS  # many short chunks
    try:
        cold = simulate(scene)
    finally:
        sim_module.Simulator.CHUNK_SECONDS = chunk
    assert len(ran) == 2                      # asked by Simulator(), then before each chunk: two chunks of Python
    _assert_same_trajectory(cold, warm)


def test_a_run_too_long_for_python_waits_for_the_compiled_kernel(monkeypatch):
    """When the steps left would take Python longer than the compilation has left, the run stops running Python and
    waits for the kernel (then compiled: the same bits)."""
    scene = load_scene("box_tip")
    warm = simulate(scene)
    ran = _go_cold(monkeypatch, ready_after=5, seconds_left=0.0)
    monkeypatch.setattr(sim_module.time, "sleep", lambda s: None)
    cold = simulate(scene)
    assert len(ran) == 1                      # the first chunk measures Python's speed; then it waits
    _assert_same_trajectory(cold, warm)


def test_a_warm_cache_runs_compiled(monkeypatch):
    """No background and no Python where the kernel is compiled (here: in this process)."""
    started = []
    monkeypatch.setattr(sim_module, "start_background", lambda *args: started.append(1))
    simulate("box_tip", t_end=0.01)
    sim = sim_module.Simulator(compile_scene(load_scene("box_tip")), sim_module.SimOptions(h=0.005),
                               python_while_cold=True)
    assert sim._background is None and not started
