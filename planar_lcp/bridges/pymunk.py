"""Build a pymunk (Chipmunk2D) space from a planar_lcp Scene and run it, for apples-to-apples comparisons.

pymunk is imported inside the functions only: `import planar_lcp.bridges.pymunk` does not need pymunk.

Mapping (docs/pymunk-comparison.md says more):

- disk -> Circle, capsule -> Segment with radius, box / polygon -> Poly with radius (pymunk inflates a Poly by its
  radius exactly as we inflate a core), segment -> Segment with radius. A half-plane -> a long static Segment of
  thickness `HALFPLANE_RADIUS` whose surface lies on the boundary (its centre line offset by that radius into the
  solid).
- Frames: a pymunk body's `position` is its body-frame origin and its `center_of_gravity` is set to our centre of
  mass (`massprops.body_mass_properties`) in that frame, so `position` and `angle` are the scene's body-frame pose.
  pymunk's `velocity` is the velocity of the centre of gravity; we convert to and from the origin's velocity.
- Mass and moment (about the centre of mass) are set on the body; shapes carry no mass, so pymunk does not
  recompute them.
- Friction: pymunk's arbiter friction is the product of the two shapes' frictions. `friction_assignment` solves
  f_a f_b = mu_ab for every body pair that can touch (least squares on log f, then checked exactly). When no
  assignment exists (e.g. an even cycle a-b-c-d with mu_ab mu_cd != mu_bc mu_da, or mu = 0 between two bodies that
  have positive mu elsewhere), a wildcard pre_solve callback sets each arbiter's friction to the scene's mu for its
  pair (slower: one Python call per touching pair per step).
- Restitution: shapes carry elasticity 0 (pymunk's product rule then gives 0 for every pair, the scene default);
  when any pair that can touch has a coefficient e > 0 (`Scene.restitution_between`: world.restitution and
  world.restitution_pairs), a wildcard pre_solve callback sets each arbiter's restitution to the scene's e for its
  pair, so pymunk's elasticity is the scene's per pair, not a product. Chipmunk applies it as a target normal
  velocity -e v_n with v_n the contact's normal velocity at the start of the step (before gravity), solved by its
  iterations together with the position bias; our model is Newton's law in the step's LCP (docs/method.md).
- Kinematic bodies -> KINEMATIC pymunk bodies with the scene's constant velocity, or a `path`'s velocity of each
  step (`set_kinematic_velocity`, the sequence our engine takes). A force-limited one (`max_force`,
  `max_torque`) -> pymunk's own velocity servo (its tank.py): a KINEMATIC control body moving at the prescribed
  velocity, and the body itself DYNAMIC, without gravity, held to it by a PivotJoint at its origin with max_bias = 0
  and max_force = max_force (and a GearJoint with max_torque, else an unlimited one). pymunk needs a mass where our
  servo is massless: SERVO_MASS_RATIO times the lightest dynamic body's mass, its moment that of a disk of the body's
  extent. Its pivot is an isotropic clamp (a disk of radius max_force) where ours is an octagon whose faces are
  max_force from the origin.
- Horizontal plane: pymunk has no table. Each dynamic body gets one PivotJoint to the static body per support
  point p_s of `massprops.support_points` (the points and load shares w_s of our support-point model), at p_s, with
  max_bias = 0 (velocity only, no position correction) and max_force = mu m g w_s (that point's Coulomb limit;
  they sum to mu m g). This is Coulomb friction at those points only as far as Chipmunk's solver gets it: each
  pivot is an isotropic clamp on its own accumulated impulse, solved one after another for `iterations` sweeps
  (10 by default) with no coupling beyond what the sweeps converge to, and the clamp projects in impulse space,
  so a sliding point's force converges to the direction of K_s^-1 (-v_s) (K_s the point's inverse
  effective-mass matrix, impulse -> velocity change) rather than -v_s: box_push's 0.2 x 0.1 m box sliding
  without spin decelerates at 0.976 mu g, not mu g (tests/commands/test_pymunk_bridge.py). pymunk cannot represent the
  limit surface of a uniform pressure (`support_model = "limit_surface"` in planar_lcp), nor a set of
  support-point forces coupled by maximal dissipation in one rigid solve (our LCP). The older set-up, one pivot
  at the COM plus a GearJoint (pymunk's tank.py), capped force and torque separately and left the box of
  box_push unturned.
"""

