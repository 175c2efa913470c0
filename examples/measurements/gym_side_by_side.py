"""planar_lcp/PushT-v0 and gym-pusht's PushT-v0 side by side: the same start states and the same actions in both, and
where the T's trajectories part (docs/gym.md, "Side by side with gym-pusht").

    python examples/measurements/gym_side_by_side.py [--pusht-python PY] [--plan docs/figures/gym/push_t_plan/plan.json]
                                        [--json FILE]

PY (default $PLANAR_LCP_PUSHT_PYTHON) is the python of a virtualenv with gym-pusht==0.1.8; it runs
examples/measurements/gym_pusht_rollout.py there. The episodes: three scripted pushes, a seeded random walk of targets, and the
planner's push_t plan (`planar-lcp plan push_t --seed 1 --iterations 3000`) executed as actions: its pusher path
(our push_t scene's frame, m) mapped into the arena (mm) and turned into PD targets. Ours runs in three settings,
to separate the causes: the defaults (table friction 0.3, pusher-T friction 0.3), gym-pusht's frictionless contact
(contact_friction=0), and no friction at all (table_friction=0 too). Prints a markdown table: per episode and
setting, the first action after which the T's pose differs from gym-pusht's by more than 2 mm or 2 degrees, and the
differences at the end; --json writes every trajectory.
"""

import argparse
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
DEFAULT_PLAN = ROOT / "docs" / "figures" / "gym" / "push_t_plan" / "plan.json"
#: where the push_t scene's origin goes in the arena, mm (the plan's whole motion stays inside the walls)
PLAN_OFFSET = (200.0, 270.0)
SETTINGS = {"ours": {}, "ours, contact mu 0": {"contact_friction": 0.0},
            "ours, no friction": {"contact_friction": 0.0, "table_friction": 0.0},
            "ours, gym-pusht's physics": {"physics": "gym_pusht"}}
PART_MM, PART_DEG = 2.0, 2.0


def reset_state(agent, frame_pose):
    """gym-pusht's reset_to_state (agent x, y, block x, y, angle) that puts the T's frame at frame_pose (x, y mm,
    angle rad): it turns the T about its frame point (0, 45) (planners.environments.push_t.PUSHT_COG), so the frame ends at
    (bx + 45 sin a, by + 45 - 45 cos a)."""
    from planners.environments.push_t import PUSHT_COG
    fx, fy, a = frame_pose
    cx, cy = PUSHT_COG
    c, s = math.cos(a), math.sin(a)
    return [float(agent[0]), float(agent[1]), fx + (c * cx - s * cy) - cx, fy + (s * cx + c * cy) - cy, float(a)]


def plan_episode(plan_path):
    """The push_t plan as an episode: start state and PD targets (mm), 10 Hz.

    Our push_t T's frame is gym-pusht's turned by 180 degrees and moved 15 mm (planners.environments.push_t._push_t_bodies): a frame
    pose (P, a) of ours is gym-pusht's (P + R(a) (0, 15 mm), a + pi). The plan's step is 0.1 s, one action: the target
    of action k is the plan's pusher position at its end plus the PD law's lag behind a ramp, (k_v / k_p) u_k."""
    import planners
    from planners.environments.push_t import K_P, K_V
    p = planners.load_plan(plan_path)
    tm = p.model
    if abs(tm.task.step_duration - 0.1) > 1e-12:
        raise SystemExit(f"gym_side_by_side.py: error: {plan_path}: the plan's step must be 0.1 s (one action), got "
                         f"{tm.task.step_duration}")
    _, dense, ok = tm.execute(p.states[0], p.controls, p.steps)
    u = np.repeat(p.controls, p.steps, axis=0)                    # the control of each 0.1 s step
    off = np.array(PLAN_OFFSET)

    def gym_frame(x):
        f = tm.object_frame_pose(x)
        c, s = math.cos(f[2]), math.sin(f[2])
        return [off[0] + 1000 * (f[0] - s * 0.015), off[1] + 1000 * (f[1] + c * 0.015), f[2] + math.pi]

    pusher = off + 1000 * dense[:, tm.ip:tm.ip + 2]
    targets = pusher[1:] + 1000 * (K_V / K_P) * u
    targets = np.vstack([targets, np.repeat(pusher[-1:], 10, axis=0)])       # then hold still for 1 s
    goal = gym_frame(np.array([*tm.goal_com, 0, 0, 0, 0, 0]))
    return {"name": "push_t plan (seed 1)", "reset_to_state": reset_state(pusher[0], gym_frame(dense[0])),
            "actions": targets.tolist(), "goal": goal, "planned_end": gym_frame(dense[-1])}


def episodes(plan_path):
    """The episodes: name, reset_to_state, actions (targets, mm)."""
    eps = [
        {"name": "straight push up the stem, then away",
         "reset_to_state": [256.0, 400.0, 256.0, 255.0, 0.0],
         "actions": [[256.0, 330.0]] * 4 + [[256.0, 480.0]] * 6},
        {"name": "off-centre push (turns the T)",
         "reset_to_state": [236.0, 420.0, 256.0, 255.0, 0.0],
         "actions": [[236.0 + 3 * k, 400.0 - 12 * k] for k in range(1, 16)]},
        {"name": "slow push of the bar's end",
         "reset_to_state": [150.0, 222.0, 256.0, 200.0, 0.0],
         "actions": [[150.0 + 6 * k, 222.0] for k in range(1, 21)]},
    ]
    rng = np.random.default_rng(0)
    walk = [np.array([256.0, 430.0])]
    for _ in range(40):                                 # a smooth random walk of targets, 25 mm steps at most
        walk.append(np.clip(walk[-1] + rng.uniform(-25, 25, 2) + [0.0, -8.0], 30, 480))
    eps.append({"name": "random walk of targets (seed 0)", "reset_to_state": [256.0, 430.0, 256.0, 230.0, 0.3],
                "actions": [w.tolist() for w in walk[1:]]})
    if plan_path is not None:
        eps.append(plan_episode(plan_path))
    return eps


