"""Compilation management: the kernels compiled once per machine, and a cold cache's first run kept short.

- background.py: on a cold numba cache, a process of its own compiles the default kernel set while the run goes on
  as Python (engine/interpreted.py) or waits; one such process per cache directory, by a lock file.
- kernel_sets.py: what compiles, by set ("default", "all" for `planar-lcp warmup`), on a small built-in scene.
- precompile.py: the helper process that compiles the island solvers on the second core meanwhile.
- notice.py: the one line a command prints while kernels compile.

Where the kernels are cached, and numba's inliner fix applied while they compile, is the engine's own
(planar_lcp/engine/__init__.py).
"""
