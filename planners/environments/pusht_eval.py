"""`planar-lcp pusht-eval`: PushTPolicy's episodes in a Push-T environment, scored as the environment scores them
(docs/closed_loop.md).

Each episode is `reset(seed=SEED + i)` of the environment as registered (its TimeLimit: 300 actions) and the policy
acting until the environment says it succeeded (coverage > 0.95) or truncates. gym-pusht's environment runs in this
process when gym_pusht imports here, else under `--pusht-python` ($PLANAR_LCP_PUSHT_PYTHON) through
planners/environments/gym_pusht_server.py. With --jobs or --scheduler the episodes are Dask tasks, a chunk of seeds each.
"""

import csv
import json
import math
import os
import time
from pathlib import Path

import numpy as np

ENVS = ("gym_pusht/PushT-v0", "planar_lcp/PushT-v0")
#: the columns of episodes.csv
COLUMNS = ("episode", "seed", "success", "coverage", "best_coverage", "actions", "compute_median_ms",
           "compute_max_ms", "replans", "wall_s")
MAX_EPISODES = 100000


def default_world(env_id):
    """The physics the policy's model takes for an environment: gym-pusht's own for gym-pusht."""
    return "gym_pusht" if env_id.startswith("gym_pusht/") else "planar_lcp"


def make_env(env_id, pusht_python=None, env_kwargs=None):
    """The environment (obs_type "state"): ours through gymnasium.make; gym-pusht's in this process when it imports,
    else in `pusht_python` (planners.environments.gym_pusht_process.SubprocessEnv). Returns (env, gym-pusht's version or None)."""
    import gymnasium as gym
    if env_id == "planar_lcp/PushT-v0":
        import planners  # noqa: F401  (registers planar_lcp/PushT-v0)
        return gym.make(env_id, obs_type="state", render_mode=None, **(env_kwargs or {})), None
    try:
        import gym_pusht  # noqa: F401
        from importlib.metadata import version
        return gym.make(env_id, obs_type="state"), version("gym-pusht")
    except ImportError:
        pass
    if not pusht_python:
        raise RuntimeError(f"{env_id}: gym_pusht does not import here; give --pusht-python (or "
                           f"$PLANAR_LCP_PUSHT_PYTHON), the python of a virtualenv with gym-pusht==0.1.8")
    from .gym_pusht_process import SubprocessEnv
    env = SubprocessEnv(pusht_python, env_id)
    return env, env.version


def run_episode(env, policy, seed=None, options=None, max_steps=300):
    """One episode of `env` (a gymnasium PushT-v0, obs_type "state") driven by `policy`: a dict with success (as
    the env says it), the final and best coverage, the actions taken, and the policy's compute per action (s, thread
    CPU time)."""
    obs, info = env.reset(seed=seed, options=options)
    policy.reset()
    compute, cover, success = [], 0.0, False
    best = 0.0
    for k in range(max_steps):
        action = policy(obs)
        compute.append(policy.compute_s)
        obs, reward, terminated, truncated, info = env.step(action)
        cover = float(info.get("coverage", 0.0))
        best = max(best, cover)
        if terminated:
            success = bool(info.get("is_success", terminated))
            break
        if truncated:
            break
    return {"seed": seed, "success": success, "coverage": cover, "best_coverage": best, "actions": k + 1,
            "compute_median_s": float(np.median(compute)), "compute_max_s": float(np.max(compute)),
            "replans": policy.replans}


def run_chunk(env_id, world, seeds, first_episode, pusht_python=None, env_kwargs=None, on_row=None):
    """Episodes of seeds `seeds` (a Dask task, or in this process) in one environment with one policy: one row
    (COLUMNS) per episode; `on_row(row)` is called as each ends."""
    from ..pusht import PushTPolicy
    env, _ = make_env(env_id, pusht_python, env_kwargs)
    policy = PushTPolicy(world=world)
    rows = []
    try:
        for k, seed in enumerate(seeds):
            t0 = time.perf_counter()
            r = run_episode(env, policy, seed=int(seed))
            rows.append({"episode": first_episode + k, "seed": int(seed), "success": bool(r["success"]),
                         "coverage": round(r["coverage"], 6), "best_coverage": round(r["best_coverage"], 6),
                         "actions": int(r["actions"]), "compute_median_ms": round(1e3 * r["compute_median_s"], 4),
                         "compute_max_ms": round(1e3 * r["compute_max_s"], 4), "replans": int(r["replans"]),
                         "wall_s": round(time.perf_counter() - t0, 3)})
            if on_row is not None:
                on_row(rows[-1])
    finally:
        env.close()
    return rows


def evaluate(env_id, episodes, seed, out, world=None, pusht_python=None, env_kwargs=None, jobs=None, scheduler=None,
             say=print):
    """Run the episodes, write OUT/episodes.csv and OUT/summary.json, return the summary."""
    world = world or default_world(env_id)
    seeds = list(range(int(seed), int(seed) + int(episodes)))
    out = Path(out)
    version = None
    if env_id.startswith("gym_pusht/"):
        env, version = make_env(env_id, pusht_python, env_kwargs)     # fails here, before any episode, if it cannot
        env.close()
    rows = []
    t0 = time.perf_counter()

    def report_one(r):
        rows.append(r)
        say(f"episode {r['episode']:4d} (seed {r['seed']}): {'success' if r['success'] else 'FAILED '}  "
            f"coverage {r['coverage']:.3f}  {r['actions']:3d} actions  compute median "
            f"{r['compute_median_ms']:.2f} ms, max {r['compute_max_ms']:.1f} ms")

    def report(rs):
        for r in rs:
            report_one(r)

    if jobs is None and scheduler is None:
        run_chunk(env_id, world, seeds, 0, pusht_python, env_kwargs, on_row=report_one)
    else:
        from planar_lcp.parallel.cluster import close_cluster, local_jobs, open_cluster
        client, cluster = open_cluster(scheduler, local_jobs(jobs, len(seeds)))
        try:
            workers = max(1, len(client.scheduler_info()["workers"]))
            size = max(1, math.ceil(len(seeds) / (2 * workers)))
            futures = [client.submit(run_chunk, env_id, world, seeds[i:i + size], i, pusht_python, env_kwargs,
                                     pure=False) for i in range(0, len(seeds), size)]
            from distributed import as_completed
            for f in as_completed(futures):
                report(f.result())
        finally:
            close_cluster(client, cluster)
    rows.sort(key=lambda r: r["episode"])
    with open(out / "episodes.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(COLUMNS))
        w.writeheader()
        w.writerows(rows)
    med = np.array([r["compute_median_ms"] for r in rows])
    mx = np.array([r["compute_max_ms"] for r in rows])
    succ = [r for r in rows if r["success"]]
    summary = {"env": env_id, "gym_pusht": version, "world": world, "env_kwargs": env_kwargs or {},
               "episodes": len(rows), "seeds": [seeds[0], seeds[-1]], "successes": len(succ),
               "success_rate": len(succ) / len(rows), "mean_final_coverage": float(np.mean([r["coverage"] for r
                                                                                             in rows])),
               "median_actions_of_successes": float(np.median([r["actions"] for r in succ])) if succ else None,
               "compute_median_ms": float(np.median(med)), "compute_max_ms": float(mx.max()),
               "failures": [{"seed": r["seed"], "coverage": r["coverage"], "best_coverage": r["best_coverage"]}
                            for r in rows if not r["success"]],
               "wall_s": round(time.perf_counter() - t0, 1), "jobs": jobs, "scheduler": scheduler,
               "cpu": os.cpu_count()}
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary
