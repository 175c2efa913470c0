"""Scene specs, TOML loading, validation messages and the shipped scene files."""

import copy
import math
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import LineString, Point, Polygon

from planar_lcp.spec.scene import (BodySpec, Scene, SceneError, ShapeSpec, SimSpec, WorldSpec, list_scenes, load_scene,
                                   parse_scene, scene_dirs, scenes_dir, shipped_dir)

SHIPPED = ["block_on_incline", "box_push", "box_stack", "box_tip", "falling_rod", "four_disks", "painleve_rod",
           "push_t"]


# --- shipped scenes -------------------------------------------------------------------------------------------


def test_list_scenes_has_the_eight_shipped_scenes_sorted():
    listed = list_scenes()
    names = [n for n, _ in listed]
    assert names == sorted(names) and set(SHIPPED) <= set(names)
    for name, description in listed:
        assert description and "\n" not in description, name
        assert (scenes_dir() / f"{name}.toml").is_file()


def test_scenes_dir_is_the_shipped_folder_wherever_the_package_runs_from(monkeypatch):
    """From this tree (editable or on PYTHONPATH): the tree's scenes/ and tasks/; from a wheel, planar_lcp/data/
    (tests/commands/test_install.py)."""
    monkeypatch.delenv("PLANAR_LCP_SCENES", raising=False)
    root = Path(__file__).resolve().parents[2]
    assert scenes_dir() == shipped_dir("scenes") == root / "scenes"
    assert shipped_dir("tasks") == root / "tasks"
    assert scene_dirs() == [root / "scenes"]
    with pytest.raises(ValueError, match="kind must be one of scenes, tasks, got 'figures'"):
        shipped_dir("figures")


def _scene_file(folder, name, description):
    (folder / f"{name}.toml").write_text(f'name = "{name}"\ndescription = "{description}"\n' + STATIC_ONLY)
    return folder / f"{name}.toml"


def test_planar_lcp_scenes_adds_a_folder_and_wins_a_name_clash(monkeypatch, tmp_path):
    """$PLANAR_LCP_SCENES adds a folder: its scenes are found by name and listed with the shipped ones; on a name in
    both, its file is the one loaded (docs/scene-format.md); the shipped one stays at scenes_dir()."""
    monkeypatch.delenv("PLANAR_LCP_SCENES", raising=False)
    shipped = dict(list_scenes())
    own = _scene_file(tmp_path, "only", "one")
    mine = _scene_file(tmp_path, "falling_rod", "my own rod")
    monkeypatch.setenv("PLANAR_LCP_SCENES", str(tmp_path))
    assert scene_dirs() == [tmp_path, scenes_dir()] and scenes_dir() == shipped_dir("scenes")
    listed = dict(list_scenes())
    assert listed == {**shipped, "only": "one", "falling_rod": "my own rod"}
    assert load_scene("only").source == str(own)
    assert load_scene("falling_rod").source == str(mine) and load_scene("falling_rod").description == "my own rod"
    assert load_scene("box_push").source == str(scenes_dir() / "box_push.toml")    # shipped, still found
    with pytest.raises(SceneError) as e:
        load_scene("nosuch")
    assert str(e.value).startswith(f"unknown scene 'nosuch': not a scene in $PLANAR_LCP_SCENES ({tmp_path}) and "
                                   f"{scenes_dir()} (available: ")
    assert "only" in str(e.value) and "box_push" in str(e.value)


def test_planar_lcp_scenes_naming_no_folder_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setenv("PLANAR_LCP_SCENES", str(tmp_path / "nope"))
    with pytest.raises(SceneError, match=r"^\$PLANAR_LCP_SCENES: must be a folder of scene files \(NAME.toml\), got "
                                         r"'.*nope' \(no such file or folder\)$"):
        load_scene("falling_rod")
    f = _scene_file(tmp_path, "only", "one")
    monkeypatch.setenv("PLANAR_LCP_SCENES", str(f))
    with pytest.raises(SceneError, match=r"got '.*only.toml' \(not a folder\)$"):
        list_scenes()
    monkeypatch.setenv("PLANAR_LCP_SCENES", str(scenes_dir()))        # the shipped folder itself: listed once
    assert scene_dirs() == [scenes_dir()]
    monkeypatch.setenv("PLANAR_LCP_SCENES", "")                         # empty: unset
    assert scene_dirs() == [scenes_dir()]


STATIC_ONLY = ('[[bodies]]\nname = "table"\ntype = "static"\n'
               'shapes = [{ type = "halfplane", point = [0, 0], normal = [0, 1] }]\n')


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scene_loads_by_name_and_path(name):
    s = load_scene(name)
    assert s.name == name
    assert s.source == str(scenes_dir() / f"{name}.toml")
    assert load_scene(scenes_dir() / f"{name}.toml") == s
    assert load_scene(str(scenes_dir() / f"{name}.toml")) == s


def test_falling_rod_values():
    s = load_scene("falling_rod")
    assert s.world == WorldSpec(plane="vertical", gravity=(0.0, -9.81), friction=0.6)
    assert (s.sim.h, s.sim.t_end) == (0.0025, 1.0)
    rod = s.body("rod")
    assert (rod.type, rod.mass, rod.inertia, rod.position, rod.velocity) == ("dynamic", 1.0, 0.002, (0.0, 1.0),
                                                                             (0.0, 0.0))
    assert rod.angle == math.radians(30.0) and rod.angular_velocity == 4.0
    assert rod.shapes == (ShapeSpec("capsule", length=0.5, radius=0.05),)
    assert s.body("table").shapes == (ShapeSpec("halfplane", point=(0.0, 0.0), normal=(0.0, 1.0)),)


def test_four_disks_values():
    s = load_scene("four_disks")
    assert [b.name for b in s.bodies] == ["thrown", "d1", "d2", "d3", "table"]
    assert s.world.friction == 0.4
    assert s.body("d2").position == (1.20001, 0.1) and s.body("d3").position == (1.40002, 0.1)
    for n in ("thrown", "d1", "d2", "d3"):
        b = s.body(n)
        assert (b.mass, b.inertia, b.shapes) == (1.0, 0.004, (ShapeSpec("disk", radius=0.1),))
    assert s.body("thrown").velocity == (1.5, 0.0)


