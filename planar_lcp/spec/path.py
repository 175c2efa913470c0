"""A kinematic body's recorded path: rows [t, x, y, angle] and the per-step velocities that follow it.

A path is the pose of the body-frame origin (world frame: s, m, m, rad) at given times. Between rows the pose is
interpolated linearly in each coordinate (the angle is continuous: rows 0 and 6.2 rad make nearly a whole turn, not
a small one back); before the first row the body rests at the first row's pose, after the last at the last row's.
The step from t_i = i h to t_i + h moves the body with the constant velocity (P(t_i + h) - P(t_i)) / h, so the
engine's kinematic update qk + h vk puts it on the path at every step's end, to round-off, with no new kernel: the
velocities are the `vk_seq` that `Simulator.rollout` takes (docs/scene-format.md, "Recorded paths").

Pure numpy: the scene validator (spec/scene.py) turns the ValueErrors raised here into its one-line SceneErrors.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

__all__ = ["MAX_PATH_ROWS", "PATH_COLUMNS", "check_path_rows", "kinematic_velocities", "path_pose", "path_velocities",
           "read_path_csv"]

#: rows of one path: a recording of 1000 s at 1 kHz
MAX_PATH_ROWS = 1_000_000
#: a path CSV's columns for a body NAME: t, then NAME.x, NAME.y, NAME.theta (a recording, docs/scene-format.md,
#: "Recordings"), or t, x, y, theta for a file of one body
PATH_COLUMNS = ("t", "x", "y", "theta")


def check_path_rows(rows, max_length: float, max_speed: float, max_angular_speed: float) -> np.ndarray:
    """The path as a (n, 4) float64 array, checked: n in [1, MAX_PATH_ROWS], finite, t >= 0 and strictly
    increasing, positions within +-max_length m, and between rows speeds within max_speed m/s per component and
    max_angular_speed rad/s (the bounds a constant `velocity` has). ValueError naming the row and the value."""
    if isinstance(rows, np.ndarray):
        arr = rows
    else:
        if not isinstance(rows, (list, tuple)):
            raise ValueError(f"must be an array of [t, x, y, angle] rows or a CSV file name, got {rows!r}")
        for i, r in enumerate(rows):
            ok = isinstance(r, (list, tuple, np.ndarray)) and len(r) == 4 and all(
                isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool) for x in r)
            if not ok:
                raise ValueError(f"[{i}] must be 4 numbers [t, x, y, angle], got {r!r}")
        arr = rows
    if len(arr) == 0:
        raise ValueError("must have at least 1 row [t, x, y, angle], got none")
    try:
        arr = np.array(arr, dtype=np.float64)
    except (OverflowError, ValueError, TypeError) as e:
        raise ValueError(f"must be an array of [t, x, y, angle] rows: {e}") from None
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ValueError(f"must be rows of 4 numbers [t, x, y, angle], got an array of shape {arr.shape}")
    n = arr.shape[0]
    if n > MAX_PATH_ROWS:
        raise ValueError(f"must have at most {MAX_PATH_ROWS} rows, got {n}")
    bad = np.flatnonzero(~np.isfinite(arr).all(axis=1))
    if bad.size:
        raise ValueError(f"[{bad[0]}] must be 4 finite numbers [t, x, y, angle], got {arr[bad[0]].tolist()}")
    if arr[0, 0] < 0.0:
        raise ValueError(f"[0][0] (t) must be >= 0 s, got {float(arr[0, 0])!r}")
    dt = np.diff(arr[:, 0])
    bad = np.flatnonzero(dt <= 0.0)
    if bad.size:
        i = bad[0] + 1
        raise ValueError(f"[{i}][0] (t) must be greater than the previous row's {float(arr[i - 1, 0])!r} s (times "
                         f"strictly increasing), got {float(arr[i, 0])!r}")
    far = np.flatnonzero(np.abs(arr[:, 1:3]).max(axis=1) > max_length)
    if far.size:
        i = far[0]
        raise ValueError(f"[{i}] position must be within +-{max_length:g} m in each coordinate (a physical bound), "
                         f"got [{float(arr[i, 1])!r}, {float(arr[i, 2])!r}]")
    if n > 1:
        speed = np.abs(np.diff(arr[:, 1:3], axis=0)).max(axis=1) / dt
        fast = np.flatnonzero(speed > max_speed)
        if fast.size:
            i = fast[0] + 1
            raise ValueError(f"[{i}] must be reached from row {i - 1} within +-{max_speed:g} m/s in each component "
                             f"(a physical bound), got {speed[fast[0]]:.6g} m/s")
        spin = np.abs(np.diff(arr[:, 3])) / dt
        fast = np.flatnonzero(spin > max_angular_speed)
        if fast.size:
            i = fast[0] + 1
            raise ValueError(f"[{i}] must be reached from row {i - 1} within +-{max_angular_speed:g} rad/s (a physical "
                             f"bound), got {spin[fast[0]]:.6g} rad/s")
    return arr


def read_path_csv(file, body: str) -> np.ndarray:
    """The rows [t, x, y, theta] of `body` in a CSV file: a recording's columns t, BODY.x, BODY.y, BODY.theta, else
    a file of one body's columns t, x, y, theta; further columns are ignored. ValueError naming the file, the row
    and the column (unchecked values: `check_path_rows` checks them)."""
    file = Path(file)
    if file.is_dir():
        raise ValueError(f"{file}: is a directory, not a CSV file")
    try:
        with open(file, newline="", encoding="utf-8") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None:
                raise ValueError(f"{file}: empty file, expected a header row with t, {body}.x, {body}.y, {body}.theta")
            header = [h.strip() for h in header]
            named = ("t", f"{body}.x", f"{body}.y", f"{body}.theta")
            cols = named if all(c in header for c in named) else PATH_COLUMNS
            missing = [c for c in cols if c not in header]
            if missing:
                raise ValueError(f"{file}: header must have the columns t, {body}.x, {body}.y, {body}.theta (or t, x, "
                                 f"y, theta), got {', '.join(header)}")
            idx = [header.index(c) for c in cols]
            rows = []
            for line, rec in enumerate(reader, start=2):
                if not rec or all(not x.strip() for x in rec):
                    continue
                try:
                    rows.append([float(rec[j]) for j in idx])
                except (ValueError, IndexError):
                    shown = [rec[j] if j < len(rec) else "" for j in idx]
                    raise ValueError(f"{file}: line {line}: columns {', '.join(cols)} must be numbers, got "
                                     f"{shown}") from None
                if len(rows) > MAX_PATH_ROWS:
                    raise ValueError(f"{file}: must have at most {MAX_PATH_ROWS} rows")
    except FileNotFoundError:
        raise ValueError(f"{file}: no such file") from None
    except UnicodeDecodeError as e:
        raise ValueError(f"{file}: not UTF-8 text ({e.reason} at byte {e.start})") from None
    except OSError as e:
        raise ValueError(f"{file}: cannot read the file: {e.strerror or e}") from None
    if not rows:
        raise ValueError(f"{file}: no data rows after the header")
    return np.array(rows, dtype=np.float64)


def path_pose(rows: np.ndarray, t) -> np.ndarray:
    """The pose [x, y, angle] at time(s) t: linear between rows, the first row's before it, the last's after it."""
    rows = np.asarray(rows, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    return np.stack([np.interp(t, rows[:, 0], rows[:, c]) for c in (1, 2, 3)], axis=-1)


def path_velocities(rows: np.ndarray, h: float, nsteps: int) -> np.ndarray:
    """(nsteps, 3) origin velocities [vx, vy, omega] of the steps from t = 0: step i moves the body from the path's
    pose at i h to its pose at (i + 1) h."""
    if not (math.isfinite(h) and h > 0.0):
        raise ValueError(f"h must be > 0, got {h!r}")
    poses = path_pose(rows, np.arange(int(nsteps) + 1) * h)
    return np.diff(poses, axis=0) / h


def kinematic_velocities(scene, names, h: float, nsteps: int) -> np.ndarray:
    """The velocities [vx, vy, omega] of the scene's kinematic bodies `names` (in that order) step by step, as
    `Simulator.rollout` takes them (`vk_seq`, step i uses row min(i, rows - 1)): (1, n, 3) their constant
    `velocity` and `angular_velocity` when none follows a `path`, else (nsteps, n, 3) with each path's
    `path_velocities`. One definition for our engine and the pymunk bridge."""
    bodies = [scene.body(name) for name in names]
    vk0 = np.array([[b.velocity[0], b.velocity[1], b.angular_velocity] for b in bodies],
                   dtype=np.float64).reshape(len(bodies), 3)
    if all(b.path is None for b in bodies):
        return vk0[None]
    vk_seq = np.repeat(vk0[None], int(nsteps), axis=0)
    for k, b in enumerate(bodies):
        if b.path is not None:
            vk_seq[:, k] = path_velocities(np.asarray(b.path), h, nsteps)
    return vk_seq
