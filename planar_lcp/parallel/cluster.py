"""The Dask cluster that `plan-bench` and `tradeoff` submit their independent runs to (docs/planning.md,
"Distributed benchmarks"): an existing one at a scheduler's address, or a local one started and stopped here,
listening on 127.0.0.1 only and without a dashboard. `distributed` is imported inside the functions."""

import contextlib
import os


class SchedulerUnreachable(OSError):
    """No Dask scheduler answered at the address given (--scheduler)."""


class SchedulerLost(OSError):
    """The Dask scheduler went away during a benchmark (its process or machine gone): the client's futures were
    cancelled. The message says what the benchmark kept."""


def local_jobs(jobs, ntasks=None):
    """Worker processes of a local cluster: `jobs` (default: the CPUs), at least one, and at most one per task when
    the number of tasks `ntasks` is given."""
    n = max(1, int(jobs or os.cpu_count() or 1))
    return n if ntasks is None else max(1, min(n, ntasks))


def lost_scheduler_message(scheduler, error):
    """One line for a benchmark whose client lost its scheduler (`error`: the FutureCancelledError of a run)."""
    where = f"at {scheduler}" if scheduler else "of the local cluster"
    if getattr(error, "reason", None) == "scheduler-connection-lost":
        # distributed cancels every future at once when the connection closes (and then tries to reconnect)
        return f"lost the Dask scheduler {where}: the connection to it closed, which cancelled the runs"
    return f"lost the Dask scheduler {where}: its runs were cancelled ({getattr(error, 'reason', error)})"


def open_cluster(scheduler=None, jobs=1, timeout=30):
    """(client, local cluster or None): a client of the Dask scheduler at `scheduler`, or of a new local cluster of
    `jobs` worker processes, one thread each (the numba kernels and OMPL's solve() hold the GIL). A scheduler that
    does not answer within `timeout` s raises SchedulerUnreachable (distributed's own OSError, named).

    The local workers ignore SIGINT: Ctrl-C at a terminal signals the whole foreground process group, and workers
    that took it died printing tracebacks (about 60 lines) while the command handled the interrupt itself; the
    command alone stops them (close_cluster)."""
    import logging
    import warnings

    from distributed import Client, LocalCluster
    # the client logs its connection's errors (e.g. the reconnection's, for 30 s, when the scheduler is gone), which
    # the commands report themselves in one line (SchedulerLost)
    logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
    if scheduler:
        try:
            return Client(scheduler, timeout=timeout), None
        except OSError as e:
            raise SchedulerUnreachable(f"--scheduler {scheduler}: {e}") from None
    # without a dashboard the scheduler still serves its health and metrics pages (on 127.0.0.1), at port 8787 if it
    # is free: another benchmark running already has it, and the warning that says so is not the command's
    warnings.filterwarnings("ignore", message=r"Port 8787 is already in use", category=UserWarning)
    cluster = LocalCluster(n_workers=0, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, silence_logs=logging.ERROR)
    client, spawned = None, []
    try:
        _spawn_ignoring_sigint(cluster, jobs, timeout, spawned)
        client = Client(cluster)
        client.wait_for_workers(jobs, timeout=timeout)
    except BaseException:
        # interrupted (or failed) while the workers come up: a worker process still unpickling its start-up state
        # when the cluster below releases that state dies printing a traceback (FileNotFoundError of a semaphore);
        # killed first, it dies silently, and none of them has done any of the command's work yet
        _silence_distributed()
        for proc in spawned:
            try:
                proc.kill()
            except Exception:  # noqa: BLE001 - already gone
                pass
        close_cluster(client, cluster, quiet=True)
        raise
    return client, cluster


def _spawn_ignoring_sigint(cluster, jobs, timeout, spawned):
    """Start the `jobs` worker processes of `cluster` with SIGINT ignored, a disposition a child process inherits
    and keeps (Python installs its KeyboardInterrupt handler only over the default one). This process ignores it
    only until the processes exist (30 to 40 ms: the cluster's event-loop thread starts them), not until they
    connect (a second or more), so that a Ctrl-C meanwhile is not lost. The processes started are appended to
    `spawned` (multiprocessing.Process) as they appear."""
    import multiprocessing
    import signal
    import threading
    import time

    if threading.current_thread() is not threading.main_thread():
        cluster.scale(jobs)                 # signal.signal works in the main thread only: these workers take Ctrl-C
        return
    before = set(multiprocessing.active_children())
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        cluster.scale(jobs)
        t0 = time.monotonic()
        while len(spawned) < jobs and time.monotonic() - t0 < timeout:
            spawned.extend(p for p in multiprocessing.active_children() if p not in before and p not in spawned)
            time.sleep(0.005)
    finally:
        signal.signal(signal.SIGINT, old)


