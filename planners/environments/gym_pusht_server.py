"""gym-pusht's PushT-v0 served over stdin/stdout, one JSON line per request: the peer's half of closed-loop runs
(`planar-lcp pusht-eval --env gym_pusht/PushT-v0`, planners.environments.gym_pusht_process.SubprocessEnv) when gym-pusht lives in its own
virtualenv (it pins pymunk < 7). It runs under that virtualenv's python and imports nothing of planar_lcp:

    PY planners/environments/gym_pusht_server.py [ENV_ID]

The environment is `gymnasium.make(ENV_ID, obs_type="state")` (default gym_pusht/PushT-v0) as registered, with its
TimeLimit, unmodified. Requests and answers:

    {"cmd": "reset", "seed": S}        -> {"obs": [...], "info": {...}}
    {"cmd": "step", "action": [x, y]}  -> {"obs": [...], "reward": r, "terminated": b, "truncated": b, "info": {...}}
    {"cmd": "render", "path": P}       -> {"shape": [h, w, 3]}: env.render()'s image saved as P (numpy's .npy)
    {"cmd": "close"}                   -> {} and the process ends

Before the first request it writes {"ready": true, "gym_pusht": VERSION, "env": ENV_ID}. An error answers
{"error": "..."} and the server goes on.
"""

import json
import sys
import warnings


def _plain(value):
    """JSON-ready: numpy arrays and scalars as lists and numbers; dicts and lists element by element."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    env_id = argv[0] if argv else "gym_pusht/PushT-v0"
    warnings.filterwarnings("ignore")
    import gymnasium as gym
    import gym_pusht  # noqa: F401  (registers gym_pusht/PushT-v0)
    import numpy as np
    from importlib.metadata import version

    env = gym.make(env_id, obs_type="state")
    out = sys.stdout
    out.write(json.dumps({"ready": True, "gym_pusht": version("gym-pusht"), "env": env_id}) + "\n")
    out.flush()
    for line in sys.stdin:
        try:
            req = json.loads(line)
            cmd = req.get("cmd")
            if cmd == "reset":
                obs, info = env.reset(seed=req.get("seed"))
                ans = {"obs": obs, "info": info}
            elif cmd == "step":
                obs, reward, terminated, truncated, info = env.step(np.asarray(req["action"], dtype=np.float64))
                ans = {"obs": obs, "reward": reward, "terminated": terminated, "truncated": truncated, "info": info}
            elif cmd == "render":
                img = np.asarray(env.render())
                np.save(req["path"], img)
                ans = {"shape": list(img.shape)}
            elif cmd == "close":
                out.write("{}\n")
                out.flush()
                break
            else:
                ans = {"error": f"unknown cmd {cmd!r}"}
        except Exception as e:                          # noqa: BLE001 (answered, the server goes on)
            ans = {"error": f"{type(e).__name__}: {e}"}
        out.write(json.dumps(_plain(ans)) + "\n")
        out.flush()
    env.close()


if __name__ == "__main__":
    main()
