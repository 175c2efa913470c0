"""Roll out a scripted policy in planar_lcp/PushT-v0 and record a GIF: no training, the environment as a user meets
it (docs/gym.md, "A scripted policy").

    python examples/gym_pusht_policy.py [--steps 150] [--seed 0] [--out pusht_policy.gif] [--size 256]

The policy reads the T's keypoints ("environment_state_agent_pos") and pushes the T's centre toward the goal T's:
it walks the pusher round to the side of the T away from the goal (never through it), then pushes through the centre,
at most 25 mm of target motion per action. It ignores the angle, so it rarely reaches the 95 % cover of success;
it shows the interface, the table's friction (the T slides a little after each push and stops) and render().
Prints the cover at the start and at the end and writes the GIF (one frame per action, 0.1 s each; Pillow merges
repeated frames into longer ones).
"""

import argparse
import sys

import numpy as np

STEP_MM = 25.0          # the farthest the target moves from the pusher per action
CLEAR_MM = 95.0         # the pusher's distance from the T's centre while it walks round (the T's reach + radius)


def t_centre(keypoints):
    """The T's area centroid from its 16 keypoint coordinates (two boxes: 120 x 30 and 30 x 90 mm)."""
    k = np.asarray(keypoints, dtype=np.float64).reshape(8, 2)
    return (3600.0 * k[:4].mean(axis=0) + 2700.0 * k[4:].mean(axis=0)) / 6300.0


def policy(obs, goal_centre):
    """The next target (mm): walk round behind the T (seen from the goal), then push through its centre."""
    agent, c = obs["agent_pos"], t_centre(obs["environment_state"])
    e = goal_centre - c
    dist = np.hypot(*e)
    if dist < 3.0:
        return agent                                        # there (up to the angle): hold still
    d = e / dist
    behind = c - d * CLEAR_MM
    rel = agent - c
    along, across = rel @ d, rel[0] * d[1] - rel[1] * d[0]
    if along < -40.0 and abs(across) < 12.0:
        target = c + d * min(dist, 40.0)                    # lined up behind the T: push through its centre
    elif np.hypot(*rel) < CLEAR_MM - 5.0:
        target = c + rel / max(np.hypot(*rel), 1e-9) * CLEAR_MM      # too close: step back out
    elif along > -40.0 and np.hypot(*(agent - behind)) > 20.0:
        # round the T on the circle of radius CLEAR_MM, the way that takes the pusher behind it sooner
        ang = np.arctan2(rel[1], rel[0]) + np.array([0.5, -0.5])
        ways = c + CLEAR_MM * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        target = ways[np.argmin((ways - c) @ d)]
    else:
        target = behind
    step = target - agent
    n = np.hypot(*step)
    return agent + (step if n <= STEP_MM else step * STEP_MM / n)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="pusht_policy.gif")
    ap.add_argument("--size", type=int, default=256, help="the GIF's side in pixels")
    args = ap.parse_args(argv)
    if args.steps < 1 or args.size < 16:
        print("gym_pusht_policy.py: error: --steps must be >= 1 and --size >= 16", file=sys.stderr)
        return 2
    try:
        import gymnasium as gym
        from PIL import Image
    except ImportError as e:
        print(f"gym_pusht_policy.py: error: {e.name} is not installed; it comes with the extra 'gym': "
              'pip install -e ".[gym]"', file=sys.stderr)
        return 2

    import planners  # noqa: F401  (registers planar_lcp/PushT-v0)
    from planners.environments.push_t import place_corners, t_box_corners

    env = gym.make("planar_lcp/PushT-v0", obs_type="environment_state_agent_pos", visualization_width=args.size,
                   visualization_height=args.size)
    obs, info = env.reset(seed=args.seed)
    goal_centre = t_centre(place_corners(t_box_corners(), info["goal_pose"]))
    frames = [env.render()]
    cover0 = env.unwrapped.coverage()
    cover, success, n = cover0, False, 0
    for n in range(1, args.steps + 1):
        obs, reward, terminated, truncated, info = env.step(policy(obs, goal_centre).astype(np.float32))
        frames.append(env.render())
        cover, success = info["coverage"], info["is_success"]
        if terminated or truncated:
            break
    images = [Image.fromarray(f) for f in frames]
    images[0].save(args.out, save_all=True, append_images=images[1:], duration=100, loop=0, optimize=True)
    print(f"seed {args.seed}: cover {cover0:.3f} at the start, {cover:.3f} after {n} actions "
          f"({'success' if success else 'no success'}); wrote {args.out} ({len(frames)} frames)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
