"""Roll gym-pusht's PushT-v0 out from given start states with given actions: the peer's half of the side-by-side
runs (examples/measurements/gym_side_by_side.py, tests/environments/test_gym.py). Runs in gym-pusht's own virtualenv (it pins pymunk < 7, which
ours does not allow), so it imports nothing of planar_lcp.

    $PLANAR_LCP_PUSHT_PYTHON examples/measurements/gym_pusht_rollout.py < episodes.json > trajectories.json

Input (JSON on stdin): {"episodes": [{"reset_to_state": [5 numbers], "actions": [[x, y], ...]}, ...]}.
Output (JSON on stdout): {"episodes": [{"state": [[agent x, y, block x, y, angle (unwrapped)], ...] (one more row
than actions: the reset's first), "coverage": [...], "terminated": [...]}, ...], "gym_pusht": version}.
"""

import json
import sys
import warnings


def main():
    warnings.filterwarnings("ignore")
    import gymnasium as gym
    import gym_pusht  # noqa: F401  (registers gym_pusht/PushT-v0)
    import numpy as np
    from importlib.metadata import version

    spec = json.load(sys.stdin)
    env = gym.make("gym_pusht/PushT-v0", obs_type="state", disable_env_checker=True).unwrapped
    out = []
    for ep in spec["episodes"]:
        env.reset(options={"reset_to_state": ep["reset_to_state"]})

        def row():
            return [*map(float, env.agent.position), *map(float, env.block.position), float(env.block.angle)]

        states, cover, term = [row()], [], []
        for a in ep["actions"]:
            _, _, terminated, _, info = env.step(np.asarray(a, dtype=np.float64))
            states.append(row())
            cover.append(float(info["coverage"]))
            term.append(bool(terminated))
        out.append({"state": states, "coverage": cover, "terminated": term})
    json.dump({"episodes": out, "gym_pusht": version("gym-pusht")}, sys.stdout)


if __name__ == "__main__":
    main()
