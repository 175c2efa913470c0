"""The same scene in MuJoCo, as a peer for timing the step's derivatives (`planar-lcp bench derivatives`).

MuJoCo offers the derivatives of its step by finite differences only (`mjd_transitionFD`); this bridge builds the
MuJoCo model of a simple planar scene so that its step and its `mjd_transitionFD` can be timed beside our step and
`Simulator.step_derivatives` in the same process. It is a timing peer, not a comparison of dynamics: MuJoCo's contacts
are soft (a regularised convex program, not an LCP) and a table is a floor under the body, touched at the corners of
its base, where our horizontal plane has a limit surface or support points.

mujoco is imported inside the functions only: `import planar_lcp.bridges.mujoco` does not need it.

Mapping:

- Vertical plane (x, y up) -> MuJoCo's x-z plane (z up): each dynamic body gets a slide joint along x, one along z
  and a hinge about -y (so that a positive angle turns x towards z, as ours turns x towards y); its `qpos` are our
  (x, y, angle) of its centre of mass. Gravity (gx, gy) -> (gx, 0, gy). A half-plane -> a plane geom through its
  point with its normal.
- Horizontal plane (top-down, a table under everything) -> MuJoCo's x-y plane over a floor, gravity
  -support_gravity along z: a dynamic body gets slide joints along x, y and z (its weight on the floor) and a hinge
  about z; its shape is extruded EXTRUSION_HEIGHT up from the floor. A kinematic body (a pusher) -> a body with slide
  joints along x and y held to its prescribed velocity by velocity actuators (gain SERVO_GAIN, implicit in the
  `implicitfast` integrator), not touching the floor; its controls are our vk's x and y.
- Shapes: disk -> sphere (vertical) or cylinder (horizontal), capsule -> capsule, box -> box; each centred on its
  body's centre of mass (the scene's shapes without offsets). Masses and the moment of inertia about the plane's
  normal as ours (`massprops.body_mass_properties`).
- Friction: every pair that can touch is an explicit `<pair>` with the scene's mu for it (the table's: the body's
  support_friction); MuJoCo's default collisions are off (contype = conaffinity = 0), so no other pair touches.
"""

from dataclasses import dataclass

import numpy as np

from planar_lcp.spec.massprops import body_mass_properties
from planar_lcp.spec.scene import Scene

#: m: the height a horizontal scene's shapes are extruded to (half of it is the geoms' half-height)
EXTRUSION_HEIGHT = 0.05
#: N s/m per kg of the pusher: its velocity actuators' gain (the pusher follows its velocity within a few steps)
SERVO_GAIN = 1000.0
#: kg: a pusher's mass in MuJoCo (ours are kinematic: no mass)
PUSHER_MASS = 10.0
#: MuJoCo's torsional and rolling friction coefficients on every pair (its defaults)
TORSIONAL, ROLLING = 0.005, 0.0001


class UnsupportedScene(ValueError):
    """The scene has something this bridge does not map (it names what)."""


@dataclass
class MujocoScene:
    """A scene's MuJoCo model and data (`model`, `data`), the MJCF it was built from (`xml`), the dynamic bodies'
    joint addresses in qpos and qvel (`qpos_adr`, `qvel_adr`: per body, the addresses of x, y, angle) and the
    kinematic bodies' actuators (`ctrl_adr`: per body, x and y)."""

    scene: Scene
    xml: str
    model: object
    data: object
    qpos_adr: dict
    qvel_adr: dict
    ctrl_adr: dict

    def set_controls(self, vk):
        """The kinematic bodies' prescribed velocities (nkin, 3), in the scene's order of kinematic bodies."""
        kin = [b for b in self.scene.bodies if b.type == "kinematic"]
        for i, b in enumerate(kin):
            for c, a in enumerate(self.ctrl_adr[b.name]):
                self.data.ctrl[a] = vk[i][c]

    def set_state(self, q, v, qk, vk):
        """Our state: the dynamic bodies' centre-of-mass poses q and velocities v (ndyn, 3), the kinematic bodies'
        poses qk and velocities vk (nkin, 3), each in the scene's order of its kind; the floor carries the bodies of
        a horizontal scene (their z at 0, at rest along it). Then mj_forward."""
        import mujoco
        dyn = [b.name for b in self.scene.bodies if b.type == "dynamic"]
        kin = [b.name for b in self.scene.bodies if b.type == "kinematic"]
        self.data.qpos[:] = 0.0
        self.data.qvel[:] = 0.0
        for names, pos, vel in ((dyn, q, v), (kin, qk, vk)):
            for i, name in enumerate(names):
                for c, a in enumerate(self.qpos_adr[name]):
                    self.data.qpos[a] = pos[i][c]
                for c, a in enumerate(self.qvel_adr[name]):
                    self.data.qvel[a] = vel[i][c]
        if kin:
            self.set_controls(vk)
        mujoco.mj_forward(self.model, self.data)

    def pose(self, name):
        """(x, y, angle) of a dynamic body."""
        return np.array([self.data.qpos[a] for a in self.qpos_adr[name]])


