"""Saying what is happening: one line before a cold numba cache's wait, nothing when the cache is warm
(planar_lcp/compilation/notice.py). The cold runs themselves are the slow suite's (tests/commands/test_readme_commands.py
`test_demo` and tests/planning/test_planning_e2e.py `test_first_plan_on_a_cold_cache` check the line there)."""

import io

import pytest
from numba import njit

from cli_helpers import run_cli
from planar_lcp import engine
from planar_lcp.compilation import background
from planar_lcp.compilation.notice import (BACKGROUND_NOTICE, NOTICE, CompileNotice, announce_background,
                                              announce_compilation, uninstall)


def _function_of(module):
    """A new numba function whose Python function lives in `module` (numba's events name it by that)."""
    namespace = {"__name__": module}
    exec("def f(x):\n    return x + 1\n", namespace)
    return njit(namespace["f"])


def test_the_notice_is_printed_once_at_our_first_compilation_and_not_for_others():
    stream = io.StringIO()
    notice = announce_compilation("planar-lcp probe", stream)
    try:
        assert _function_of("somebody_else.module")(1) == 2           # not ours: nothing said
        assert stream.getvalue() == ""
        assert _function_of("planar_lcp.engine.probe")(1) == 2        # ours, compiled: the line, before the wait
        assert stream.getvalue() == f"planar-lcp probe: {NOTICE}\n"
        assert _function_of("planar_lcp.spec.probe")(2) == 3          # once per process
        assert stream.getvalue().count(NOTICE) == 1
    finally:
        uninstall(notice)
    assert isinstance(notice, CompileNotice) and notice.said


def test_a_background_compilation_is_announced_once_and_nothing_after_it():
    stream = io.StringIO()
    notice = announce_compilation("planar-lcp probe", stream)
    try:
        announce_background()
        assert stream.getvalue() == f"planar-lcp probe: {BACKGROUND_NOTICE}\n"
        _function_of("planar_lcp.engine.probe")(1)                   # a compilation after it: said already
        announce_background()
        assert stream.getvalue() == f"planar-lcp probe: {BACKGROUND_NOTICE}\n"
    finally:
        uninstall(notice)


def test_an_uninstalled_notice_says_nothing():
    stream = io.StringIO()
    uninstall(announce_compilation("planar-lcp probe", stream))
    _function_of("planar_lcp.engine.probe")(1)
    assert stream.getvalue() == ""


@pytest.mark.needs_jit
def test_a_warm_cache_prints_nothing(tmp_path):
    """The same command twice on one cache: the first may compile (and then says so, once: in the foreground or in
    the background), the second finds every kernel in the cache and prints nothing on stderr."""
    args = ("simulate", "falling_rod", "--t-end", "0.05")
    first = run_cli(*args, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    assert first.stderr in ("", f"planar-lcp simulate: {NOTICE}\n", f"planar-lcp simulate: {BACKGROUND_NOTICE}\n"), \
        first.stderr
    lock = background.lock_file(engine.cache_dir())                    # this process's cache: the CLI's too
    assert background.Background(None, lock, 0.0).wait(timeout=600)   # a background compilation has ended
    second = run_cli(*args, cwd=tmp_path)
    assert second.returncode == 0 and second.stderr == "", second.stderr


def test_simulate_reports_its_progress_to_the_end():
    from planar_lcp import simulate
    seen = []
    tr = simulate("box_tip", progress=lambda done, total: seen.append((done, total)))
    n = len(tr.t) - 1
    assert seen and seen[-1] == (n, n) and all(t == n for _, t in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)


def test_a_long_simulate_command_shows_a_progress_bar_and_a_short_one_does_not(monkeypatch, capsys):
    """The bar (tqdm, on stderr) appears on a terminal once a run has taken PROGRESS_DELAY_S: 0 here, so any run
    shows it; a pipe or a log never gets it (tests/commands/test_cli_simulate.py's Ctrl-C test reads stderr whole)."""
    pytest.importorskip("tqdm")
    import sys
    import planar_lcp.cli as cli
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert cli.main(["simulate", "box_tip", "--t-end", "0.5"]) == 0
    assert "simulate box_tip" not in capsys.readouterr().err          # shorter than the delay: nothing
    import planar_lcp.cli_support as cli_support
    monkeypatch.setattr(cli_support, "PROGRESS_DELAY_S", 0.0)
    assert cli.main(["simulate", "box_tip", "--t-end", "0.5"]) == 0
    err = capsys.readouterr().err
    assert "simulate box_tip" in err and "step" in err, err
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    assert cli.main(["simulate", "box_tip", "--t-end", "0.5"]) == 0
    assert capsys.readouterr().err == ""                              # not a terminal: no bar
