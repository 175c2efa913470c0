"""Helpers for tests that run the command line in a subprocess."""

import os
import signal
import subprocess
import sys
import time

CLI = [sys.executable, "-c", "import sys; from planar_lcp.cli import main; sys.exit(main())"]


def interrupt_cli(args, started, tmp_path, wait=1.0):
    """Run the CLI, wait for the line `started` on stdout and `wait` seconds more, send SIGINT; returns (exit status,
    stderr and what stdout printed after the line `started`, seconds from the signal to the exit)."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    p = subprocess.Popen(CLI + [str(a) for a in args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         cwd=tmp_path, env=env)
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
