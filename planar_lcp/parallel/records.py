"""Benchmarks that lose nothing: the record file of `plan-bench` and `tradeoff` (docs/planning.md, "Interrupted
benchmarks and --resume").

Each finished run is appended to `OUT/records.jsonl` as soon as its result reaches the client, one JSON object per
line, flushed and fsynced before the next result is taken: Ctrl-C, a crash, a lost scheduler or a killed client
keeps every run that finished before it. The commands write their outputs (summary, logs, CSV, plots) from these
records, at the end and also when stopped; `--resume` reads them back, checks that they belong to the same
benchmark and runs only the missing items.

The lines, in order of writing:

- the header, first: ``{"header": {...}}``, which benchmark this is (the command, its task or scenes, planners,
  budget, runs: what `--resume` compares);
- one line per finished run: ``{"run": KEY, "invocation": S, "elapsed": SECONDS, "record": {...}}``, KEY a list naming
  the item (planner and seed; scene and setting), S the command's invocation (1 for the first, one more for each
  `--resume`), SECONDS from the invocation's start to the record's arrival;
- one line at each invocation's end (not after a kill): ``{"invocation": S, "elapsed": SECONDS, "ended": "complete" |
  "interrupted" | "failed", "info": {...}}``.

A crash in the middle of a write can leave the last line cut short: reading ignores it with a note (its run is done
again) and `--resume` truncates it before appending. Any other line that is not such a record is an error: the
file is not this program's or was edited.
"""

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

#: the record file's name in a benchmark's output directory
RECORDS = "records.jsonl"
#: how an invocation that ended before its benchmark did is told in the partial outputs, by its end line's "ended"
STOPPED = {"interrupted": "interrupted by Ctrl-C", "failed": "stopped by an error or a lost scheduler"}


class RecordFileError(Exception):
    """A record file that cannot be used as asked (a different benchmark, a line that is not a record, finished runs
    that a new benchmark would overwrite): one line naming the file, what differs, the expected and the actual."""


class BenchmarkInterrupted(KeyboardInterrupt):
    """Ctrl-C that stopped a benchmark after it kept its finished runs; the message says what it kept, for the
    command's one line (planar-lcp's `main` prints it; exit status 130)."""


@dataclass
class Contents:
    """What a record file holds.

    Attributes
    ----------
    path : Path
    header : dict
        The benchmark's description as written in line 1.
    runs : dict
        Item key (tuple) -> its record (dict), in the order written; a key written twice keeps its first record.
    arrivals : list of (int, float)
        (invocation, elapsed s) of each run line, in the order written.
    invocations : dict
        Invocation number -> its end line (invocations killed before their end have none).
    torn : str or None
        A note when the last line was cut short (and is ignored), else None.
    valid_bytes : int
        The length of the file's intact lines: where appending resumes.
    """
    path: Path
    header: dict
    runs: dict = field(default_factory=dict)
    arrivals: list = field(default_factory=list)
    invocations: dict = field(default_factory=dict)
    torn: str | None = None
    valid_bytes: int = 0

    @property
    def last_invocation(self):
        """The highest invocation number in the file (0 when no invocation wrote a line)."""
        return max([s for s, _ in self.arrivals] + list(self.invocations), default=0)

    def invocation_times(self):
        """Invocation -> its wall time (s): its end line's, or for an invocation killed before its end, the arrival of its
        last record."""
        times = {}
        for s, t in self.arrivals:
            times[s] = max(times.get(s, 0.0), t)
        for s, end in self.invocations.items():
            times[s] = end["elapsed"]
        return times


def _key(k):
    """A run's key as a tuple (JSON gives lists)."""
    return tuple(k)


def read_records(path):
    """The Contents of the record file at `path`.

    Raises
    ------
    RecordFileError
        The file cannot be read, its first line is not a header, or a line other than the last is not a record.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise RecordFileError(f"{path}: cannot be read: {e.strerror or e}") from None
    lines = data.split(b"\n")
    whole = lines[-1] == b""         # the file ends with a newline: its last line was written to the end
    if whole:
        lines.pop()
    contents = None
    for i, raw in enumerate(lines, start=1):
        last = i == len(lines)
        try:
            line = json.loads(raw.decode())
            if not isinstance(line, dict):
                raise ValueError(f"a JSON {type(line).__name__}, not an object")
        except (UnicodeDecodeError, ValueError) as e:
            line, error = None, e
        if last and (line is None or not whole) and contents is not None:
            # a crash while the last line was written: without its newline, or not JSON (a prefix of one)
            contents.torn = (f"{path}: line {i} was cut short (the command stopped while writing it) and is "
                             "ignored; its run is done again")
            break
        if line is None:
            raise RecordFileError(f"{path}: line {i} is not a record of this program: {error}")
        if contents is None:
            if not isinstance(line.get("header"), dict) or not whole and last:
                raise RecordFileError(f"{path}: line 1 must be the benchmark's header {{\"header\": {{...}}}}, got "
                                      f"keys {sorted(line)}")
            contents = Contents(path=path, header=line["header"])
        elif "run" in line:
            if not (isinstance(line["run"], list) and isinstance(line.get("record"), dict)
                    and isinstance(line.get("invocation"), int) and isinstance(line.get("elapsed"), (int, float))):
                raise RecordFileError(f"{path}: line {i} must be a run {{\"run\": [...], \"invocation\": N, "
                                      f"\"elapsed\": S, \"record\": {{...}}}}, got keys {sorted(line)}")
            contents.runs.setdefault(_key(line["run"]), line["record"])
            contents.arrivals.append((line["invocation"], float(line["elapsed"])))
        elif "ended" in line:
            if not (isinstance(line.get("invocation"), int) and isinstance(line.get("elapsed"), (int, float))):
                raise RecordFileError(f"{path}: line {i} must be an invocation's end {{\"invocation\": N, \"elapsed\": S, "
                                      f"\"ended\": ...}}, got keys {sorted(line)}")
            contents.invocations[line["invocation"]] = line
        else:
            raise RecordFileError(f"{path}: line {i} must be a run or an invocation's end, got keys {sorted(line)}")
        contents.valid_bytes += len(raw) + 1
    if contents is None:
        raise RecordFileError(f"{path}: empty: line 1 must be the benchmark's header")
    return contents


def _fsync_dir(path):
    """Make a new file's directory entry durable (a crash right after creating it must not lose it)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