from dataclasses import dataclass, field

import numpy as np

from planar_lcp.frames import com_velocity, frame_to_com
from planar_lcp.spec.massprops import body_mass_properties, support_points
from planar_lcp.spec.path import kinematic_velocities
from planar_lcp.spec.scene import Scene, load_scene
from planar_lcp.trajectory import Trajectory, mechanical_energy

#: pymunk's defaults (slop 0.1, for pixels) are far too large in metres; these are SI-sensible.
DEFAULT_ITERATIONS = 10            # solver iterations per step (pymunk's default)
DEFAULT_COLLISION_SLOP = 1e-4      # m: overlap pymunk leaves uncorrected (0.1 mm; pymunk's 0.1 would be 10 cm)
DEFAULT_COLLISION_BIAS = (1.0 - 0.1) ** 60   # fraction of overlap left after 1 s (pymunk's default, time-based)
HALFPLANE_HALF_LENGTH = 100.0      # m: a half-plane is a static segment this long each way from its point
HALFPLANE_RADIUS = 0.5             # m: its thickness (radius); the surface is on the half-plane's boundary
SERVO_MASS_RATIO = 1e-3            # a force-limited kinematic body's pymunk mass, times the lightest dynamic mass


def _mu_key(a, b):
    return (a, b) if a <= b else (b, a)


#: The per-pair coefficients `contact_pairs` can give: the Scene method that defines each.
PAIR_COEFFICIENTS = {"friction": "friction_between", "restitution": "restitution_between"}


def contact_pairs(scene: Scene, coefficient="friction"):
    """{(name_a, name_b) sorted: value} for every pair of bodies that can touch (different, at least one dynamic):
    the scene's Coulomb mu (coefficient "friction") or Newton's e ("restitution") of the pair."""
    between = getattr(scene, PAIR_COEFFICIENTS[coefficient])
    out = {}
    bodies = scene.bodies
    for i, a in enumerate(bodies):
        for b in bodies[i + 1:]:
            if a.type != "dynamic" and b.type != "dynamic":
                continue
            out[_mu_key(a.name, b.name)] = float(between(a.name, b.name))
    return out


def friction_assignment(scene: Scene, rtol=1e-12):
    """Per-body shape frictions f with f_a f_b = mu_ab for every pair that can touch, if they exist.

    Returns
    -------
    f : dict name -> float
        The frictions to put on each body's shapes (the best least-squares fit when not exact).
    exact : bool
        True if pymunk's product rule reproduces every pair's mu to `rtol`; False means a pre_solve callback is
        needed.
    """
    pairs = contact_pairs(scene)
    names = [b.name for b in scene.bodies]
    f = {n: 1.0 for n in names}
    # a body whose every pair has mu = 0 gets friction 0; the others are solved on log f
    zero_only = {n for n in names
                 if all(mu == 0.0 for (a, b), mu in pairs.items() if n in (a, b))
                 and any(n in k for k in pairs)}
    for n in zero_only:
        f[n] = 0.0
    rows = [(a, b, mu) for (a, b), mu in pairs.items() if mu > 0.0 and a not in zero_only and b not in zero_only]
    free = sorted({n for a, b, _ in rows for n in (a, b)})
    if rows:
        idx = {n: i for i, n in enumerate(free)}
        A = np.zeros((len(rows), len(free)))
        rhs = np.zeros(len(rows))
        for r, (a, b, mu) in enumerate(rows):
            A[r, idx[a]] += 1.0
            A[r, idx[b]] += 1.0
            rhs[r] = np.log(mu)
        x = np.linalg.lstsq(A, rhs, rcond=None)[0]  # minimum norm: balanced (sqrt mu each) when underdetermined
        for n, i in idx.items():
            f[n] = float(np.exp(x[i]))
    exact = all(abs(f[a] * f[b] - mu) <= rtol * max(mu, 1e-300) if mu > 0 else f[a] * f[b] == 0.0
                for (a, b), mu in pairs.items())
    return f, exact


