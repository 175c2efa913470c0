"""gym-pusht's T identified from its own transitions with `planar_lcp.fit` (docs/closed_loop.md, "The model").

    python examples/measurements/identify_gym_pusht.py --pusht-python PY [--episodes 3] [--window 20]

Records PushTPolicy's episodes in gym-pusht's own environment (its virtualenv, planners/environments/gym_pusht_server.py): the T's
observed pose after every action and the pusher's path, which is the PD law's from the actions (ten substeps per
action, exactly as gym-pusht computes it). Cuts them into windows of `--window` actions that start with the pusher
clear of the T, and fits the T's inertia per unit mass and its centre of mass along its stem (mm) of our engine with
gym-pusht's other options (damping 0, no table friction, frictionless contacts) by least squares of the simulated
against the observed poses, from a start far from gym-pusht's values (1500 mm^2, 35 mm). Prints the fit with its
standard errors beside the values gym-pusht's source sets (3000 mm^2: the bar's moment about the frame origin,
twice; 45 mm: the mean of the two boxes' centroids).
"""

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

SUB = 10                      # physics steps per action
DT = 0.01


def pd_path(agent0, actions):
    """The pusher's positions (mm) at every physics step of the actions, from rest at agent0: gym-pusht's PD law."""
    from planners.environments.push_t import pd_substeps
    p, v = np.asarray(agent0, float) * 1e-3, np.zeros(2)
    out = [p[None] * 1e3]
    for a in actions:
        ps, vs = pd_substeps(p, v, np.asarray(a, float) * 1e-3)
        p, v = ps[-1], vs[-1]
        out.append(ps * 1e3)
    return np.concatenate(out)


def record(env, policy, seed, actions_max):
    """(agent positions, T poses (unwrapped angle), actions) of one episode, at most actions_max actions."""
    obs, _ = env.reset(seed=seed)
    policy.reset()
    agents, poses, acts = [obs[0:2].copy()], [obs[2:5].copy()], []
    for _ in range(actions_max):
        a = policy(obs)
        obs, _, terminated, truncated, _ = env.step(a)
        acts.append(a.copy())
        agents.append(obs[0:2].copy())
        poses.append(obs[2:5].copy())
        if terminated or truncated:
            break
    poses = np.array(poses)
    poses[:, 2] = np.unwrap(poses[:, 2])
    return np.array(agents), poses, np.array(acts)


def windows(agents, poses, acts, length, clearance=1.0):
    """(pusher path rows (t, x, y, 0) in m at every physics step, the T's recorded frame poses in m) of the windows
    of `length` actions that start with the pusher at least `clearance` mm off the T."""
    from planners.environments.push_t import PushTEnv
    from planners.pusht import _boxes_mm, _frame_maps, _sdf
    boxes = _boxes_mm(PushTEnv(obs_type="state", render_mode=None, physics="gym_pusht"))
    path = pd_path(agents[0], acts)
    out = []
    k = 0
    while k + length <= len(acts):
        to_t, _ = _frame_maps(poses[k])
        if _sdf(boxes, to_t(path[k * SUB])) >= 15.0 + clearance:
            seg = path[k * SUB:(k + length) * SUB + 1] * 1e-3
            t = np.arange(len(seg)) * DT
            rows = np.column_stack([t, seg, np.zeros(len(seg))])
            obs = poses[k:k + length + 1].copy()
            obs[:, :2] *= 1e-3
            out.append((rows, obs))
            k += length
        else:
            k += 1
    return out


def scene_doc(rows, inertia_mm2, com_y_mm):
    """Our PushT-v0's scene with gym-pusht's physics, the pusher on `rows`, the T's inertia and centre of mass."""
    from planners.environments.push_t import PushTEnv
    env = PushTEnv(obs_type="state", render_mode=None, physics="gym_pusht")
    doc = env._scene_document()
    for b in doc["bodies"]:
        if b["name"] == "pusher":
            b.pop("position", None)
            b["path"] = rows.tolist()
        if b["name"] == "T":
            b["inertia"] = env.t_mass * inertia_mm2 * 1e-6
            b["center_of_mass"] = [0.0, com_y_mm * 1e-3]
    doc["sim"]["t_end"] = float(rows[-1, 0])
    return doc


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pusht-python", default=os.environ.get("PLANAR_LCP_PUSHT_PYTHON"))
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--seed", type=int, default=7000)
    ap.add_argument("--window", type=int, default=20, help="actions per recording (default 20)")
    ap.add_argument("--actions", type=int, default=120, help="actions recorded per episode (default 120)")
    args = ap.parse_args(argv)
    if not args.pusht_python:
        sys.exit("identify_gym_pusht.py: error: --pusht-python (or $PLANAR_LCP_PUSHT_PYTHON) must name the python of "
                 "a virtualenv with gym-pusht==0.1.8")
    from planar_lcp.fitting import fit
    from planar_lcp.spec.recordings import RecordedRun
    from planners.environments.push_t import GYM_PUSHT_INERTIA, PUSHT_COG
    from planners.environments.gym_pusht_process import SubprocessEnv
    from planners.pusht import PushTPolicy

    env = SubprocessEnv(args.pusht_python)
    policy = PushTPolicy("gym_pusht")
    data = []
    for i in range(args.episodes):
        data += windows(*record(env, policy, args.seed + i, args.actions), args.window)
    env.close()
    if not data:
        sys.exit("identify_gym_pusht.py: error: no window starts with the pusher clear of the T")
    recs = [RecordedRun(t=np.arange(len(obs)) * SUB * DT, names=("T",), poses=obs[:, None, :],
                        source=f"gym-pusht window {j}") for j, (_, obs) in enumerate(data)]
    moved = [float(np.hypot(*(obs[-1, :2] - obs[0, :2])) * 1e3) for _, obs in data]
    print(f"recorded       {len(recs)} windows of {args.window} actions from {args.episodes} episodes of gym-pusht "
          f"(seeds {args.seed}..{args.seed + args.episodes - 1}); the T moves {np.median(moved):.1f} mm in the median "
          f"window, {max(moved):.1f} at most")
    res = fit(lambda j, v: scene_doc(data[j][0], v["inertia_mm2"], v["com_y_mm"]), recs, ["inertia_mm2", "com_y_mm"],
              x0=[1500.0, 35.0], bounds=[(300.0, 30000.0), (20.0, 70.0)], diff_step=1e-3, length_scale=0.05)
    for name, source in (("inertia_mm2", GYM_PUSHT_INERTIA), ("com_y_mm", PUSHT_COG[1])):
        print(f"  {name:12s} = {res.values[name]:.2f} +- {res.stderr[name]:.2f} (by window: "
              f"+- {res.stderr_by_run[name]:.2f}); gym-pusht's source: {source:g}")
    rms = np.sqrt(np.mean([r["rms_position"] ** 2 for r in res.per_run]))
    print(f"  rms position error over the windows at the fit: {1e3 * rms:.3f} mm ({res.nfev} evaluations)")


if __name__ == "__main__":
    main()
