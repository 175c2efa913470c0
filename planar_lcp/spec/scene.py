"""Scene specification: frozen dataclasses, TOML loading and validation.

A scene is a world (plane, gravity, friction), simulation settings and a list of bodies, each made of shapes. Every
shape except the halfplane is a convex *core* (1, 2 or >= 3 vertices) inflated by a rounding radius: a disk is a
point inflated by its radius, a capsule a segment inflated by its radius, a rounded box a rectangle inflated by its
radius. The file format is documented in docs/scene-format.md.

All user input is validated here, at the boundary; every error is a `SceneError` whose message names the source,
the field path in the TOML structure and what was expected, e.g.
``scenes/x.toml: bodies[1].mass must be > 0, got -2.0``.
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import math
import numbers
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planar_lcp.frames import rotation
from planar_lcp.spec.path import check_path_rows, read_path_csv

SHAPE_TYPES = ("disk", "capsule", "box", "polygon", "segment", "halfplane")
BODY_TYPES = ("dynamic", "static", "kinematic")
PLANES = ("vertical", "horizontal")
SOLVERS = ("lemke", "pgs", "osqp")
FORMULATIONS = ("position", "fixed_point", "velocity")
#: How the table carries a body in the horizontal plane (docs/method.md, "Table friction"): its support pressure's
#: limit surface (the default), or Coulomb friction at each support point (Stewart & Trinkle's reference model).
SUPPORT_MODELS = ("limit_surface", "points")

# Polygon vertex checks are relative to the polygon's size: a turn whose sine is below this is "collinear", two
# points closer than this times the size are "repeated".
_POLY_REL_TOL = 1e-10

# Upper bounds on the simulation settings, so that a typo cannot start a run that takes hours inside a kernel (which
# Python cannot interrupt) or asks for more memory than the machine has; see docs/scene-format.md, "Limits".
MAX_STEPS = 10_000_000                 # round(t_end / h): 10 to 100 us per step make this minutes to hours
MAX_PGS_ITERATIONS = 100_000           # sweeps per island per step
MAX_FIXED_POINT_ITERATIONS = 1_000     # LCP solves per step
MAX_FRICTION_DIRECTIONS = 256          # edges of the table-friction polygon (8 already approximates the disk to 8 %)
MAX_LIMIT_SURFACE_TWISTS = 256         # fixed twists of the polyhedral limit surface (LCP unknowns per body)
MAX_LIMIT_SURFACE_RESOLUTION = 64      # Gauss points per direction of a curved piece (nodes grow as its square)
# Physical bounds: magnitudes outside them are typos or unit mistakes that the numerics cannot carry (a disk
# radius of 1e308 overflowed the mass properties; a box of 1e308 failed at step 0 as an invalid LCP). They span the
# machine-to-micro range a planar contact simulator is used at, with room on either side.
MIN_LENGTH = 1e-6                      # m: a shape's radius, width, height or length when > 0 (a micron)
MAX_LENGTH = 1e4                       # m: shape sizes, and every position, offset or vertex coordinate (10 km)
MIN_MASS, MAX_MASS = 1e-6, 1e6         # kg: a milligram to a thousand tonnes
MIN_INERTIA = MIN_MASS * MIN_LENGTH ** 2   # kg m^2
MAX_INERTIA = MAX_MASS * MAX_LENGTH ** 2
MAX_SPEED = 1e3                        # m/s: each velocity component
MAX_ANGULAR_SPEED = 1e4                # rad/s
MAX_GRAVITY = 1e3                      # m/s^2: each component of world.gravity, and world.support_gravity
MAX_SERVO_FORCE, MAX_SERVO_TORQUE = 1e9, 1e9   # N, N m: a kinematic body's max_force, max_torque
# A support point may lie outside the bounding box of its body's shapes by at most this fraction of the box's
# diagonal (rounding only): a point outside would carry load where the body has no material.
_SUPPORT_REL_TOL = 1e-6


class SceneError(ValueError):
    """A scene file or dict is invalid; the message names the source, the field and the expected value."""


@dataclass(frozen=True)
class ShapeSpec:
    """One shape of a body, in the body frame.

    Lengths in m, angles in rad. Every shape except "halfplane" is its convex core (see `core_vertices_body`)
    inflated by `radius`.
    """

    type: str
    radius: float = 0.0
    length: float = 0.0
    width: float = 0.0
    height: float = 0.0
    vertices: tuple = ()
    a: tuple = (0.0, 0.0)
    b: tuple = (0.0, 0.0)
    point: tuple = (0.0, 0.0)
    normal: tuple = (0.0, 1.0)
    offset: tuple = (0.0, 0.0)
    angle: float = 0.0

    def core_vertices_local(self) -> np.ndarray:
        """(k, 2) float64, m: the core in the shape's own frame (before `offset` and `angle`)."""
        t = self.type
        if t == "disk":
            return np.zeros((1, 2))
        if t == "capsule":
            h = 0.5 * self.length
            return np.array([[-h, 0.0], [h, 0.0]])
        if t == "box":
            w, h = 0.5 * self.width, 0.5 * self.height
            return np.array([[-w, -h], [w, -h], [w, h], [-w, h]])
        if t == "polygon":
            return np.array(self.vertices, dtype=np.float64).reshape(-1, 2)
        if t == "segment":
            return np.array([self.a, self.b], dtype=np.float64)
        if t == "halfplane":
            raise ValueError("a halfplane has no core vertices (it is unbounded)")
        raise ValueError(f"unknown shape type {t!r}")

    def core_vertices_body(self) -> np.ndarray:
        """The convex core in the BODY frame, `offset` and `angle` applied.

        Returns
        -------
        (k, 2) float64, m
            disk: 1 vertex (the centre); capsule: 2 (the end-cap centres, at +-length/2 on the shape's x axis);
            box: 4 (the corners of the width x height core, counter-clockwise); polygon: its vertices (CCW);
            segment: a, b. A halfplane raises ValueError.
        """
        local = self.core_vertices_local()
        return local @ rotation(self.angle).T + np.asarray(self.offset, dtype=np.float64)