@dataclass
class SpaceHandles:
    """What `build_space` made, by scene body name.

    bodies : name -> pymunk.Body (static bodies map to their own STATIC body)
    shapes : name -> list of pymunk shapes, in the scene's shape order
    shape_body : pymunk shape -> body name
    dynamic_names, kinematic_names : scene order
    com_local : name -> (2,) centre of mass in the body frame (dynamic bodies)
    friction_mode : "product" (shape frictions reproduce every pair's mu) or "pre_solve" (a callback sets them)
    pair_mu : {(a, b) sorted: mu}
    pair_e : {(a, b) sorted: e}, the same pairs
    restitution_mode : "zero" (every pair e = 0: shape elasticities 0 give it) or "pre_solve" (a callback sets each
        arbiter's restitution to its pair's e)
    support_joints : dynamic body name -> tuple of its table-friction PivotJoints to the static body, one
        per support point in `massprops.support_points` order (horizontal plane; an empty dict otherwise)
    h : the time step the space is meant to be stepped with (s)
    settings : iterations, collision_slop, collision_bias as set
    servo_joints : force-limited kinematic body name -> (PivotJoint, GearJoint) to its control body
    """

    bodies: dict
    shapes: dict
    shape_body: dict
    dynamic_names: tuple
    kinematic_names: tuple
    com_local: dict
    friction_mode: str
    pair_mu: dict
    pair_e: dict
    restitution_mode: str
    support_joints: dict
    h: float
    settings: dict = field(default_factory=dict)
    servo_joints: dict = field(default_factory=dict)


def _make_shapes(pymunk, body, spec):
    """pymunk shapes for one ShapeSpec on `body` (body-frame coordinates)."""
    t = spec.type
    if t == "halfplane":
        p = np.asarray(spec.point, float)
        n = np.asarray(spec.normal, float)
        n = n / np.linalg.norm(n)
        tang = np.array([-n[1], n[0]])
        c = p - HALFPLANE_RADIUS * n
        a, b = c - HALFPLANE_HALF_LENGTH * tang, c + HALFPLANE_HALF_LENGTH * tang
        return pymunk.Segment(body, tuple(a), tuple(b), HALFPLANE_RADIUS)
    core = np.asarray(spec.core_vertices_body(), float).reshape(-1, 2)
    r = float(spec.radius)
    if t == "disk":
        return pymunk.Circle(body, r, tuple(core[0]))
    if t in ("capsule", "segment"):
        return pymunk.Segment(body, tuple(core[0]), tuple(core[1]), r)
    if t in ("box", "polygon"):
        return pymunk.Poly(body, [tuple(v) for v in core], None, r)
    raise ValueError(f"unknown shape type {t!r}")


