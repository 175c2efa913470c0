"""The MIT pushing data set (Yu, Bauza, Fazeli, Rodriguez, "More than a Million Ways to Be Pushed", IROS 2016):
recorded pushes of real objects by a robot's rod, read into scenes and recordings of this package.

The data is not part of the repository (docs/real_pushes.md, "The data"). `find_data_root` finds it:
$PLANAR_LCP_MIT_PUSH when set, else ``../shared/data/mit-push`` relative to the current folder, else the same
relative to this source tree's checkout (or one folder further up). A data root holds `SURFACE/SPLIT/*.h5` (one
push each) and `objects/NAME_ext.npy` (each object's outline, m).

One push (`read_push`): three streams, each with its own UNIX timestamps, about 250 Hz:

- ``tip_pose`` (t, x, y, unused): the pusher's centre, m, world frame;
- ``object_pose`` (t, x, y, yaw): the object's pose frame, m and rad, same world frame;
- ``ft_wrench`` (t, fx, fy, torque): the force at the pusher, N (sensor offset not removed: up to 5 N).

Times here are s from the push's first object sample (t = 0); the yaw is unwrapped. A few samples of a stream come
out of time order (the stamps are arrival times; examples/measurements/pushdata_summary.py counts them): each stream is sorted by
time and a repeated time keeps its first sample.

The object's outline file is not in its pose frame for every object; `object_model` registers it from where the
pusher was when contact began (`contact_onset`: the force's rise, never the object's response when the force says
something), and `push_scene` / `push_recording` turn a push into a scene whose dynamic body's frame IS the pose
frame, so that a simulated pose compares with the recorded one directly (docs/real_pushes.md).

h5py is needed to read the files (the extra `pushdata`); scipy for the registration.
"""

from __future__ import annotations

import functools
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planar_lcp.studies.pushdata.outline import (Registration, clean, convex_pieces, register_outline,
                                                     signed_distance)
from planar_lcp.spec.recordings import RecordedRun

#: the environment variable naming the data root
DATA_ENV = "PLANAR_LCP_MIT_PUSH"
#: the pusher's radius, m: `probe4` of the authors' code (mcubelab/push-est-public, probe_db.py), a 9.5 mm steel
#: rod (the data's README says 4.76 mm, 3/16 inch: the two differ by 0.01 mm)
PUSHER_RADIUS = 0.00475
#: object masses, kg: the authors' shape database (mcubelab/push-est-public, software/isamShapePose/script/config/
#: shape_db.py; stainless steel, 13 mm thick); the paper's text does not give them, and the data's URDF files have
#: their inertial fields permuted. rect1: 0.8374 = 7.9 g/cm^3 x 90 x 90 x 13 mm^3, to 0.6 %
MASSES = {"rect1": 0.8374, "rect2": 1.045, "rect3": 1.2508, "tri1": 0.8028, "tri2": 0.9826, "tri3": 1.1326,
          "ellip1": 0.8937, "ellip2": 1.1104, "ellip3": 1.3338, "hex": 0.9827, "butter": 1.1974}
#: scene body names: every push's scene and recording use these, whatever the object
OBJECT, PUSHER = "object", "pusher"
#: push_scene's parameters: the table's Coulomb coefficient under the object (ABS: no value is published with the
#: data; a guess to be fitted), the pusher-object coefficient (likewise), the time step, s; the support pressure:
#: `ring_share` of the load on a ring of RING_POINTS points (0: uniform over the outline), the outline shrunk by
#: `ring_scale` about the centre of mass (`support_ring`); `inertia_scale` multiplies
#: the object's mass and inertia while the table's load stays m g (1: the dynamics; small: the quasi-static limit,
#: inertia negligible beside friction)
DEFAULT_PARAMS = {"support_friction": 0.25, "pusher_friction": 0.25, "h": 0.004, "ring_share": 0.0,
                  "ring_scale": 0.9, "inertia_scale": 1.0}
