"""The kernels' structs (planar_lcp/kernels/structs.py) mirror the namedtuples field for field and share buffers."""

import numba
import numpy as np
import pytest

from planar_lcp import load_scene
from planar_lcp.engine.step import ST_NCON, StepWork, make_step_work
from planar_lcp.engine.layout import MODEL_FIELDS, WORK_FIELDS, model_struct, work_struct
from planar_lcp.model import ModelArrays, compile_scene
from planar_lcp.sim import SimOptions, Simulator

JIT = not numba.config.DISABLE_JIT


def test_struct_fields_are_the_namedtuple_fields_in_order():
    assert tuple(k for k, _ in MODEL_FIELDS) == ModelArrays._fields
    assert tuple(k for k, _ in WORK_FIELDS) == StepWork._fields


@pytest.mark.parametrize("name", ["falling_rod", "box_push", "push_t", "four_disks"])
def test_every_field_has_the_declared_type(name):
    model = compile_scene(load_scene(name))
    model_struct(model.arrays)          # raises TypeError naming the field on a mismatch
    work_struct(make_step_work(model))


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
    ncon = int(sim.stats[ST_NCON])
    assert ncon > 0
    assert np.array_equal(sim.work.v_new, v)          # written by the kernel through sim.kwork
    assert np.all(sim.work.con_cn[:ncon] >= 0.0) and sim.work.con_cn[:ncon].max() > 0.0