def close_cluster(client, cluster, futures=(), quiet=False):
    """Cancel `futures` (if any still run), close the client and stop a local cluster. `quiet` (after Ctrl-C or a
    failure): nothing of distributed's reaches the terminal, whose last line is the command's own (a worker stopped
    inside a run, or a scheduler already gone, makes distributed log errors while it closes)."""
    if quiet:
        _silence_distributed()
    try:
        if client is not None:
            if futures:
                client.cancel(list(futures), force=True)
            if cluster is not None and not quiet:
                try:
                    client.run(_quiet_heartbeat_at_close)
                except Exception:  # noqa: BLE001 - a worker lost: the others still close, maybe less quietly
                    pass
            client.close()
    except Exception:  # noqa: BLE001 - closing after a lost scheduler: nothing is left to close
        if not quiet:
            raise
    finally:
        if cluster is not None:
            try:
                # the workers before the scheduler: one alive when the scheduler closes logs its failed heartbeat
                # with a traceback on the command's stderr. Quiet: a worker inside a run does not stop before the
                # run's end (a planning run holds its one thread for up to --time); stopped or failed, nothing a
                # worker holds is kept, so each is killed
                cluster.sync(_close_workers, cluster, STOP_GRACE_S if quiet else CLOSE_TIMEOUT_S, quiet)
            except Exception:  # noqa: BLE001 - cluster.close() below stops whatever is left
                pass
            cluster.close()


#: the message of a worker whose heartbeat was in flight as it closed (distributed.worker.Worker.heartbeat)
_HEARTBEAT_FAILED = "Failed to communicate with scheduler during heartbeat"


def _drop_heartbeat_failure(record):
    """False for the closing worker's failed heartbeat (a logging filter); every other record passes."""
    return not str(record.msg).startswith(_HEARTBEAT_FAILED)


def _quiet_heartbeat_at_close():
    """Run in each local worker process before its nanny closes it: a worker that closes stops its periodic
    heartbeat, then closes its connections, and a heartbeat still awaiting the scheduler's answer then fails and
    logs the error with a traceback on the command's stderr (a race inside distributed, met on a loaded machine).
    The runs are done; that one message is dropped, every other of distributed's errors still shows."""
    import logging

    logger = logging.getLogger("distributed.worker")
    if _drop_heartbeat_failure not in logger.filters:
        logger.addFilter(_drop_heartbeat_failure)


def _silence_distributed():
    """Nothing of distributed's reaches the terminal any more, for good, not only while closing: the event loop's
    thread and distributed's exit handlers still log after close() returns, and the command's one line must stay
    the last."""
    import logging
    import warnings

    # tornado.application has a level of its own (set when distributed configures logging), so it is named
    for name in ("distributed", "tornado", "tornado.application", "asyncio"):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    # a Client interrupted inside its constructor (Ctrl-C as the workers come up) is never returned to be closed:
    # its __del__ closes it at exit with coroutines that no event loop runs, and Python warns of each
    warnings.filterwarnings("ignore", message=r"coroutine '.*' was never awaited", category=RuntimeWarning)


#: seconds a local worker's nanny is given to see its killed process joined when a stopped command closes its cluster
STOP_GRACE_S = 0.5


#: seconds each local worker is given to close (its runs are done) when a command closes its cluster
CLOSE_TIMEOUT_S = 10.0


async def _close_workers(cluster, timeout, kill=False):
    """Close each local worker's nanny, told first that the cluster closes so that it does not start a new worker
    (before the scheduler); with kill, SIGKILL each worker process first (a killed process prints nothing)."""
    import asyncio
    import os
    import signal

    nannies = list(cluster.workers.values())
    for nanny in nannies:
        nanny.close_gracefully(reason="planar-lcp-stopped" if kill else "planar-lcp-done")
        pid = nanny.pid
        if kill and pid:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
    await asyncio.gather(*[nanny.close(timeout=timeout) for nanny in nannies], return_exceptions=True)


@contextlib.contextmanager
def sigint_ignored():
    """Ctrl-C ignored inside (in the main thread; elsewhere it cannot be caught anyway): for the seconds in which a
    stopped benchmark closes its cluster and writes what it kept, which a second Ctrl-C would cut short."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def retried_runs(client, keys):
    """How many of the tasks `keys` the scheduler ran again because a worker was lost while it held them."""
    def count(dask_scheduler, keys=tuple(keys)):
        return sum(1 for k in keys if k in dask_scheduler.tasks and dask_scheduler.tasks[k].suspicious > 0)
    return int(client.run_on_scheduler(count))


def worker_address():
    """The address of the Dask worker running the calling task, None outside Dask."""
    try:
        from distributed import get_worker
        return get_worker().address
    except (ImportError, ValueError):
        return None


def host_info():
    """(host name, CPU description) of the calling process's machine, as OMPL's Benchmark puts them in its log
    ("Running on <host>" and the second <<<| ... |>>> block: `lscpu`'s output on Linux, as OMPL's
    machine::getCPUInfo gives it; the processor name and count where lscpu is missing)."""
    global _HOST_INFO
    if _HOST_INFO is None:
        import platform
        import shutil
        import socket
        import subprocess
        cpu = ""
        if shutil.which("lscpu"):
            try:
                cpu = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=10).stdout.strip()
            except (OSError, subprocess.SubprocessError):
                cpu = ""
        if not cpu:
            cpu = f"{platform.processor() or platform.machine()} x {os.cpu_count()}"
        _HOST_INFO = (socket.gethostname(), cpu)
    return _HOST_INFO


_HOST_INFO = None
