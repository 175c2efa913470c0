"""Numba kernels. Importing this package first points numba's on-disk cache at a directory keyed by a hash of every
kernel source file.

Why: numba's cache (`cache=True`) is invalidated only when the file defining a function changes, not when a callee in
another file changes. After an edit or an upgrade, `rollout_lemke` (rollout.py unchanged) would silently keep an
old inlined `step_pipeline` (step.py changed). Keying the cache directory on all kernel sources makes any change start
a fresh cache. A user-set NUMBA_CACHE_DIR is respected as is. numba's cache setting is process-wide: other numba
libraries imported after planar_lcp (QuantEcon in the benchmarks) cache into the same directory.

It also makes numba's inlining of `inline='always'` functions copy a callee's IR in linear time
(`_copy_inlined_ir_once`): the step's compilation spent a third of its own time there (docs/performance.md, "Issue M").
"""

import ast
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


if not os.environ.get("NUMBA_CACHE_DIR"):
    try:
        d = _cache_dir()
        os.makedirs(d, exist_ok=True)
        numba.config.CACHE_DIR = d
    except OSError:
        pass  # an unwritable home: numba falls back to its own locators (next to the sources, or a temp dir)


# numba's `InlineWorker.inline_ir` copies the callee's IR block by block, a deep copy with a memo of its own per
# block; every variable refers to the function's scope, which holds all its variables, so each block's copy copies
# them all again: O(blocks x variables). The step's kernels inline the whole pipeline (engine/step.py), and a cold
# cache spent 4 to 5 s of the step's 12 to 15 s of compiling there (numba issues #8989 and #9204 name the same
# copies). One deep copy of all the blocks with one memo gives the same blocks, variables and statements (the blocks
# then share one copy of the scope, as the callee's own blocks share one scope), so the same IR and machine code
# (tests/test_golden.py bit for bit). Applied only where the installed numba's source has those lines exactly.
# The lines as they stand in the method's source once dedented (copy_ir is nested in inline_ir's body).
_PER_BLOCK_COPY = """        kernel_copy.blocks = {}
        for block_label, block in the_ir.blocks.items():
            new_block = copy.deepcopy(the_ir.blocks[block_label])
            kernel_copy.blocks[block_label] = new_block
"""
_ONE_COPY = """        kernel_copy.blocks = copy.deepcopy(the_ir.blocks)
        # (planar_lcp: one copy with one memo; padded to keep the line numbers of numba's file)


"""


def _copy_inlined_ir_once():
    """Patch numba's `InlineWorker.inline_ir` as the comment above says; returns whether it was patched."""
    from numba.core import inline_closurecall as ic
    worker = ic.InlineWorker
    if getattr(worker.inline_ir, "_planar_lcp_one_copy", False):
        return True
    try:
        lines, first = inspect.getsourcelines(worker.inline_ir)
    except (OSError, TypeError):
        return False
    src = textwrap.dedent("".join(lines))
    if src.count(_PER_BLOCK_COPY) != 1:
        return False
    tree = ast.parse(src.replace(_PER_BLOCK_COPY, _ONE_COPY))
    ast.increment_lineno(tree, first - 1)       # tracebacks point at numba's own lines
    namespace = {}
    exec(compile(tree, ic.__file__, "exec"), ic.__dict__, namespace)
    patched = namespace["inline_ir"]
    patched._planar_lcp_one_copy = True
    patched._numba_original = worker.inline_ir
    worker.inline_ir = patched
    return True


INLINE_COPY_PATCHED = _copy_inlined_ir_once()
