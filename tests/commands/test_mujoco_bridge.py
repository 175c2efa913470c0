"""planar_lcp.bridges.mujoco builds the same scene in MuJoCo (the timing peer of `bench derivatives`): the axes,
the angle's sign, masses, inertia, friction and the controls map as its docstring says, checked against our own
step and geometry."""

import math

import numpy as np
import pytest

from planar_lcp.bridges.mujoco import UnsupportedScene, mujoco_scene, mujoco_xml
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec.scene import load_scene

mujoco = pytest.importorskip("mujoco")


def test_a_free_rod_steps_as_ours_and_its_axis_turns_the_same_way():
    """Free flight (no contact): semi-implicit Euler in both, so one MuJoCo step is ours to round-off; the capsule's
    axis in MuJoCo's x-z plane is (cos a, sin a) of our angle a."""
    sc = load_scene("falling_rod")
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
    q, v, qk, vk = sim.initial_state()
    ms = mujoco_scene(sc)
    ms.set_state(q, v, qk, vk)
    assert ms.data.ncon == 0
    gid = mujoco.mj_name2id(ms.model, mujoco.mjtObj.mjOBJ_GEOM, "rod_geom")
    axis = ms.data.geom_xmat[gid].reshape(3, 3)[:, 2]         # a fromto capsule's local z is its segment
    a = q[0, 2]
    assert abs(abs(axis @ [math.cos(a), 0.0, math.sin(a)]) - 1.0) < 1e-12 and abs(axis[1]) < 1e-12
    mujoco.mj_step(ms.model, ms.data)
    q1, v1, _, _ = sim.step(q, v, qk, vk)
    np.testing.assert_allclose(ms.pose("rod"), q1[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose([ms.data.qvel[i] for i in ms.qvel_adr["rod"]], v1[0], rtol=0, atol=1e-12)
    assert math.isclose(ms.model.body_mass[1], 1.0) and math.isclose(ms.model.dof_armature[0] + 1.0, 1.0)
    assert math.isclose(ms.model.body_inertia[1][1], 0.002)   # about the hinge's axis (-y): the scene's inertia


def test_the_rod_touching_the_table_is_one_contact_at_our_gap():
    sc = load_scene("falling_rod")
    ms = mujoco_scene(sc, margin=2e-3)
    L, r = 0.5, 0.05
    for a, gap in ((0.3, 1e-3), (2.0, -2e-4)):
        # the lower end's core point at height r + gap
        y = r + gap + 0.5 * L * abs(math.sin(a))
        ms.set_state([[0.1, y, a]], [[0.0, 0.0, 0.0]], np.zeros((0, 3)), np.zeros((0, 3)))
        assert ms.data.ncon == 1
        assert abs(ms.data.contact[0].dist - gap) < 1e-12
        assert math.isclose(ms.data.contact[0].friction[0], 0.6)


def test_the_pushed_box_on_its_floor():
    """Horizontal: gravity along -z at the support gravity, the box on the floor with the table's friction, the
    pusher held to its velocity by two velocity actuators, touching the box with the pair's friction."""
    sc = load_scene("box_push")
    ms = mujoco_scene(sc, margin=2e-3)
    m, d = ms.model, ms.data
    np.testing.assert_allclose(m.opt.gravity, [0, 0, -9.81])
    assert m.nu == 2 and list(d.ctrl) == [0.1, 0.0]
    assert math.isclose(m.body_inertia[1][2], 1.0 * (0.2 ** 2 + 0.1 ** 2) / 12)     # about z: ours (uniform box)
    frictions = sorted(float(c.friction[0]) for c in d.contact[:d.ncon])
    assert d.ncon >= 5 and frictions[0] == 0.3 and frictions[-1] == 0.35      # the pusher's and the floor's
    for _ in range(20):
        mujoco.mj_step(m, d)
    box, z = ms.pose("box"), d.qpos[ms.qpos_adr["box"][0] + 2]
    # pushed along x; on the floor, within the contacts' margin: MuJoCo holds a contact's distance at its margin
    assert box[0] > 0.0 and 0.0 < z < 2e-3
    assert abs(d.qvel[ms.qvel_adr["pusher"][0]] - 0.1) < 0.01                 # the servo holds the pusher's speed


@pytest.mark.parametrize("name, why", [("bouncing_disk", "restitution"),
                                       ("box_tip", "kinematic body in the vertical plane"),
                                       ("tower", "")])
def test_what_the_bridge_does_not_map_is_named(name, why):
    sc = load_scene(name)
    try:
        mujoco_xml(sc)
    except UnsupportedScene as e:
        assert why in str(e)
    else:
        assert why == "", f"{name} was mapped"
