"""The kernels' structs (planar_lcp/engine/layout.py): one table per struct makes the namedtuple, the struct and the
allocator; the arrays compile_scene and make_step_work make match the tables, and the struct shares their buffers."""

import numba
import numpy as np
import pytest

from planar_lcp import load_scene, simulate
from planar_lcp.engine.layout import (DENSE_CAPACITY, MODEL_LAYOUT, WORK_LAYOUT, Stat, make_step_work, model_struct,
                                      work_sizes, work_struct)
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator

JIT = not numba.config.DISABLE_JIT
SCENES = ["falling_rod", "box_push", "push_t", "four_disks"]


def _shape(field, sizes):
    return tuple(int(d) if d.isdigit() else sizes[d] for d in field.shape.split(" x ")) if field.shape else ()


@pytest.mark.parametrize("name", SCENES)
def test_every_field_has_the_declared_type(name):
    model = compile_scene(load_scene(name))
    model_struct(model.arrays)          # raises TypeError naming the field on a mismatch
    work_struct(make_step_work(model))


@pytest.mark.parametrize("name", SCENES)
def test_the_model_arrays_have_the_shapes_the_table_declares(name):
    """Sizes counted from the scene (bodies, shapes, dynamic bodies) or read from one array each (vertices, pairs,
    support points, friction directions): every field's shape must follow from them as MODEL_LAYOUT says."""
    sc = load_scene(name)
    a = compile_scene(sc).arrays
    sizes = dict(nbody=len(sc.bodies), nshape=sum(len(b.shapes) for b in sc.bodies),
                 ndyn=sum(b.type == "dynamic" for b in sc.bodies), nkin=sum(b.type == "kinematic" for b in sc.bodies),
                 nvert=a.vert_local.shape[0],
                 npair=a.pair_a.shape[0], nsup=a.sup_dyn.shape[0], k=a.fric_dirs.shape[0],
                 nedge=a.ls_edge.shape[0], nnode=a.ls_node.shape[0], K=sc.sim.limit_surface_twists,
                 ndisk=a.ls_disk.shape[0], ntab=a.ls_disk_table.shape[0])
    for f, v in zip(MODEL_LAYOUT, a):
        assert np.shape(v) == _shape(f, sizes), f.name


def test_the_allocator_sizes_the_lcp_buffers_for_the_largest_problem():
    """Linear buffers for the largest LCP; the dense (quadratic) ones for min(that, DENSE_CAPACITY), grown on demand
    (tests/simulation/test_piles.py::test_dense_buffers_grow_when_an_island_needs_them)."""
    model = compile_scene(load_scene("push_t"))
    w, sizes = make_step_work(model), work_sizes(model)
    U = model.max_unknowns()
    D = min(U, DENSE_CAPACITY)
    assert sizes["unknown"] == U and sizes["dense"] == D
    assert w.lemke_tableau.shape == (D * (2 * D + 2),) and w.lcp_matrix.shape == (D * D,)
    assert w.lemke_lu.shape == (D, D) and w.lemke_z.shape == (U,)
    assert w.con_pair.shape == (model.max_contacts(),) and w.warm_basic_z.shape == (model.ndyn, U)
    assert np.all(w.warm_size == -1) and np.all(w.warm_size_saved == -1) and not w.warm_basic_z.any()
    for f, v in zip(WORK_LAYOUT, w):
        assert v.shape == _shape(f, sizes), f.name


@pytest.mark.skipif(not JIT, reason="with NUMBA_DISABLE_JIT the namedtuples are used as they are")
def test_a_wrong_field_type_is_named():
    model = compile_scene(load_scene("falling_rod"))
    bad = model.arrays._replace(dyn_mass=model.arrays.dyn_mass.astype(np.float32))
    with pytest.raises(TypeError, match=r"ModelArrays\.dyn_mass: expected array\(float64, 1d, C\), got "
                                        r"array\(float32, 1d, C\)"):
        model_struct(bad)


def test_kernel_writes_through_the_struct_are_seen_in_the_namedtuple():
    sc = load_scene("falling_rod")
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
    q, v, qk, vk = sim.initial_state()
    for _ in range(160):  # until the rod has hit the table (t ~ 0.386 s)
        q, v, qk, st = sim.step(q, v, qk, vk)
    ncon = int(sim.stats[Stat.N_CONTACTS])
    assert ncon > 0
    assert np.array_equal(sim.work.v_new, v)          # written by the kernel through sim.kwork
    assert np.all(sim.work.con_cn[:ncon] >= 0.0) and sim.work.con_cn[:ncon].max() > 0.0


def test_trajectory_stats_keys_are_the_contract():
    tr = simulate("falling_rod", t_end=0.05)
    assert sorted(tr.stats) == sorted([
        "lcp_size", "lcp_max", "pivots", "n_contacts", "n_islands", "fp_iterations", "resolves", "residual",
        "penetration", "lemke_retries", "warm_starts", "solved_sparse", "sparse_fallbacks", "solved_block", "solved_lemke",
        "solved_equilibrated", "solved_strict", "solved_velocity", "solved_inelastic", "pgs_uncertified", "servo_limited", "fp_change", "pgs_update", "status", "energy",
        "certified_infeasible", "unclassified"])
    assert tr.stats["pivots"].dtype.kind == "i" and tr.stats["residual"].dtype.kind == "f"


