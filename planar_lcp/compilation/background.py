"""The simulation kernels compiled once, in a process of their own, on a cold numba cache.

No kernel's type depends on a scene: the model and work structs have the same fields for every scene (sizes are
run-time values), and every Lemke run, whatever its plane, formulation, options, large islands, force-limited or
turning kinematic bodies, takes the one rollout kernel `rollout_lemke` (engine/rollout.py). So one compilation
serves every scene, and `compile_kernels` (kernel_sets.py) makes it on a small built-in scene.

What compiles, by set:

- "default": what a run with the default solver reaches: the model's and the work buffers' structs, the contacts of
  one configuration (a scene's start-overlap check, the pymunk bridge), the limit surface's fixed twists, the rollout
  kernel, the checks of a failed step (planar_lcp/infeasibility.py) and `planar_lcp.lemke`.
- "all" (`planar-lcp warmup`): "default", and the solver "pgs"'s rollout kernel, the step's checked differences
  (`step_derivatives(method="differences")`) and the kernels the solver "osqp"'s Python pipeline calls (where osqp
  is installed).

A cold run (`Simulator`, `compile_scene`) calls `start_background()`: the process `python -m
planar_lcp.compilation.kernel_sets`
compiles the default set into numba's cache while the run goes on as Python (`simulate`) or waits for it (Ctrl-C
stops the wait at once; the compilation goes on, so the next run finds the cache warm); its second core goes to the
helper of compilation/precompile.py, which compiles the island solvers meanwhile. One such process per cache directory at
a time, by a lock file there holding its pid; a run that finds one running waits for it instead of starting another.
"""

import os
import subprocess
import sys
import time

from planar_lcp.compilation.notice import COLD_START_SECONDS, announce_background
from planar_lcp.compilation.precompile import may_start
from planar_lcp.engine import cache_dir as engine_cache_dir
from planar_lcp.engine.interpreted import compiled

#: the lock file's name in numba's cache directory
BACKGROUND_LOCK = "planar_lcp_compiling.pid"

#: the background process: `python -m KERNEL_SETS_MODULE default`
KERNEL_SETS_MODULE = "planar_lcp.compilation.kernel_sets"

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
#: True in the background process itself: its own runs compile in-process
compiling_here = False


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


def default_kernel():
    """The kernel whose presence in numba's cache says the default set is compiled (the set's largest)."""
    from planar_lcp.engine.rollout import rollout_lemke
    return rollout_lemke


def start_background(kernel=None):
    """On a cold cache, start the background compilation of the default set (module docstring), or join the one
    another process runs; `kernel`: the rollout kernel the caller needs (default `rollout_lemke`). Returns a
    `Background`, or None when there is nothing to wait for: the kernel is compiled or cached, it is not one the
    background compiles, or no second process may compile (compilation/precompile.py `may_start`: the JIT off, one CPU,
    PLANAR_LCP_PRECOMPILE=0) or numba has no cache directory; the caller then compiles in-process."""
    global _background
    kernel = default_kernel() if kernel is None else kernel
    if compiling_here or kernel is not default_kernel() or compiled(kernel):
        return None
    cache_dir = engine_cache_dir()
    if not may_start() or not cache_dir:
        return None
    if _background is not None and _background.running():
        return _background
    lock = lock_file(cache_dir)
    if _lock_holder(lock) is not None:         # another process's: this run waits for it as for its own
        try:
            started_at = os.path.getmtime(lock)
        except OSError:
            started_at = time.time()
        _background = Background(None, lock, started_at)
        announce_background()
        return _background
    try:
        os.makedirs(cache_dir, exist_ok=True)
        env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
        # its own process group (start_new_session): a Ctrl-C at the terminal stops the run, not the compilation
        # the next run needs
        popen = subprocess.Popen([sys.executable, "-m", KERNEL_SETS_MODULE, "default"], env=env,
                                 stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                 start_new_session=True)
    except OSError:
        return None
    take_lock(lock, popen.pid)  # for it, now: it takes the lock as its own once it has imported numba
    _background = Background(popen, lock, time.time())
    announce_background()
    return _background


def wait_for(kernel):
    """Before a first call of `kernel` (a numba dispatcher of the default set) from Python: on a cold cache, start
    the background compilation (or join the running one) and wait, Ctrl-C stopping the wait, until `kernel` is in
    numba's cache; at once when it is compiled or cached, or when no background can run (the call then compiles
    it in-process)."""
    from planar_lcp.interrupt import raise_if_interrupted
    if compiling_here or compiled(kernel):
        return
    bg = start_background()
    while bg is not None and bg.running() and not compiled(kernel):
        time.sleep(0.05)
        raise_if_interrupted()


def take_lock(lock, pid):
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