@dataclass(frozen=True)
class BodySpec:
    """A rigid body: its shapes (body frame) and initial state.

    `position` and `velocity` are those of the body-frame ORIGIN (world frame, m and m/s); the dynamics use the
    centre of mass that `planar_lcp.spec.massprops.body_mass_properties` computes from the shapes, or
    `center_of_mass` when given.
    """

    name: str
    type: str
    shapes: tuple
    mass: float | None = None
    inertia: float | None = None
    position: tuple = (0.0, 0.0)
    angle: float = 0.0
    velocity: tuple = (0.0, 0.0)
    angular_velocity: float = 0.0
    support_friction: float | None = None
    support_points: tuple | None = None
    #: the share of the table load at `support_points` (equal shares among them), in (0, 1]; the rest is spread over
    #: the shapes as without support_points. None: 1 (all of it at the points)
    support_share: float | None = None
    max_force: float | None = None       # N: kinematic only; a force-limited velocity servo (docs/method.md)
    max_torque: float | None = None      # N m: kinematic only; its torque limit (None: the rotation is prescribed)
    #: kinematic only: rows (t, x, y, angle) the body-frame origin follows (spec/path.py); `position` and `angle`
    #: are then the path's pose at t = 0 and `velocity`, `angular_velocity` zero (the velocities are per step)
    path: tuple | None = None
    #: dynamic only: the centre of mass in the body frame (m) in place of the shapes' area centroid, for a body of
    #: uneven density (the table's pressure stays spread over the shapes)
    center_of_mass: tuple | None = None


@dataclass(frozen=True)
class WorldSpec:
    """Plane, gravity (m/s^2) and friction. In the horizontal plane `gravity` is (0, 0)."""

    plane: str = "vertical"
    gravity: tuple = (0.0, -9.81)
    support_gravity: float = 9.81
    friction: float = 0.5
    friction_pairs: tuple = ()
    support_model: str = "limit_surface"
    restitution: float = 0.0
    restitution_pairs: tuple = ()
    #: the fraction of every dynamic body's velocity kept after one second, as Chipmunk's `space.damping`: each step
    #: starts from v damping^h. 1: none (the method's); 0: every step starts at rest (gym-pusht's Push-T)
    damping: float = 1.0


@dataclass(frozen=True)
class SimSpec:
    """Time step (s), duration (s) and solver settings."""

    h: float = 0.0025
    t_end: float = 1.0
    solver: str = "lemke"
    formulation: str = "position"
    fixed_point_iterations: int = 10
    friction_directions: int = 8
    pgs_iterations: int = 20
    limit_surface_twists: int = 6
    limit_surface_resolution: int = 8


@dataclass(frozen=True)
class Scene:
    """A validated scene. `source` is the file it came from, or "<dict>"."""

    name: str
    description: str
    world: WorldSpec
    sim: SimSpec
    bodies: tuple
    source: str
    #: the file's [task] table as written (a planning task, docs/scene-format.md "Task files"), or None; the scene
    #: itself ignores it: planar_lcp.spec.task validates it against the scene
    task: dict | None = dataclasses.field(default=None, hash=False)

    def body(self, name: str) -> BodySpec:
        """The body called `name`; KeyError if there is none."""
        for b in self.bodies:
            if b.name == name:
                return b
        raise KeyError(f"scene {self.name!r} has no body {name!r} (bodies: {', '.join(b.name for b in self.bodies)})")

    def friction_between(self, name_a: str, name_b: str) -> float:
        """Coulomb coefficient between two bodies: the `world.friction_pairs` override if any, else `world.friction`.

        Order-insensitive. KeyError if either name is not a body of the scene.
        """
        return self._pair_value(self.world.friction_pairs, self.world.friction, name_a, name_b)

    def restitution_between(self, name_a: str, name_b: str) -> float:
        """Newton's coefficient of restitution between two bodies: the `world.restitution_pairs` override if any,
        else `world.restitution` (0: Stewart & Trinkle's perfectly inelastic contact). Order-insensitive; KeyError if either
        name is not a body of the scene."""
        return self._pair_value(self.world.restitution_pairs, self.world.restitution, name_a, name_b)

    def _pair_value(self, pairs, default, name_a, name_b):
        """The value of the (a, b, value) entry of `pairs` for the two bodies in either order, else `default`."""
        self.body(name_a)
        self.body(name_b)
        for a, b, value in pairs:
            if {a, b} == {name_a, name_b}:
                return value
        return default


# ---------------------------------------------------------------------------------------------------------------
# Locating and loading scene files


#: the folders of files that ship with the package: the repository keeps them at its top (scenes/, tasks/), a wheel
#: as package data (planar_lcp/data/scenes, planar_lcp/data/tasks: setup.py)
SHIPPED_FOLDERS = ("scenes", "tasks")
#: the environment variable naming a folder of scene files of one's own, looked up by name before the shipped ones
SCENES_ENV = "PLANAR_LCP_SCENES"


def shipped_dir(kind: str = "scenes") -> Path:
    """The folder of the shipped `kind` files ("scenes": scenes/*.toml, "tasks": tasks/*.toml).

    Installed from a wheel (or `pip install .`), the package data planar_lcp/data/KIND, found with
    importlib.resources; in a source tree (an editable install, or the tree on PYTHONPATH), the tree's top-level
    KIND/ folder. The one definition of where shipped files live."""
    if kind not in SHIPPED_FOLDERS:
        raise ValueError(f"shipped_dir: kind must be one of {', '.join(SHIPPED_FOLDERS)}, got {kind!r}")
    data = importlib.resources.files("planar_lcp").joinpath("data", kind)
    if isinstance(data, Path) and data.is_dir():
        return data
    return Path(__file__).resolve().parents[2] / kind


def scenes_dir() -> Path:
    """The folder of the shipped scenes (`shipped_dir("scenes")`); `scene_dirs` adds $PLANAR_LCP_SCENES."""
    return shipped_dir("scenes")


def scene_dirs() -> list[Path]:
    """The folders a scene name is looked up in, in order: $PLANAR_LCP_SCENES when set (a name there wins over a
    shipped scene of the same name), then the shipped scenes. SceneError when the variable names no folder."""
    shipped = scenes_dir()
    env = os.environ.get(SCENES_ENV)
    if not env:
        return [shipped]
    own = Path(env)
    if not own.is_dir():
        what = "no such file or folder" if not own.exists() else "not a folder"
        raise SceneError(f"${SCENES_ENV}: must be a folder of scene files (NAME.toml), got {env!r} ({what})")
    try:
        if own.resolve() == shipped.resolve():
            return [shipped]
    except OSError:
        pass
    return [own, shipped]


