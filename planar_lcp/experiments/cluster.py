"""The Dask cluster that `plan-bench` and `tradeoff` submit their independent runs to (docs/planning.md,
"Distributed benchmarks"): an existing one at a scheduler's address, or a local one started and stopped here,
listening on 127.0.0.1 only and without a dashboard. `distributed` is imported inside the functions."""

import os


class SchedulerUnreachable(OSError):
    """No Dask scheduler answered at the address given (--scheduler)."""


def local_jobs(jobs, ntasks=None):
    """Worker processes of a local cluster: `jobs` (default: the CPUs), at least one, and at most one per task when
    the number of tasks `ntasks` is given."""
    n = max(1, int(jobs or os.cpu_count() or 1))
    return n if ntasks is None else max(1, min(n, ntasks))


def open_cluster(scheduler=None, jobs=1, timeout=30):
    """(client, local cluster or None): a client of the Dask scheduler at `scheduler`, or of a new local cluster of
    `jobs` worker processes, one thread each (the numba kernels and OMPL's solve() hold the GIL). A scheduler that
    does not answer within `timeout` s raises SchedulerUnreachable (distributed's own OSError, named)."""
    import logging

    from distributed import Client, LocalCluster
    if scheduler:
        try:
            return Client(scheduler, timeout=timeout), None
        except OSError as e:
            raise SchedulerUnreachable(f"--scheduler {scheduler}: {e}") from None
    cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, silence_logs=logging.ERROR)
    return Client(cluster), cluster


def close_cluster(client, cluster, futures=()):
    """Cancel `futures` (if any still run), close the client and stop a local cluster."""
    if futures:
        client.cancel(list(futures), force=True)
    client.close()
    if cluster is not None:
        cluster.close()


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