def _variants(v):
    """v and values that differ from it in one of the properties that make its numba type."""
    if not isinstance(v, np.ndarray):
        return [v, int(v), float(v), bool(v), np.int64(v), np.float64(v), np.bool_(v), np.int32(v), np.float32(v)]
    ro = v.copy()
    ro.flags.writeable = False
    out = [v, ro, v.astype(np.float32), v.astype(np.int32), v.astype(np.float64), v.astype(np.int64),
           v.astype(np.bool_), v.astype(v.dtype.newbyteorder()), v[None], np.asfortranarray(v)]
    if v.size > 1:
        out.append(v.reshape(-1)[::2] if v.ndim == 1 else v[:, ::2] if v.shape[1] > 1 else v[::2])
    return out


@pytest.mark.parametrize("name", ["box_push", "tower"])
def test_the_fast_field_check_never_accepts_what_numba_types_differently(name):
    """`_struct` checks each field with numpy's attributes (`_has_field_type`) and asks numba.typeof only when that
    says no: the fast check must never say yes where numba's type is not the field's (a struct of a wrong type would
    compile the kernels again, or fail inside them). Every field of both structs, and variants of each that differ
    in dtype, byte order, ndim, layout, writeability or scalar type."""
    from planar_lcp.engine.layout import OPTIONS_LAYOUT, _has_field_type, numba_type
    model = compile_scene(load_scene(name))
    opts = SimOptions(h=0.01).kernel_options()
    checked = accepted = 0
    for layout, view in ((MODEL_LAYOUT, model.arrays), (WORK_LAYOUT, make_step_work(model)), (OPTIONS_LAYOUT, opts)):
        for f, v in zip(layout, view):
            assert _has_field_type(f, v), f.name            # the arrays as made: the fast path
            for x in _variants(v):
                checked += 1
                if _has_field_type(f, x):
                    accepted += 1
                    assert numba.typeof(x) == numba_type(f), (f.name, x.dtype if hasattr(x, "dtype") else type(x))
    assert accepted < checked



#: compiles the kernels of a run and of a planner's run in this process, then prints every engine kernel compiled
#: without numba's runtime with the return types of its compiled signatures
_RUNTIME_FREE_KERNELS = """
import importlib, json, pkgutil
from numba.core import types
from numba.core.dispatcher import Dispatcher
import planar_lcp.engine as engine
from planar_lcp import load_scene
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator

def holds_array(ty):
    return isinstance(ty, types.Array) or (isinstance(ty, types.BaseTuple) and any(holds_array(t) for t in ty.types))

for options in ({}, {"warm_start": True}):
    sc = load_scene("box_tip")
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, **options))
    q, v, qk, vk = sim.initial_state()
    sim.rollout(q, v, qk, vk[None], 5, record_contacts=True, trajectory_rows=True)
found = []
for info in pkgutil.walk_packages(engine.__path__, "planar_lcp.engine."):
    for obj in vars(importlib.import_module(info.name)).values():
        if isinstance(obj, Dispatcher) and obj.targetoptions.get("_nrt") is False:
            found += [(obj.py_func.__qualname__, str(sig.return_type), holds_array(sig.return_type))
                      for sig in obj.nopython_signatures]
print(json.dumps(found))
"""


@pytest.mark.slow
@pytest.mark.skipif(not JIT, reason="numba's compiled signatures")
def test_kernels_without_numbas_runtime_return_no_array(tmp_path):
    """The engine's kernels compiled without numba's runtime (`_nrt=False`, docs/performance.md "Reference counts")
    hold no reference to what they touch, so none may return an array (it would outlive its owner unowned): every
    such kernel a run and a planner's run compile, on an empty cache in one process, returns none. A struct's field
    cannot be assigned at all (engine/layout.py registers no setattr)."""
    import json
    import os
    import subprocess
    import sys
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PLANAR_LCP_PRECOMPILE="0")
    out = subprocess.run([sys.executable, "-c", _RUNTIME_FREE_KERNELS], env=env, capture_output=True, text=True,
                         timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    found = json.loads(out.stdout.strip().splitlines()[-1])
    assert len(found) >= 30, found                  # the whole step: contacts, assembly, Lemke, the rollouts
    assert [f for f in found if f[2]] == []


@pytest.mark.skipif(not JIT, reason="numba's structs")
def test_calls_of_kernels_without_numbas_runtime_leak_nothing():
    """A kernel without numba's runtime takes a reference to each struct it is given from Python, which its call
    wrapper would never drop: the struct's unboxing releases it after the call (engine/layout.py). Many calls from
    Python (rollouts, steps) leave the structs' reference counts, and with NUMBA_NRT_STATS=1 numba's allocation
    counts, as they were."""
    from numba.core.runtime import rtsys
    sc = load_scene("box_tip")
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
    q, v, qk, vk = sim.initial_state()
    sim.rollout(q, v, qk, vk[None], 5, record_contacts=True)
    sim.step(q, v, qk, vk)
    counts = (sim.kmodel._meminfo.refcount, sim.kwork._meminfo.refcount)
    stats_on = numba.config.NRT_STATS
    before = rtsys.get_allocation_stats() if stats_on else None
    for _ in range(200):
        sim.rollout(q, v, qk, vk[None], 5, record_contacts=True, trajectory_rows=True)
        sim.step(q, v, qk, vk)
    assert (sim.kmodel._meminfo.refcount, sim.kwork._meminfo.refcount) == counts
    if stats_on:
        after = rtsys.get_allocation_stats()
        assert after.alloc - before.alloc == after.free - before.free
