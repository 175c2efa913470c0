"""The record file of plan-bench and tradeoff (planar_lcp.parallel.records): each run appended and
fsynced as it arrives, read back exactly, a line cut short by a crash ignored with a note and cut off on resume, any
other damage refused; the checks --resume and a new benchmark make before any work; the interrupt's one line."""

import json
import math
import os

import pytest

from planar_lcp import cli
from planar_lcp.parallel import records
from planar_lcp.parallel.records import (RECORDS, BenchmarkInterrupted, RecordFileError, RecordWriter,
                                            count_finished, prepare, read_records, stopped_message)

HEADER = {"command": "plan-bench", "task": "tip_box", "planners": ["RRT", "EST"], "runs": 2}


def _differences(old, new):
    return [(f"task '{old['task']}'", f"task '{new['task']}'")] if old["task"] != new["task"] else []


def _write(path, runs, end=None, header=HEADER):
    w = RecordWriter(path, header)
    back = [w.run(key, rec, elapsed) for key, rec, elapsed in runs]
    if end:
        w.end(end, 9.0, lost_workers=[], retried_runs=0)
    w.close()
    return back


def test_runs_are_appended_and_read_back_exactly(tmp_path):
    """Every value a run's record holds comes back as written (NaN, None, booleans, floats bit for bit); a key
    written twice keeps its first record; invocations and their times are counted."""
    path = tmp_path / RECORDS
    rec = dict(planner="RRT", seed=1, exact=False, goal_distance=float("nan"), solve_time=0.1 + 0.2, replayed=None,
               iterations=400)
    back = _write(path, [(("RRT", 1), rec, 1.5), (("EST", 1), dict(rec, planner="EST"), 2.5),
                         (("RRT", 1), dict(rec, seed=99), 3.0)], end="interrupted")
    assert back[0]["solve_time"] == 0.1 + 0.2 and math.isnan(back[0]["goal_distance"])
    c = read_records(path)
    assert c.header == HEADER and list(c.runs) == [("RRT", 1), ("EST", 1)]
    got = c.runs[("RRT", 1)]
    assert json.dumps(got) == json.dumps(rec) and got["replayed"] is None and got["exact"] is False
    assert c.torn is None and c.valid_bytes == path.stat().st_size
    assert c.last_invocation == 1 and c.invocation_times() == {1: 9.0}
    assert c.invocations[1]["ended"] == "interrupted"
    assert count_finished(path, [("RRT", 1), ("RRT", 2)], 7) == 1
    assert count_finished(tmp_path / "none.jsonl", [("RRT", 1)], 7) == 7


def test_each_run_is_on_disk_when_run_returns(tmp_path, monkeypatch):
    """The line is flushed and fsynced before `run` returns: another reader sees it at once, and os.fsync is
    called for each line (a crash right after keeps the run)."""
    synced = []
    real = os.fsync
    monkeypatch.setattr(records.os, "fsync", lambda fd: (synced.append(fd), real(fd))[1])
    path = tmp_path / RECORDS
    w = RecordWriter(path, HEADER)
    n = len(synced)
    w.run(("RRT", 1), {"seed": 1}, 0.5)
    assert len(synced) == n + 1
    assert '"run":["RRT",1]' in path.read_text()        # read through another file object, before close
    w.close()


