"""A small data root in the MIT pushing data set's layout, made by our own simulator: `make_root(path)` writes
ROOT/objects/ellip1_ext.npy (a 60-gon of the data set's circle, 52.4 mm in radius) and ROOT/abs/train/*.h5 (pushes of
it named as the data set names them), whose object poses are the predictions of `mit.push_scene(push, TRUE)` on their
recordings (`planar_lcp.fitting.predict_run`), so that `planar-lcp pushdata predict --model` with TRUE reproduces
them and `planar-lcp pushdata fit` recovers TRUE.

How the files are made so that the reader's registration of the outline does not depend on the simulated poses:
the force stream rises (2 N over a 0.01 N noise) when the tip is 2 mm from the circle, about 1 mm of travel before
it touches; the three pushes press it at points 120 degrees apart, so the registration (a shift: a circle has no
angle) stays near the identity and the contacts it uses are read while the object is still at rest. Each file is
first written with the object at rest (the registration reads only that part), then with the poses simulated on the
registered outline; `make_root` checks that the registration is the same after, and that the files' poses are
reproduced to 1e-12 m.
"""

import math
from pathlib import Path

import numpy as np

#: the parameters the synthetic pushes are made with
TRUE = {"support_friction": 0.3, "pusher_friction": 0.2, "h": 0.004}
SHAPE = "ellip1"
RADIUS = 0.0524                               # m: the data set's circle
START = (0.30, 0.02, 0.4)                     # the object's first pose, world frame (m, m, rad)
DT = 0.004                                    # 250 Hz, as the data set
T_REST = 0.1                                  # s at rest before the tip moves
GAP = 0.003                                   # m from the tip's disk to the square at the start
FORCE_GAP = 0.002                             # m: the force rises when the gap is below this
TRAVEL = 0.028                                # m the tip moves
SPEED = 0.1                                   # m/s
T_AFTER = 0.15                                # s of recording after the tip stops
T0 = 1000.0                                   # the streams' UNIX time of the first object sample
#: (the contact point's outward normal, rad in the object's frame; the push's angle from the inward normal, rad)
PUSHES = [(math.pi, 0.6), (math.pi / 3, -0.5), (-math.pi / 3, 0.4)]


def push_name(normal, t, v=SPEED * 1000):
    """The data set's name of a push: i = 0 for a smooth outline, s the contact's place along it (a fraction)."""
    s = (normal / (2.0 * math.pi)) % 1.0
    return f"motion_surface=abs_shape={SHAPE}_a=0_v={v:g}_i=0.000_s={s:.3f}_t={t:.3f}.h5"


def outline(n=60):
    """The circle as a clockwise n-gon (the data set's files are clockwise)."""
    a = -2.0 * math.pi * np.arange(n) / n
    return RADIUS * np.column_stack([np.cos(a), np.sin(a)])


def _rot(th):
    return np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])


def _streams(normal, push_angle, seed):
    """(tip (N, 4), object (M, 4) at rest, force (K, 4)): the streams of one push, UNIX times."""
    from planar_lcp.studies.pushdata.mit import PUSHER_RADIUS
    rng = np.random.default_rng(seed)
    n_out = np.array([math.cos(normal), math.sin(normal)])                   # outward normal, object frame
    start_local = (RADIUS + PUSHER_RADIUS + GAP) * n_out
    direction = _rot(push_angle) @ (-n_out)                                  # into the object, turned by push_angle
    duration = T_REST + TRAVEL / SPEED + T_AFTER
    t_obj = np.arange(0.0, duration, DT)
    t_tip = t_obj + 0.5 * DT
    t_force = t_obj + 0.25 * DT
    travel = np.clip((t_tip - T_REST) * SPEED, 0.0, TRAVEL)
    tip_local = start_local + travel[:, None] * direction
    R, origin = _rot(START[2]), np.array(START[:2])
    tip_world = tip_local @ R.T + origin
    travel_f = np.clip((t_force - T_REST) * SPEED, 0.0, TRAVEL)
    gap_f = np.linalg.norm(start_local + travel_f[:, None] * direction, axis=1) - RADIUS - PUSHER_RADIUS
    press = (gap_f < FORCE_GAP).astype(float)
    force = rng.normal(0.0, 0.01, size=(len(t_force), 3)) + 2.0 * press[:, None] * np.append(R @ direction, 0.0)
    tip = np.column_stack([T0 + t_tip, tip_world, np.zeros(len(t_tip))])
    obj = np.column_stack([T0 + t_obj, np.tile(START, (len(t_obj), 1))])
    return tip, obj, np.column_stack([T0 + t_force, force])


def _write(path, tip, obj, force):
    import h5py
    with h5py.File(path, "w") as h:
        h["tip_pose"] = tip
        h["object_pose"] = obj
        h["ft_wrench"] = force


def make_root(root, pushes=PUSHES, params=TRUE) -> list:
    """Write the data root `root` (module docstring); returns the push files, sorted."""
    from planar_lcp.studies.pushdata import mit
    from planar_lcp.fitting import predict_run

    root = Path(root)
    (root / "objects").mkdir(parents=True, exist_ok=True)
    folder = root / "abs" / "train"
    folder.mkdir(parents=True, exist_ok=True)
    np.save(root / "objects" / f"{SHAPE}_ext.npy", outline())
    streams = {}
    for k, (normal, push_angle) in enumerate(pushes):
        path = folder / push_name(normal, push_angle)
        streams[path] = _streams(normal, push_angle, seed=k)
        _write(path, *streams[path])
    mit._object_model.cache_clear()
    model = mit.object_model(SHAPE, root)
    for path, (tip, obj, force) in streams.items():
        push = mit.read_push(path, root)
        _, pred = predict_run(mit.push_scene(push, params, model=model), mit.push_recording(push, model))
        obj = obj.copy()
        obj[1:, 1:] = pred[1:, 0]                                           # the first pose is the input
        _write(path, tip, obj, force)
    mit._object_model.cache_clear()
    again = mit.object_model(SHAPE, root)
    assert all(np.array_equal(a, b) for a, b in zip(model.pieces, again.pieces)), "the registration moved"
    for path in streams:
        push = mit.read_push(path, root)
        rec = mit.push_recording(push, again)
        _, pred = predict_run(mit.push_scene(push, params, model=again), rec)
        assert np.abs(pred[:, 0] - rec.poses[:, 0]).max() < 1e-12, path
    mit._object_model.cache_clear()
    return sorted(streams)


if __name__ == "__main__":
    import sys
    import time
    t0 = time.perf_counter()
    for f in make_root(sys.argv[1]):
        print(f)
    print(f"{time.perf_counter() - t0:.1f} s")
