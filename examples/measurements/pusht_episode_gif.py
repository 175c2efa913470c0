"""A GIF of one Push-T episode driven by PushTPolicy, drawn by the environment itself (docs/closed_loop.md).

    python examples/measurements/pusht_episode_gif.py --env gym_pusht/PushT-v0 --pusht-python PY --seed S --out FILE.gif

gym-pusht's frames are its own render() (pygame), served from its virtualenv (planners/environments/gym_pusht_server.py); ours are
PushT-v0's render(). Every other action is a frame (the episode at 5 frames per second of its 10 Hz actions, played
at 10 frames per second: twice as fast); the last frame is held for a second. Prints the episode's outcome.
"""

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", default="gym_pusht/PushT-v0", choices=["gym_pusht/PushT-v0", "planar_lcp/PushT-v0"])
    ap.add_argument("--pusht-python", default=os.environ.get("PLANAR_LCP_PUSHT_PYTHON"))
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--out", default="pusht_episode.gif")
    ap.add_argument("--every", type=int, default=2, help="a frame every K actions (default 2)")
    args = ap.parse_args(argv)
    from PIL import Image

    from planners.environments.gym_pusht_process import SubprocessEnv
    from planners.pusht import PushTPolicy
    if args.env == "gym_pusht/PushT-v0":
        if not args.pusht_python:
            sys.exit("pusht_episode_gif.py: error: --pusht-python (or $PLANAR_LCP_PUSHT_PYTHON) must name the python "
                     "of a virtualenv with gym-pusht==0.1.8")
        env = SubprocessEnv(args.pusht_python, args.env)
        policy = PushTPolicy("gym_pusht")
    else:
        from planners.environments.push_t import PushTEnv
        env = PushTEnv(obs_type="state", render_mode="rgb_array")
        policy = PushTPolicy("planar_lcp")
    obs, _ = env.reset(seed=args.seed)
    policy.reset()
    frames = [env.render()]
    info, k = {}, 0
    for k in range(1, 301):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        if k % args.every == 0 or terminated or truncated or k == 300:
            frames.append(env.render())
        if terminated or truncated:
            break
    env.close()
    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)).resize((340, 340)) for f in frames]
    images += [images[-1]] * 10
    images[0].save(args.out, save_all=True, append_images=images[1:], duration=100, loop=0)
    print(f"seed {args.seed}: {'success' if info.get('is_success') else 'no success'} after {k} actions, coverage "
          f"{float(info.get('coverage', 0.0)):.3f}; wrote {args.out} ({len(images)} frames)")


if __name__ == "__main__":
    main()