def build_space(scene, *, iterations=DEFAULT_ITERATIONS, collision_slop=DEFAULT_COLLISION_SLOP,
                collision_bias=DEFAULT_COLLISION_BIAS, h=None):
    """A pymunk.Space holding the scene's bodies at their initial state.

    Parameters
    ----------
    scene : Scene, shipped scene name or .toml path
    iterations : int
        Chipmunk's solver iterations per step (sequential impulses; more = stiffer contacts and stacks).
    collision_slop : float, m
        Overlap allowed before pymunk pushes shapes apart. pymunk's default 0.1 assumes pixels (10 cm here).
    collision_bias : float
        Fraction of an overlap still left after one second (pymunk's time-based Baumgarte-like correction).
    h : float, s, optional
        The step the space will be stepped with (default the scene's sim.h); recorded in the handles.

    Returns
    -------
    (pymunk.Space, SpaceHandles)
    """
    import pymunk

    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    if int(iterations) < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    if not (np.isfinite(collision_slop) and collision_slop >= 0):
        raise ValueError(f"collision_slop must be >= 0 (m), got {collision_slop}")
    if not (np.isfinite(collision_bias) and 0 <= collision_bias <= 1):
        raise ValueError(f"collision_bias must be in [0, 1], got {collision_bias}")
    h = float(scene.sim.h if h is None else h)
    space = pymunk.Space()
    space.iterations = int(iterations)
    space.collision_slop = float(collision_slop)
    space.collision_bias = float(collision_bias)
    horizontal = scene.world.plane == "horizontal"
    space.gravity = (0.0, 0.0) if horizontal else tuple(float(g) for g in scene.world.gravity)
    space.damping = float(scene.world.damping)          # the same meaning: velocity kept after 1 s

    fric, exact = friction_assignment(scene)
    pair_mu = contact_pairs(scene)
    pair_e = contact_pairs(scene, "restitution")
    bodies, shapes, shape_body, com_local, joints, servo_joints = {}, {}, {}, {}, {}, {}
    dyn, kin = [], []
    servo_mass = SERVO_MASS_RATIO * min([float(b.mass) for b in scene.bodies if b.type == "dynamic"] or [1.0])
    for b in scene.bodies:
        if b.type == "dynamic":
            com, inertia = body_mass_properties(b)
            body = pymunk.Body(float(b.mass), float(inertia), body_type=pymunk.Body.DYNAMIC)
            dyn.append(b.name)
            com_local[b.name] = np.asarray(com, float)
        elif b.type == "kinematic" and b.max_force is not None:
            reach = max(float(np.max(np.linalg.norm(s.core_vertices_body(), axis=1))) + s.radius for s in b.shapes)
            body = pymunk.Body(servo_mass, servo_mass * reach * reach / 2.0, body_type=pymunk.Body.DYNAMIC)
            body.velocity_func = _without_gravity
            kin.append(b.name)
        elif b.type == "kinematic":
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            kin.append(b.name)
        else:
            body = pymunk.Body(body_type=pymunk.Body.STATIC)
        made = []
        for s in b.shapes:
            sh = _make_shapes(pymunk, body, s)
            sh.friction = fric[b.name]
            sh.elasticity = 0.0          # the scene's e > 0 goes on the arbiters (pre_solve below)
            made.append(sh)
            shape_body[sh] = b.name
        if b.type == "dynamic":
            # set after the shapes: mass-less shapes leave mass and moment alone, and the COG is ours
            body.mass = float(b.mass)
            body.moment = float(inertia)
            body.center_of_gravity = tuple(com_local[b.name])
        body.angle = float(b.angle)
        body.position = (float(b.position[0]), float(b.position[1]))
        w = float(b.angular_velocity)
        vo = np.asarray(b.velocity, float)
        if b.type == "dynamic":
            body.velocity = com_velocity(b.angle, vo, w, com_local[b.name])  # pymunk's is the centre of gravity's
        else:
            body.velocity = tuple(vo)
        body.angular_velocity = w
        space.add(body, *made)
        bodies[b.name] = body
        shapes[b.name] = made
        if b.type == "kinematic" and b.max_force is not None:
            # the servo: a control body on the prescribed motion, the body held to it within its limits
            control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            control.position, control.angle = body.position, body.angle
            control.velocity, control.angular_velocity = tuple(vo), w
            pivot = pymunk.PivotJoint(control, body, (0.0, 0.0), (0.0, 0.0))
            pivot.max_bias = 0.0
            pivot.max_force = float(b.max_force)
            gear = pymunk.GearJoint(control, body, 0.0, 1.0)
            gear.max_bias = 0.0
            if b.max_torque is not None:
                gear.max_force = float(b.max_torque)
            space.add(control, pivot, gear)
            servo_joints[b.name] = (pivot, gear)

    if horizontal:
        g = float(scene.world.support_gravity)
        for b in scene.bodies:
            if b.type != "dynamic":
                continue
            body = bodies[b.name]
            pts, wts, mu = support_points(b, scene.world)
            made = []
            for p, w in zip(np.asarray(pts, float), np.asarray(wts, float)):
                # pymunk's anchors are in the body's local frame, relative to `position` (the body-frame origin,
                # not the centre of gravity), i.e. our body frame: the support point goes in as is. The static
                # body's frame is the world, so its anchor is the same point in world coordinates.
                pivot = pymunk.PivotJoint(space.static_body, body, tuple(body.local_to_world(tuple(p))), tuple(p))
                pivot.max_bias = 0.0                           # velocity only: the table has no rest position
                pivot.max_force = float(mu * b.mass * g * w)   # this point's Coulomb limit, mu times its load
                made.append(pivot)
            space.add(*made)
            joints[b.name] = tuple(made)

    mode = "product" if exact else "pre_solve"
    bouncy = any(e > 0.0 for e in pair_e.values())
    if not exact or bouncy:
        set_mu = pair_mu if not exact else None
        set_e = pair_e if bouncy else None

        def pre_solve(arbiter, space_, data):
            s1, s2 = arbiter.shapes
            key = _mu_key(shape_body[s1], shape_body[s2])
            if set_mu is not None:
                arbiter.friction = set_mu[key]
            if set_e is not None:
                arbiter.restitution = set_e[key]
        space.on_collision(None, None, pre_solve=pre_solve)

    handles = SpaceHandles(bodies=bodies, shapes=shapes, shape_body=shape_body, dynamic_names=tuple(dyn),
                           kinematic_names=tuple(kin), com_local=com_local, friction_mode=mode, pair_mu=pair_mu,
                           pair_e=pair_e, restitution_mode="pre_solve" if bouncy else "zero", support_joints=joints,
                           h=h, servo_joints=servo_joints,
                           settings=dict(iterations=int(iterations), collision_slop=float(collision_slop),
                                         collision_bias=float(collision_bias)))
    return space, handles


