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

import math

import numpy as np

__all__ = ["MAX_PATH_ROWS", "check_path_rows", "kinematic_velocities", "path_pose", "path_velocities",
           "read_path_csv"]

#: rows of one path: a recording of 1000 s at 1 kHz
MAX_PATH_ROWS = 1_000_000


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
    """The rows [t, x, y, theta] of `body` in a recording (CSV, `planar_lcp.spec.recordings`: columns t, BODY.x, BODY.y,
    BODY.theta; other bodies' columns are ignored). ValueError in one line naming the file (and the line and column
    for a broken rule of the format)."""
    from planar_lcp.spec.recordings import read_recording

    run = read_recording(file)
    if body not in run.names:
        raise ValueError(f"{file}: header must have the columns t, {body}.x, {body}.y, {body}.theta (a recording of "
                         f"the body's poses), got the bodies {', '.join(run.names)}")
    return run.path_rows(body)


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
