"""Cold start: the second process that compiles the island solvers' kernels while the first compiles the rest
(planar_lcp/compilation/precompile.py). What must hold: the kernels it caches are the ones the step asks for (the
same argument types, so the step loads them instead of compiling them again), the steps they make are bit for bit
the steps of kernels compiled in-process, and it starts only on a cold cache."""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from cli_helpers import _COMPILE_LISTENER
from planar_lcp.compilation import precompile

# Runs a snippet in a fresh process on the numba cache `cache`; prints a JSON list of the functions numba compiled
# (cli_helpers' compile listener, the one python_compiling runs).
_PROBE = _COMPILE_LISTENER + "import sys\n{body}\nprint(json.dumps(compiled))\n"


def _run(body, cache, **env):
    full = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PLANAR_LCP_PRECOMPILE="0", **env)
    full.pop("NUMBA_DISABLE_JIT", None)
    out = subprocess.run([sys.executable, "-c", _PROBE.format(body=textwrap.indent(body, "").strip())],
                         capture_output=True, text=True, env=full, timeout=900)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip().splitlines()


def _inline_overload(name):
    """An `inline="always"` overload's implementation (layout.matrix_view's): typed in every process that compiles a
    caller, and not a cached kernel of its own."""
    return name.endswith("_overload.<locals>.impl")


@pytest.mark.slow
def test_the_helpers_kernels_are_the_ones_the_step_loads_and_step_alike(tmp_path):
    """The helper's work on an empty cache, then a planner's propagations and `simulate` on that cache in another
    process: none of the planar_lcp kernels the helper compiled is compiled again (a driver typed unlike the step's
    call would leave them unused), and the run equals, bit for bit, the same run with every kernel compiled by this
    (the test) process."""
    pytest.importorskip("shapely")
    from planar_lcp import simulate
    helper = json.loads(_run("from planar_lcp.compilation.precompile import HELPER_KINDS, compile_kinds\n"
                             "compile_kinds(HELPER_KINDS)", tmp_path)[-1])
    ours = {f for f in helper if f.startswith("planar_lcp.") and "._drive" not in f and not _inline_overload(f)}
    assert {"planar_lcp.engine.solvers.lemke.lemke_kernel", "planar_lcp.engine.assemble.assemble_lcp",
            "planar_lcp.engine.islands.find_islands", "planar_lcp.engine.layout._new_struct",
            "planar_lcp.engine.solvers.block_lemke.block_lemke",
            "planar_lcp.engine.solvers.sparse.solve_island_sparse"} <= ours
    lines = _run("import numpy as np\nfrom planar_lcp import simulate\nfrom planners.tasks import TaskModel\n"
                 "tm = TaskModel('push_box')\n"
                 "x, ok = tm.advance(tm.initial_state(), (0.1, 0.0), tm.steps_per_prop)\n"
                 "assert ok\n"
                 "tr = simulate('box_push')\n"
                 "np.save(%r, np.concatenate([tr.q.ravel(), tr.v.ravel()]))"
                 % str(tmp_path / "run.npy"), tmp_path)
    again = set(json.loads(lines[-1])) & ours
    # the model struct's constructor is the one kernel both compile (another signature: the helper makes the work's)
    assert again <= {"planar_lcp.engine.layout._new_struct"}, sorted(again)
    tr = simulate("box_push")
    assert np.array_equal(np.load(tmp_path / "run.npy"), np.concatenate([tr.q.ravel(), tr.v.ravel()]))


