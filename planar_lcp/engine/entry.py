"""Compiled kernels called without numba's dispatcher, for a caller whose arguments keep their types.

numba's dispatcher types every argument of every call to choose the compiled overload: arrays and scalars in C, the
kernels' options (namedtuples) and structs through Python, a part of a small scene's derivatives call that matters
where their cost is counted in steps (docs/performance.md, "The step's derivatives"). `EntryPoints.call` calls a
kernel through the dispatcher the first time, then through the entry point of the overload that call chose
(numba's `overloads[signature].entry_point`, which converts the arguments by that signature without typing them).
Its caller keeps the arguments' types: a simulator's own structs and options, float64 C-contiguous arrays of fixed
dimensions and a float step. Where the kernels are not compiled (NUMBA_DISABLE_JIT=1: no overloads) every call goes
to the kernel.
"""


class EntryPoints:
    """The entry points of the kernels one caller has called (a `Simulator`'s: its structs' and options' types)."""

    def __init__(self):
        self._entry = {}
        #: a caller's objects made over these entry points, by kernel (derivatives/differences.py `FirstTry`)
        self.bound = {}

    def __contains__(self, kernel):
        """Whether `kernel` is called by its entry point."""
        return kernel in self._entry

    def entry(self, kernel):
        """The compiled entry point of `kernel` (after its first `call`)."""
        return self._entry[kernel]

    def call(self, kernel, *args):
        """kernel(*args), by its compiled entry point after the first call (module docstring)."""
        entry = self._entry.get(kernel)
        if entry is not None:
            return entry(*args)
        out = kernel(*args)
        overloads = getattr(kernel, "overloads", None)
        if overloads:
            compiled = overloads.get(tuple(kernel.typeof_pyval(a) for a in args))
            if compiled is not None:
                self._entry[kernel] = compiled.entry_point
        return out