class RecordWriter:
    """Appends runs to a record file, each line flushed and fsynced before `run` returns.

    Parameters
    ----------
    path : path
        The record file.
    header : dict
        The benchmark's description; written as line 1 of a new file.
    resume : Contents or None
        The file's contents to continue: its torn last line (if any) is cut off and appending starts after its
        intact lines, in a new invocation. None: a new file (an existing one is replaced).
    """

    def __init__(self, path, header, resume=None):
        self.path = Path(path)
        if resume is None:
            self._f = open(self.path, "wb")
            self.invocation = 1
            self._write({"header": header})
            _fsync_dir(self.path.parent)
        else:
            self._f = open(self.path, "r+b")
            self._f.truncate(resume.valid_bytes)
            self._f.seek(resume.valid_bytes)
            os.fsync(self._f.fileno())
            self.invocation = resume.last_invocation + 1

    def _write(self, obj):
        # allow_nan: a run's record may hold NaN (no solution: no path duration), which json reads back
        line = json.dumps(obj, separators=(",", ":")).encode() + b"\n"
        self._f.write(line)
        self._f.flush()
        os.fsync(self._f.fileno())
        return line

    def run(self, key, record, elapsed):
        """Append one finished run; returns its record as read back from the line (the outputs are always made
        from records as the file holds them, so that a resumed benchmark's outputs equal an uninterrupted one's).
        """
        line = self._write({"run": list(key), "invocation": self.invocation, "elapsed": float(elapsed),
                            "record": record})
        return json.loads(line)["record"]

    def end(self, ended, elapsed, **info):
        """Append this invocation's end ("complete", "interrupted" or "failed") with its wall time and `info`."""
        self._write({"invocation": self.invocation, "elapsed": float(elapsed), "ended": ended, "info": info})

    def close(self):
        self._f.close()


def prepare(out, header, differences, resume, command, unit="run"):
    """Before any work: the record file of a benchmark in `out`, checked against `header`.

    Parameters
    ----------
    out : path
        The output directory (it exists).
    header : dict
        This benchmark's description.
    differences : callable
        differences(old_header, header) -> list of (what the file was written for, what was asked) phrases, empty
        when the two describe the same benchmark.
    resume : bool
        --resume: continue the benchmark the file holds (a file that holds none of its runs yet, or no file, starts
        it anew).
    command : str
        The command's name, for the messages.
    unit : str
        What a record is, for the messages ("run", "setting").

    Returns
    -------
    Contents or None
        With --resume, the file's contents to continue (None: no file, start anew).

    Raises
    ------
    RecordFileError
        With --resume, the file was written for another benchmark (naming each difference, the file's and the
        command's) or cannot be read; without it, the file holds finished runs, which a new benchmark would
        overwrite. Nothing is written either way.
    """
    path = Path(out) / RECORDS
    if not path.exists():
        return None
    if resume:
        try:
            contents = read_records(path)
        except RecordFileError as e:
            raise RecordFileError(f"--resume: {e}") from None
        diff = differences(contents.header, header)
        if diff:
            was = " and ".join(a for a, _ in diff)
            got = " and ".join(b for _, b in diff)
            raise RecordFileError(f"--resume: {path} was written for {was}; got {got} (give the benchmark's own "
                                  "settings to finish it, or another --out for a new benchmark)")
        return contents
    try:
        n = len(read_records(path).runs)
    except RecordFileError:
        # not a record file this program can read: refused as if it held runs, so that nothing is overwritten
        n = None
    if n == 0:
        return None          # a header alone (a benchmark stopped before its first run): nothing to lose
    held = "records that cannot be read" if n is None else f"{n} finished {unit}{'s' if n != 1 else ''}"
    raise RecordFileError(f"--out {out} holds {held} of an earlier {command} ({path}): add --resume to finish that "
                          "benchmark, or pick another --out (nothing was overwritten)")


def count_finished(path, keys, otherwise):
    """How many of the items `keys` the record file at `path` holds (`otherwise` if it cannot be read)."""
    keys = set(keys)
    try:
        return sum(1 for k in read_records(path).runs if k in keys)
    except RecordFileError:
        return otherwise


def stopped_message(done, planned, path, unit, outputs):
    """What a stopped benchmark kept, for its one line: `done` of `planned` `unit`s ("run", "setting") finished, kept
    in the record file `path` with `outputs` (what was written from them)."""
    if not done:
        return f"after 0 of {planned} {unit}s: none had finished"
    return (f"after {done} of {planned} {unit}s: {'it is' if done == 1 else 'they are'} kept in {path} with "
            f"{outputs}; the same command with --resume runs the other {planned - done}")


def write_text_atomic(path, text, newline=None):
    """Write `text` to `path` (with `newline` as open() takes it) through a temporary file renamed over it: an
    interrupted write leaves the old file or the new one, never half of one."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text, newline=newline)
    os.replace(tmp, path)
    return path
