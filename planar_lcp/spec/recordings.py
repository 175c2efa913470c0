"""Recorded runs: the poses of named bodies sampled at common times, read from and written to CSV.

A recording is what a real experiment (or another simulator) measured: per row a time and, for each body, the pose
of its body frame in the world frame. It uses the column convention of `Trajectory.to_csv` (`planar-lcp simulate
--csv`), so a simulated run and a recorded one are read the same way (docs/scene-format.md, "Recordings"):

- header: ``t``, then per body ``NAME.x``, ``NAME.y``, ``NAME.theta`` (NAME a body of the scene the recording is
  compared with; any name, dots included: the suffix after the LAST dot is the coordinate);
- one row per sample: t in s, strictly increasing; x, y in m: the world position of the body-frame ORIGIN (the
  scene's `position`); theta in rad: the body frame's angle, continuous (unwrapped: no jump of more than pi between
  rows; `numpy.unwrap` makes it so);
- every body has a value in every row (a missing sample is not allowed: interpolate onto the common times first);
- further columns (`NAME.vx`, `NAME.vy`, `NAME.omega` of `simulate --csv`, anything else) are accepted and ignored.

The file says nothing about which bodies drive the run and which are observed: the scene does (`RecordedRun.split`).
A kinematic body's recorded poses are an input, the rows its `path` key takes (`RecordedRun.path_rows`); a dynamic
body's are observations to predict.

Errors are `RecordingError` (a ValueError) with one line naming the file, the line and column, what was expected
and what was found, e.g. ``run.csv: line 7, column box.theta must be a finite number, got 'nan'``.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["COORDS", "RecordedRun", "RecordingError", "read_recording"]

#: the pose columns of a body NAME: NAME.x, NAME.y (m), NAME.theta (rad)
COORDS = ("x", "y", "theta")


class RecordingError(ValueError):
    """A recording that cannot be used: one line naming the file, the line or column, the expected and the actual."""


@dataclass(frozen=True)
class RecordedRun:
    """Poses of named bodies sampled at common times.

    Attributes
    ----------
    t : (T,) float64, s
        Strictly increasing sample times, T >= 2.
    names : tuple of str
        The bodies, in column order; unique, non-empty.
    poses : (T, nbody, 3) float64
        Per sample and body: x, y (m) of the body-frame origin and theta (rad) of the body frame, world frame; theta
        continuous (no jump above pi between samples).
    source : str
        The file it was read from, or a description; messages name it.

    The arrays are copied and made read-only on construction, and checked by the rules of the file format
    (RecordingError naming `source`).
    """

    t: np.ndarray
    names: tuple
    poses: np.ndarray
    source: str = "<recording>"

    def __post_init__(self):
        src = self.source
        t = np.array(self.t, dtype=np.float64)
        poses = np.array(self.poses, dtype=np.float64)
        names = tuple(self.names)
        if t.ndim != 1:
            raise RecordingError(f"{src}: t must be a 1-d array of times, got shape {t.shape}")
        if not names or not all(isinstance(n, str) and n for n in names):
            raise RecordingError(f"{src}: names must be a non-empty tuple of non-empty strings, got {names!r}")
        dup = next((n for i, n in enumerate(names) if n in names[:i]), None)
        if dup is not None:
            raise RecordingError(f"{src}: names must be unique, got {dup!r} twice")
        if poses.shape != (len(t), len(names), 3):
            raise RecordingError(f"{src}: poses must have shape (T, nbody, 3) = {(len(t), len(names), 3)}, got "
                                 f"{poses.shape}")
        _check_values(src, t, poses, names, line_of_row=None)
        t.flags.writeable = False
        poses.flags.writeable = False
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "poses", poses)
        object.__setattr__(self, "names", names)

    @property
    def duration(self) -> float:
        """t[-1] - t[0], s."""
        return float(self.t[-1] - self.t[0])

    def index(self, name: str) -> int:
        """The column of body `name` in `poses`; KeyError naming the bodies if it has none."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"{self.source}: no body {name!r} in the recording (bodies: "
                           f"{', '.join(self.names)})") from None

    def pose(self, name: str) -> np.ndarray:
        """(T, 3) the poses x, y (m), theta (rad) of body `name`."""
        return self.poses[:, self.index(name)]

    def path_rows(self, name: str) -> np.ndarray:
        """(T, 4) rows [t, x, y, theta] of body `name`: what a kinematic body's scene key `path` takes (as a list of
        lists: `run.path_rows("pusher").tolist()`). The body rests at the first row's pose before it and at the last
        row's after it."""
        return np.column_stack([self.t, self.pose(name)])

    def split(self, scene) -> tuple:
        """(input names, observed names) by the scene's body types: a kinematic body's recorded poses drive the run
        (its `path`), a dynamic body's are observations to predict. Each keeps the recording's column order.

        RecordingError (one line: the file, the column, the expected and the actual) for a name that is not a
        kinematic or dynamic body of `scene` (a static body does not move: a recording of it is a mistake)."""
        types = {b.name: b.type for b in scene.bodies}
        movable = [n for n, kind in types.items() if kind in ("kinematic", "dynamic")]
        inputs, observed = [], []
        for n in self.names:
            kind = types.get(n)
            if kind == "kinematic":
                inputs.append(n)
            elif kind == "dynamic":
                observed.append(n)
            else:
                got = f"a static body {n!r}" if kind == "static" else f"{n!r}, not a body of the scene"
                raise RecordingError(f"{self.source}: column {n}.x must name a kinematic or dynamic body of scene "
                                     f"{scene.name!r} (one of {', '.join(repr(m) for m in movable)}), got {got}")
        return tuple(inputs), tuple(observed)

    def select(self, names) -> "RecordedRun":
        """The recording of the bodies `names` only (in that order)."""
        idx = [self.index(n) for n in names]
        return RecordedRun(self.t, tuple(names), self.poses[:, idx], self.source)

    def to_csv(self, path) -> None:
        """Write the recording: header t, NAME.x, NAME.y, NAME.theta per body; one row per sample, every number as
        Python's repr (read back bit for bit)."""
        header = ["t"] + [f"{n}.{c}" for n in self.names for c in COORDS]
        with open(path, "w", newline="", encoding="utf-8") as f:
            wr = csv.writer(f)
            wr.writerow(header)
            for i in range(len(self.t)):
                wr.writerow([repr(float(self.t[i]))] + [repr(float(x)) for x in self.poses[i].ravel()])

    @classmethod
    def from_trajectory(cls, traj, source: str = "<simulated>") -> "RecordedRun":
        """The poses of a simulated run (`planar_lcp.Trajectory`): its dynamic bodies, then its kinematic ones."""
        poses = np.concatenate([traj.q, traj.qk], axis=1) if traj.qk.shape[1] else traj.q
        return cls(traj.t, tuple(traj.body_names) + tuple(traj.kinematic_names), poses, source)