def _without_gravity(body, gravity, damping, dt):
    """A force-limited kinematic body's velocity update: no gravity (our servo is massless: gravity does not move it)."""
    type(body).update_velocity(body, (0.0, 0.0), damping, dt)


def read_state(handles):
    """Body-frame poses and origin velocities of the dynamic bodies, and kinematic poses, as numpy arrays.

    Returns q (ndyn, 3), v (ndyn, 3), qk (nkin, 3), v_com (ndyn, 3) the centre-of-mass velocities.
    """
    nd, nk = len(handles.dynamic_names), len(handles.kinematic_names)
    q, v, qk, vc = np.zeros((nd, 3)), np.zeros((nd, 3)), np.zeros((nk, 3)), np.zeros((nd, 3))
    for j, n in enumerate(handles.dynamic_names):
        b = handles.bodies[n]
        p = b.position
        vo = b.velocity_at_world_point(p)
        q[j] = (p.x, p.y, b.angle)
        v[j] = (vo.x, vo.y, b.angular_velocity)
        vc[j] = (b.velocity.x, b.velocity.y, b.angular_velocity)
    for j, n in enumerate(handles.kinematic_names):
        b = handles.bodies[n]
        qk[j] = (b.position.x, b.position.y, b.angle)
    return q, v, qk, vc


def set_kinematic_velocity(handles, name, vk):
    """Give kinematic body `name` the origin velocity vk = (vx, vy, omega) for the next step: the body itself, or a
    force-limited one's control body (the servo's reference). pymunk moves a KINEMATIC body by h times it at the
    start of `space.step(h)`, as our engine's qk + h vk does."""
    joints = handles.servo_joints.get(name)
    body = joints[0].a if joints is not None else handles.bodies[name]
    body.velocity = (float(vk[0]), float(vk[1]))
    body.angular_velocity = float(vk[2])


