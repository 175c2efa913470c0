"""One line before the wait when the simulation kernels must be compiled, nothing when numba's cache has them.

numba announces a compilation with a "numba:compile" event only after its on-disk cache missed (numba's
`Dispatcher.compile`: the cache is tried first, the event wraps the compiler), so a listener sees exactly the
compilations a run waits for. The CLI installs it for every command (`planar_lcp/cli.py`, `main`).
"""

import sys

from numba.core import event

#: measured: the background compilation of the default set (planar_lcp/compilation/background.py) on an empty numba cache, 2 cores:
#: 47 to 50 s wall clock (docs/performance.md, "Compile time")
COLD_START_SECONDS = 50

NOTICE = (f"compiling the simulation kernels once (about {COLD_START_SECONDS} s on 2 cores); "
          "later runs start at once")

#: A cold cache's background compilation started (planar_lcp/compilation/background.py): `simulate` goes on meanwhile as Python
#: (the same results), other runs wait for it
BACKGROUND_NOTICE = (f"compiling the simulation kernels once, in a background process (about {COLD_START_SECONDS} s "
                     "on 2 cores); later runs start at once")

_PACKAGES = ("planar_lcp",)  # the planners have no numba code of their own

_installed = []


class CompileNotice(event.Listener):
    """Prints `prefix: NOTICE` to `stream` at the first compilation of one of our kernels, or `prefix:
    BACKGROUND_NOTICE` if a background compilation starts first (`announce_background`): one line per process."""

    def __init__(self, prefix, stream=None):
        self.prefix = prefix
        self.stream = stream
        self.said = False

    def on_start(self, ev):
        func = getattr(ev.data.get("dispatcher"), "py_func", None)
        module = getattr(func, "__module__", None) or ""
        if module.split(".")[0] in _PACKAGES:
            self.say(NOTICE)

    def say(self, notice):
        """Print `prefix: notice`, if nothing was said yet."""
        if not self.said:
            self.said = True
            print(f"{self.prefix}: {notice}", file=self.stream or sys.stderr, flush=True)

    def on_end(self, ev):
        pass


def announce_compilation(prefix, stream=None):
    """Install a `CompileNotice` for this process (numba's listeners are global) and return it; `uninstall` it."""
    notice = CompileNotice(prefix, stream)
    event.register("numba:compile", notice)
    _installed.append(notice)
    return notice


def uninstall(notice):
    """Uninstall a notice (nothing if it was already)."""
    if notice in _installed:
        event.unregister("numba:compile", notice)
        _installed.remove(notice)


def uninstall_all():
    """Uninstall every installed notice (a command that reports its compilation itself)."""
    for notice in list(_installed):
        uninstall(notice)


def announce_background():
    """The installed notices say BACKGROUND_NOTICE (a background compilation started), unless they said theirs."""
    for notice in _installed:
        notice.say(BACKGROUND_NOTICE)