def test_horizontal_scenes_values():
    push = load_scene("box_push")
    assert push.world.plane == "horizontal" and push.world.gravity == (0.0, 0.0)
    assert push.world.support_gravity == 9.81 and push.sim.friction_directions == 8
    assert push.body("box").support_friction == 0.35
    assert push.body("pusher").type == "kinematic" and push.body("pusher").velocity == (0.1, 0.0)
    t = load_scene("push_t")
    assert t.body("T").mass == 0.1 and t.body("T").support_friction == 0.3 and len(t.body("T").shapes) == 2
    assert t.sim == SimSpec(h=0.01, t_end=3.0, friction_directions=8)


def test_box_tip_pair_friction():
    s = load_scene("box_tip")
    assert s.friction_between("finger", "box") == 0.2
    assert s.friction_between("box", "finger") == 0.2
    assert s.friction_between("box", "table") == 0.8
    assert s.friction_between("finger", "table") == 0.8
    with pytest.raises(KeyError, match="no body 'boxx'"):
        s.friction_between("boxx", "table")
    with pytest.raises(KeyError, match="no body 'nobody'"):
        s.body("nobody")


def test_painleve_rod_lower_cap_on_the_table_at_x0():
    rod = load_scene("painleve_rod").body("rod")
    assert rod.angle == pytest.approx(math.atan(2.0), abs=1e-15)
    caps = world_core(rod, rod.shapes[0])
    low = caps[np.argmin(caps[:, 1])]
    np.testing.assert_allclose(low, [0.0, 0.01], atol=1e-15)


def test_block_on_incline_centre_on_the_normal():
    s = load_scene("block_on_incline")
    n = np.array(s.body("incline").shapes[0].normal)
    a = math.radians(30.0)
    np.testing.assert_allclose(n, [-math.sin(a), math.cos(a)], atol=1e-16)
    np.testing.assert_allclose(s.body("box").position, 0.05 * n, atol=1e-16)
    assert math.tan(a) > s.world.friction


# Gaps between every pair of bodies in the shipped scenes: listed pairs must have exactly this gap (to 1e-12),
# all others must be clearly apart. Computed from the geometry with shapely, independently of any collision code.
EXPECTED_GAPS = {
    "falling_rod": {("rod", "table"): 1.0 - 0.25 * 0.5 - 0.05},
    "four_disks": {("d1", "table"): 0.0, ("d2", "table"): 0.0, ("d3", "table"): 0.0, ("d1", "d2"): 1e-5,
                   ("d2", "d3"): 1e-5, ("thrown", "table"): 0.9},
    "block_on_incline": {("box", "incline"): 0.0},
    "box_push": {("box", "pusher"): 0.0},
    "box_tip": {("box", "table"): 0.0, ("box", "finger"): 0.0, ("finger", "table"): 0.16},
    "painleve_rod": {("rod", "table"): 0.0},
    "box_stack": {("box1", "table"): 0.0, ("box1", "box2"): 0.0, ("box2", "box3"): 0.0, ("box1", "box3"): 0.1,
                  ("box2", "table"): 0.1, ("box3", "table"): 0.2},
    "push_t": {("T", "pusher"): 0.0},
}


def world_core(body, shape):
    c, s = math.cos(body.angle), math.sin(body.angle)
    return shape.core_vertices_body() @ np.array([[c, s], [-s, c]]) + np.array(body.position)


def shape_gap(b1, s1, b2, s2):
    if s1.type == "halfplane":
        b1, s1, b2, s2 = b2, s2, b1, s1
    if s2.type == "halfplane":
        assert b2.position == (0.0, 0.0) and b2.angle == 0.0
        d = (world_core(b1, s1) - np.array(s2.point)) @ np.array(s2.normal)
        return float(d.min()) - s1.radius
    geoms = []
    for b, s in ((b1, s1), (b2, s2)):
        core = world_core(b, s)
        geoms.append(Point(core[0]) if len(core) == 1 else LineString(core) if len(core) == 2 else Polygon(core))
    if all(g.geom_type == "Polygon" for g in geoms):
        assert geoms[0].intersection(geoms[1]).area < 1e-15, "overlapping cores"
    return geoms[0].distance(geoms[1]) - s1.radius - s2.radius


def body_gap(b1, b2):
    return min(shape_gap(b1, s1, b2, s2) for s1 in b1.shapes for s2 in b2.shapes)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scene_contacts_and_no_overlap(name):
    s = load_scene(name)
    expected = {frozenset(k): v for k, v in EXPECTED_GAPS[name].items()}
    seen = set()
    for i, b1 in enumerate(s.bodies):
        for b2 in s.bodies[i + 1:]:
            if b1.type == "static" and b2.type == "static":
                continue
            key = frozenset((b1.name, b2.name))
            g = body_gap(b1, b2)
            if key in expected:
                seen.add(key)
                assert g == pytest.approx(expected[key], abs=1e-12), (b1.name, b2.name, g)
            else:
                assert g > 1e-3, (b1.name, b2.name, g)
    assert seen == set(expected)


# --- the spec classes -----------------------------------------------------------------------------------------


R90 = math.pi / 2


@pytest.mark.parametrize("shape,expected", [
    (ShapeSpec("disk", radius=0.1, offset=(1.0, 2.0)), [[1.0, 2.0]]),
    (ShapeSpec("capsule", length=0.5, radius=0.05), [[-0.25, 0.0], [0.25, 0.0]]),
    (ShapeSpec("capsule", length=0.5, radius=0.05, angle=R90, offset=(1.0, 0.0)), [[1.0, -0.25], [1.0, 0.25]]),
    (ShapeSpec("box", width=0.2, height=0.1), [[-0.1, -0.05], [0.1, -0.05], [0.1, 0.05], [-0.1, 0.05]]),
    (ShapeSpec("box", width=0.2, height=0.1, radius=0.5, angle=R90, offset=(0.0, -1.0)),
     [[0.05, -1.1], [0.05, -0.9], [-0.05, -0.9], [-0.05, -1.1]]),
    (ShapeSpec("polygon", vertices=((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)), offset=(2.0, 3.0), angle=math.pi),
     [[2.0, 3.0], [1.0, 3.0], [2.0, 2.0]]),
    (ShapeSpec("segment", a=(0.0, 0.0), b=(1.0, 0.0), angle=R90, offset=(0.5, 0.5)), [[0.5, 0.5], [0.5, 1.5]]),
])
def test_core_vertices_body(shape, expected):
    np.testing.assert_allclose(shape.core_vertices_body(), expected, atol=1e-15)


