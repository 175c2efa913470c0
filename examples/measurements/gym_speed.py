"""Environment steps per second of planar_lcp/PushT-v0 against gym-pusht's PushT-v0, in one process (docs/gym.md,
"Speed").

gym-pusht pins pymunk < 7 and our compare extra wants pymunk >= 7's API, so the two meet in gym-pusht's virtualenv,
with our package installed there without its dependencies plus numba (docs/gym.md gives the commands):

    $PLANAR_LCP_PUSHT_PYTHON examples/measurements/gym_speed.py [--rounds 15] [--steps 200] [--obs-types state pixels]

Per obs type, each round steps each environment `--steps` times with the same seeded random actions (a reset every
300 steps, or at success), the order of the two alternating from round to round; the time is the thread's CPU time
(time.thread_time). Prints, per obs type, both environments' microseconds per step and steps per second (median and
the range over rounds) and the ratio of ours to gym-pusht's steps per second (median, range).
"""

import argparse
import statistics
import sys
import time
import warnings


def run(env, actions, seed):
    """Step env through actions (resetting with seed at the start, every 300 steps and at termination): thread s."""
    t0 = time.thread_time()
    env.reset(seed=seed)
    n = 0
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        n += 1
        if terminated or truncated or n == 300:
            env.reset(seed=seed + n)
            n = 0
    return time.thread_time() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--obs-types", nargs="+", default=["state", "pixels"], choices=["state", "pixels"])
    args = ap.parse_args(argv)
    if args.rounds < 1 or args.steps < 1:
        print("gym_speed.py: error: --rounds and --steps must be >= 1", file=sys.stderr)
        return 2
    warnings.filterwarnings("ignore")
    try:
        import gym_pusht  # noqa: F401
    except ImportError:
        print("gym_speed.py: error: gym_pusht is not importable by this interpreter; run this script with the python "
              "of gym-pusht's virtualenv, with planar_lcp installed there (docs/gym.md, 'Speed')", file=sys.stderr)
        return 2
    import gymnasium as gym
    import numpy as np

    import planners  # noqa: F401  (registers planar_lcp/PushT-v0)
    from importlib.metadata import version

    print(f"gym-pusht {version('gym-pusht')}, pymunk {version('pymunk')}, gymnasium {version('gymnasium')}; "
          f"{args.rounds} rounds x {args.steps} steps per environment, alternating, thread CPU time")
    for obs_type in args.obs_types:
        envs = {"planar_lcp": gym.make("planar_lcp/PushT-v0", obs_type=obs_type),
                "gym_pusht": gym.make("gym_pusht/PushT-v0", obs_type=obs_type)}
        rng = np.random.default_rng(0)
        warm = rng.uniform(0, 512, (20, 2)).astype(np.float32)
        for env in envs.values():
            run(env, warm, 0)                 # first calls (imports, numba's cache) outside the rounds
        per_step = {k: [] for k in envs}
        for r in range(args.rounds):
            actions = rng.uniform(0, 512, (args.steps, 2)).astype(np.float32)
            order = list(envs) if r % 2 == 0 else list(envs)[::-1]
            for k in order:
                per_step[k].append(run(envs[k], actions, 1000 * r) / args.steps)
        print(f"obs_type {obs_type!r}:")
        for k, ts in per_step.items():
            us = [1e6 * t for t in ts]
            print(f"  {k:10s} {statistics.median(us):8.1f} us/step ({min(us):.1f}-{max(us):.1f}), "
                  f"{1 / statistics.median(ts):8.0f} steps/s")
        ratio = [b / a for a, b in zip(per_step["planar_lcp"], per_step["gym_pusht"])]
        print(f"  ours / gym-pusht steps per second: median {statistics.median(ratio):.2f} "
              f"({min(ratio):.2f}-{max(ratio):.2f} over rounds)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