@dataclass(frozen=True)
class PymunkOptions:
    """The settings of a pymunk run, as `Trajectory.options` (a SimOptions for our runs): h (s), Chipmunk's
    iterations, collision_slop (m) and collision_bias, the friction rule ("product" or "pre_solve") and the
    restitution rule ("zero" or "pre_solve", `SpaceHandles.restitution_mode`)."""

    h: float
    iterations: int
    collision_slop: float
    collision_bias: float
    friction_mode: str
    restitution_mode: str = "zero"
    solver: str = "pymunk"
    formulation: str = "sequential impulses"


def _record_contacts(handles, pair_index, k, con):
    """Step k's touching shape pairs from the pymunk arbiters (after `space.step`), one row per pair: our
    conventions (body A the arbiter's first shape, n onto A, t = (-n_y, n_x), cn and ft the impulse on A, N s;
    phi the deepest point's distance, m; point the midpoint of the contact points). Chipmunk does not expose each
    contact point's impulse, only the pair's total."""
    seen = set()

    def visit(arb):
        s1, s2 = arb.shapes
        key = frozenset((s1, s2))
        pts = arb.contact_point_set.points
        if key in seen or not pts:
            return
        seen.add(key)
        j = int(con["count"][k])
        n = -np.array(arb.normal)            # pymunk's normal points from the first shape to the second
        imp = np.array(arb.total_impulse)    # the impulse on the first shape's body
        con["pair"][k, j] = pair_index[(handles.shape_body[s1], handles.shape_body[s2])]
        con["phi"][k, j] = min(p.distance for p in pts)
        con["normal"][k, j] = n
        con["point"][k, j] = np.mean([(np.array(p.point_a) + np.array(p.point_b)) / 2 for p in pts], axis=0)
        con["cn"][k, j] = imp @ n
        con["ft"][k, j] = imp @ np.array([-n[1], n[0]])
        con["count"][k] = j + 1

    for name in handles.dynamic_names:
        handles.bodies[name].each_arbiter(visit)