def _describe_scene_dirs(dirs) -> str:
    """How messages name the folders of `scene_dirs()`."""
    if len(dirs) == 1:
        return str(dirs[0])
    return f"${SCENES_ENV} ({dirs[0]}) and {dirs[1]}"


def scene_files() -> list[Path]:
    """The scene file each name stands for, sorted by name: every NAME.toml of `scene_dirs()`, the first folder's on
    a name in both."""
    found = {}
    for d in scene_dirs():
        if d.is_dir():
            for p in d.glob("*.toml"):
                found.setdefault(p.stem, p)
    return [found[name] for name in sorted(found)]


def find_scene_file(name: str) -> Path | None:
    """The file the scene name `name` stands for (see `scene_dirs`), or None."""
    for d in scene_dirs():
        path = d / f"{name}.toml"
        if path.is_file():
            return path
    return None


def list_scenes(tasks: bool = False) -> list[tuple]:
    """(name, description) of every scene found by name (`scene_files()`: $PLANAR_LCP_SCENES's and the shipped ones),
    sorted by name; with `tasks`, (name, description, has_task), has_task True for a scene file with a [task] table.
    Each file is loaded and validated."""
    out = []
    for path in scene_files():
        s = load_scene(path)
        out.append((s.name, s.description, s.task is not None) if tasks else (s.name, s.description))
    return sorted(out)


def display_source(scene) -> str:
    """The scene's source for reports and files other people read: `scenes/NAME.toml` (`tasks/NAME.toml`) for a
    shipped file wherever the package is installed, the path relative to the working directory when it is below it,
    else the path as given (never this machine's absolute path for a shipped file)."""
    src = Path(scene.source)
    for kind in SHIPPED_FOLDERS:
        try:
            return str(Path(kind) / src.resolve().relative_to(shipped_dir(kind).resolve()))
        except (ValueError, OSError):
            pass
    try:
        return str(src.resolve().relative_to(Path.cwd().resolve()))
    except (ValueError, OSError):
        return scene.source


def scene_path(name_or_path) -> Path:
    """The file of a scene: a name (looked up in `scene_dirs()`: $PLANAR_LCP_SCENES, then the shipped scenes) or a
    path (a PathLike, or a string ending in ".toml" or containing a path separator). SceneError for an unknown name
    (the message lists the known ones)."""
    if isinstance(name_or_path, os.PathLike):
        return Path(name_or_path)
    if not isinstance(name_or_path, str):
        raise TypeError(f"load_scene: expected a scene name or a path, got {type(name_or_path).__name__}")
    s = name_or_path
    if s.endswith(".toml") or "/" in s or os.sep in s or (os.altsep and os.altsep in s):
        return Path(s)
    path = find_scene_file(s)
    if path is None:
        dirs = scene_dirs()
        names = ", ".join(p.stem for p in scene_files()) or "none"
        kind = "shipped scene" if len(dirs) == 1 else "scene"
        raise SceneError(f"unknown scene {s!r}: not a {kind} in {_describe_scene_dirs(dirs)} (available: {names}); "
                         "give a path to a .toml file to load another")
    return path


def read_document(path) -> tuple[dict, str]:
    """The TOML document of a scene file as (dict, text); SceneError for a missing or unreadable file, text that is
    not UTF-8, or invalid TOML."""
    path = Path(path)
    if path.is_dir():
        raise SceneError(f"{path}: is a directory, not a scene file")
    if not path.is_file():
        raise SceneError(f"{path}: no such scene file")
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise SceneError(f"{path}: cannot read the scene file: {e.strerror or e}") from None
    text = _decode_utf8(raw, path)
    return parse_toml(text, str(path)), text


