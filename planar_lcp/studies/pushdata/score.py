"""Scores of predicted pushes against recorded ones (docs/real_pushes.md, "Predicting a push"): functions on arrays,
SI units (m, rad) in and out.

- The final displacement of a push: (dx, dy, dtheta) from its first to its last object pose, (dx, dy) in the object's
  INITIAL frame (the world displacement turned by -theta0), dtheta the change of the continuous angle.
- The normalized mean squared error (NMSE) over a set of pushes: for each of the three components c,
  sum_k (pred_kc - rec_kc)^2 / sum_k (rec_kc - mean_k rec_kc)^2, averaged over the three. 0 is a perfect prediction,
  1 is as good as predicting every push's mean displacement.
- The final errors of a push: |(dx, dy)_pred - (dx, dy)_rec| (m) and |dtheta_pred - dtheta_rec| (rad). Both runs
  start at the recorded first pose, so these are also the errors of the final pose.
- The error along a push: at every sample, the position error |(x, y)_pred - (x, y)_rec| and the angle error
  |theta_pred - theta_rec|; their root mean square and maximum over the push.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["along_push_errors", "final_displacement", "final_errors", "nmse", "nmse_components", "summary"]


def final_displacement(poses) -> np.ndarray:
    """(3,) dx, dy (m, in the object's initial frame), dtheta (rad) of one push's poses (T, 3) of x, y, theta (the
    angle continuous), from the first pose to the last."""
    p = np.asarray(poses, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 1:
        raise ValueError(f"final_displacement: poses must be a (T, 3) array with T >= 1, got shape {p.shape}")
    x0, y0, th0 = p[0]
    x1, y1, th1 = p[-1]
    c, s = math.cos(th0), math.sin(th0)
    dx, dy = x1 - x0, y1 - y0
    return np.array([c * dx + s * dy, -s * dx + c * dy, th1 - th0])


def _pair(pred, rec, what):
    a = np.asarray(pred, dtype=np.float64)
    b = np.asarray(rec, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{what}: pred and rec must be (N, 3) arrays of the same shape, got {a.shape} and {b.shape}")
    return a, b


def nmse_components(pred, rec) -> np.ndarray:
    """(3,) the NMSE of each component over N pushes: pred, rec (N, 3) final displacements (`final_displacement`).
    A component whose recorded values are all equal (e.g. a single push) has no variance: NaN."""
    a, b = _pair(pred, rec, "nmse_components")
    num = np.sum((a - b) ** 2, axis=0)
    den = np.sum((b - b.mean(axis=0)) ** 2, axis=0)
    out = np.full(3, np.nan)
    ok = den > 0.0
    out[ok] = num[ok] / den[ok]
    return out


def nmse(pred, rec) -> float:
    """The NMSE over N pushes: the mean of `nmse_components` over dx, dy, dtheta (NaN when one is undefined)."""
    return float(np.mean(nmse_components(pred, rec)))


def final_errors(pred, rec) -> tuple:
    """(position (N,) m, angle (N,) rad): each push's final errors from its predicted and recorded final
    displacements pred, rec (N, 3)."""
    a, b = _pair(pred, rec, "final_errors")
    d = a - b
    return np.hypot(d[:, 0], d[:, 1]), np.abs(d[:, 2])


def along_push_errors(pred_poses, rec_poses) -> dict:
    """The errors at every sample of one push, pred_poses and rec_poses (T, 3) on the same times: rms_position,
    max_position (m), rms_angle, max_angle (rad)."""
    a = np.asarray(pred_poses, dtype=np.float64)
    b = np.asarray(rec_poses, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 2 or a.shape[1] != 3 or len(a) < 1:
        raise ValueError(f"along_push_errors: the poses must be (T, 3) arrays of the same shape, got {a.shape} and "
                         f"{b.shape}")
    pos = np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])
    ang = np.abs(a[:, 2] - b[:, 2])
    return {"rms_position": float(np.sqrt(np.mean(pos ** 2))), "max_position": float(pos.max()),
            "rms_angle": float(np.sqrt(np.mean(ang ** 2))), "max_angle": float(ang.max())}


def summary(pred, rec) -> dict:
    """The scores of a set of pushes from their final displacements pred, rec (N, 3): nmse, nmse_components
    (dx, dy, dtheta), median_position_error (m), median_angle_error (rad), and the per-push final errors
    position_errors (m) and angle_errors (rad)."""
    pos, ang = final_errors(pred, rec)
    comps = nmse_components(pred, rec)
    return {"nmse": float(np.mean(comps)), "nmse_components": [float(c) for c in comps],
            "median_position_error": float(np.median(pos)), "median_angle_error": float(np.median(ang)),
            "position_errors": [float(v) for v in pos], "angle_errors": [float(v) for v in ang]}