def simulate_pymunk(scene, *, t_end=None, h=None, **settings) -> Trajectory:
    """Run the scene in pymunk with a fixed step h (default the scene's) to t_end (default the scene's).

    Returns a `planar_lcp.trajectory.Trajectory` with `options` a PymunkOptions; stats holds what pymunk gives:
    energy (T,) J, n_contacts (T-1,) touching shape pairs and penetration (T-1,) its deepest overlap (m) at the end
    of each step; contacts holds count, pair, phi, normal, point, cn, ft per touching shape pair (see
    `_record_contacts`) and shape_pairs.

    Note Chipmunk's order within `space.step(h)`: positions are integrated FIRST with the velocities of the end of
    the previous step (q+ = q + h v), then collisions are detected and velocities updated and solved. Ours updates
    velocities first and positions with the new velocities (q+ = q + h v+). In free flight both velocity sequences
    are identical and pymunk's positions lag ours by one velocity update (tests/commands/test_pymunk_bridge.py).

    `settings` go to `build_space` (iterations, collision_slop, collision_bias).
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    h = float(scene.sim.h if h is None else h)
    t_end = float(scene.sim.t_end if t_end is None else t_end)
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"h must be > 0, got {h}")
    if not (np.isfinite(t_end) and t_end > 0):
        raise ValueError(f"t_end must be > 0, got {t_end}")
    space, hd = build_space(scene, h=h, **settings)
    n = int(round(t_end / h))
    nd, nk = len(hd.dynamic_names), len(hd.kinematic_names)
    q, v, qk = np.zeros((n + 1, nd, 3)), np.zeros((n + 1, nd, 3)), np.zeros((n + 1, nk, 3))
    vc = np.zeros((n + 1, nd, 3))
    shape_pairs = [p for a, b in hd.pair_mu for p in ((a, b), (b, a))]   # both orders: A is the arbiter's first
    pair_index = {p: i for i, p in enumerate(shape_pairs)}
    C = max(1, sum(len(hd.shapes[a]) * len(hd.shapes[b]) for a, b in hd.pair_mu))
    con = dict(count=np.zeros(n, np.int64), pair=np.zeros((n, C), np.int64), phi=np.zeros((n, C)),
               normal=np.zeros((n, C, 2)), point=np.zeros((n, C, 2)), cn=np.zeros((n, C)), ft=np.zeros((n, C)))
    q[0], v[0], qk[0], vc[0] = read_state(hd)
    # the kinematic bodies' velocities step by step, as our engine takes them (a `path` body's change per step)
    vk_seq = kinematic_velocities(scene, hd.kinematic_names, h, n)
    moving = [name for name in hd.kinematic_names if scene.body(name).path is not None] if len(vk_seq) > 1 else []
    for i in range(n):
        for name in moving:
            set_kinematic_velocity(hd, name, vk_seq[i, hd.kinematic_names.index(name)])
        space.step(h)
        q[i + 1], v[i + 1], qk[i + 1], vc[i + 1] = read_state(hd)
        _record_contacts(hd, pair_index, i, con)
    com = np.array([hd.com_local[nm] for nm in hd.dynamic_names]).reshape(nd, 2)
    q_com = frame_to_com(q, com)
    dyn = [scene.body(nm) for nm in hd.dynamic_names]
    gravity = np.zeros(2) if scene.world.plane == "horizontal" else np.asarray(scene.world.gravity, float)
    mass = np.array([b.mass for b in dyn], float)
    inertia = np.array([body_mass_properties(b)[1] for b in dyn], float)
    recorded = np.arange(C)[None, :] < con["count"][:, None]
    stats = dict(energy=mechanical_energy(mass, inertia, gravity, q_com, vc), n_contacts=con["count"].copy(),
                 penetration=np.maximum(0.0, np.where(recorded, -con["phi"], 0.0).max(axis=1)))
    con["shape_pairs"] = shape_pairs
    options = PymunkOptions(h=h, friction_mode=hd.friction_mode, restitution_mode=hd.restitution_mode, **hd.settings)
    return Trajectory(t=np.arange(n + 1) * h, q=q, v=v, q_com=q_com, v_com=vc, qk=qk, body_names=hd.dynamic_names,
                      kinematic_names=hd.kinematic_names, stats=stats, contacts=con, options=options, scene=scene)


class PymunkRun:
    """One unit of pymunk work to time: `nsteps` steps of h on a fresh space of the scene, a whole run from the
    initial state as our rollout is timed, without recording. `prepare(k)` builds the spaces of the next k units, so
    that a caller can keep building them out of its clock (`planar_lcp.benchmarks.bench` calls it before each round)."""

    def __init__(self, scene, nsteps, *, h=None, **settings):
        self.scene = scene if isinstance(scene, Scene) else load_scene(scene)
        self.nsteps, self.settings = int(nsteps), settings
        self.h = float(self.scene.sim.h if h is None else h)
        self.spaces = []
        # a `path` body's velocity changes step by step: set before each step, as run_pymunk does
        kin = [b.name for b in self.scene.bodies if b.type == "kinematic"]
        self.moving = [(k, name) for k, name in enumerate(kin) if self.scene.body(name).path is not None]
        self.vk_seq = kinematic_velocities(self.scene, kin, self.h, self.nsteps) if self.moving else None

    def prepare(self, k):
        self.spaces = [self._fresh() for _ in range(k)]

    def __call__(self):
        space, hd = self.spaces.pop() if self.spaces else self._fresh()
        step, h = space.step, self.h
        if not self.moving:
            for _i in range(self.nsteps):
                step(h)
            return
        vk_seq = self.vk_seq
        for i in range(self.nsteps):
            for k, name in self.moving:
                set_kinematic_velocity(hd, name, vk_seq[i, k])
            step(h)

    def _fresh(self):
        return build_space(self.scene, h=self.h, **self.settings)


def time_pymunk(scene, nsteps, *, h=None, repeats=3, **settings):
    """Microseconds per `space.step(h)`: the best of `repeats` PymunkRun units (each space built before the clock
    starts)."""
    import time

    run = PymunkRun(scene, nsteps, h=h, **settings)
    best = np.inf
    for _ in range(max(1, int(repeats))):
        run.prepare(1)
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / max(1, int(nsteps))