def test_the_helper_starts_only_on_a_cold_cache(monkeypatch):
    """Once the rollout kernel is compiled (or loaded) in this process: no helper. Nor with the switch off, nor on one
    CPU. A cold cache (faked) starts one, once per process, with the island solvers' kinds."""
    from planar_lcp.model import compile_scene
    from planar_lcp.sim import SimOptions, Simulator
    from planar_lcp.spec.scene import load_scene
    if precompile.numba.config.DISABLE_JIT:
        pytest.skip("no JIT: nothing compiles")
    scene = load_scene("falling_rod")
    model = compile_scene(scene)
    Simulator(model, SimOptions(h=scene.sim.h)).rollout(model.q0, model.v0, model.qk0, model.vk0[None], 1)
    monkeypatch.setattr(precompile, "_helper", None)
    assert precompile.start_helper() is None                             # compiled here: warm
    # the drivers' options are typed as the step's (SimOptions.kernel_options)
    assert precompile._options_type() == precompile.numba.typeof(SimOptions(h=0.01).kernel_options())
    started = []

    class FakePopen:
        def __init__(self, args, **kw):
            started.append((args, kw["env"]))

        def poll(self):
            return 0

    monkeypatch.setattr(precompile.subprocess, "Popen", FakePopen)
    monkeypatch.setattr(precompile, "compiled", lambda dispatcher: False)
    monkeypatch.setenv(precompile.ENV_SWITCH, "0")
    assert precompile.start_helper() is None and not started             # switched off
    monkeypatch.delenv(precompile.ENV_SWITCH)
    monkeypatch.setattr(precompile, "_cpus", lambda: 1)
    assert precompile.start_helper() is None and not started             # one CPU: nothing to gain
    monkeypatch.setattr(precompile, "_cpus", lambda: 2)
    assert isinstance(precompile.start_helper(), FakePopen)
    assert precompile.start_helper() is None                             # once per process
    (args, env), = started
    assert args[1:] == ["-m", "planar_lcp.compilation.precompile", *precompile.HELPER_KINDS]
    assert set(precompile.HELPER_KINDS) == set(precompile._DRIVERS) | set(precompile._CALLS)   # every kind
    assert env[precompile.ENV_SWITCH] == "0"                             # the helper starts no helper


