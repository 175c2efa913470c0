"""The one way the tests run the command line in a subprocess, as a user does: `planar-lcp ARGS`."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# `python -c` instead of the `planar-lcp` script: the tests run from a checkout that need not be installed
CLI = [sys.executable, "-c", "import sys; from planar_lcp.cli import main; sys.exit(main())"]
# a small exact plan: tip_box needs only a few hundred RRT iterations with this seed (add "--out DIR")
TIP_PLAN_ARGS = ("plan", "tip_box", "--planner", "RRT", "--iterations", "400", "--seed", "1", "--no-gif")


def cli_env(**extra):
    """The environment of a CLI subprocess: this one, the checkout first on the path, no display; plus `extra`."""
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT),
                                                                                        os.environ.get("PYTHONPATH")])))
    env.update(extra)
    return env


def run_cli(*args, cwd=ROOT, timeout=600, env=None):
    """Run `planar-lcp ARGS` to its end. Returns the subprocess.CompletedProcess (returncode, stdout, stderr as
    text) with one more attribute, `seconds`: its wall time. `env`: extra environment variables."""
    t0 = time.perf_counter()
    r = subprocess.run(CLI + [str(a) for a in args], capture_output=True, text=True, timeout=timeout, cwd=cwd,
                       env=cli_env(**(env or {})))
    r.seconds = time.perf_counter() - t0
    return r


def interrupt_cli(args, started, tmp_path, wait=1.0):
    """Run the CLI, wait for the line `started` on stdout and `wait` seconds more, send SIGINT; returns (exit status,
    stderr and what stdout printed after the line `started`, seconds from the signal to the exit)."""
    p = subprocess.Popen(CLI + [str(a) for a in args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         cwd=tmp_path, env=cli_env(PYTHONUNBUFFERED="1"))
    try:
        for line in p.stdout:
            if line.startswith(started):
                break
        time.sleep(wait)                      # inside the long part
        assert p.poll() is None, "the command finished before it could be interrupted"
        t0 = time.perf_counter()
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=30)
        return p.returncode, err if p.returncode == 130 else err + out, time.perf_counter() - t0
    finally:
        if p.poll() is None:
            p.kill()


def group_size(pgid):
    """How many live processes the process group `pgid` holds (read from Linux's /proc)."""
    n = 0
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                n += os.getpgid(int(d.name)) == pgid
            except (ProcessLookupError, PermissionError):
                pass
    return n


def ignores_sigint(pid):
    """Whether the process `pid` ignores SIGINT now (bit 2 of SigIgn in Linux's /proc/PID/status): a command does
    while it starts a local cluster's workers (planar_lcp.parallel.cluster), and a Ctrl-C then is lost."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("SigIgn:"):
                    return bool(int(line.split()[1], 16) & (1 << (2 - 1)))
    except OSError:
        pass
    return False


def ctrl_c_cli(args, ready, cwd, timeout=300, env=None):
    """Run `planar-lcp ARGS` in a process group of its own, wait until `ready()` is true, then press Ctrl-C as a
    terminal does: SIGINT to the whole foreground group, the command and every process it started (a local Dask
    cluster's workers too). `ready` takes no argument, or one: the group's id (see `group_size`). `env`: extra
    environment variables. Returns a subprocess.CompletedProcess (returncode,
    stdout, stderr) with `seconds` from the signal to the exit and `group_left`: whether any process of the group
    outlived the command by 10 s."""
    p = subprocess.Popen(CLI + [str(a) for a in args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         cwd=cwd, env=cli_env(PYTHONUNBUFFERED="1", **(env or {})), start_new_session=True)
    try:
        t0 = time.monotonic()
        takes_group = ready.__code__.co_argcount == 1
        while not (ready(p.pid) if takes_group else ready()):
            if p.poll() is not None:
                out, err = p.communicate()
                raise AssertionError(f"the command ended (exit status {p.returncode}) before it was ready to be "
                                     f"interrupted\n{out[-3000:]}\n{err[-3000:]}")
            assert time.monotonic() - t0 < timeout, "never ready to be interrupted"
            time.sleep(0.05)
        assert p.poll() is None, "the command finished before it could be interrupted"
        t1 = time.perf_counter()
        os.killpg(p.pid, signal.SIGINT)
        out, err = p.communicate(timeout=60)
        seconds = time.perf_counter() - t1
        t2 = time.monotonic()
        group_left = True
        while time.monotonic() - t2 < 10:
            try:
                os.killpg(p.pid, 0)          # any process left in the group?
            except ProcessLookupError:
                group_left = False
                break
            time.sleep(0.1)
        r = subprocess.CompletedProcess(p.args, p.returncode, out, err)
        r.seconds, r.group_left = seconds, group_left
        return r
    finally:
        if p.poll() is None:
            p.kill()
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


# A process that records numba's compile events (the functions it compiled, not those it loaded from the cache), runs
# a body of code, and prints them as JSON on its last line.
_COMPILE_LISTENER = """
import json
from numba.core import event
compiled = []
class L(event.Listener):
    def on_start(self, ev):
        d = ev.data.get("dispatcher")
        compiled.append(d.py_func.__module__ + "." + d.py_func.__qualname__ if d is not None else "?")
    def on_end(self, ev):
        pass
event.register("numba:compile", L())
"""


def python_compiling(body, cache, timeout=1800, **env):
    """Run the Python code `body` in a fresh process on the numba cache `cache`, with numba's compile events recorded;
    `body` ends by printing `json.dumps(compiled)`. Returns (its stdout lines but the last, the last as JSON: the
    functions it compiled)."""
    import json
    full = cli_env(NUMBA_CACHE_DIR=str(cache), **env)
    full.pop("NUMBA_DISABLE_JIT", None)
    out = subprocess.run([sys.executable, "-c", _COMPILE_LISTENER + body], capture_output=True, text=True, env=full,
                         timeout=timeout, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-3000:]
    lines = out.stdout.strip().splitlines()
    return lines[:-1], json.loads(lines[-1])