def _f(x):
    return f"{float(x):.17g}"


def _shape_geom(shape, horizontal, name):
    """The geom element of one shape (centred on the body), or UnsupportedScene."""
    if tuple(shape.offset) != (0.0, 0.0) or shape.angle != 0.0:
        raise UnsupportedScene(f"body {name}: a shape with an offset or angle (the bridge maps centred shapes)")
    hz = 0.5 * EXTRUSION_HEIGHT
    lift = f' pos="0 0 {_f(hz)}"' if horizontal else ""
    if shape.type == "disk":
        if horizontal:
            return f'<geom type="cylinder" size="{_f(shape.radius)} {_f(hz)}"{lift}'
        return f'<geom type="sphere" size="{_f(shape.radius)}"'
    if shape.type == "capsule":
        half = 0.5 * shape.length
        z = _f(hz) if horizontal else "0"
        return (f'<geom type="capsule" fromto="{_f(-half)} 0 {z} {_f(half)} 0 {z}" size="{_f(shape.radius)}"')
    if shape.type == "box" and shape.radius == 0.0:
        # vertical plane: our x-y is MuJoCo's x-z, so the box's height is along z and its depth along y
        if horizontal:
            return f'<geom type="box" size="{_f(shape.width / 2)} {_f(shape.height / 2)} {_f(hz)}"{lift}'
        return f'<geom type="box" size="{_f(shape.width / 2)} {_f(hz)} {_f(shape.height / 2)}"'
    raise UnsupportedScene(f"body {name}: shape {shape.type!r}{' with a radius' if shape.type == 'box' else ''} "
                           "(the bridge maps disks, capsules and boxes)")


