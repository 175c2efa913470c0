"""Ctrl-C that cannot be lost: a SIGINT handler that also remembers the interrupt.

Python's own handler raises KeyboardInterrupt in whatever Python code the main thread runs when the signal is
handled. When that code was called from C that discards errors, the interrupt is gone: numba's dispatcher reads a
structref argument's `_numba_type_` property (the model and work structs of every kernel call) and clears any error
raised there, and llvmlite's object-cache callback prints one and goes on. A replay interrupted at random moments
lost its Ctrl-C about once in ten tries that way and ran to its end (16 s).

`catch_sigint` (the CLI installs it) raises KeyboardInterrupt as Python's handler does and also sets a flag;
`raise_if_interrupted`, called between the rollout kernel's chunks (`Simulator`), raises the interrupt again when it
was swallowed, so a long run still stops within a chunk (0.25 s). Without `catch_sigint` (the library used from a
user's program, whose signal handlers are its own) the flag is never set and nothing changes.
"""

import signal
import threading

_pending = False


def _handler(signum, frame):
    global _pending
    _pending = True
    raise KeyboardInterrupt


def catch_sigint():
    """Install the remembering SIGINT handler (main thread only; elsewhere signal handlers cannot be set). Returns
    the previous handler, or None when nothing was installed."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGINT, _handler)


def interrupted():
    """Whether a SIGINT reached `catch_sigint`'s handler since the last `clear`."""
    return _pending


def clear():
    """Forget a remembered SIGINT (once it has been handled)."""
    global _pending
    _pending = False


def raise_if_interrupted():
    """Raise KeyboardInterrupt if a SIGINT arrived that may have been swallowed (and forget it)."""
    global _pending
    if _pending:
        _pending = False
        raise KeyboardInterrupt
