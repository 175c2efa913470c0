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
                 ndyn=sum(b.type == "dynamic" for b in sc.bodies), nvert=a.vert_local.shape[0],
                 npair=a.pair_a.shape[0], nsup=a.sup_dyn.shape[0], k=a.fric_dirs.shape[0],
                 nedge=a.ls_edge.shape[0], nnode=a.ls_node.shape[0], K=sc.sim.limit_surface_twists,
                 ndisk=a.ls_disk.shape[0], ntab=a.ls_disk_table.shape[0])
    for f, v in zip(MODEL_LAYOUT, a):
        assert np.shape(v) == _shape(f, sizes), f.name


def test_the_allocator_sizes_the_lcp_buffers_for_the_largest_problem():
    """Linear buffers for the largest LCP; the dense (quadratic) ones for min(that, DENSE_CAPACITY), grown on demand
    (tests/test_piles.py::test_dense_buffers_grow_when_an_island_needs_them)."""
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
        "penetration", "lemke_retries", "warm_starts", "solved_sparse", "sparse_fallbacks", "solved_lemke",
        "solved_equilibrated", "solved_strict", "solved_velocity", "solved_inelastic", "pgs_uncertified", "fp_change", "pgs_update", "status", "energy"])
    assert tr.stats["pivots"].dtype.kind == "i" and tr.stats["residual"].dtype.kind == "f"
