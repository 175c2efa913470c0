"""The background compilation of a cold cache's first run (issue M: docs/performance.md, "Issue M, sixth session").

`Simulator(..., python_while_cold=True)`, what `simulate` makes, calls `start_background(model, options)` when the
run's rollout kernel is neither compiled in this process nor in numba's cache: a process of its own compiles what a
run of (model, options) compiles, as a cold run in the foreground would (engine/precompile.py's helper included),
while the run goes on as Python (engine/interpreted.py) and switches to the kernels once they are in the cache. The
process outlives the run if it must, so that the next run finds the kernels cached. One such process per cache
directory at a time, by a lock file there holding its pid.
"""

import os
import pickle
import subprocess
import sys
import tempfile
import time

import numba
import numpy as np

from planar_lcp.engine.compile_notice import COLD_START_SECONDS, announce_background
from planar_lcp.engine.contacts import contacts_at
from planar_lcp.engine.limit_surface import unit_load_wrench
from planar_lcp.engine.precompile import may_start, start_if_cold

#: the lock file's name in numba's cache directory
BACKGROUND_LOCK = "planar_lcp_compiling.pid"


def lock_file(cache_dir):
    """The lock file of a background compilation into the numba cache `cache_dir`."""
    return os.path.join(cache_dir, BACKGROUND_LOCK)


class Background:
    """A background compilation: this process's child (`popen`), or another process's (its lock file only)."""

    def __init__(self, popen, lock, started):
        self.popen, self.lock, self.started = popen, lock, started

    def running(self):
        if self.popen is not None:
            return self.popen.poll() is None
        return _lock_holder(self.lock) is not None

    def seconds_left(self):
        """The compilation's expected time left (COLD_START_SECONDS from its start)."""
        return max(0.0, COLD_START_SECONDS - (time.time() - self.started))

    def wait(self, timeout=None):
        """Wait until it ends (for tests and scripts that measure the cache it leaves); True if it did."""
        end = None if timeout is None else time.monotonic() + timeout
        while self.running():
            if end is not None and time.monotonic() > end:
                return False
            time.sleep(0.05)
        return True


_background = None


def started():
    """The background compilation this process started (a `Background`), or None."""
    return _background


def _lock_holder(lock):
    """The pid in the lock file if that process is alive, else None."""
    try:
        with open(lock) as f:
            pid = int(f.read().strip() or 0)
        os.kill(pid, 0)
    except (OSError, ValueError):
        return None
    return pid


def start_background(model, options):
    """Compile the kernels that `Simulator(model, options)` runs in a background process, if a second process may
    compile (engine/precompile.py `may_start`) and numba has a cache directory; at most one per cache directory (a
    running one is returned instead of a new one). The caller has found the cache cold. Returns a `Background`, or
    None: the caller then compiles in-process."""
    global _background
    cache_dir = numba.config.CACHE_DIR
    if not may_start() or not cache_dir:
        return None
    if _background is not None and _background.running():
        return _background
    lock = lock_file(cache_dir)
    if _lock_holder(lock) is not None:         # another process's: this run waits for it as for its own
        try:
            started = os.path.getmtime(lock)
        except OSError:
            started = time.time()
        return Background(None, lock, started)
    try:
        os.makedirs(cache_dir, exist_ok=True)
        fd, payload = tempfile.mkstemp(prefix="planar_lcp_run_", suffix=".pickle", dir=cache_dir)
        with os.fdopen(fd, "wb") as f:
            pickle.dump((model, options), f)
        env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
        popen = subprocess.Popen([sys.executable, "-m", __name__, payload], env=env,
                                 stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                 start_new_session=True)
    except (OSError, pickle.PicklingError, TypeError, AttributeError):
        return None
    _take_lock(lock, popen.pid)  # for it, now: it takes the lock as its own once it has imported numba
    _background = Background(popen, lock, time.time())
    announce_background()
    return _background


def _take_lock(lock, pid):
    """Create the lock file holding `pid`; a stale one (its process gone) is replaced. False if another process
    holds it."""
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            holder = _lock_holder(lock)
            if holder == pid:
                return True
            if holder is not None:
                return False
            try:
                os.unlink(lock)
            except OSError:
                pass
            continue
        with os.fdopen(fd, "w") as f:
            f.write(str(pid))
        return True
    return False


def _compile_in_background(payload):
    """The background process: the kernels of a run of (model, options) from `payload`, compiled into the cache as a
    cold run in the foreground compiles them: the model's (the start-overlap check's contacts, the limit surfaces'
    fixed columns), the structs' constructors, the first rollout kernel (one step of the run)."""
    lock = lock_file(numba.config.CACHE_DIR)
    try:
        with open(payload, "rb") as f:
            model, options = pickle.load(f)
    finally:
        os.unlink(payload)
    if not _take_lock(lock, os.getpid()):
        return
    try:
        from planar_lcp.sim import Simulator
        start_if_cold(model, options.single_kernel or options.warm_start, options.formulation == "velocity")
        contacts_at(model.arrays, model.q0, model.qk0, 0.0, m=model.struct)
        if model.arrays.ls_wrench.shape[0] and model.arrays.ls_wrench.shape[1]:
            unit_load_wrench(model.struct, 0, 1.0, 0.0, 0.0, np.zeros(3))
        Simulator(model, options).rollout(model.q0, model.v0, model.qk0, model.vk0[None], 1, record_contacts=True)
    finally:
        os.unlink(lock)


if __name__ == "__main__":
    _compile_in_background(sys.argv[1])
