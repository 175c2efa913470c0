"""Importing planar_lcp and running a simulation leaves numba as it was for the rest of the process: its config
(NUMBA_CACHE_DIR and every other setting) and its inliner; another library's cached kernel is cached where numba
puts it, not in planar_lcp's directory; planar_lcp's own kernels are cached in planar_lcp.engine.cache_dir()."""

import json
import os
import subprocess
import sys

import pytest

CODE = r'''
import json, os, sys, textwrap
import numba
from numba.core.inline_closurecall import InlineWorker
config_before = {k: repr(v) for k, v in vars(numba.config).items() if k.isupper()}
inline_before = InlineWorker.inline_ir
import planar_lcp
from planar_lcp import simulate
from planar_lcp import engine
traj = simulate("falling_rod", t_end=0.05)
config_after = {k: repr(v) for k, v in vars(numba.config).items() if k.isupper()}
other = os.path.join(sys.argv[1], "other_lib.py")
open(other, "w").write(textwrap.dedent("""
    from numba import njit
    @njit(cache=True)
    def twice(x):
        return 2 * x
"""))
sys.path.insert(0, sys.argv[1])
import other_lib
other_lib.twice(3)
print(json.dumps({"config_changed": sorted(k for k in config_before if config_before[k] != config_after.get(k)),
                  "inline_ir_same": InlineWorker.inline_ir is inline_before,
                  "steps": len(traj.t),
                  "cache_dir": engine.cache_dir(),
                  "other_cached": sorted(os.listdir(os.path.join(sys.argv[1], "__pycache__")))}))
'''


@pytest.mark.needs_jit
def test_importing_and_simulating_leaves_numba_as_it_was(tmp_path):
    from planar_lcp import engine
    # the child has no NUMBA_CACHE_DIR, so that planar_lcp's own locator serves its kernels, from its keyed directory
    # under XDG_CACHE_HOME: made a link to this suite's cache, which holds them compiled already (the two locators
    # give the same paths below their directories)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = str(tmp_path / "xdg")
    env["PLANAR_LCP_PRECOMPILE"] = "0"
    keyed = tmp_path / "xdg" / "planar_lcp" / "numba" / engine.kernel_source_hash()
    keyed.parent.mkdir(parents=True)
    keyed.symlink_to(engine.cache_dir(), target_is_directory=True)
    lib = tmp_path / "lib"
    lib.mkdir()
    r = subprocess.run([sys.executable, "-c", CODE, str(lib)], capture_output=True, text=True, env=env,
                       timeout=1200)        # minutes if this suite's cache is still cold; seconds warm
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.splitlines()[-1])
    assert out["config_changed"] == [] and out["inline_ir_same"], out
    assert out["steps"] > 1
    # planar_lcp's kernels in its own keyed directory (under XDG_CACHE_HOME), the other library's beside its source
    assert out["cache_dir"].startswith(env["XDG_CACHE_HOME"]), out
    assert any(f.startswith("other_lib.twice") for f in out["other_cached"]), out
    ours = [f for _, _, fs in os.walk(out["cache_dir"]) for f in fs]
    assert any(f.endswith(".nbi") for f in ours) and not any(f.startswith("other_lib") for f in ours), ours[:10]