def read_recording(path) -> RecordedRun:
    """Read a recording (CSV: the format of the module docstring).

    Raises
    ------
    RecordingError
        For a missing or unreadable file, and for any rule of the format broken: a header that is not ``t`` then
        columns NAME.x, NAME.y, NAME.theta with each body's three present and no column twice; a row with another
        number of fields than the header; a value that is not a finite number; times not strictly increasing; an
        angle that jumps by more than pi (wrapped, not continuous); fewer than 2 rows. The message names the file,
        the line (the header is line 1) and the column, the expected and the actual.
    """
    path = Path(path)
    src = str(path)
    if path.is_dir():
        raise RecordingError(f"{src}: is a directory, not a recording (CSV file)")
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise RecordingError(f"{src}: no such recording (CSV file)") from None
    except OSError as e:
        raise RecordingError(f"{src}: cannot read the recording: {e.strerror or e}") from None
    bom = 3 if raw.startswith(b"\xef\xbb\xbf") else 0
    try:
        text = raw[bom:].decode("utf-8")
    except UnicodeDecodeError as e:
        raise RecordingError(f"{src}: must be UTF-8 text, got byte 0x{raw[bom + e.start]:02x} at byte offset "
                             f"{bom + e.start} ({e.reason})") from None
    return _parse(src, list(_records(src, io.StringIO(text, newline=""))))


def _records(src: str, fh):
    """(line number, fields) of each non-blank line; csv.Error as a RecordingError naming the line."""
    reader = csv.reader(fh)
    try:
        for fields in reader:
            if fields and any(f.strip() for f in fields):
                yield reader.line_num, fields
    except csv.Error as e:
        raise RecordingError(f"{src}: line {reader.line_num} must be a CSV row, got {e}") from None