#: the support ring's points (equal shares)
RING_POINTS = 16
#: the largest overlap of the pusher and the registered outline at t = 0 that `reconcile_start` removes, m; a deeper
#: one is a registration failure, refused
MAX_START_OVERLAP = 0.003
#: contact onset: a sample is "above the noise" when its force deviation from the baseline exceeds the baseline's
#: median + ONSET_K x MAD (for a 2-d Gaussian noise about 5.7 standard deviations: a chance of 1e-7 per sample) ...
ONSET_K = 10.0
#: ... and the onset is the first crossing after which the deviation stays above for this long, s
ONSET_HOLD = 0.05
#: ... and it must come before the tip has travelled this far from its rest pose, m: these pushes start at or within
#: a few mm of contact, and a later rise is not the first touch (the robot stopping at the end of a push, whose
#: inertia the sensor feels, or a second touch after the pusher slid off)
ONSET_MAX_TRAVEL = 0.01
#: the registration's prior: the outline's centroid at its pose frame's origin (the authors' object frames are
#: centred on the centroid: shape_db.py) within this standard deviation, m, against contact points scattered by
#: REGISTRATION_NOISE (m: the contact onset's and the tracking's); the angle has no prior
REGISTRATION_SHIFT_SD = 0.005
REGISTRATION_NOISE = 0.0005
#: the tip has left its rest pose once it is this far from its first sample, m (the tip stream is exactly constant at
#: rest: it is the robot's pose)
TIP_REST_TOL = 1e-5

_NAME = re.compile(r"^motion_surface=(?P<surface>[A-Za-z0-9]+)_shape=(?P<shape>[A-Za-z0-9]+)_a=(?P<a>[-+.0-9eE]+)"
                   r"_v=(?P<v>[-+.0-9eE]+)_i=(?P<i>[-+.0-9eE]+)_s=(?P<s>[-+.0-9eE]+)_t=(?P<t>[-+.0-9eE]+)\.h5$")
_STREAMS = ("tip_pose", "object_pose", "ft_wrench")


class PushDataError(ValueError):
    """A push file, an outline or the data root that cannot be used: one line naming the file, the expected and the
    actual."""


# ---------------------------------------------------------------------------------------------------------------
# Files


def find_data_root() -> Path | None:
    """The data root: $PLANAR_LCP_MIT_PUSH when set (PushDataError if it is not a folder with objects/), else the
    first of ../shared/data/mit-push relative to the current folder, to this source tree's checkout and to the
    folder above it that holds objects/; None when there is none."""
    env = os.environ.get(DATA_ENV)
    if env:
        root = Path(env)
        if not (root / "objects").is_dir():
            raise PushDataError(f"${DATA_ENV}: must be the MIT push data folder (with objects/ and "
                                f"SURFACE/SPLIT/*.h5), "
                                f"got {env!r}")
        return root
    checkout = Path(__file__).resolve().parents[3]
    for base in (Path.cwd(), checkout, checkout.parent):
        root = base / ".." / "shared" / "data" / "mit-push"
        if (root / "objects").is_dir():
            return root.resolve()
    return None


def data_root(root=None) -> Path:
    """`root` as a Path, or `find_data_root()`; PushDataError naming where it looked when there is none."""
    if root is not None:
        return Path(root)
    found = find_data_root()
    if found is None:
        raise PushDataError(f"the MIT push data was not found: set ${DATA_ENV} to its folder, or put it at "
                            "../shared/data/mit-push (docs/real_pushes.md, 'The data')")
    return found


def push_files(root=None, shape: str | None = None) -> list:
    """The push files (*.h5) below the data root, sorted; those of one object when `shape` is given."""
    files = sorted(data_root(root).glob("*/*/*.h5"))
    return [f for f in files if shape is None or parse_push_name(f).shape == shape]


@dataclass(frozen=True)
class PushName:
    """A push's parameters, from its file name (motion_surface=abs_shape=rect1_a=0_v=20_i=0.000_s=0.675_t=0.349.h5).

    surface, shape : the table's material and the object; a : the pusher's acceleration (0: constant speed);
    v : the commanded pusher speed, mm/s; i : the side of a polygon pushed (0 for a smooth outline); s : the contact
    point's position along that side or the outline, a fraction in [0, 1); t : the push direction relative to the
    contact normal, rad.
    """

    surface: str
    shape: str
    a: float
    v: float
    i: int
    s: float
    t: float