def test_core_vertices_of_halfplane_raises():
    with pytest.raises(ValueError, match="halfplane"):
        ShapeSpec("halfplane").core_vertices_body()


def test_specs_are_frozen_and_hashable():
    s = load_scene("push_t")
    with pytest.raises(AttributeError):
        s.name = "other"
    hash(s)


# --- parsing: defaults and accepted input ---------------------------------------------------------------------


def base():
    """A valid vertical scene: dynamic rod, static table, kinematic pusher."""
    return {
        "name": "x",
        "description": "d",
        "world": {"plane": "vertical", "gravity": [0.0, -9.81], "friction": 0.5},
        "sim": {"h": 0.01, "t_end": 1.0},
        "bodies": [
            {"name": "rod", "type": "dynamic", "mass": 1.0, "position": [0.0, 1.0],
             "shapes": [{"type": "capsule", "length": 0.5, "radius": 0.05}]},
            {"name": "table", "type": "static",
             "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]},
            {"name": "pusher", "type": "kinematic", "position": [2.0, 0.1], "velocity": [-1.0, 0.0],
             "shapes": [{"type": "disk", "radius": 0.1}]},
        ],
    }


def hbase():
    """A valid horizontal scene: dynamic box, kinematic pusher, static wall."""
    return {
        "name": "x",
        "world": {"plane": "horizontal", "friction": 0.3},
        "bodies": [
            {"name": "box", "type": "dynamic", "mass": 1.0, "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]},
            {"name": "pusher", "type": "kinematic", "position": [-0.2, 0.0],
             "shapes": [{"type": "disk", "radius": 0.02}]},
            {"name": "wall", "type": "static", "shapes": [{"type": "segment", "a": [1.0, -1.0], "b": [1.0, 1.0]}]},
        ],
    }


def test_minimal_scene_gets_defaults():
    s = parse_scene({"name": "m", "bodies": [{"name": "b", "type": "dynamic", "mass": 2,
                                              "shapes": [{"type": "disk", "radius": 1}]}]})
    assert s.description == "" and s.source == "<dict>"
    assert s.world == WorldSpec() and s.sim == SimSpec()
    b = s.bodies[0]
    assert b == BodySpec(name="b", type="dynamic", mass=2.0, shapes=(ShapeSpec("disk", radius=1.0),))
    assert isinstance(b.mass, float) and isinstance(b.shapes[0].radius, float)


def test_every_schema_key_is_accepted():
    data = {
        "name": "all", "description": "every key",
        "world": {"plane": "horizontal", "gravity": [0.0, 0.0], "support_gravity": 9.0, "friction": 0.6,
                  "friction_pairs": [{"a": "rod", "b": "wall", "mu": 0.25}], "restitution": 0.3,
                  "restitution_pairs": [{"a": "wall", "b": "rod", "e": 0.8}]},
        "sim": {"h": 0.0025, "t_end": 1.0, "solver": "pgs", "formulation": "fixed_point",
                "fixed_point_iterations": 12, "friction_directions": 6, "pgs_iterations": 30},
        "bodies": [
            {"name": "rod", "type": "dynamic", "mass": 1.0, "inertia": 0.002, "position": [0.0, 1.0],
             "angle": 0.5235987755982988, "velocity": [0.5, 0.0], "angular_velocity": 4.0,
             "support_friction": 0.35, "support_points": [[0.0, 0.0], [0.1, 0.0]],
             "shapes": [{"type": "capsule", "length": 0.5, "radius": 0.05, "offset": [0.0, 0.1], "angle_deg": 90},
                        {"type": "box", "width": 0.1, "height": 0.2, "radius": 0.01, "angle": 0.1},
                        {"type": "polygon", "vertices": [[0, 0], [1, 0], [0, 1]], "radius": 0.0},
                        {"type": "segment", "a": [0, 0], "b": [1, 1], "radius": 0.02},
                        {"type": "disk", "radius": 0.1}]},
            {"name": "wall", "type": "static", "angle_deg": 10.0,
             "shapes": [{"type": "segment", "a": [1.0, -1.0], "b": [1.0, 1.0]}]},
        ],
    }
    s = parse_scene(data, "all.toml")
    assert s.world == WorldSpec(plane="horizontal", gravity=(0.0, 0.0), support_gravity=9.0, friction=0.6,
                                friction_pairs=(("rod", "wall", 0.25),), restitution=0.3,
                                restitution_pairs=(("wall", "rod", 0.8),))
    assert s.sim == SimSpec(h=0.0025, t_end=1.0, solver="pgs", formulation="fixed_point", fixed_point_iterations=12,
                            friction_directions=6, pgs_iterations=30)
    rod = s.body("rod")
    assert rod.support_points == ((0.0, 0.0), (0.1, 0.0)) and rod.support_friction == 0.35
    assert rod.inertia == 0.002 and rod.angular_velocity == 4.0 and rod.velocity == (0.5, 0.0)
    assert rod.shapes[0].angle == math.radians(90) and rod.shapes[0].offset == (0.0, 0.1)
    assert rod.shapes[2].vertices == ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0))
    assert s.body("wall").angle == math.radians(10.0)
    assert s.friction_between("wall", "rod") == 0.25
    assert s.restitution_between("rod", "wall") == 0.8


def test_halfplane_normal_is_normalised():
    d = base()
    d["bodies"][1]["shapes"][0]["normal"] = [3.0, 4.0]
    assert parse_scene(d).body("table").shapes[0].normal == (0.6, 0.8)