@pytest.mark.parametrize("cut", ["half a line", "no newline", "garbage"])
def test_a_last_line_cut_short_is_ignored_with_a_note_and_cut_off_on_resume(tmp_path, cut):
    path = tmp_path / RECORDS
    _write(path, [(("RRT", 1), {"seed": 1}, 1.0), (("RRT", 2), {"seed": 2}, 2.0)])
    whole = path.read_bytes()
    first_two = whole[:whole.index(b'{"run":["RRT",2]')]
    last = whole[len(first_two):]
    torn = {"half a line": last[:len(last) // 2], "no newline": last[:-1], "garbage": b"\x00\x00\x00\n"}[cut]
    path.write_bytes(first_two + torn)
    c = read_records(path)
    assert list(c.runs) == [("RRT", 1)] and c.valid_bytes == len(first_two)
    assert c.torn == (f"{path}: line 3 was cut short (the command stopped while writing it) and is ignored; its run "
                      "is done again")
    w = RecordWriter(path, HEADER, resume=c)
    assert w.invocation == 2
    w.run(("RRT", 2), {"seed": 2}, 0.5)
    w.close()
    c = read_records(path)
    assert path.read_bytes().startswith(first_two) and list(c.runs) == [("RRT", 1), ("RRT", 2)] and c.torn is None
    assert c.arrivals == [(1, 1.0), (2, 0.5)] and c.invocation_times() == {1: 1.0, 2: 0.5}


@pytest.mark.parametrize("content, message", [
    (b"", "empty: line 1 must be the benchmark's header"),
    (b'{"run":["RRT",1]}\n', "line 1 must be the benchmark's header {\"header\": {...}}, got keys ['run']"),
    (b'{"header":{}}\nnot json\n{"run":["RRT",1],"invocation":1,"elapsed":1,"record":{}}\n',
     "line 2 is not a record of this program: Expecting value: line 1 column 1 (char 0)"),
    (b'{"header":{}}\n{"run":"RRT","invocation":1}\n{"header":{}}\n',
     "line 2 must be a run {\"run\": [...], \"invocation\": N, \"elapsed\": S, \"record\": {...}}, got keys "
     "['invocation', 'run']"),
    (b'{"header":{}}\n[1, 2]\n{"header":{}}\n', "line 2 is not a record of this program: a JSON list, not an object"),
    (b'{"header":{}}\n{"what":1}\n', "line 2 must be a run or an invocation's end, got keys ['what']"),
])
def test_any_other_damage_is_refused_naming_the_line(tmp_path, content, message):
    path = tmp_path / RECORDS
    path.write_bytes(content)
    with pytest.raises(RecordFileError) as e:
        read_records(path)
    assert str(e.value) == f"{path}: {message}"


def test_prepare_checks_before_any_work_and_overwrites_nothing(tmp_path):
    """No file: a new benchmark (with --resume too); a header alone (stopped before its first run) may be replaced;
    finished runs without --resume, an unreadable file, another benchmark with --resume: one-line refusals that
    leave the file as it was; the same benchmark with --resume: its contents."""
    path = tmp_path / RECORDS
    for resume in (False, True):
        assert prepare(tmp_path, HEADER, _differences, resume, "plan-bench") is None
    _write(path, [])
    assert prepare(tmp_path, HEADER, _differences, False, "plan-bench") is None
    _write(path, [(("RRT", 1), {"seed": 1}, 1.0)], end="interrupted")
    before = path.read_bytes()
    with pytest.raises(RecordFileError) as e:
        prepare(tmp_path, HEADER, _differences, False, "plan-bench")
    assert str(e.value) == (f"--out {tmp_path} holds 1 finished run of an earlier plan-bench ({path}): add --resume "
                            "to finish that benchmark, or pick another --out (nothing was overwritten)")
    with pytest.raises(RecordFileError) as e:
        prepare(tmp_path, dict(HEADER, task="push_t"), _differences, True, "plan-bench")
    assert str(e.value) == (f"--resume: {path} was written for task 'tip_box'; got task 'push_t' (give the "
                            "benchmark's own settings to finish it, or another --out for a new benchmark)")
    c = prepare(tmp_path, HEADER, _differences, True, "plan-bench")
    assert list(c.runs) == [("RRT", 1)]
    assert path.read_bytes() == before
    path.write_bytes(b"a file of someone else's\n")
    with pytest.raises(RecordFileError, match=r"holds records that cannot be read of an earlier tradeoff"):
        prepare(tmp_path, HEADER, _differences, False, "tradeoff", "setting")
    with pytest.raises(RecordFileError, match=rf"^--resume: {path}: line 1 is not a record"):
        prepare(tmp_path, HEADER, _differences, True, "tradeoff", "setting")
    assert path.read_bytes() == b"a file of someone else's\n"


def test_the_benchmark_headers_name_each_difference():
    """plan-bench compares the task by name and document hash, the planners as a set, the runs and the budget;
    tradeoff the scenes as a set, --quick, the scene files and the sweep's settings."""
    pytest.importorskip("ompl")
    from planners.bench import header_differences as bench_differences
    old = dict(command="plan-bench", task="push_box", task_sha256="a" * 64, task_source="scenes/push_box.toml",
               planners=["RRT", "KPIECE1"], runs=4, time_limit=None, iterations=20000)
    assert bench_differences(old, dict(old, planners=["KPIECE1", "RRT"])) == []
    assert bench_differences(old, dict(old, task="push_t", planners=["RRT"])) == [
        ("task 'push_box'", "task 'push_t'"), ("planners RRT, KPIECE1", "planners RRT")]
    assert bench_differences(old, dict(old, task_sha256="b" * 64, time_limit=60.0, iterations=None)) == [
        ("task 'push_box' as its file read then (document sha256 aaaaaaaaaaaa)",
         "the task file as it reads now (scenes/push_box.toml: document sha256 bbbbbbbbbbbb)"),
        ("a budget of 20000 iterations per run", "a budget of 60 s per run")]
    assert bench_differences(dict(old, command="tradeoff"), old) == [("planar-lcp tradeoff", "planar-lcp plan-bench")]

    from planar_lcp.benchmarks.tradeoff import _settings, header_differences, tradeoff_header
    plans = [(name, *_settings(name, True)) for name in ("falling_rod", "box_push")]
    h = tradeoff_header(plans, True, 1)
    assert h["settings"] == 12 and header_differences(h, dict(h, scenes=["box_push", "falling_rod"])) == []
    assert header_differences(h, dict(h, quick=False)) == [("the --quick sweep", "the full sweep (no --quick)")]
    edited = dict(h, scene_sha256=dict(h["scene_sha256"], box_push="c" * 64))
    assert header_differences(h, edited) == [(f"scene box_push as its file read then (sha256 "
                                              f"{h['scene_sha256']['box_push'][:12]})",
                                              "scene box_push as it reads now (sha256 cccccccccccc)")]
    assert header_differences(h, dict(h, settings_sha256="d" * 64))[0][1].startswith(
        "this version's sweep of 12 settings, 1 timed run(s) each")


def test_an_interrupted_benchmark_says_what_it_kept_in_its_one_line(monkeypatch, capsys):
    """main prints the message of a BenchmarkInterrupted after the interrupt's usual words: one line, 130."""
    msg = stopped_message(2, 4, "OUT/records.jsonl", "run", "a partial summary")
    assert msg == ("after 2 of 4 runs: they are kept in OUT/records.jsonl with a partial summary; the same command "
                   "with --resume runs the other 2")
    assert stopped_message(0, 4, "x", "setting", "y") == "after 0 of 4 settings: none had finished"
    parser = cli.build_parser

    def with_func(p):
        sub = next(a for a in p._actions if a.dest == "command")
        sub.choices["scenes"].set_defaults(func=lambda args: (_ for _ in ()).throw(BenchmarkInterrupted(msg)))
        return p
    monkeypatch.setattr(cli, "build_parser", lambda: with_func(parser()))
    assert cli.main(["scenes"]) == 130
    assert capsys.readouterr().err == f"planar-lcp scenes: error: interrupted (Ctrl-C); stopped {msg}\n"