def parse_push_name(path) -> PushName:
    """The parameters in a push file's name; PushDataError naming the file for a name of another form."""
    name = Path(path).name
    m = _NAME.match(name)
    if m is None:
        raise PushDataError(f"{path}: the file name must be motion_surface=SURFACE_shape=SHAPE_a=A_v=V_i=I_s=S_t=T.h5, "
                            f"got {name!r}")
    g = m.groupdict()
    try:
        i = float(g["i"])
        out = PushName(surface=g["surface"], shape=g["shape"], a=float(g["a"]), v=float(g["v"]), i=int(i),
                       s=float(g["s"]), t=float(g["t"]))
    except ValueError:
        raise PushDataError(f"{path}: the file name's a, v, i, s, t must be numbers, got {name!r}") from None
    if i != int(i):
        raise PushDataError(f"{path}: the file name's i (a side) must be a whole number, got {g['i']!r}")
    return out


@dataclass(frozen=True)
class Push:
    """One recorded push.

    Attributes
    ----------
    path : str, the h5 file.
    name : PushName, its parameters.
    t0 : float, UNIX time (s) of the first object sample: t = 0 of every array below.
    tip : (N, 3) t (s), x, y (m): the pusher's centre, world frame.
    object : (M, 4) t (s), x, y (m), theta (rad, unwrapped): the object's pose frame in the world frame.
    force : (K, 4) t (s), fx, fy (N), torque (N m): the force at the pusher as recorded (offset included).
    outline : (n, 2) m: the object's outline as its file gives it (its own frame; `object_model` registers it).
    root : str, the data root (for the object's other pushes and outline).
    reordered : dict stream -> samples that were out of time order (sorted) or repeated a time (dropped).
    """

    path: str
    name: PushName
    t0: float
    tip: np.ndarray
    object: np.ndarray
    force: np.ndarray
    outline: np.ndarray
    root: str
    reordered: dict

    @property
    def shape(self) -> str:
        return self.name.shape

    @property
    def duration(self) -> float:
        """The last object sample's time, s (the first is 0)."""
        return float(self.object[-1, 0])

    def tip_at(self, t) -> np.ndarray:
        """The pusher's centre (..., 2) at times t (s): linear between samples, the first before them, the last
        after."""
        t = np.asarray(t, dtype=np.float64)
        return np.stack([np.interp(t, self.tip[:, 0], self.tip[:, k]) for k in (1, 2)], axis=-1)

    def object_at(self, t) -> np.ndarray:
        """The object's pose (..., 3) at times t (s), as `tip_at`."""
        t = np.asarray(t, dtype=np.float64)
        return np.stack([np.interp(t, self.object[:, 0], self.object[:, k]) for k in (1, 2, 3)], axis=-1)


def _h5py():
    from planar_lcp.cli_support import require
    require("h5py")                     # the extra 'pushdata': one line naming it when missing
    import h5py
    return h5py


def read_outline(shape: str, root=None) -> np.ndarray:
    """The outline of object `shape` as stored, (n, 2) m: objects/SHAPE_ext.npy below the data root."""
    path = data_root(root) / "objects" / f"{shape}_ext.npy"
    try:
        p = np.load(path)
    except FileNotFoundError:
        raise PushDataError(f"{path}: no such outline file (objects/{shape}_ext.npy beside the data)") from None
    except (OSError, ValueError) as e:
        raise PushDataError(f"{path}: must be a numpy .npy array, got {e}") from None
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3 or not np.isfinite(p).all():
        raise PushDataError(f"{path}: must be an (n, 2) array of finite vertices, n >= 3, got shape {p.shape}")
    return np.asarray(p, dtype=np.float64)


