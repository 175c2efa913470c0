"""A benchmark whose runs are Dask tasks, recorded as they finish (tradeoff, plan-bench): the lines it starts with
when resumed, and its run, which on any stop (Ctrl-C, a lost scheduler, an error) closes the cluster, ends the record
file, writes the outputs of what finished and says in one line what was kept."""

import sys
import time

from planar_lcp.cli_support import raised_while_interrupted

from .cluster import SchedulerLost, close_cluster, sigint_ignored
from .records import BenchmarkInterrupted, count_finished, stopped_message


def say_resumed(previous, resume, path, finished, planned, unit, width=None):
    """Print what a resumed benchmark finds in its record file `path` (`previous`: its contents, None without one):
    `finished` of `planned` `unit`s. width: the column of the lines' text (None: "resume: ...")."""
    def line(word, text):
        print(f"{word}: {text}" if width is None else f"{word:<{width}}{text}", flush=True)

    if previous is not None:
        line("resume", f"{path}: {finished} of {planned} {unit}s finished before; "
             + (f"running the other {planned - finished}" if planned > finished
                else "nothing left to run: writing the outputs"))
        if previous.torn:
            line("note", previous.torn)
    elif resume:
        line("resume", f"{path}: no record file yet; running every {unit}")


def run_recorded(run, writer, keys, finished_before, unit, write_partial, kept_outputs, info=None, t0=None):
    """Run a recorded benchmark: `run(live)` submits and records its runs, putting what it opens into `live`
    (client, cluster, futures, progress bar) as soon as it exists, so that it is closed here after any stop.

    keys: every item the benchmark plans (in the record file's terms); finished_before: how many had finished
    before this run (counted again on disk after a stop: a Ctrl-C can land between a record's write and its
    count); write_partial(ended): writes the outputs of the finished items after a stop ("interrupted" or "failed");
    kept_outputs: what those outputs are, for the stop's message; info: a dict written with the record file's end
    line (read when the run ends: `run` may fill it); t0: the start of the run's clock (perf_counter).

    Raises BenchmarkInterrupted (Ctrl-C) or SchedulerLost with what was kept, or the error that stopped the run."""
    info = {} if info is None else info
    t0 = time.perf_counter() if t0 is None else t0
    live = dict(client=None, cluster=None, futures=[], bar=None)
    try:
        run(live)
    except BaseException as e:
        # a second Ctrl-C while the finished runs are kept would cut that short, so it waits (seconds)
        with sigint_ignored():
            if live["bar"] is not None:
                live["bar"].leave = False      # the interrupted bar is cleared: the command's one line stays alone
                live["bar"].close()
            close_cluster(live["client"], live["cluster"], live["futures"], quiet=True)
            # an error raised while a Ctrl-C was handled (e.g. by distributed, starting the cluster) is the interrupt
            interrupted = isinstance(e, KeyboardInterrupt) or raised_while_interrupted(e)
            ended = "interrupted" if interrupted else "failed"
            writer.end(ended, time.perf_counter() - t0, **info)
            writer.close()
            try:
                write_partial(ended)
            except Exception as w:  # noqa: BLE001 - the records are on disk; the stop's own cause is reported
                print(f"warning: no partial outputs: {w!r}", file=sys.stderr)
        kept = stopped_message(count_finished(writer.path, keys, finished_before), len(keys), writer.path, unit,
                               kept_outputs)
        if interrupted:
            raise BenchmarkInterrupted(kept) from None
        if isinstance(e, SchedulerLost):
            raise SchedulerLost(f"{e}; stopped {kept}") from None
        raise
    if live["bar"] is not None:
        live["bar"].close()
    writer.end("complete", time.perf_counter() - t0, **info)
    writer.close()
