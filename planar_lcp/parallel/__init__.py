"""The Dask runs that tradeoff, plan-bench, pushdata fit and pusht-eval share: `cluster` (a local cluster on the
loopback address, or a scheduler's address the user gives; closing it on Ctrl-C), `records` (each finished run
appended to a record file as it arrives, read back by --resume)."""