def _stream(path, h, key) -> tuple:
    """A stream (N, 4) sorted by time with repeated times dropped, and how many samples that moved or dropped."""
    if key not in h:
        raise PushDataError(f"{path}: must hold the dataset {key!r} (datasets: {', '.join(_STREAMS)}), got "
                            f"{', '.join(sorted(h.keys())) or 'none'}")
    a = np.asarray(h[key][()], dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 4 or len(a) < 2:
        raise PushDataError(f"{path}: {key} must be an (N, 4) array with N >= 2 (a timestamp and 3 values per row), "
                            f"got shape {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
    if bad.size:
        raise PushDataError(f"{path}: {key} row {bad[0]} must be finite, got {a[bad[0]].tolist()}")
    order = np.argsort(a[:, 0], kind="stable")
    moved = int(np.sum(order != np.arange(len(a))))
    a = a[order]
    keep = np.concatenate([[True], np.diff(a[:, 0]) > 0.0])
    return a[keep], moved + int(np.sum(~keep))


def read_push(path, root=None) -> Push:
    """Read one push file (the module docstring says what it holds).

    Parameters
    ----------
    path : the h5 file.
    root : the data root, for the object's outline (objects/SHAPE_ext.npy); default: the folder two levels above
        the file when it has objects/, else `find_data_root()`.

    Raises
    ------
    PushDataError
        For a file name of another form, a missing dataset, a stream of another shape or with non-finite values.
    """
    h5py = _h5py()
    path = Path(path)
    name = parse_push_name(path)
    if root is None:
        root = path.parent.parent.parent if (path.parent.parent.parent / "objects").is_dir() else data_root()
    try:
        with h5py.File(path, "r") as h:
            streams = {key: _stream(path, h, key) for key in _STREAMS}
    except FileNotFoundError:
        raise PushDataError(f"{path}: no such push file") from None
    except OSError as e:
        raise PushDataError(f"{path}: must be an HDF5 file, got {e}") from None
    obj, tip, force = streams["object_pose"][0], streams["tip_pose"][0], streams["ft_wrench"][0]
    t0 = float(obj[0, 0])
    obj = np.column_stack([obj[:, 0] - t0, obj[:, 1:3], np.unwrap(obj[:, 3])])
    tip = np.column_stack([tip[:, 0] - t0, tip[:, 1:3]])
    force = np.column_stack([force[:, 0] - t0, force[:, 1:]])
    for a in (obj, tip, force):
        a.flags.writeable = False
    outline = read_outline(name.shape, root)
    outline.flags.writeable = False
    return Push(path=str(path), name=name, t0=t0, tip=tip, object=obj, force=force, outline=outline,
                root=str(root), reordered={k: v[1] for k, v in streams.items()})


# ---------------------------------------------------------------------------------------------------------------
# Contact onset


@dataclass(frozen=True)
class Onset:
    """When the pusher began to touch the object.

    t : s; cue : "force" (the force left its noise) or "motion" (the object left its noise: only where the force
    stream carries no signal); threshold : the level crossed (N, or m of motion); baseline : samples that set it
    (those before the tip left its rest pose)."""

    t: float
    cue: str
    threshold: float
    baseline: int


def tip_departure(push: Push) -> float:
    """The time (s) of the tip's last sample at rest before it first moves more than TIP_REST_TOL from its start."""
    d = np.hypot(*(push.tip[:, 1:3] - push.tip[0, 1:3]).T)
    moved = np.flatnonzero(d > TIP_REST_TOL)
    if moved.size == 0:
        raise PushDataError(f"{push.path}: the pusher must move, got a tip that stays within {TIP_REST_TOL:g} m of its "
                            "start")
    return float(push.tip[max(moved[0] - 1, 0), 0])


def force_has_signal(push: Push) -> bool:
    """Whether the force stream varies as a sensor's does: distinct (fx, fy) in at least half of its samples (some
    files hold only 2 to 4 distinct values repeated: a stale stream)."""
    return len(np.unique(push.force[:, 1:3], axis=0)) >= 0.5 * len(push.force)


def _rise(t, level, t_rest, hold, t_last) -> tuple:
    """The crossing of `level` (>= 0 deviations at times t) out of its noise: the baseline is the samples before
    t_rest (at least 10); the threshold median + ONSET_K x MAD; the onset the time, linear between the last sample at
    or below it and the next, after which the level stays above for `hold` s, at t_last at the latest.
    (None, thr, n) if there is none."""
    base = level[t < t_rest]
    if len(base) < 10:
        base = level[:10]
    med = float(np.median(base))
    thr = med + ONSET_K * float(np.median(np.abs(base - med)))
    above = level > thr
    n, start, k = len(t), None, 1
    while k < n and t[k] <= t_last:
        if above[k] and not above[k - 1]:
            j = k
            while j < n and above[j]:
                j += 1
            if j == n or t[j - 1] - t[k] >= hold:   # a run to the end of the recording counts too
                start = k
                break
            k = j
        k += 1
    if start is None:
        return None, thr, len(base)
    a, b = level[start - 1], level[start]
    frac = (thr - a) / (b - a) if b > a else 1.0
    return float(t[start - 1] + frac * (t[start] - t[start - 1])), thr, len(base)


def contact_onset(push: Push) -> Onset | None:
    """When contact began: the first time the force at the pusher rises out of its noise and stays out.

    The force's deviation |f - f0| from its median f0 over the baseline (the samples before the tip leaves its rest
    pose: the sensor's offset is not the contact's) crosses the baseline's median + ONSET_K x MAD and stays above for
    ONSET_HOLD s, before the tip has travelled ONSET_MAX_TRAVEL. Where the force stream carries no signal
    (`force_has_signal`: rect1's files), the object's motion is the cue instead, by the same rule on its displacement
    (the origin's, plus the turn times the outline's radius): it lags the touch by the force build-up, so it is used
    only there. None when neither rises.
    """
    t_rest = tip_departure(push)
    travel = np.hypot(*(push.tip[:, 1:3] - push.tip[0, 1:3]).T)
    t_last = float(push.tip[np.argmax(travel > ONSET_MAX_TRAVEL), 0]) if travel[-1] > ONSET_MAX_TRAVEL else np.inf
    if force_has_signal(push):
        f = push.force
        base = f[f[:, 0] < t_rest, 1:3] if np.sum(f[:, 0] < t_rest) >= 10 else f[:10, 1:3]
        level = np.hypot(*(f[:, 1:3] - np.median(base, axis=0)).T)
        t_on, thr, nb = _rise(f[:, 0], level, t_rest, ONSET_HOLD, t_last)
        return None if t_on is None else Onset(t_on, "force", thr, nb)
    o = push.object
    radius = float(np.max(np.linalg.norm(push.outline, axis=1)))
    base = o[o[:, 0] < t_rest, 1:4] if np.sum(o[:, 0] < t_rest) >= 10 else o[:10, 1:4]
    ref = np.median(base, axis=0)
    level = np.hypot(*(o[:, 1:3] - ref[:2]).T) + radius * np.abs(o[:, 3] - ref[2])
    t_on, thr, nb = _rise(o[:, 0], level, t_rest, ONSET_HOLD, t_last)
    return None if t_on is None else Onset(t_on, "motion", thr, nb)


def contact_point(push: Push, t: float) -> np.ndarray:
    """(2,) the pusher's centre at time t in the object's pose frame at t, m."""
    x, y, th = push.object_at(t)
    c, s = math.cos(th), math.sin(th)
    d = push.tip_at(t) - (x, y)
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


# ---------------------------------------------------------------------------------------------------------------
# The object: registered outline, convex pieces, mass


@dataclass(frozen=True)
class ObjectModel:
    """An object of the data set as a simulated body.

    shape : its name; outline : (n, 2) m, counter-clockwise, in its POSE frame (registered); pieces : convex pieces
    of it (each (k, 2), counter-clockwise: a scene's polygons); mass : kg; registration : the transform applied to
    the outline file; files : the pushes the registration used (their onsets in `onsets`, a None for a push without
    one), and each used push's residual in registration.residuals, in that order."""

    shape: str
    outline: np.ndarray
    pieces: tuple
    mass: float
    registration: Registration
    files: tuple
    onsets: tuple

    def residual(self, path) -> float | None:
        """The registration residual (m) of the push file `path`, None if it had no onset."""
        used = [f for f, o in zip(self.files, self.onsets) if o is not None]
        name = Path(path).name
        for f, r in zip(used, self.registration.residuals):
            if Path(f).name == name:
                return float(r)
        return None


def register_object(pushes) -> tuple:
    """(Registration, onsets) of one object's outline from its pushes (all of the same shape): each push's contact
    onset (`contact_onset`), the pusher's centre then in the object's pose frame, and `register_outline` of the
    outline with a disk of PUSHER_RADIUS through those points, with the prior REGISTRATION_SHIFT_SD on the shift
    of its centroid."""
    pushes = list(pushes)
    shapes = {p.shape for p in pushes}
    if len(shapes) != 1:
        raise ValueError(f"register_object: the pushes must be of one object, got {', '.join(sorted(shapes))}")
    onsets = tuple(contact_onset(p) for p in pushes)
    points = [contact_point(p, o.t) for p, o in zip(pushes, onsets) if o is not None]
    if len(points) < 2:
        raise PushDataError(f"{pushes[0].root}: the {pushes[0].shape} outline needs 2 pushes with a contact onset to "
                            f"be registered, got {len(points)}")
    return register_outline(pushes[0].outline, np.array(points), PUSHER_RADIUS, shift_sd=REGISTRATION_SHIFT_SD,
                            noise_sd=REGISTRATION_NOISE), onsets


@functools.lru_cache(maxsize=32)
def _object_model(shape: str, root: str) -> ObjectModel:
    files = push_files(root, shape)
    if not files:
        raise PushDataError(f"{root}: must hold pushes of {shape!r} (SURFACE/SPLIT/*shape={shape}_*.h5), got none")
    pushes = [read_push(f, root) for f in files]
    reg, onsets = register_object(pushes)
    outline = clean(reg.apply(pushes[0].outline))
    pieces = tuple(convex_pieces(outline))
    for a in (outline, *pieces):
        a.flags.writeable = False
    if shape not in MASSES:
        raise PushDataError(f"{root}: the mass of {shape!r} is not known (known: {', '.join(MASSES)})")
    return ObjectModel(shape=shape, outline=outline, pieces=pieces, mass=MASSES[shape], registration=reg,
                       files=tuple(str(f) for f in files), onsets=onsets)


def object_model(shape: str, root=None) -> ObjectModel:
    """The registered object `shape` (every push of it below the data root registers it; computed once per
    process)."""
    return _object_model(shape, str(Path(data_root(root)).resolve()))


# ---------------------------------------------------------------------------------------------------------------
# Start overlap, scene and recording


@dataclass(frozen=True)
class StartContact:
    """The pusher at t = 0 against the registered outline.

    gap : m, the distance from the pusher's disk to the outline before reconciliation (negative: overlap);
    shift : (2,) m, world frame, what `reconcile_start` added to every tip sample (zero unless gap < 0);
    gap_after : m, the gap once shifted (0 to round-off after an overlap, else `gap`)."""

    gap: float
    shift: tuple
    gap_after: float


def _start_gap(push: Push, model: ObjectModel, shift=(0.0, 0.0)) -> tuple:
    """(gap, outward unit normal in the world frame) of the pusher at t = 0, with the tip shifted by `shift`."""
    x, y, th = push.object[0, 1:4]
    c, s = math.cos(th), math.sin(th)
    d = push.tip_at(0.0) + np.asarray(shift) - (x, y)
    local = np.array([[c * d[0] + s * d[1], -s * d[0] + c * d[1]]])
    sd, g = signed_distance(local, model.outline)
    n = np.array([c * g[0, 0] - s * g[0, 1], s * g[0, 0] + c * g[0, 1]])
    return float(sd[0]) - PUSHER_RADIUS, n


def reconcile_start(push: Push, model: ObjectModel | None = None, max_overlap: float = MAX_START_OVERLAP) \
        -> StartContact:
    """The rule for a pusher that starts inside the registered outline: shift the whole recorded tip path out.

    If the pusher's disk overlaps the outline at t = 0 by d > 0, every tip sample moves by d along the outline's
    outward normal at the point closest to the tip, so that the push starts touching (gap 0 to round-off); a gap
    is left as recorded (the pusher travels to the object, as the robot did). The input moves, never the object:
    its recorded poses are the observations a model must predict, and a start pose moved by d would put d into
    every prediction's error. An overlap above `max_overlap` (m) is not noise but a failed registration:
    PushDataError naming the file."""
    model = model or object_model(push.shape, push.root)
    gap, n = _start_gap(push, model)
    if gap >= 0.0:
        return StartContact(gap=gap, shift=(0.0, 0.0), gap_after=gap)
    if -gap > max_overlap:
        raise PushDataError(f"{push.path}: the pusher must start within {max_overlap * 1000:g} mm of the registered "
                            f"{push.shape} outline, got an overlap of {-gap * 1000:.2f} mm at t = 0 (a registration "
                            "failure, not noise)")
    shift = -gap * n
    after, n2 = _start_gap(push, model, shift)
    for _ in range(3):                  # next to a vertex the first normal can leave a sliver: step again
        if after >= -1e-12:
            break
        shift = shift - after * n2
        after, n2 = _start_gap(push, model, shift)
    return StartContact(gap=gap, shift=(float(shift[0]), float(shift[1])), gap_after=after)


def tip_path(push: Push, start: StartContact | None = None) -> np.ndarray:
    """(N, 4) rows [t, x, y, 0] of the pusher (a kinematic body's `path`) after `reconcile_start`: times >= 0 (a
    sample before the first object sample is replaced by the pose at t = 0)."""
    start = start or reconcile_start(push)
    tip = push.tip
    keep = tip[:, 0] >= 0.0
    rows = np.column_stack([tip[keep, 0], tip[keep, 1:3] + start.shift, np.zeros(int(keep.sum()))])
    if not keep.all():
        first = np.concatenate([[0.0], push.tip_at(0.0) + start.shift, [0.0]])
        rows = np.vstack([first, rows[rows[:, 0] > 0.0]])
    return rows


def push_scene(push: Push, params: dict | None = None, with_path: bool = True,
               model: ObjectModel | None = None) -> dict:
    """The scene of one push, as the dict `planar_lcp.spec.scene.parse_scene` takes.

    Horizontal plane, support_gravity GRAVITY / inertia_scale; the body OBJECT (dynamic: the registered outline's
    convex pieces, its mass times inertia_scale, the support pressure uniform over the outline or ring_share of it
    on `support_ring`; at its first recorded pose, at rest) and the body PUSHER (kinematic disk of
    PUSHER_RADIUS following the recorded tip, `tip_path` after `reconcile_start`); world.friction the
    pusher-object coefficient; sim.h and sim.t_end the recording's duration.

    Parameters
    ----------
    params : dict, optional
        Any of DEFAULT_PARAMS' keys: support_friction, pusher_friction, h (s).
    with_path : bool
        True: the pusher's `path` key (rows [t, x, y, 0]). False: its `position` at t = 0 only (a scene for a
        loader without the `path` key; the pusher then stands still).
    model : ObjectModel, optional
        Default `object_model(push.shape, push.root)`.
    """
    p = dict(DEFAULT_PARAMS)
    for key, value in (params or {}).items():
        if key not in DEFAULT_PARAMS:
            raise KeyError(f"push_scene: unknown parameter {key!r} (known: {', '.join(DEFAULT_PARAMS)})")
        p[key] = value
    model = model or object_model(push.shape, push.root)
    rows = tip_path(push, reconcile_start(push, model))
    x, y, th = (float(v) for v in push.object[0, 1:4])
    pusher = {"name": PUSHER, "type": "kinematic", "shapes": [{"type": "disk", "radius": PUSHER_RADIUS}]}
    if with_path:
        pusher["path"] = rows.tolist()
    else:
        pusher["position"] = rows[0, 1:3].tolist()
    n = push.name
    obj = {"name": OBJECT, "type": "dynamic", "mass": model.mass * float(p["inertia_scale"]), "position": [x, y],
           "angle": th, "support_friction": float(p["support_friction"]),
           "shapes": [{"type": "polygon", "vertices": piece.tolist()} for piece in model.pieces]}
    if p["ring_share"] > 0.0:
        obj["support_points"] = support_ring(model, float(p["ring_scale"])).tolist()
        obj["support_share"] = float(p["ring_share"])
    return {
        "name": f"mit_{n.shape}",
        "description": (f"MIT push {Path(push.path).name}: {n.shape} on {n.surface}, v = {n.v:g} mm/s, side {n.i}, "
                        f"s = {n.s:g}, t = {n.t:g} rad (Yu et al. 2016)"),
        # the table's load m g whatever inertia_scale does to the mass
        "world": {"plane": "horizontal", "support_gravity": GRAVITY / float(p["inertia_scale"]),
                  "friction": float(p["pusher_friction"])},
        "sim": {"h": float(p["h"]), "t_end": push.duration},
        "bodies": [obj, pusher],
    }


#: m/s^2
GRAVITY = 9.81


def support_ring(model: ObjectModel, scale: float) -> np.ndarray:
    """(RING_POINTS, 2) points, pose frame, m: the outline shrunk about its centroid (the centre of mass) by `scale`
    (1: on the outline), sampled evenly by arc length: a ring that follows the object's shape, inside it for an
    outline star-shaped about its centroid (every object of the data set)."""
    from planar_lcp.studies.pushdata.outline import centroid

    poly = model.outline
    closed = np.vstack([poly, poly[:1]])
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))])
    at = arc[-1] * np.arange(RING_POINTS) / RING_POINTS
    rim = np.column_stack([np.interp(at, arc, closed[:, 0]), np.interp(at, arc, closed[:, 1])])
    c = centroid(poly)
    return c + scale * (rim - c)