@pytest.mark.slow
def test_the_cold_start_example_runs_end_to_end():
    """docs/performance.md's cold-start measurement: `python examples/measurements/cold_start.py` end to end (one round, one
    variant, a command that compiles nothing: the script's own work; the cold compilation it measures is the compile
    events example's, below)."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ)
    env.pop("NUMBA_DISABLE_JIT", None)
    run = subprocess.run([sys.executable, str(root / "examples" / "measurements" / "cold_start.py"), "--rounds", "1", "--",
                          "scenes"], capture_output=True, text=True, env=env, timeout=900)
    assert run.returncode == 0, run.stderr
    assert "planar-lcp scenes, empty numba cache, wall clock, 1 alternating rounds:" in run.stdout
    assert "this tree: median" in run.stdout


@pytest.mark.slow
def test_the_compile_events_example_logs_every_process(tmp_path):
    """docs/performance.md's per-process compile figures: `python examples/measurements/compile_events.py` end to end on a cold
    `simulate` (the command, its background compilation and that one's second process). Each process's compile
    events are exclusive (a function's time less the functions it compiled on the way), so their sum cannot exceed
    the process's CPU time; the background compiled the run's rollout kernel, which the command itself did not."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ)
    env.pop("NUMBA_DISABLE_JIT", None)
    out = tmp_path / "events.json"
    run = subprocess.run([sys.executable, str(root / "examples" / "measurements" / "compile_events.py"), "--top", "3", "--json",
                          str(out), "--", "simulate", "falling_rod", "--t-end", "0.01"], capture_output=True,
                         text=True, env=env, timeout=900)
    assert run.returncode == 0, run.stderr
    assert "simulate falling_rod --t-end 0.01, empty numba cache:" in run.stdout
    procs = json.loads(out.read_text())
    roles = [Path(p["argv"][0]).name for p in procs]
    assert "kernel_sets.py" in roles and "precompile.py" in roles, roles
    for p in procs:
        assert sum(e["cpu"] for e in p["events"]) <= p["cpu"] + 0.05, (p["argv"], p["cpu"])
    names = {Path(p["argv"][0]).name: {e["name"] for e in p["events"]} for p in procs}
    assert "planar_lcp.engine.rollout.rollout_lemke" in names["kernel_sets.py"]
    assert "planar_lcp.engine.rollout.rollout_lemke" not in names["planar-lcp"]
    assert "background compilation (planar_lcp/compilation/kernel_sets.py), pid" in run.stdout


@pytest.mark.parametrize("args, message", [
    (["--top", "-1", "--", "scenes"], "--top must be >= 0, got -1"),
    (["--json", "/nonexistent_dir_x/e.json", "--", "scenes"], "--json: the directory of /nonexistent_dir_x/e.json"),
    ([], "give the command after --"),
])
def test_the_compile_events_example_refuses_bad_arguments_before_running(args, message):
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, str(root / "examples" / "measurements" / "compile_events.py"), *args], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 2
    assert message in run.stderr
    assert "Traceback" not in run.stderr


def _inlined_kernel():
    """A fresh kernel (not cached) with two levels of inline='always' callees, each called at two sites."""
    from numba import njit

    @njit(inline='always')
    def inner(a, k):
        s = 0.0
        for i in range(a.shape[0]):
            if a[i] > k:
                s += a[i]
            else:
                s -= 1.0
        return s

    @njit(inline='always')
    def middle(a, k):
        return inner(a, k) + inner(a, k + 1.0)

    @njit
    def outer(a):
        t = 0.0
        for j in range(3):
            t += middle(a, float(j))
        return t
    return outer


def _normalised_llvm(text):
    """LLVM IR without what differs between two compilations of the same code: the dispatchers' serial numbers in
    names (also inside a mangled name's length-prefixed ABI tag, B<length>v<serial>, whose length changes with the
    serial's digits, and so does the length of a string constant that holds such a name), the global block-label
    counter, comments."""
    import re
    parts, pos = [], 0
    for m in re.finditer(r"B(\d+)(?=v\d)", text):
        if m.start() >= pos:
            parts += [text[pos:m.start()], "Bv"]
            pos = m.end() + int(m.group(1))
    text = "".join(parts) + text[pos:]
    text = re.sub(r"\[\d+ x i8\](?= c\")", "[n x i8]", text)
    text = re.sub(r"\s*;.*", "", text)
    text = re.sub(r"_v\d+|v\d+B", "v", text)
    labels = {}
    return re.sub(r"\bB\d+", lambda m: labels.setdefault(m.group(0), f"B#{len(labels)}"), text)


@pytest.mark.needs_jit
def test_numbas_inlining_copies_a_callee_once_and_compiles_the_same_code():
    """planar_lcp.engine.copying_inlined_ir_once() makes numba's inline_ir copy a callee's IR with one memo (linear
    time instead of blocks x variables) inside it, numba's own method back after: where it applies (numba 0.68.1), a
    kernel with inlined callees compiles to the same LLVM IR and the same result with it as with numba's own copy."""
    import numba
    import planar_lcp.engine as engine
    from numba.core.inline_closurecall import InlineWorker
    original = InlineWorker.inline_ir
    a = np.arange(5.0)
    outputs = []
    with engine.copying_inlined_ir_once() as applies:
        if not applies:
            # another numba: its inline_ir no longer has the lines the edit replaces, and it compiles as it does
            pytest.skip(f"numba {numba.__version__}: inline_ir without the per-block copy; the edit does not apply")
        assert InlineWorker.inline_ir._planar_lcp_one_copy and InlineWorker.inline_ir._numba_original is original
        kernel = _inlined_kernel()
        outputs.append((kernel(a), _normalised_llvm(kernel.inspect_llvm(kernel.signatures[0]))))
    assert InlineWorker.inline_ir is original
    kernel = _inlined_kernel()
    outputs.append((kernel(a), _normalised_llvm(kernel.inspect_llvm(kernel.signatures[0]))))
    assert outputs[0][0] == outputs[1][0] == 31.0
    assert outputs[0][1] == outputs[1][1]
