"""Numba kernels, and where numba caches them: a directory keyed by a hash of every kernel source file, for
planar_lcp's own files only.

Why: numba's cache (`cache=True`) is invalidated only when the file defining a function changes, not when a callee in
another file changes. After an edit or an upgrade, `rollout_lemke` (rollout.py unchanged) would silently keep an
old inlined `step_pipeline` (step.py changed). Keying the cache directory on all kernel sources makes any change start
a fresh cache. The directory is given to numba by a cache locator of ours, consulted first and answering only for
files of the planar_lcp package, so that other numba libraries' caches stay where numba puts them and
`numba.config` is left as it was. A user-set NUMBA_CACHE_DIR is respected as is: numba's own locator then serves every
file, ours among them (`cache_dir()` says which directory holds our kernels).

`copying_inlined_ir_once()`: a context in which numba's inlining of `inline='always'` functions copies a callee's IR
in linear time; the processes that compile the kernels for the others (background.py, precompile.py, `planar-lcp
warmup`) compile inside it: the step's compilation spends a third of its own time in that copy otherwise.
"""
import ast
import contextlib
import hashlib
import inspect
import os
import textwrap
from pathlib import Path

import numba


def kernel_source_hash():
    h = hashlib.sha256()
    here = Path(__file__).resolve().parent
    for p in sorted(here.rglob("*.py")):
        h.update(str(p.relative_to(here)).encode())
        h.update(p.read_bytes())
    h.update(numba.__version__.encode())
    return h.hexdigest()[:16]


def _cache_dir():
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "planar_lcp", "numba", kernel_source_hash())


def _own_cache_dir():
    try:
        d = _cache_dir()
        os.makedirs(d, exist_ok=True)
        return d
    except OSError:
        return None  # an unwritable home: numba's own locators serve (next to the sources, or a temp dir)


#: the keyed directory (module docstring), or None when it cannot be created
OWN_CACHE_DIR = _own_cache_dir()
#: the planar_lcp package's directory: the files our locator answers for
_PACKAGE_DIR = str(Path(__file__).resolve().parent.parent) + os.sep


def cache_dir():
    """The directory numba caches planar_lcp's kernels in: NUMBA_CACHE_DIR when set (numba.config.CACHE_DIR), else
    the keyed directory; None when neither exists (numba then caches beside the sources)."""
    return numba.config.CACHE_DIR or OWN_CACHE_DIR


def _install_cache_locator():
    """Put _KernelCacheLocator first among numba's cache locators (once)."""
    from numba.core.caching import CacheImpl, UserProvidedCacheLocator

    class _KernelCacheLocator(UserProvidedCacheLocator):
        """numba's locator of a user-provided cache directory, with OWN_CACHE_DIR as the directory, for the files
        of the planar_lcp package only, and only when the user has set no NUMBA_CACHE_DIR: the same paths as
        numba's own locator gives with NUMBA_CACHE_DIR = OWN_CACHE_DIR (the processes that compile for this one
        are started so), so both share one cache."""

        def __init__(self, py_func, py_file):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = os.path.join(OWN_CACHE_DIR, self.get_suitable_cache_subpath(py_file))

        @classmethod
        def from_function(cls, py_func, py_file):
            if numba.config.CACHE_DIR or OWN_CACHE_DIR is None or not os.path.exists(py_file):
                return None
            if not os.path.realpath(py_file).startswith(_PACKAGE_DIR):
                return None
            self = cls(py_func, py_file)
            try:
                self.ensure_cache_path()
            except OSError:
                return None
            return self

    if not any(getattr(c, "_planar_lcp", False) for c in CacheImpl._locator_classes):
        _KernelCacheLocator._planar_lcp = True
        CacheImpl._locator_classes.insert(0, _KernelCacheLocator)


_install_cache_locator()


# numba's `InlineWorker.inline_ir` copies the callee's IR block by block, a deep copy with a memo of its own per
# block; every variable refers to the function's scope, which holds all its variables, so each block's copy copies
# them all again: O(blocks x variables). The step's kernels inline the whole pipeline (engine/step.py), and a cold
# cache spent 4 to 5 s of the step's 12 to 15 s of compiling there (numba bugs #8989 and #9204 name the same
# copies). One deep copy of all the blocks with one memo gives the same blocks, variables and statements (the blocks
# then share one copy of the scope, as the callee's own blocks share one scope), so the same IR and machine code
# (tests/simulation/test_golden.py bit for bit). Applied only where the installed numba's source has those lines exactly.
# The lines as they stand in the method's source once dedented (copy_ir is nested in inline_ir's body).
_PER_BLOCK_COPY = """        kernel_copy.blocks = {}
        for block_label, block in the_ir.blocks.items():
            new_block = copy.deepcopy(the_ir.blocks[block_label])
            kernel_copy.blocks[block_label] = new_block
"""
_ONE_COPY = """        kernel_copy.blocks = copy.deepcopy(the_ir.blocks)
        # (planar_lcp: one copy with one memo; padded to keep the line numbers of numba's file)


"""


def _one_copy_inline_ir():
    """numba's `InlineWorker.inline_ir` edited as the comment above says, or None where the installed numba's
    source does not have those lines exactly (made once, on first use)."""
    from numba.core import inline_closurecall as ic
    original = ic.InlineWorker.inline_ir
    try:
        lines, first = inspect.getsourcelines(original)
    except (OSError, TypeError):
        return None
    src = textwrap.dedent("".join(lines))
    if src.count(_PER_BLOCK_COPY) != 1:
        return None
    tree = ast.parse(src.replace(_PER_BLOCK_COPY, _ONE_COPY))
    ast.increment_lineno(tree, first - 1)       # tracebacks point at numba's own lines
    namespace = {}
    exec(compile(tree, ic.__file__, "exec"), ic.__dict__, namespace)
    patched = namespace["inline_ir"]
    patched._planar_lcp_one_copy = True
    patched._numba_original = original
    return patched


_PATCHED = []


@contextlib.contextmanager
def copying_inlined_ir_once():
    """Inside: numba's inliner copies a callee's IR once (the comment above); numba's own method is back after.
    Yields whether the edit applies to the installed numba."""
    from numba.core import inline_closurecall as ic
    if not _PATCHED:
        _PATCHED.append(_one_copy_inline_ir())
    patched = _PATCHED[0]
    worker = ic.InlineWorker
    if patched is None or getattr(worker.inline_ir, "_planar_lcp_one_copy", False):
        yield patched is not None
        return
    original = worker.inline_ir
    worker.inline_ir = patched
    try:
        yield True
    finally:
        worker.inline_ir = original