def push_recording(push: Push, model: ObjectModel | None = None) -> RecordedRun:
    """The push as a recording (planar_lcp.spec.recordings) on the object's sample times: OBJECT (observed: its recorded
    pose) and PUSHER (the input: the tip after `reconcile_start`, interpolated linearly onto those times, angle 0)."""
    model = model or object_model(push.shape, push.root)
    rows = tip_path(push, reconcile_start(push, model))
    t = push.object[:, 0]
    tip = np.column_stack([np.interp(t, rows[:, 0], rows[:, 1]), np.interp(t, rows[:, 0], rows[:, 2]),
                           np.zeros(len(t))])
    return RecordedRun(t, (OBJECT, PUSHER), np.stack([push.object[:, 1:4], tip], axis=1), push.path)


# ---------------------------------------------------------------------------------------------------------------
# Summary


def tip_speed(push: Push) -> float:
    """The pusher's measured speed, m/s: the slope of a straight line fitted (least squares) to its distance along
    its net displacement against time, over the samples from its departure (`tip_departure`) to its arrival (its
    last sample short of the final distance by TIP_REST_TOL)."""
    xy = push.tip[:, 1:3] - push.tip[0, 1:3]
    direction = xy[-1] / np.linalg.norm(xy[-1])
    dist = xy @ direction
    t = push.tip[:, 0]
    moving = (t >= tip_departure(push)) & (dist <= dist[-1] - TIP_REST_TOL)
    return float(np.polyfit(t[moving], dist[moving], 1)[0])