def parse_toml(text: str, source: str) -> dict:
    """tomllib.loads with a SceneError naming `source` for invalid TOML."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"{source}: invalid TOML: {e}") from None


def load_scene(name_or_path) -> Scene:
    """Load and validate a scene.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        A scene name (e.g. "falling_rod", looked up in `scene_dirs()`: $PLANAR_LCP_SCENES, then the shipped
        scenes), or a path to a .toml file (a PathLike, or a string ending in ".toml" or containing a path
        separator).

    Raises
    ------
    SceneError
        For an unknown name (the message lists the known names), a missing or unreadable file, invalid TOML, or
        any validation failure.
    """
    path = scene_path(name_or_path)
    data, _ = read_document(path)
    return parse_scene(data, source=str(path))


_UTF16_BOMS = {b"\xff\xfe": "UTF-16 (little-endian)", b"\xfe\xff": "UTF-16 (big-endian)"}


def _decode_utf8(raw: bytes, path) -> str:
    """The text of a scene file, which TOML requires to be UTF-8 (a leading UTF-8 byte-order mark is dropped)."""
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    for bom, name in _UTF16_BOMS.items():
        if raw.startswith(bom):
            raise SceneError(f"{path}: the scene file must be UTF-8 text, got a {name} byte-order mark at byte "
                             "offset 0 (save the file as UTF-8)")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line = raw.count(b"\n", 0, e.start) + 1
        raise SceneError(f"{path}: the scene file must be UTF-8 text, got byte 0x{raw[e.start]:02x} at byte offset "
                         f"{e.start} (line {line}: {e.reason}; save the file as UTF-8)") from None


# ---------------------------------------------------------------------------------------------------------------
# Validation


_TOP_KEYS = ("name", "description", "world", "sim", "bodies", "task")
_WORLD_KEYS = ("plane", "gravity", "support_gravity", "friction", "friction_pairs", "support_model", "restitution",
               "restitution_pairs", "damping")
_SIM_KEYS = ("h", "t_end", "solver", "formulation", "fixed_point_iterations", "friction_directions", "pgs_iterations",
             "limit_surface_twists", "limit_surface_resolution")
#: [sim] keys that shape the horizontal plane's table friction only
_TABLE_KEYS = ("friction_directions", "limit_surface_twists", "limit_surface_resolution")
_BODY_KEYS = ("name", "type", "shapes", "mass", "inertia", "center_of_mass", "position", "angle", "angle_deg",
              "velocity", "angular_velocity", "support_friction", "support_points", "support_share", "max_force",
              "max_torque", "path")
_PAIR_KEYS = {"friction_pairs": ("a", "b", "mu"), "restitution_pairs": ("a", "b", "e")}
_PLACEMENT_KEYS = ("offset", "angle", "angle_deg")
# Per shape type: (required keys, optional keys with their defaults). Placement keys are added for all but halfplane.
_SHAPE_KEYS = {
    "disk": (("radius",), {}),
    "capsule": (("length", "radius"), {}),
    "box": (("width", "height"), {"radius": 0.0}),
    "polygon": (("vertices",), {"radius": 0.0}),
    "segment": (("a", "b"), {"radius": 0.0}),
    "halfplane": (("point", "normal"), {}),
}


def _allowed_shape_keys(stype: str) -> tuple:
    req, opt = _SHAPE_KEYS[stype]
    own = tuple(sorted(req + tuple(opt) + ("type",)))
    return own if stype == "halfplane" else _PLACEMENT_KEYS + own


def _is_real(x) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


def _is_int(x) -> bool:
    return isinstance(x, numbers.Integral) and not isinstance(x, (bool, np.bool_))


def _show_vec(value) -> str:
    """A vector for a message: numbers as floats ([nan, 1.0]), anything else as given."""
    if isinstance(value, (list, tuple)) and all(_is_real(v) for v in value):
        try:
            return repr([float(v) for v in value])
        except OverflowError:
            pass
    return repr(value)


def _fmt_num(x: float) -> str:
    return repr(float(x))


class _Validator:
    def __init__(self, source: str):
        self.source = source

    def fail(self, msg: str):
        raise SceneError(f"{self.source}: {msg}")

    # -- tables and keys --------------------------------------------------------------------------------------

    def table(self, path: str, value) -> dict:
        if not isinstance(value, dict):
            self.fail(f"{path} must be a table, got {value!r}")
        return value

    def keys(self, path: str, table: dict, allowed) -> None:
        for k in table:
            if k not in allowed:
                where = f"{path}: " if path else ""
                self.fail(f"{where}unknown key {k!r} (allowed: {', '.join(allowed)})")

    def require(self, path: str, table: dict, key: str, context: str = ""):
        if key not in table:
            self.fail(f"{_join(path, key)} is required{context}")
        return table[key]

    # -- scalars ------------------------------------------------------------------------------------------------

    def number(self, path: str, value) -> float:
        if not _is_real(value):
            self.fail(f"{path} must be a number, got {value!r}")
        try:
            x = float(value)
        except OverflowError:
            self.fail(f"{path} must be a finite number, got {value!r}")
        if not math.isfinite(x):
            self.fail(f"{path} must be a finite number, got {x!r}")
        return x

    def positive(self, path: str, value) -> float:
        x = self.number(path, value)
        if not x > 0.0:
            self.fail(f"{path} must be > 0, got {_fmt_num(x)}")
        return x

    def within(self, path: str, x: float, lo: float | None, hi: float, unit: str) -> float:
        """x itself (its magnitude when lo is None) within the physical bounds [lo, hi] (Limits, docs/scene-format.md)."""
        size = abs(x) if lo is None else x
        if size > hi:
            self.fail(f"{path} must be {'at most' if lo is not None else 'within +-'} {hi:g} {unit} (a physical bound), "
                      f"got {_fmt_num(x)}")
        if lo is not None and x < lo:
            self.fail(f"{path} must be at least {lo:g} {unit} (a physical bound), got {_fmt_num(x)}")
        return x

    def length(self, path: str, value, positive: bool = True) -> float:
        """A shape size: > 0 (>= 0 if not positive) and within [MIN_LENGTH, MAX_LENGTH] when > 0."""
        x = self.positive(path, value) if positive else self.nonneg(path, value)
        return self.within(path, x, MIN_LENGTH if x > 0.0 else None, MAX_LENGTH, "m")

    def place(self, path: str, value) -> tuple:
        """A point or offset, m: two finite numbers within +-MAX_LENGTH."""
        x, y = self.vec2(path, value)
        if max(abs(x), abs(y)) > MAX_LENGTH:
            self.fail(f"{path} must be within +-{MAX_LENGTH:g} m in each coordinate (a physical bound), got "
                      f"{_show_vec(value)}")
        return x, y

    def nonneg(self, path: str, value) -> float:
        x = self.number(path, value)
        if not x >= 0.0:
            self.fail(f"{path} must be >= 0, got {_fmt_num(x)}")
        return x

    def restitution(self, path: str, value) -> float:
        """A coefficient of restitution: a number in [0, 1]."""
        x = self.number(path, value)
        if not 0.0 <= x <= 1.0:
            self.fail(f"{path} must be in [0, 1], got {_fmt_num(x)}")
        return x

    def integer(self, path: str, value, minimum: int, maximum: int | None = None) -> int:
        if not _is_int(value):
            self.fail(f"{path} must be an integer, got {value!r}")
        n = int(value)
        if n < minimum:
            self.fail(f"{path} must be >= {minimum}, got {n}")
        if maximum is not None and n > maximum:
            self.fail(f"{path} must be <= {maximum}, got {n}")
        return n

    def string(self, path: str, value, nonempty: bool = False) -> str:
        if not isinstance(value, str) or (nonempty and not value):
            self.fail(f"{path} must be a {'non-empty ' if nonempty else ''}string, got {value!r}")
        return value

    def choice(self, path: str, value, allowed) -> str:
        if not isinstance(value, str) or value not in allowed:
            self.fail(f"{path} must be one of {', '.join(repr(a) for a in allowed)}, got {value!r}")
        return value

    def vec2(self, path: str, value) -> tuple:
        ok = isinstance(value, (list, tuple)) and len(value) == 2 and all(_is_real(v) for v in value)
        if ok:
            try:
                out = (float(value[0]), float(value[1]))
            except OverflowError:
                ok = False
            else:
                ok = math.isfinite(out[0]) and math.isfinite(out[1])
        if not ok:
            self.fail(f"{path} must be 2 finite numbers, got {_show_vec(value)}")
        return out

    def points(self, path: str, value, minimum: int) -> tuple:
        if not isinstance(value, (list, tuple)):
            self.fail(f"{path} must be an array of [x, y] points, got {value!r}")
        if len(value) < minimum:
            if minimum == 1:
                self.fail(f"{path} must be a non-empty array of [x, y] points, got {value!r}")
            self.fail(f"{path} must have at least {minimum} points, got {len(value)}")
        return tuple(self.place(f"{path}[{i}]", p) for i, p in enumerate(value))

    def angle(self, path: str, table: dict) -> float:
        """`angle` (rad) or `angle_deg` (degrees), not both; 0 if neither."""
        if "angle" in table and "angle_deg" in table:
            self.fail(f"{path}: give angle or angle_deg, not both, got angle = {table['angle']!r} "
                      f"and angle_deg = {table['angle_deg']!r}")
        if "angle_deg" in table:
            return math.radians(self.number(_join(path, "angle_deg"), table["angle_deg"]))
        if "angle" in table:
            return self.number(_join(path, "angle"), table["angle"])
        return 0.0


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def parse_scene(data: dict, source: str = "<dict>") -> Scene:
    """Validate a scene given as a dict (as parsed from TOML) and build the `Scene`.

    Parameters
    ----------
    data : dict
        The TOML document as a dict (tomllib's output, or built by hand).
    source : str
        Names the origin in error messages and is stored as `Scene.source`.

    Raises
    ------
    SceneError
        On the first violated rule (see docs/scene-format.md), naming `source`, the field and the expected value.
    """
    v = _Validator(source)
    if not isinstance(data, dict):
        v.fail(f"the scene must be a table, got {data!r}")
    v.keys("", data, _TOP_KEYS)
    name = v.string("name", v.require("", data, "name"), nonempty=True)
    description = v.string("description", data.get("description", ""))
    world_tbl = v.table("world", data.get("world", {}))
    world = _parse_world(v, world_tbl)
    sim = _parse_sim(v, v.table("sim", data.get("sim", {})))

    if "bodies" not in data:
        v.fail("bodies is required (at least one [[bodies]] table)")
    bodies_raw = data["bodies"]
    if not isinstance(bodies_raw, (list, tuple)) or not bodies_raw:
        v.fail(f"bodies must be a non-empty array of tables, got {bodies_raw!r}")
    bodies = []
    seen = {}
    for i, braw in enumerate(bodies_raw):
        body = _parse_body(v, f"bodies[{i}]", braw, world.plane)
        if body.name in seen:
            v.fail(f"bodies[{i}].name must be unique, got {body.name!r} (already used by bodies[{seen[body.name]}])")
        seen[body.name] = i
        bodies.append(body)

    task = v.table("task", data["task"]) if "task" in data else None
    names = [b.name for b in bodies]
    world = dataclasses.replace(
        world, friction_pairs=_parse_pairs(v, "friction_pairs", world_tbl.get("friction_pairs", []), names),
        restitution_pairs=_parse_pairs(v, "restitution_pairs", world_tbl.get("restitution_pairs", []), names))
    return Scene(name=name, description=description, world=world, sim=sim, bodies=tuple(bodies), source=source,
                 task=task)


def _sim_value(v: _Validator, key: str, label: str, value):
    """One [sim] setting, checked by the rule of its key; `label` is how the message names it."""
    if key in ("h", "t_end"):
        return v.positive(label, value)
    if key == "solver":
        return v.choice(label, value, SOLVERS)
    if key == "formulation":
        return v.choice(label, value, FORMULATIONS)
    if key == "fixed_point_iterations":
        return v.integer(label, value, 1, MAX_FIXED_POINT_ITERATIONS)
    if key == "friction_directions":
        return v.integer(label, value, 3, MAX_FRICTION_DIRECTIONS)
    if key == "pgs_iterations":
        return v.integer(label, value, 1, MAX_PGS_ITERATIONS)
    if key == "limit_surface_twists":
        n = v.integer(label, value, 6, MAX_LIMIT_SURFACE_TWISTS)
        if n % 2:
            v.fail(f"{label} must be even (the twists come in opposite pairs), got {n}")
        return n
    if key == "limit_surface_resolution":
        return v.integer(label, value, 1, MAX_LIMIT_SURFACE_RESOLUTION)
    raise KeyError(key)


def _check_duration(v: _Validator, h: float, t_end: float, labels: dict, knobs: dict) -> int:
    """At least one step and at most MAX_STEPS; returns the number of steps, round(t_end / h). `labels` name where
    the values came from, `knobs` what the user can change (a keyword, a flag, or the [sim] key)."""
    if not h < t_end:
        v.fail(f"{labels['h']} must be < {labels['t_end']} = {_fmt_num(t_end)} s (at least one step), "
               f"got {_fmt_num(h)}")
    ratio = t_end / h
    if not ratio <= MAX_STEPS + 0.5:
        v.fail(f"the number of steps {labels['t_end']} / {labels['h']} must be <= {MAX_STEPS}, got {t_end:g} s / "
               f"{h:g} s = {ratio:.3g} (reduce {knobs['t_end']} or increase {knobs['h']})")
    return int(round(ratio))


def _parse_sim(v: _Validator, t: dict) -> SimSpec:
    v.keys("sim", t, _SIM_KEYS)
    d = SimSpec()
    kw = {k: (_sim_value(v, k, f"sim.{k}", t[k]) if k in t else getattr(d, k)) for k in _SIM_KEYS}
    keys = {"h": "sim.h", "t_end": "sim.t_end"}
    _check_duration(v, kw["h"], kw["t_end"], keys, keys)
    return SimSpec(**kw)


def sim_settings(scene: Scene, overrides: dict, names: dict | None = None) -> tuple:
    """The [sim] settings of a run: `scene.sim` with `overrides` (a value of None keeps the scene's), each override
    checked by the same rules as the scene file's [sim] table, then the duration (h < t_end, at most MAX_STEPS).

    Parameters
    ----------
    scene : Scene
    overrides : dict
        {key of [sim]: value or None}.
    names : dict, optional
        How messages name an override, and what they tell the user to change (default: its key, a keyword of
        `simulate`); the CLI passes its flags. A value taken from the scene is named `sim.KEY`.

    Returns
    -------
    (SimSpec, int, dict)
        The settings, the number of steps round(t_end / h), and the label of every setting as messages name it.

    Raises
    ------
    SceneError
        ``"{scene.source}: {label} must be ..., got ..."``.
    """
    v = _Validator(scene.source)
    names = names or {}
    labels, kw = {}, {}
    for key in _SIM_KEYS:
        value = overrides.get(key)
        if value is None:
            labels[key], kw[key] = f"sim.{key}", getattr(scene.sim, key)
        else:
            labels[key] = names.get(key, key)
            kw[key] = _sim_value(v, key, labels[key], value)
    for key in overrides:
        if key not in _SIM_KEYS:
            raise KeyError(f"sim_settings: {key!r} is not a [sim] key")
    for key in _TABLE_KEYS:
        if overrides.get(key) is not None and scene.world.plane != "horizontal":
            v.fail(f"{labels[key]} applies only in the horizontal plane (the table friction), "
                   f"got {kw[key]} for a scene with world.plane = {scene.world.plane!r}")
    knobs = {key: names.get(key, key) for key in ("h", "t_end")}
    nsteps = _check_duration(v, kw["h"], kw["t_end"], labels, knobs)
    return SimSpec(**kw), nsteps, labels


def restitution_setting(scene: Scene, value, label: str = "restitution") -> Scene:
    """The scene with `value` (in [0, 1]) as its world.restitution when given, the default of every pair without a
    world.restitution_pairs entry; the scene itself when `value` is None. Raises SceneError naming `label`."""
    if value is None:
        return scene
    e = _Validator(scene.source).restitution(label, value)
    return dataclasses.replace(scene, world=dataclasses.replace(scene.world, restitution=e))


def support_model_setting(scene: Scene, value, label: str = "support_model") -> str:
    """The support model of a run: `scene.world.support_model`, or `value` (one of SUPPORT_MODELS) when given, which
    only the horizontal plane takes. Raises SceneError naming `label`."""
    if value is None:
        return scene.world.support_model
    v = _Validator(scene.source)
    model = v.choice(label, value, SUPPORT_MODELS)
    if scene.world.plane != "horizontal":
        v.fail(f"{label} applies only in the horizontal plane (the table friction), got {model!r} for a scene with "
               f"world.plane = {scene.world.plane!r}")
    return model


def _parse_world(v: _Validator, t: dict) -> WorldSpec:
    """Everything but friction_pairs and restitution_pairs, which need the body names."""
    v.keys("world", t, _WORLD_KEYS)
    d = WorldSpec()
    plane = v.choice("world.plane", t["plane"], PLANES) if "plane" in t else d.plane
    if plane == "horizontal":
        gravity = (0.0, 0.0)
        if "gravity" in t:
            g = v.vec2("world.gravity", t["gravity"])
            if g != (0.0, 0.0):
                v.fail("world.gravity must be absent or [0, 0] in the horizontal plane (the table load is "
                       f"world.support_gravity), got {_show_vec(g)}")
    else:
        gravity = v.vec2("world.gravity", t["gravity"]) if "gravity" in t else d.gravity
        if max(abs(gravity[0]), abs(gravity[1])) > MAX_GRAVITY:
            v.fail(f"world.gravity must be within +-{MAX_GRAVITY:g} m/s^2 in each component (a physical bound), "
                   f"got {_show_vec(gravity)}")
    support_gravity = v.within("world.support_gravity", v.nonneg("world.support_gravity", t["support_gravity"]),
                               None, MAX_GRAVITY, "m/s^2") if "support_gravity" in t else d.support_gravity
    friction = v.nonneg("world.friction", t["friction"]) if "friction" in t else d.friction
    support_model = v.choice("world.support_model", t["support_model"], SUPPORT_MODELS) if "support_model" in t \
        else d.support_model
    restitution = v.restitution("world.restitution", t["restitution"]) if "restitution" in t else d.restitution
    damping = d.damping
    if "damping" in t:
        damping = v.number("world.damping", t["damping"])
        if not 0.0 <= damping <= 1.0:
            v.fail(f"world.damping must be in [0, 1] (the fraction of velocity kept after 1 s), got "
                   f"{_fmt_num(damping)}")
    return WorldSpec(plane=plane, gravity=gravity, support_gravity=support_gravity, friction=friction,
                     support_model=support_model, restitution=restitution, damping=damping)


def _parse_pairs(v: _Validator, key: str, raw, names: list) -> tuple:
    """world.friction_pairs ({a, b, mu >= 0}) or world.restitution_pairs ({a, b, e in [0, 1]}) as (a, b, value)
    triples: two different bodies of the scene, each pair at most once."""
    a_key, b_key, value_key = _PAIR_KEYS[key]
    if not isinstance(raw, (list, tuple)):
        v.fail(f"world.{key} must be an array of tables {{{a_key}, {b_key}, {value_key}}}, got {raw!r}")
    out = []
    seen = {}
    for i, p in enumerate(raw):
        path = f"world.{key}[{i}]"
        p = v.table(path, p)
        v.keys(path, p, _PAIR_KEYS[key])
        ends = []
        for end in (a_key, b_key):
            n = v.string(f"{path}.{end}", v.require(path, p, end))
            if n not in names:
                v.fail(f"{path}.{end} must name a body (one of {', '.join(repr(x) for x in names)}), got {n!r}")
            ends.append(n)
        a, b = ends
        if a == b:
            v.fail(f"{path}.b must differ from {path}.a, got {b!r}")
        raw_value = v.require(path, p, value_key)
        value = v.nonneg(f"{path}.mu", raw_value) if key == "friction_pairs" else v.restitution(f"{path}.e", raw_value)
        pair = frozenset((a, b))
        if pair in seen:
            v.fail(f"{path} must not repeat the pair of world.{key}[{seen[pair]}], got ({a!r}, {b!r})")
        seen[pair] = i
        out.append((a, b, value))
    return tuple(out)


def _parse_body(v: _Validator, path: str, raw, plane: str) -> BodySpec:
    t = v.table(path, raw)
    v.keys(path, t, _BODY_KEYS)
    name = v.string(f"{path}.name", v.require(path, t, "name"), nonempty=True)
    btype = v.choice(f"{path}.type", v.require(path, t, "type"), BODY_TYPES)

    shapes_raw = v.require(path, t, "shapes")
    if not isinstance(shapes_raw, (list, tuple)) or not shapes_raw:
        v.fail(f"{path}.shapes must be a non-empty array of tables, got {shapes_raw!r}")
    shapes = tuple(_parse_shape(v, f"{path}.shapes[{j}]", s, btype, plane) for j, s in enumerate(shapes_raw))

    mass = inertia = support_friction = support_points = support_share = center_of_mass = None
    if btype == "dynamic":
        mass = v.positive(f"{path}.mass", v.require(path, t, "mass", " for a dynamic body"))
        v.within(f"{path}.mass", mass, MIN_MASS, MAX_MASS, "kg")
        if "inertia" in t:
            inertia = v.within(f"{path}.inertia", v.positive(f"{path}.inertia", t["inertia"]), MIN_INERTIA,
                               MAX_INERTIA, "kg m^2")
        if "center_of_mass" in t:
            center_of_mass = v.place(f"{path}.center_of_mass", t["center_of_mass"])
        for key in ("support_friction", "support_points", "support_share"):
            if key in t and plane != "horizontal":
                v.fail(f"{path}.{key} is only allowed in the horizontal plane, got world.plane = {plane!r}")
        if "support_friction" in t:
            support_friction = v.nonneg(f"{path}.support_friction", t["support_friction"])
        if "support_points" in t:
            support_points = v.points(f"{path}.support_points", t["support_points"], 1)
            _check_support_points(v, f"{path}.support_points", support_points, shapes)
        if "support_share" in t:
            if support_points is None:
                v.fail(f"{path}.support_share needs support_points on the same body (the points that carry the "
                       f"share), got support_share = {t['support_share']!r} alone")
            support_share = v.number(f"{path}.support_share", t["support_share"])
            if not 0.0 < support_share <= 1.0:
                v.fail(f"{path}.support_share must be in (0, 1] (the load's share at the support points), got "
                       f"{_fmt_num(support_share)}")
        if not any(s.type != "segment" or s.radius > 0.0 for s in shapes):
            v.fail(f"{path}.shapes must include a shape with area for a dynamic body (a disk, capsule, box, polygon "
                   "or a segment with radius > 0), got only segments with radius 0")
    else:
        for key in ("mass", "inertia", "center_of_mass", "support_friction", "support_points", "support_share"):
            if key in t:
                v.fail(f"{path}.{key} is not allowed on a {btype} body, got {t[key]!r}")
    max_force = max_torque = None
    for key in ("max_force", "max_torque"):
        if key in t and btype != "kinematic":
            v.fail(f"{path}.{key} is only allowed on a kinematic body (a force-limited velocity servo), got a "
                   f"{btype} body")
    if "max_force" in t:
        max_force = v.within(f"{path}.max_force", v.positive(f"{path}.max_force", t["max_force"]), None,
                             MAX_SERVO_FORCE, "N")
    if "max_torque" in t:
        if "max_force" not in t:
            v.fail(f"{path}.max_torque needs max_force on the same body (a servo limits its force first), got "
                   f"max_torque = {t['max_torque']!r} alone")
        max_torque = v.within(f"{path}.max_torque", v.positive(f"{path}.max_torque", t["max_torque"]), None,
                              MAX_SERVO_TORQUE, "N m")

    rows = _parse_path(v, path, t, btype) if "path" in t else None
    if rows is not None:
        # the path is the motion: its pose at t = 0 is the start, the velocities are per step (spec/path.py)
        # (at rest at the first row's pose until its time)
        position, angle = (rows[0][1], rows[0][2]), rows[0][3]
    else:
        position = v.place(f"{path}.position", t["position"]) if "position" in t else (0.0, 0.0)
        angle = v.angle(path, t)
    velocity = v.vec2(f"{path}.velocity", t["velocity"]) if "velocity" in t else (0.0, 0.0)
    if max(abs(velocity[0]), abs(velocity[1])) > MAX_SPEED:
        v.fail(f"{path}.velocity must be within +-{MAX_SPEED:g} m/s in each component (a physical bound), got "
               f"{_show_vec(velocity)}")
    omega = v.number(f"{path}.angular_velocity", t["angular_velocity"]) if "angular_velocity" in t else 0.0
    v.within(f"{path}.angular_velocity", omega, None, MAX_ANGULAR_SPEED, "rad/s")
    if btype == "static":
        if velocity != (0.0, 0.0):
            v.fail(f"{path}.velocity must be [0, 0] on a static body (use a kinematic body for prescribed "
                   f"motion), got {_show_vec(velocity)}")
        if omega != 0.0:
            v.fail(f"{path}.angular_velocity must be 0 on a static body (use a kinematic body for prescribed "
                   f"motion), got {omega!r}")

    return BodySpec(name=name, type=btype, shapes=shapes, mass=mass, inertia=inertia, position=position,
                    angle=angle, velocity=velocity, angular_velocity=omega, support_friction=support_friction,
                    support_points=support_points, support_share=support_share, max_force=max_force,
                    max_torque=max_torque, path=rows, center_of_mass=center_of_mass)


def _parse_path(v: _Validator, path: str, t: dict, btype: str) -> tuple:
    """A kinematic body's `path` (spec/path.py): rows [t, x, y, angle], or a CSV file name (relative to the scene
    file's folder) of a recording (planar_lcp.spec.recordings) with the body's columns NAME.x, NAME.y, NAME.theta. As a
    tuple of row tuples (a Scene is hashable); the pose at t = 0 becomes the body's position and angle."""
    where = f"{path}.path"
    if btype != "kinematic":
        v.fail(f"{where} is only allowed on a kinematic body (prescribed motion), got a {btype} body")
    for key in ("position", "angle", "angle_deg", "velocity", "angular_velocity"):
        if key in t:
            v.fail(f"{path}.{key} is not allowed with {where} (the path gives the pose and the velocities), got "
                   f"{key} = {t[key]!r}")
    raw = t["path"]
    if isinstance(raw, str):
        if not raw:
            v.fail(f"{where} must be an array of [t, x, y, angle] rows or a CSV file name, got ''")
        file = Path(raw)
        if not file.is_absolute() and not v.source.startswith("<"):
            file = Path(v.source).parent / file
        try:
            raw = read_path_csv(file, t.get("name", ""))
        except ValueError as e:
            v.fail(f"{where}: {e}")
        where = f"{where} ({file})"
    try:
        rows = check_path_rows(raw, MAX_LENGTH, MAX_SPEED, MAX_ANGULAR_SPEED)
    except ValueError as e:
        sep = "" if str(e).startswith("[") else " "
        v.fail(f"{where}{sep}{e}")
    return tuple(tuple(float(x) for x in r) for r in rows)


def _parse_shape(v: _Validator, path: str, raw, btype: str, plane: str) -> ShapeSpec:
    t = v.table(path, raw)
    stype = v.choice(f"{path}.type", v.require(path, t, "type"), SHAPE_TYPES)
    v.keys(path, t, _allowed_shape_keys(stype))
    required, optional = _SHAPE_KEYS[stype]
    for key in required:
        v.require(path, t, key, f" for a {stype}")

    if stype == "halfplane":
        if btype != "static":
            v.fail(f"{path}.type 'halfplane' is only allowed on a static body, got a {btype} body")
        if plane == "horizontal":
            v.fail(f"{path}.type 'halfplane' is not allowed in the horizontal plane (the table is implicit), "
                   f"got world.plane = {plane!r}")
        point = v.place(f"{path}.point", t["point"])
        normal = v.vec2(f"{path}.normal", t["normal"])
        norm = math.hypot(*normal)
        if norm == 0.0:
            v.fail(f"{path}.normal must be non-zero, got {_show_vec(normal)}")
        return ShapeSpec(type="halfplane", point=point, normal=(normal[0] / norm, normal[1] / norm))

    kw = {"type": stype}
    kw["offset"] = v.place(f"{path}.offset", t["offset"]) if "offset" in t else (0.0, 0.0)
    kw["angle"] = v.angle(path, t)
    if stype in ("disk", "capsule"):
        kw["radius"] = v.length(f"{path}.radius", t["radius"])
    else:
        kw["radius"] = v.length(f"{path}.radius", t["radius"], positive=False) if "radius" in t else optional["radius"]
    if stype == "capsule":
        kw["length"] = v.length(f"{path}.length", t["length"])
    elif stype == "box":
        kw["width"] = v.length(f"{path}.width", t["width"])
        kw["height"] = v.length(f"{path}.height", t["height"])
    elif stype == "polygon":
        verts = v.points(f"{path}.vertices", t["vertices"], 3)
        _check_convex_ccw(v, f"{path}.vertices", verts)
        kw["vertices"] = verts
    elif stype == "segment":
        kw["a"] = v.place(f"{path}.a", t["a"])
        kw["b"] = v.place(f"{path}.b", t["b"])
        if kw["a"] == kw["b"]:
            v.fail(f"{path}.b must differ from {path}.a, got {_show_vec(kw['b'])}")
    return ShapeSpec(**kw)


def _check_convex_ccw(v: _Validator, path: str, verts: tuple) -> None:
    """Strictly convex (no repeated points, no collinear triples, simple) and counter-clockwise."""
    p = np.array(verts, dtype=np.float64)
    k = len(p)
    size = float(np.max(np.linalg.norm(p - p.mean(axis=0), axis=1)))
    for i in range(k):
        for j in range(i + 1, k):
            if np.linalg.norm(p[i] - p[j]) <= _POLY_REL_TOL * size:
                v.fail(f"{path} must be strictly convex, got a repeated point at vertices[{i}] and vertices[{j}]")
    e = np.roll(p, -1, axis=0) - p                      # e[i] = p[i+1] - p[i]
    e_next = np.roll(e, -1, axis=0)                     # turn at vertex i+1
    cross = e[:, 0] * e_next[:, 1] - e[:, 1] * e_next[:, 0]
    dot = np.sum(e * e_next, axis=1)
    scale = np.linalg.norm(e, axis=1) * np.linalg.norm(e_next, axis=1)
    for i in range(k):
        if abs(cross[i]) <= _POLY_REL_TOL * scale[i]:
            a, b, c = i, (i + 1) % k, (i + 2) % k
            v.fail(f"{path} must be strictly convex, got collinear vertices {a}, {b}, {c}")
    turning = float(np.sum(np.arctan2(cross, dot)))
    # All turns one way and a total turn of exactly one revolution: convex and simple (a pentagram turns twice).
    if np.all(cross > 0) and abs(turning - 2 * math.pi) < 1e-6:
        return
    if np.all(cross < 0) and abs(turning + 2 * math.pi) < 1e-6:
        v.fail(f"{path} must be counter-clockwise, got a clockwise polygon")
    v.fail(f"{path} must be strictly convex, got a non-convex polygon")


def _check_support_points(v: _Validator, path: str, points: tuple, shapes: tuple) -> None:
    """Each support point within the bounding box of the body's shapes (body frame, rounding included), up to
    _SUPPORT_REL_TOL of its diagonal."""
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for s in shapes:
        core = s.core_vertices_body()
        lo = np.minimum(lo, core.min(axis=0) - s.radius)
        hi = np.maximum(hi, core.max(axis=0) + s.radius)
    tol = _SUPPORT_REL_TOL * float(np.hypot(*(hi - lo)))
    for j, p in enumerate(points):
        if not (lo[0] - tol <= p[0] <= hi[0] + tol and lo[1] - tol <= p[1] <= hi[1] + tol):
            v.fail(f"{path}[{j}] must lie within the body's extent x in [{lo[0]:.6g}, {hi[0]:.6g}], y in "
                   f"[{lo[1]:.6g}, {hi[1]:.6g}] (the bounding box of its shapes, body frame, m), got {_show_vec(p)}")


def parse_perturbation(text: str) -> dict:
    """"mu=F,mass=G" (either or both; `planar-lcp replay --perturb`) -> {"mu": F, "mass": G}, positive finite factors
    for `perturbed_scene`; ValueError naming what is wrong."""
    out = {}
    for part in text.split(","):
        key, eq, val = part.partition("=")
        key = key.strip()
        if not eq or key not in ("mu", "mass") or key in out:
            raise ValueError(f"must be mu=F,mass=G (factors, either or both), got {text!r}")
        try:
            f = float(val)
        except ValueError:
            f = float("nan")
        if not (math.isfinite(f) and f > 0):
            raise ValueError(f"{key} must be a positive finite factor, got {val.strip()!r}")
        out[key] = f
    return out


def perturbed_scene(scene: Scene, friction: float = 1.0, mass: float = 1.0) -> Scene:
    """The scene with every Coulomb coefficient (world.friction, world.friction_pairs, each body's
    support_friction) times `friction` and every dynamic body's mass (and a given inertia) times `mass`: the world
    a plan made in `scene` is executed in when that world is not the model (`planar-lcp replay --perturb`)."""
    for label, f in (("friction", friction), ("mass", mass)):
        if not (isinstance(f, (int, float)) and math.isfinite(f) and f > 0):
            raise SceneError(f"{scene.source}: the {label} factor must be a positive number, got {f!r}")
    w = scene.world
    world = dataclasses.replace(w, friction=w.friction * friction,
                                friction_pairs=tuple((a, b, v * friction) for a, b, v in w.friction_pairs))
    bodies = []
    for b in scene.bodies:
        kw = {}
        if b.support_friction is not None:
            kw["support_friction"] = b.support_friction * friction
        if b.type == "dynamic":
            kw["mass"] = b.mass * mass
            if b.inertia is not None:
                kw["inertia"] = b.inertia * mass
        bodies.append(dataclasses.replace(b, **kw))
    return dataclasses.replace(scene, world=world, bodies=tuple(bodies))