def run_ours(ep, **kwargs):
    import gymnasium as gym

    import planners  # noqa: F401
    env = gym.make("planar_lcp/PushT-v0", disable_env_checker=True, **kwargs).unwrapped
    env.reset(options={"reset_to_state": ep["reset_to_state"], **({"goal": ep["goal"]} if "goal" in ep else {})})

    def row():
        return [*env.agent_pos(), *env.block_pose()]

    states, cover = [row()], []
    for a in ep["actions"]:
        _, _, _, _, info = env.step(np.asarray(a, dtype=np.float32))
        states.append(row())
        cover.append(info["coverage"])
    return {"state": states, "coverage": cover}


def run_pusht(python, eps):
    spec = {"episodes": [{"reset_to_state": e["reset_to_state"], "actions": [list(map(float, np.float32(a)))
                                                                             for a in e["actions"]]} for e in eps]}
    r = subprocess.run([python, str(HERE / "gym_pusht_rollout.py")], input=json.dumps(spec), capture_output=True,
                       text=True, timeout=600)
    if r.returncode != 0:
        raise SystemExit(f"gym_side_by_side.py: error: gym-pusht's run with {python} failed: "
                         f"{r.stderr.strip().splitlines()[-1] if r.stderr.strip() else r.returncode}")
    return json.loads(r.stdout)


def cover_of(frame_pose, goal):
    from planners.environments.push_t import coverage, t_box_corners
    return coverage(t_box_corners(), frame_pose, goal)


def parting(ours, theirs):
    """(first action after which the T's poses differ by > PART_MM or PART_DEG, or None; final position and angle
    differences (mm, deg); largest pusher difference (mm))."""
    a, b = np.asarray(ours), np.asarray(theirs)
    dpos = np.hypot(a[:, 2] - b[:, 2], a[:, 3] - b[:, 3])
    dang = np.degrees(np.abs((a[:, 4] - b[:, 4] + math.pi) % (2 * math.pi) - math.pi))
    bad = np.flatnonzero((dpos > PART_MM) | (dang > PART_DEG))
    return (int(bad[0]) if bad.size else None, float(dpos[-1]), float(dang[-1]),
            float(np.abs(a[:, :2] - b[:, :2]).max()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pusht-python", default=os.environ.get("PLANAR_LCP_PUSHT_PYTHON"))
    ap.add_argument("--plan", default=str(DEFAULT_PLAN), help="a push_t plan file ('' for none)")
    ap.add_argument("--json", help="write every trajectory here")
    args = ap.parse_args(argv)
    if not args.pusht_python or not Path(args.pusht_python).is_file():
        print("gym_side_by_side.py: error: --pusht-python (or $PLANAR_LCP_PUSHT_PYTHON) must name the python of a "
              f"virtualenv with gym-pusht==0.1.8, got {args.pusht_python!r}", file=sys.stderr)
        return 2
    if args.plan and not Path(args.plan).is_file():
        print(f"gym_side_by_side.py: error: --plan: no such plan file {args.plan!r}", file=sys.stderr)
        return 2
    eps = episodes(args.plan or None)
    theirs = run_pusht(args.pusht_python, eps)
    out = {"gym_pusht": theirs["gym_pusht"], "episodes": []}
    print(f"T pose after each action, ours against gym-pusht {theirs['gym_pusht']} (same start, same actions); "
          f"'parts at': the first action after which they differ by > {PART_MM:g} mm or {PART_DEG:g} deg\n")
    print("| episode | actions | setting | parts at action | end: position diff (mm) | end: angle diff (deg) "
          "| end cover: ours / gym-pusht | pusher diff (mm) |")
    print("|---|---|---|---|---|---|---|---|")
    for ep, th in zip(eps, theirs["episodes"]):
        rec = {"name": ep["name"], "gym_pusht": th, "ours": {}}
        for setting, kw in SETTINGS.items():
            mine = run_ours(ep, **kw)
            rec["ours"][setting] = mine
            k, dp, da, dpush = parting(mine["state"], th["state"])
            if "goal" in ep:
                ours_end, theirs_end = mine["state"][-1][2:], th["state"][-1][2:]
                cov = f"{cover_of(ours_end, ep['goal']):.3f} / {cover_of(theirs_end, ep['goal']):.3f}"
            else:
                cov = f"{mine['coverage'][-1]:.3f} / {th['coverage'][-1]:.3f}"
            print(f"| {ep['name']} | {len(ep['actions'])} | {setting} | {'-' if k is None else k} | {dp:.1f} | "
                  f"{da:.1f} | {cov} | {dpush:.1e} |")
        if "planned_end" in ep:
            rec["planned_end"] = ep["planned_end"]
            rec["goal"] = ep["goal"]
        out["episodes"].append(rec)
    if "planned_end" in eps[-1]:
        ep = eps[-1]
        print("\nThe plan's own end (our push_t scene, velocity-driven pusher): cover "
              f"{cover_of(ep['planned_end'], ep['goal']):.3f} of its goal; the cover column above is of the same goal, "
              "after the plan's actions and 1 s of holding still.")
    if args.json:
        Path(args.json).write_text(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