def _parse(src: str, records: list) -> RecordedRun:
    if not records:
        raise RecordingError(f"{src}: line 1 must be a header (t, NAME.x, NAME.y, NAME.theta, ...), got an empty file")
    hline, header = records[0]
    header = [h.strip() for h in header]
    if header[0] != "t":
        raise RecordingError(f"{src}: line {hline}, column 1 must be 't' (the time, s), got {header[0]!r}")
    seen = {}
    for j, h in enumerate(header):
        if not h:
            raise RecordingError(f"{src}: line {hline}, column {j + 1} must be a column name, got an empty one")
        if h in seen:
            raise RecordingError(f"{src}: line {hline}, column {j + 1} must not repeat column {seen[h] + 1}, got "
                                 f"{h!r} twice")
        seen[h] = j
    # bodies in order of their first pose column; columns that are not NAME.x/y/theta are ignored
    names, cols = [], {}
    for j, h in enumerate(header[1:], start=1):
        name, dot, coord = h.rpartition(".")
        if dot and name and coord in COORDS:
            if name not in cols:
                names.append(name)
                cols[name] = {}
            cols[name][coord] = j
    if not names:
        raise RecordingError(f"{src}: line {hline} must name at least one body's columns NAME.x, NAME.y, NAME.theta "
                             f"after t, got {', '.join(header)}")
    for n in names:
        missing = [f"{n}.{c}" for c in COORDS if c not in cols[n]]
        if missing:
            raise RecordingError(f"{src}: line {hline} must have the columns {n}.x, {n}.y, {n}.theta of body {n!r}, "
                                 f"got no {', '.join(missing)}")
    rows = records[1:]
    if len(rows) < 2:
        raise RecordingError(f"{src}: must have at least 2 rows of samples after the header, got {len(rows)}")
    used = [0] + [cols[n][c] for n in names for c in COORDS]
    data = np.empty((len(rows), len(used)))
    for i, (line, fields) in enumerate(rows):
        if len(fields) != len(header):
            raise RecordingError(f"{src}: line {line} must have {len(header)} fields (as the header), got "
                                 f"{len(fields)}")
        for k, j in enumerate(used):
            try:
                data[i, k] = float(fields[j])
            except ValueError:
                raise RecordingError(f"{src}: line {line}, column {header[j]} must be a number, got "
                                     f"{fields[j]!r}") from None
    lines = [line for line, _ in rows]
    poses = data[:, 1:].reshape(len(rows), len(names), 3)
    _check_values(src, data[:, 0], poses, names, line_of_row=lines)
    return RecordedRun(data[:, 0], tuple(names), poses, src)


def _check_values(src: str, t: np.ndarray, poses: np.ndarray, names, line_of_row) -> None:
    """Finite values, t strictly increasing, theta continuous, at least 2 samples. `line_of_row` gives each row's line
    in a file (messages say "line L, column C"); without it, "row i" (0-based) and the array."""

    def where(i, col):
        return f"line {line_of_row[i]}, column {col}" if line_of_row is not None else f"row {i}, {col}"

    if len(t) < 2:
        raise RecordingError(f"{src}: must have at least 2 samples, got {len(t)}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise RecordingError(f"{src}: {where(bad[0], 't')} must be a finite number, got {float(t[bad[0]])!r}")
    finite = np.isfinite(poses)
    if not finite.all():
        i, b, c = (int(x) for x in np.argwhere(~finite)[0])
        raise RecordingError(f"{src}: {where(i, f'{names[b]}.{COORDS[c]}')} must be a finite number, got "
                             f"{float(poses[i, b, c])!r}")
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        raise RecordingError(f"{src}: {where(i, 't')} must be greater than the previous sample's "
                             f"{float(t[i - 1])!r} s (strictly increasing), got {float(t[i])!r}")
    jumps = np.abs(np.diff(poses[:, :, 2], axis=0))
    if (jumps > math.pi).any():
        i, b = (int(x) for x in np.argwhere(jumps > math.pi)[0])
        raise RecordingError(f"{src}: {where(i + 1, f'{names[b]}.theta')} must be continuous (unwrapped: within pi "
                             f"of the previous sample's {float(poses[i, b, 2])!r} rad), got "
                             f"{float(poses[i + 1, b, 2])!r}")