def mujoco_xml(scene: Scene, h=None, margin=0.0) -> tuple:
    """The MJCF of `scene` (module docstring) with time step h (default the scene's) and contacts generated within
    `margin` (m; ours: SimOptions.contact_margin): (xml, dynamic names, kinematic names, static names).
    UnsupportedScene names what the bridge does not map."""
    horizontal = scene.world.plane == "horizontal"
    h = scene.sim.h if h is None else h
    if scene.world.restitution > 0.0 or scene.world.restitution_pairs:
        raise UnsupportedScene("restitution (MuJoCo's contacts have none of Newton's law)")
    gx, gy = scene.world.gravity
    gravity = f"0 0 {_f(-scene.world.support_gravity)}" if horizontal else f"{_f(gx)} 0 {_f(gy)}"
    lines = [f'<mujoco model="{scene.name}">',
             f'  <option timestep="{_f(h)}" gravity="{gravity}" integrator="implicitfast"/>',
             "  <worldbody>"]
    dyn, kin, static, geoms = [], [], [], {}
    if horizontal:
        lines.append('    <geom name="floor" type="plane" size="0 0 1" contype="0" conaffinity="0"/>')
    for b in scene.bodies:
        if b.type == "static":
            if horizontal:
                raise UnsupportedScene(f"body {b.name}: a static body on a horizontal table")
            if len(b.shapes) != 1 or b.shapes[0].type != "halfplane":
                raise UnsupportedScene(f"body {b.name}: a static body other than one half-plane")
            s = b.shapes[0]
            (px, py), (nx, ny) = s.point, s.normal
            geoms[b.name] = f"{b.name}_geom"
            lines.append(f'    <geom name="{b.name}_geom" type="plane" size="0 0 1" pos="{_f(px)} 0 {_f(py)}" '
                         f'zaxis="{_f(nx)} 0 {_f(ny)}" contype="0" conaffinity="0"/>')
            static.append(b.name)
            continue
        if len(b.shapes) != 1:
            raise UnsupportedScene(f"body {b.name}: {len(b.shapes)} shapes (the bridge maps one per body)")
        if b.path is not None or b.max_force is not None or b.max_torque is not None:
            raise UnsupportedScene(f"body {b.name}: a path or a force limit")
        geom = _shape_geom(b.shapes[0], horizontal, b.name)
        geoms[b.name] = f"{b.name}_geom"
        x, y = b.position
        if b.type == "kinematic":
            if not horizontal:
                raise UnsupportedScene(f"body {b.name}: a kinematic body in the vertical plane")
            kin.append(b.name)
            i = 0.5 * PUSHER_MASS * max(b.shapes[0].radius, b.shapes[0].width, b.shapes[0].height) ** 2
            lines += [f'    <body name="{b.name}" pos="0 0 0">',
                      f'      <joint name="{b.name}_x" type="slide" axis="1 0 0"/>',
                      f'      <joint name="{b.name}_y" type="slide" axis="0 1 0"/>',
                      f'      <inertial pos="0 0 0" mass="{_f(PUSHER_MASS)}" diaginertia="{_f(i)} {_f(i)} {_f(i)}"/>',
                      f'      {geom} name="{b.name}_geom" contype="0" conaffinity="0"/>',
                      "    </body>"]
            continue
        dyn.append(b.name)
        com, inertia = body_mass_properties(b)
        if np.any(np.abs(com) > 0.0):
            raise UnsupportedScene(f"body {b.name}: a centre of mass off the body's origin")
        if b.mass is None:
            raise UnsupportedScene(f"body {b.name}: no mass given")
        mass = float(b.mass)
        if horizontal:
            joints = [(f"{b.name}_x", "slide", "1 0 0"), (f"{b.name}_y", "slide", "0 1 0"),
                      (f"{b.name}_z", "slide", "0 0 1"), (f"{b.name}_a", "hinge", "0 0 1")]
        else:
            joints = [(f"{b.name}_x", "slide", "1 0 0"), (f"{b.name}_y", "slide", "0 0 1"),
                      (f"{b.name}_a", "hinge", "0 -1 0")]
        lines.append(f'    <body name="{b.name}" pos="0 0 0">')
        lines += [f'      <joint name="{n}" type="{t}" axis="{a}"/>' for n, t, a in joints]
        lines += [f'      <inertial pos="0 0 0" mass="{_f(mass)}" diaginertia="{_f(inertia)} {_f(inertia)} '
                  f'{_f(inertia)}"/>',
                  f'      {geom} name="{b.name}_geom" contype="0" conaffinity="0"/>',
                  "    </body>"]
    lines.append("  </worldbody>")
    pairs = []
    names = [b.name for b in scene.bodies]
    for i, a in enumerate(names):
        for bname in names[i + 1:]:
            ta, tb = scene.body(a).type, scene.body(bname).type
            if "dynamic" not in (ta, tb):
                continue
            mu = scene.friction_between(a, bname)
            pairs.append((geoms[a], geoms[bname], mu))
    if horizontal:
        for name in dyn:
            b = scene.body(name)
            mu = scene.world.friction if b.support_friction is None else b.support_friction
            pairs.append(("floor", geoms[name], mu))
    lines.append("  <contact>")
    lines += [f'    <pair geom1="{g1}" geom2="{g2}" condim="3" margin="{_f(margin)}" friction="{_f(mu)} {_f(mu)} '
              f'{TORSIONAL} {TORSIONAL} {ROLLING}"/>' for g1, g2, mu in pairs]
    lines.append("  </contact>")
    if kin:
        lines.append("  <actuator>")
        for name in kin:
            for c in ("x", "y"):
                lines.append(f'    <velocity name="{name}_v{c}" joint="{name}_{c}" kv="{_f(SERVO_GAIN * PUSHER_MASS)}" '
                             'ctrllimited="false"/>')
        lines.append("  </actuator>")
    lines.append("</mujoco>")
    return "\n".join(lines), dyn, kin, static


def mujoco_scene(scene: Scene, h=None, margin=0.0) -> MujocoScene:
    """The MuJoCo model and data of `scene` (`mujoco_xml`'s arguments) at its initial state (positions, velocities,
    the pushers' controls)."""
    import mujoco

    xml, dyn, kin, _ = mujoco_xml(scene, h, margin)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    qpos_adr, qvel_adr, ctrl_adr = {}, {}, {}
    for name in dyn + kin:
        axes = ("x", "y", "a") if name in dyn else ("x", "y")
        jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_{c}") for c in axes]
        qpos_adr[name] = [int(model.jnt_qposadr[j]) for j in jids]
        qvel_adr[name] = [int(model.jnt_dofadr[j]) for j in jids]
    for name in kin:
        ctrl_adr[name] = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{name}_v{c}") for c in "xy"]
    out = MujocoScene(scene=scene, xml=xml, model=model, data=data, qpos_adr=qpos_adr, qvel_adr=qvel_adr,
                      ctrl_adr=ctrl_adr)
    # the scene's start: its bodies' poses and velocities (their frames' origins are their centres of mass here)
    poses = {n: (*scene.body(n).position, scene.body(n).angle) for n in dyn + kin}
    rates = {n: (*scene.body(n).velocity, scene.body(n).angular_velocity) for n in dyn + kin}
    out.set_state([poses[n] for n in dyn], [rates[n] for n in dyn], [poses[n] for n in kin], [rates[n] for n in kin])
    return out