def test_zero_gravity_is_allowed_in_the_horizontal_plane_and_vertical_is_any():
    d = hbase()
    d["world"]["gravity"] = [0, 0]
    assert parse_scene(d).world.gravity == (0.0, 0.0)
    d = base()
    d["world"]["gravity"] = [1.0, 0.0]
    assert parse_scene(d).world.gravity == (1.0, 0.0)


def test_rounded_segment_gives_a_dynamic_body_area():
    d = base()
    d["bodies"][0]["shapes"] = [{"type": "segment", "a": [0, 0], "b": [1, 0], "radius": 0.01}]
    assert parse_scene(d).bodies[0].shapes[0].radius == 0.01


def test_numpy_numbers_are_numbers():
    d = base()
    d["bodies"][0]["mass"] = np.float64(2.0)
    d["sim"]["pgs_iterations"] = np.int64(5)
    s = parse_scene(d)
    assert s.bodies[0].mass == 2.0 and s.sim.pgs_iterations == 5 and type(s.sim.pgs_iterations) is int


# --- loading errors -------------------------------------------------------------------------------------------


def test_unknown_scene_name_lists_available():
    with pytest.raises(SceneError) as e:
        load_scene("falling_rodd")
    msg = str(e.value)
    assert msg.startswith("unknown scene 'falling_rodd': not a shipped scene in ")
    # every shipped scene is listed, sorted (the planning tasks add scenes beyond the eight of SHIPPED)
    listed = msg.split("(available: ")[1].split(")")[0].split(", ")
    assert set(SHIPPED) <= set(listed) and listed == sorted(listed)


def test_missing_path(tmp_path):
    p = tmp_path / "nope.toml"
    with pytest.raises(SceneError, match=r"nope.toml: no such scene file$"):
        load_scene(p)


