"""gym-pusht's own PushT-v0 in another python (its own virtualenv: it pins pymunk < 7), driven from this one
through gym_pusht_server.py, which runs there and imports nothing of planar_lcp."""

import numpy as np


class SubprocessEnv:
    """gym-pusht's environment in another python (its own virtualenv: it pins pymunk < 7), driven through
    gym_pusht_server.py: `reset(seed=...)` and `step(action)` as a gymnasium environment's, obs_type "state".

    Raises RuntimeError naming the interpreter when the server cannot start (no such python, no gym-pusht there)."""

    def __init__(self, python, env_id="gym_pusht/PushT-v0"):
        import json
        import subprocess
        from pathlib import Path
        self._json = json
        server = Path(__file__).resolve().parent / "gym_pusht_server.py"
        try:
            self._p = subprocess.Popen([str(python), str(server), env_id], stdin=subprocess.PIPE,
                                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1)
        except OSError as e:
            raise RuntimeError(f"cannot start {python} for {env_id}: {e}") from None
        first = self._p.stdout.readline()
        if not first:
            err = self._p.stderr.read().strip().splitlines()
            raise RuntimeError(f"{python} could not serve {env_id}: {err[-1] if err else 'it exited'}")
        hello = json.loads(first)
        self.version = hello.get("gym_pusht")
        self.env_id = env_id

    def _ask(self, req):
        self._p.stdin.write(self._json.dumps(req) + "\n")
        self._p.stdin.flush()
        ans = self._json.loads(self._p.stdout.readline())
        if "error" in ans:
            raise RuntimeError(f"{self.env_id}: {ans['error']}")
        return ans

    def reset(self, seed=None, options=None):
        if options:
            raise ValueError("SubprocessEnv.reset: options are not served")
        a = self._ask({"cmd": "reset", "seed": seed})
        return np.asarray(a["obs"], dtype=np.float64), a["info"]

    def step(self, action):
        a = self._ask({"cmd": "step", "action": [float(x) for x in action]})
        return (np.asarray(a["obs"], dtype=np.float64), float(a["reward"]), bool(a["terminated"]),
                bool(a["truncated"]), a["info"])

    def render(self):
        """gym-pusht's own drawing of the current state (its render(): 680 x 680 RGB), through a temporary file."""
        import tempfile
        from pathlib import Path
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "frame.npy"
            self._ask({"cmd": "render", "path": str(path)})
            return np.load(path)

    def close(self):
        if self._p.poll() is None:
            try:
                self._ask({"cmd": "close"})
            except (OSError, ValueError):
                pass
            self._p.wait(timeout=10)