def summary(root=None) -> list:
    """One dict per push file below the data root (sorted): file, split (the folder: train or test_butter), object,
    v (mm/s, the name's), v_measured (mm/s, `tip_speed`), duration (s), displacement (mm: the object's origin from
    the first to the last sample), rotation (deg, likewise), onset_cue and onset (s), residual (mm: its registration
    residual, None without an onset), gap (mm: the pusher's gap to the registered outline at t = 0, negative an
    overlap), shift (mm: `reconcile_start`'s), gap_after (mm), reordered (samples of the three streams out of time
    order or repeating a time)."""
    out = []
    for f in push_files(root):
        push = read_push(f, root)
        model = object_model(push.shape, push.root)
        onset = model.onsets[[Path(x).name for x in model.files].index(f.name)]
        start = reconcile_start(push, model)
        o = push.object
        res = model.residual(f)
        out.append({
            "file": f.name, "split": f.parent.name, "object": push.shape, "v": push.name.v,
            "v_measured": 1000.0 * tip_speed(push), "duration": push.duration,
            "displacement": 1000.0 * float(np.hypot(*(o[-1, 1:3] - o[0, 1:3]))),
            "rotation": math.degrees(float(o[-1, 3] - o[0, 3])),
            "onset_cue": onset.cue if onset else None, "onset": onset.t if onset else None,
            "residual": None if res is None else 1000.0 * res,
            "gap": 1000.0 * start.gap, "shift": 1000.0 * float(np.hypot(*start.shift)),
            "gap_after": 1000.0 * start.gap_after, "reordered": sum(push.reordered.values()),
        })
    return out