def test_invalid_toml(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("name = \n")
    with pytest.raises(SceneError) as e:
        load_scene(str(p))
    assert str(e.value).startswith(f"{p}: invalid TOML: ")


def test_file_errors_name_the_file(tmp_path):
    p = tmp_path / "x.toml"
    p.write_text('name = "x"\n' + STATIC_ONLY + '[[bodies]]\nname = "b"\ntype = "dynamic"\nmass = -2.0\n'
                 'shapes = [{ type = "disk", radius = 0.1 }]\n')
    with pytest.raises(SceneError) as e:
        load_scene(p)
    assert str(e.value) == f"{p}: bodies[1].mass must be > 0, got -2.0"


def test_toml_nan_and_inf(tmp_path):
    p = tmp_path / "n.toml"
    p.write_text('name = "n"\n[[bodies]]\nname = "b"\ntype = "dynamic"\nmass = 1.0\nposition = [nan, 1.0]\n'
                 'shapes = [{ type = "disk", radius = 0.1 }]\n')
    with pytest.raises(SceneError) as e:
        load_scene(p)
    assert str(e.value) == f"{p}: bodies[0].position must be 2 finite numbers, got [nan, 1.0]"
    p.write_text('name = "n"\n[sim]\nh = inf\n' + STATIC_ONLY)
    with pytest.raises(SceneError) as e:
        load_scene(p)
    assert str(e.value) == f"{p}: sim.h must be a finite number, got inf"


def test_load_scene_rejects_other_types():
    with pytest.raises(TypeError):
        load_scene(3)


# --- validation messages --------------------------------------------------------------------------------------


def at(d, path):
    for k in path:
        d = d[k]
    return d


def put(path, value):
    def f(d):
        at(d, path[:-1])[path[-1]] = value
    return f


def drop(path):
    def f(d):
        del at(d, path[:-1])[path[-1]]
    return f


B0, B1, B2 = ("bodies", 0), ("bodies", 1), ("bodies", 2)
S00, S10, S20 = B0 + ("shapes", 0), B1 + ("shapes", 0), B2 + ("shapes", 0)
SQUARE_CW = [[0, 0], [0, 1], [1, 1], [1, 0]]
PENTAGRAM = [[math.cos(2 * math.pi * i / 5), math.sin(2 * math.pi * i / 5)] for i in (0, 2, 4, 1, 3)]
BODY_KEYS = ("name, type, shapes, mass, inertia, center_of_mass, position, angle, angle_deg, velocity, "
             "angular_velocity, support_friction, support_points, support_share, max_force, max_torque, path")

# (id, base, mutations, message after "x.toml: ")
CASES = [
    # unknown keys, everywhere
    ("top-unknown", base, [put(("foo",), 1)],
     "unknown key 'foo' (allowed: name, description, world, sim, bodies, task)"),
    ("world-unknown", base, [put(("world", "gravty"), [0, 0])],
     "world: unknown key 'gravty' (allowed: plane, gravity, support_gravity, friction, friction_pairs, "
     "support_model, restitution, restitution_pairs, damping)"),
    ("sim-unknown", base, [put(("sim", "dt"), 0.1)],
     "sim: unknown key 'dt' (allowed: h, t_end, solver, formulation, fixed_point_iterations, friction_directions, "
     "pgs_iterations, limit_surface_twists, limit_surface_resolution)"),
    ("body-unknown", base, [put(B0 + ("masss",), 1.0)], f"bodies[0]: unknown key 'masss' (allowed: {BODY_KEYS})"),
    ("shape-unknown", base, [put(S20 + ("raduis",), 0.1)],
     "bodies[2].shapes[0]: unknown key 'raduis' (allowed: offset, angle, angle_deg, radius, type)"),
    ("shape-key-of-other-type", base, [put(S00 + ("width",), 0.1)],
     "bodies[0].shapes[0]: unknown key 'width' (allowed: offset, angle, angle_deg, length, radius, type)"),
    ("halfplane-no-offset", base, [put(S10 + ("offset",), [0, 1])],
     "bodies[1].shapes[0]: unknown key 'offset' (allowed: normal, point, type)"),
    ("box-keys", base, [put(S20, {"type": "box", "width": 1, "height": 1, "length": 1})],
     "bodies[2].shapes[0]: unknown key 'length' (allowed: offset, angle, angle_deg, height, radius, type, width)"),
    ("pair-unknown", base, [put(("world", "friction_pairs"), [{"a": "rod", "b": "table", "mu": 0.1, "c": 1}])],
     "world.friction_pairs[0]: unknown key 'c' (allowed: a, b, mu)"),
    # missing required keys
    ("name-missing", base, [drop(("name",))], "name is required"),
    ("bodies-missing", base, [drop(("bodies",))], "bodies is required (at least one [[bodies]] table)"),
    ("bodies-empty", base, [put(("bodies",), [])], "bodies must be a non-empty array of tables, got []"),
    ("body-name-missing", base, [drop(B1 + ("name",))], "bodies[1].name is required"),
    ("body-type-missing", base, [drop(B1 + ("type",))], "bodies[1].type is required"),
    ("shapes-missing", base, [drop(B0 + ("shapes",))], "bodies[0].shapes is required"),
    ("shapes-empty", base, [put(B0 + ("shapes",), [])], "bodies[0].shapes must be a non-empty array of tables, got []"),
    ("mass-missing", base, [drop(B0 + ("mass",))], "bodies[0].mass is required for a dynamic body"),
    ("shape-type-missing", base, [drop(S00 + ("type",))], "bodies[0].shapes[0].type is required"),
    ("capsule-length-missing", base, [drop(S00 + ("length",))],
     "bodies[0].shapes[0].length is required for a capsule"),
    ("disk-radius-missing", base, [drop(S20 + ("radius",))], "bodies[2].shapes[0].radius is required for a disk"),
    ("box-height-missing", base, [put(S20, {"type": "box", "width": 1})],
     "bodies[2].shapes[0].height is required for a box"),
    ("polygon-vertices-missing", base, [put(S20, {"type": "polygon", "radius": 0.1})],
     "bodies[2].shapes[0].vertices is required for a polygon"),
    ("segment-b-missing", base, [put(S20, {"type": "segment", "a": [0, 0]})],
     "bodies[2].shapes[0].b is required for a segment"),
    ("halfplane-normal-missing", base, [drop(S10 + ("normal",))],
     "bodies[1].shapes[0].normal is required for a halfplane"),
    ("pair-mu-missing", base, [put(("world", "friction_pairs"), [{"a": "rod", "b": "table"}])],
     "world.friction_pairs[0].mu is required"),
    ("pair-a-missing", base, [put(("world", "friction_pairs"), [{"b": "table", "mu": 0.1}])],
     "world.friction_pairs[0].a is required"),
    # wrong types
    ("name-not-string", base, [put(("name",), 3)], "name must be a non-empty string, got 3"),
    ("name-empty", base, [put(("name",), "")], "name must be a non-empty string, got ''"),
    ("description-not-string", base, [put(("description",), 1)], "description must be a string, got 1"),
    ("world-not-table", base, [put(("world",), 3)], "world must be a table, got 3"),
    ("sim-not-table", base, [put(("sim",), [1])], "sim must be a table, got [1]"),
    ("body-not-table", base, [put(B1, "table")], "bodies[1] must be a table, got 'table'"),
    ("shape-not-table", base, [put(S20, "disk")], "bodies[2].shapes[0] must be a table, got 'disk'"),
    ("body-name-not-string", base, [put(B1 + ("name",), 7)], "bodies[1].name must be a non-empty string, got 7"),
    ("mass-string", base, [put(B0 + ("mass",), "heavy")], "bodies[0].mass must be a number, got 'heavy'"),
    ("mass-bool", base, [put(B0 + ("mass",), True)], "bodies[0].mass must be a number, got True"),
    ("h-string", base, [put(("sim", "h"), "0.01")], "sim.h must be a number, got '0.01'"),
    ("radius-bool", base, [put(S20 + ("radius",), False)], "bodies[2].shapes[0].radius must be a number, got False"),
    ("fpi-float", base, [put(("sim", "fixed_point_iterations"), 10.0)],
     "sim.fixed_point_iterations must be an integer, got 10.0"),
    ("fd-bool", base, [put(("sim", "friction_directions"), True)],
     "sim.friction_directions must be an integer, got True"),
    ("pgs-string", base, [put(("sim", "pgs_iterations"), "20")], "sim.pgs_iterations must be an integer, got '20'"),
    ("position-short", base, [put(B0 + ("position",), [1.0])],
     "bodies[0].position must be 2 finite numbers, got [1.0]"),
    ("position-string", base, [put(B0 + ("position",), ["a", 1.0])],
     "bodies[0].position must be 2 finite numbers, got ['a', 1.0]"),
    ("velocity-bool", base, [put(B0 + ("velocity",), [True, 1.0])],
     "bodies[0].velocity must be 2 finite numbers, got [True, 1.0]"),
    ("velocity-scalar", base, [put(B0 + ("velocity",), 1.0)], "bodies[0].velocity must be 2 finite numbers, got 1.0"),
    ("pair-a-not-string", base, [put(("world", "friction_pairs"), [{"a": 1, "b": "table", "mu": 0.1}])],
     "world.friction_pairs[0].a must be a string, got 1"),
    ("pairs-not-array", base, [put(("world", "friction_pairs"), {"a": "rod"})],
     "world.friction_pairs must be an array of tables {a, b, mu}, got {'a': 'rod'}"),
    ("pair-not-table", base, [put(("world", "friction_pairs"), [["rod", "table", 0.1]])],
     "world.friction_pairs[0] must be a table, got ['rod', 'table', 0.1]"),
    ("vertices-not-array", base, [put(S20, {"type": "polygon", "vertices": "square"})],
     "bodies[2].shapes[0].vertices must be an array of [x, y] points, got 'square'"),
    # non-finite numbers
    ("position-nan", base, [put(B0 + ("position",), [math.nan, 1.0])],
     "bodies[0].position must be 2 finite numbers, got [nan, 1.0]"),
    ("gravity-inf", base, [put(("world", "gravity"), [0.0, -math.inf])],
     "world.gravity must be 2 finite numbers, got [0.0, -inf]"),
    ("mass-inf", base, [put(B0 + ("mass",), math.inf)], "bodies[0].mass must be a finite number, got inf"),
    ("angle-nan", base, [put(B0 + ("angle",), math.nan)], "bodies[0].angle must be a finite number, got nan"),
    ("omega-nan", base, [put(B0 + ("angular_velocity",), math.nan)],
     "bodies[0].angular_velocity must be a finite number, got nan"),
    ("friction-nan", base, [put(("world", "friction"), math.nan)], "world.friction must be a finite number, got nan"),
    ("vertex-nan", base, [put(S20, {"type": "polygon", "vertices": [[0, 0], [math.nan, 0], [0, 1]]})],
     "bodies[2].shapes[0].vertices[1] must be 2 finite numbers, got [nan, 0.0]"),
    # ranges
    ("mass-negative", base, [put(B0 + ("mass",), -2.0)], "bodies[0].mass must be > 0, got -2.0"),
    ("mass-zero-int", base, [put(B0 + ("mass",), 0)], "bodies[0].mass must be > 0, got 0.0"),
    ("inertia-zero", base, [put(B0 + ("inertia",), 0.0)], "bodies[0].inertia must be > 0, got 0.0"),
    ("disk-radius-zero", base, [put(S20 + ("radius",), 0.0)], "bodies[2].shapes[0].radius must be > 0, got 0.0"),
    ("capsule-radius-negative", base, [put(S00 + ("radius",), -0.1)],
     "bodies[0].shapes[0].radius must be > 0, got -0.1"),
    ("capsule-length-zero", base, [put(S00 + ("length",), 0.0)], "bodies[0].shapes[0].length must be > 0, got 0.0"),
    ("box-radius-negative", base, [put(S20, {"type": "box", "width": 1, "height": 1, "radius": -0.01})],
     "bodies[2].shapes[0].radius must be >= 0, got -0.01"),
    ("box-width-zero", base, [put(S20, {"type": "box", "width": 0, "height": 1})],
     "bodies[2].shapes[0].width must be > 0, got 0.0"),
    ("box-height-negative", base, [put(S20, {"type": "box", "width": 1, "height": -1.0})],
     "bodies[2].shapes[0].height must be > 0, got -1.0"),
    ("polygon-radius-negative", base,
     [put(S20, {"type": "polygon", "vertices": [[0, 0], [1, 0], [0, 1]], "radius": -1})],
     "bodies[2].shapes[0].radius must be >= 0, got -1.0"),
    ("segment-radius-negative", base, [put(S20, {"type": "segment", "a": [0, 0], "b": [1, 0], "radius": -1})],
     "bodies[2].shapes[0].radius must be >= 0, got -1.0"),
    ("world-friction", base, [put(("world", "friction"), -0.1)], "world.friction must be >= 0, got -0.1"),
    ("pair-mu", base, [put(("world", "friction_pairs"), [{"a": "rod", "b": "table", "mu": -0.5}])],
     "world.friction_pairs[0].mu must be >= 0, got -0.5"),
    ("world-restitution-negative", base, [put(("world", "restitution"), -0.1)],
     "world.restitution must be in [0, 1], got -0.1"),
    ("world-restitution-above-one", base, [put(("world", "restitution"), 1.5)],
     "world.restitution must be in [0, 1], got 1.5"),
    ("world-restitution-not-number", base, [put(("world", "restitution"), "high")],
     "world.restitution must be a number, got 'high'"),
    ("restitution-pair-e", base, [put(("world", "restitution_pairs"), [{"a": "rod", "b": "table", "e": 1.2}])],
     "world.restitution_pairs[0].e must be in [0, 1], got 1.2"),
    ("restitution-pair-e-negative", base,
     [put(("world", "restitution_pairs"), [{"a": "rod", "b": "table", "e": -0.5}])],
     "world.restitution_pairs[0].e must be in [0, 1], got -0.5"),
    ("restitution-pair-unknown-body", base,
     [put(("world", "restitution_pairs"), [{"a": "rod", "b": "floor", "e": 0.5}])],
     "world.restitution_pairs[0].b must name a body (one of 'rod', 'table', 'pusher'), got 'floor'"),
    ("restitution-pair-e-missing", base, [put(("world", "restitution_pairs"), [{"a": "rod", "b": "table"}])],
     "world.restitution_pairs[0].e is required"),
    ("restitution-pair-mu-key", base,
     [put(("world", "restitution_pairs"), [{"a": "rod", "b": "table", "mu": 0.5}])],
     "world.restitution_pairs[0]: unknown key 'mu' (allowed: a, b, e)"),
    ("restitution-pair-repeated", base,
     [put(("world", "restitution_pairs"), [{"a": "rod", "b": "table", "e": 0.5}, {"a": "table", "b": "rod", "e": 0.2}])],
     "world.restitution_pairs[1] must not repeat the pair of world.restitution_pairs[0], got ('table', 'rod')"),
    ("restitution-pairs-not-array", base, [put(("world", "restitution_pairs"), {"a": "rod"})],
     "world.restitution_pairs must be an array of tables {a, b, e}, got {'a': 'rod'}"),
    ("support-friction", hbase, [put(B0 + ("support_friction",), -0.2)],
     "bodies[0].support_friction must be >= 0, got -0.2"),
    ("support-gravity", hbase, [put(("world", "support_gravity"), -9.81)],
     "world.support_gravity must be >= 0, got -9.81"),
    ("h-zero", base, [put(("sim", "h"), 0.0)], "sim.h must be > 0, got 0.0"),
    ("t_end-negative", base, [put(("sim", "t_end"), -1.0)], "sim.t_end must be > 0, got -1.0"),
    ("fpi-zero", base, [put(("sim", "fixed_point_iterations"), 0)], "sim.fixed_point_iterations must be >= 1, got 0"),
    ("fd-two", base, [put(("sim", "friction_directions"), 2)], "sim.friction_directions must be >= 3, got 2"),
    ("pgs-zero", base, [put(("sim", "pgs_iterations"), 0)], "sim.pgs_iterations must be >= 1, got 0"),
    # enumerations
    ("solver", base, [put(("sim", "solver"), "dantzig")],
     "sim.solver must be one of 'lemke', 'pgs', 'osqp', got 'dantzig'"),
    ("formulation", base, [put(("sim", "formulation"), "acceleration")],
     "sim.formulation must be one of 'position', 'fixed_point', 'velocity', got 'acceleration'"),
    ("plane", base, [put(("world", "plane"), "3d")], "world.plane must be one of 'vertical', 'horizontal', got '3d'"),
    ("body-type", base, [put(B1 + ("type",), "fixed")],
     "bodies[1].type must be one of 'dynamic', 'static', 'kinematic', got 'fixed'"),
    ("shape-type", base, [put(S20 + ("type",), "circle")],
     "bodies[2].shapes[0].type must be one of 'disk', 'capsule', 'box', 'polygon', 'segment', 'halfplane', "
     "got 'circle'"),
    ("solver-not-string", base, [put(("sim", "solver"), 1)], "sim.solver must be one of 'lemke', 'pgs', 'osqp', got 1"),
    # polygons
    ("polygon-two-points", base, [put(S20, {"type": "polygon", "vertices": [[0, 0], [1, 0]]})],
     "bodies[2].shapes[0].vertices must have at least 3 points, got 2"),
    ("polygon-clockwise", base, [put(S20, {"type": "polygon", "vertices": SQUARE_CW})],
     "bodies[2].shapes[0].vertices must be counter-clockwise, got a clockwise polygon"),
    ("polygon-collinear", base, [put(S20, {"type": "polygon", "vertices": [[0, 0], [1, 0], [2, 0], [1, 1]]})],
     "bodies[2].shapes[0].vertices must be strictly convex, got collinear vertices 0, 1, 2"),
    ("polygon-collinear-wrap", base, [put(S20, {"type": "polygon", "vertices": [[1, 0], [1, 1], [0, 1], [0, 0],
                                                                                 [0.5, 0]]})],
     "bodies[2].shapes[0].vertices must be strictly convex, got collinear vertices 3, 4, 0"),
    ("polygon-repeated", base, [put(S20, {"type": "polygon", "vertices": [[0, 0], [1, 0], [1, 0], [0, 1]]})],
     "bodies[2].shapes[0].vertices must be strictly convex, got a repeated point at vertices[1] and vertices[2]"),
    ("polygon-nonconvex", base,
     [put(S20, {"type": "polygon", "vertices": [[0, 0], [2, 0], [1, 0.5], [2, 2], [0, 2]]})],
     "bodies[2].shapes[0].vertices must be strictly convex, got a non-convex polygon"),
    ("polygon-pentagram", base, [put(S20, {"type": "polygon", "vertices": PENTAGRAM})],
     "bodies[2].shapes[0].vertices must be strictly convex, got a non-convex polygon"),
    # segments and halfplanes
    ("segment-degenerate", base, [put(S20, {"type": "segment", "a": [1, 1], "b": [1.0, 1.0]})],
     "bodies[2].shapes[0].b must differ from bodies[2].shapes[0].a, got [1.0, 1.0]"),
    ("halfplane-dynamic", base, [put(S00, {"type": "halfplane", "point": [0, 0], "normal": [0, 1]})],
     "bodies[0].shapes[0].type 'halfplane' is only allowed on a static body, got a dynamic body"),
    ("halfplane-kinematic", base, [put(S20, {"type": "halfplane", "point": [0, 0], "normal": [0, 1]})],
     "bodies[2].shapes[0].type 'halfplane' is only allowed on a static body, got a kinematic body"),
    ("halfplane-normal-zero", base, [put(S10 + ("normal",), [0, 0.0])],
     "bodies[1].shapes[0].normal must be non-zero, got [0.0, 0.0]"),
    ("halfplane-horizontal", hbase,
     [put(B2 + ("shapes",), [{"type": "halfplane", "point": [0, 0], "normal": [0, 1]}])],
     "bodies[2].shapes[0].type 'halfplane' is not allowed in the horizontal plane (the table is implicit), "
     "got world.plane = 'horizontal'"),
    # what static and kinematic bodies may not carry
    ("static-mass", base, [put(B1 + ("mass",), 1.0)], "bodies[1].mass is not allowed on a static body, got 1.0"),
    ("kinematic-inertia", base, [put(B2 + ("inertia",), 0.1)],
     "bodies[2].inertia is not allowed on a kinematic body, got 0.1"),
    ("static-support-friction", hbase, [put(B2 + ("support_friction",), 0.3)],
     "bodies[2].support_friction is not allowed on a static body, got 0.3"),
    ("kinematic-support-points", hbase, [put(B1 + ("support_points",), [[0, 0]])],
     "bodies[1].support_points is not allowed on a kinematic body, got [[0, 0]]"),
    ("static-velocity", base, [put(B1 + ("velocity",), [1.0, 0])],
     "bodies[1].velocity must be [0, 0] on a static body (use a kinematic body for prescribed motion), "
     "got [1.0, 0.0]"),
    ("static-omega", base, [put(B1 + ("angular_velocity",), 0.5)],
     "bodies[1].angular_velocity must be 0 on a static body (use a kinematic body for prescribed motion), got 0.5"),
    # angle and angle_deg
    ("body-angle-both", base, [put(B0 + ("angle",), 0.5), put(B0 + ("angle_deg",), 30.0)],
     "bodies[0]: give angle or angle_deg, not both, got angle = 0.5 and angle_deg = 30.0"),
    ("shape-angle-both", base, [put(S00 + ("angle",), 0), put(S00 + ("angle_deg",), 90)],
     "bodies[0].shapes[0]: give angle or angle_deg, not both, got angle = 0 and angle_deg = 90"),
    ("angle-deg-string", base, [put(S00 + ("angle_deg",), "90")],
     "bodies[0].shapes[0].angle_deg must be a number, got '90'"),
    # names and pairs
    ("duplicate-name", base, [put(B2 + ("name",), "rod")],
     "bodies[2].name must be unique, got 'rod' (already used by bodies[0])"),
    ("pair-unknown-body", base, [put(("world", "friction_pairs"), [{"a": "rod", "b": "tabel", "mu": 0.1}])],
     "world.friction_pairs[0].b must name a body (one of 'rod', 'table', 'pusher'), got 'tabel'"),
    ("pair-same-body", base, [put(("world", "friction_pairs"), [{"a": "rod", "b": "rod", "mu": 0.1}])],
     "world.friction_pairs[0].b must differ from world.friction_pairs[0].a, got 'rod'"),
    ("pair-repeated", base, [put(("world", "friction_pairs"), [{"a": "rod", "b": "table", "mu": 0.1},
                                                              {"a": "table", "b": "rod", "mu": 0.2}])],
     "world.friction_pairs[1] must not repeat the pair of world.friction_pairs[0], got ('table', 'rod')"),
    # planes
    ("horizontal-gravity", hbase, [put(("world", "gravity"), [0.0, -9.81])],
     "world.gravity must be absent or [0, 0] in the horizontal plane (the table load is world.support_gravity), "
     "got [0.0, -9.81]"),
    ("vertical-support-points", base, [put(B0 + ("support_points",), [[0.0, 0.0]])],
     "bodies[0].support_points is only allowed in the horizontal plane, got world.plane = 'vertical'"),
    ("vertical-support-friction", base, [put(B0 + ("support_friction",), 0.3)],
     "bodies[0].support_friction is only allowed in the horizontal plane, got world.plane = 'vertical'"),
    ("support-points-empty", hbase, [put(B0 + ("support_points",), [])],
     "bodies[0].support_points must be a non-empty array of [x, y] points, got []"),
    ("support-point-bad", hbase, [put(B0 + ("support_points",), [[0.0, 0.0], [1.0]])],
     "bodies[0].support_points[1] must be 2 finite numbers, got [1.0]"),
    # a dynamic body needs area
    ("dynamic-only-segments", base, [put(B0 + ("shapes",), [{"type": "segment", "a": [0, 0], "b": [1, 0]},
                                                           {"type": "segment", "a": [0, 0], "b": [0, 1]}])],
     "bodies[0].shapes must include a shape with area for a dynamic body (a disk, capsule, box, polygon or a "
     "segment with radius > 0), got only segments with radius 0"),
]


@pytest.mark.parametrize("base_fn,mutations,message", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_validation_message(base_fn, mutations, message):
    d = base_fn()
    parse_scene(copy.deepcopy(d), "x.toml")   # the base itself is valid
    for m in mutations:
        m(d)
    with pytest.raises(SceneError) as e:
        parse_scene(d, "x.toml")
    assert str(e.value) == "x.toml: " + message


def test_docs_examples_are_valid():
    import re
    import tomllib
    doc = (Path(__file__).resolve().parents[2] / "docs" / "scene-format.md").read_text()
    blocks = re.findall(r"```toml\n(.*?)```", doc, flags=re.S)
    # "Recorded paths": a kinematic body on its path, in a table scene
    path_block = next(b for b in blocks if "path = [[" in b)
    blocks.remove(path_block)
    body = tomllib.loads(path_block)["bodies"][0]
    pusher = parse_scene({"name": "doc", "world": {"plane": "horizontal"}, "bodies": [body]}, "doc").body("pusher")
    assert pusher.path[0] == (0.0, -0.12, 0.02, 0.0) and len(pusher.path) == 3 and pusher.position == (-0.12, 0.02)
    assert len(blocks) == 3
    first = parse_scene(tomllib.loads(blocks[0]), "doc")
    shipped = load_scene("box_tip")
    assert (first.world, first.sim, first.bodies, first.description) == (shipped.world, shipped.sim, shipped.bodies,
                                                                         shipped.description)
    t = parse_scene(tomllib.loads(blocks[1]), "doc").body("T")
    assert t.inertia == 0.0002 and len(t.support_points) == 3
    # the minimal task of "Task files": three lines, which with push_box's scene are a task that loads
    from planar_lcp.spec.scene import read_document, scenes_dir
    from planar_lcp.spec.task import load_task
    task = tomllib.loads(blocks[2])
    assert list(task) == ["task"] and blocks[2].strip().count("\n") == 3            # the header and three lines
    doc, _ = read_document(scenes_dir() / "push_box.toml")
    doc["task"] = task["task"]
    t = load_task(doc)
    assert (t.object, t.pusher, t.goal.x, t.goal.y, t.goal.angle) == ("box", "pusher", 0.25, 0.08, None)


def test_scene_must_be_a_table():
    with pytest.raises(SceneError) as e:
        parse_scene([1], "x.toml")
    assert str(e.value) == "x.toml: the scene must be a table, got [1]"


def test_scene_error_is_a_value_error():
    assert issubclass(SceneError, ValueError)


def test_the_issue_example_is_rejected_only_for_its_vertical_support_keys():
    # An example schema listing that puts support_* on a body in the vertical plane, which is an error.
    data = {
        "name": "falling_rod", "description": "...",
        "world": {"plane": "vertical", "gravity": [0.0, -9.81], "support_gravity": 9.81, "friction": 0.6,
                  "friction_pairs": [{"a": "rod", "b": "table", "mu": 0.6}]},
        "sim": {"h": 0.0025, "t_end": 1.0, "solver": "lemke", "formulation": "position",
                "fixed_point_iterations": 10, "friction_directions": 8, "pgs_iterations": 20},
        "bodies": [
            {"name": "rod", "type": "dynamic", "mass": 1.0, "inertia": 0.002, "position": [0.0, 1.0],
             "angle": 0.5235987755982988, "velocity": [0.0, 0.0], "angular_velocity": 4.0,
             "support_friction": 0.35, "support_points": [[0.0, 0.0]],
             "shapes": [{"type": "capsule", "length": 0.5, "radius": 0.05}]},
            {"name": "table", "type": "static",
             "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]},
        ],
    }
    with pytest.raises(SceneError, match="support_friction is only allowed in the horizontal plane"):
        parse_scene(copy.deepcopy(data), "x.toml")
    for key in ("support_friction", "support_points"):
        del data["bodies"][0][key]
    s = parse_scene(data, "x.toml")
    assert s.friction_between("rod", "table") == 0.6 and isinstance(s, Scene)
