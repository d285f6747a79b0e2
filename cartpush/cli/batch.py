"""`cartpush batch estimate|diagnose INPUTS... --out RESULTS.jsonl`: one job over many logs, locally or on Ray."""

from __future__ import annotations

import argparse
import os
import shlex

DESCRIPTION = """\
Run `estimate` or `diagnose` over many logs and write one JSON line per log to RESULTS.jsonl
as each finishes: {"path": ..., "ok": true, "result": <the command's --json output>, "seconds": ...}
or {"path": ..., "ok": false, "error": "one line"}. A bad log is an error line, not a crash.

INPUTS: files, directories (their *.csv and *.csv.gz, sorted) or glob patterns ('runs/**/*.csv.gz').
A rerun with the same --out skips the logs already done (ok true) and retries the failed ones, so an
interrupted run loses nothing that finished; the last line of a path wins.

Locally the logs run on --workers joblib processes (default 1: in this process). With --ray auto
(or a cluster address, e.g. ray://head:10001) they run as Ray tasks on an existing cluster, at most
--workers in flight (default: the cluster's CPUs); every node must have cartpush installed and see the
logs at the same paths. A progress bar shows on a terminal; the summary (counts, logs per minute)
is printed at the end (--json: one JSON object).

Example:
  cartpush batch estimate logs/ --out results.jsonl --workers 2
  cartpush batch estimate 'runs/**/*.csv.gz' --out est.jsonl --job-args '--method ekf'
  cartpush batch diagnose logs/ --out diag.jsonl --ray auto --json
"""


def register(subparsers) -> None:
    """Add the `batch` subcommand."""
    p = subparsers.add_parser(
        "batch",
        help="run estimate or diagnose over many logs, locally or on a Ray cluster",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("job", choices=("estimate", "diagnose"), help="the command to run on every log")
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="log files, directories or glob patterns")
    p.add_argument(
        "--out",
        required=True,
        metavar="RESULTS.jsonl",
        help="JSON Lines results file (appended; existing ok lines are skipped)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="local processes (default 1), or with --ray the most tasks in flight (default: cluster CPUs)",
    )
    p.add_argument(
        "--ray",
        metavar="ADDRESS",
        default=None,
        help="run on a Ray cluster: 'auto' or its address (needs pip install 'cartpush[cluster]')",
    )
    p.add_argument(
        "--job-args",
        default="",
        metavar="'OPTIONS'",
        help="options of the job's command, quoted, e.g. '--method ekf' or '--threshold 20'",
    )
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=run)


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt


def _term_is_interrupt() -> None:
    """Make SIGTERM stop the batch like Ctrl-C (the workers are stopped too; finished lines are kept)."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _raise_interrupt)


def run(args: argparse.Namespace) -> int:
    """Run the batch; print the summary; return 0 (failed logs are error lines in the results, counted)."""
    from cart.jsonout import dumps_strict
    from cartpush.batch import BatchError, CommandJob, expand_inputs, run_batch

    if args.workers is not None and args.workers < 1:
        raise BatchError(f"--workers must be at least 1, got {args.workers}")
    if args.workers is not None and args.workers > 4 * (os.cpu_count() or 1) and args.ray is None:
        raise BatchError(f"--workers {args.workers}: more than 4x this machine's {os.cpu_count()} CPUs")
    try:
        job_argv = tuple(shlex.split(args.job_args))
    except ValueError as exc:
        raise BatchError(f"--job-args: {exc}") from None
    job = CommandJob(args.job, job_argv)
    job.check()
    paths = expand_inputs(args.inputs)
    _term_is_interrupt()
    summary = run_batch(job, paths, args.out, workers=args.workers, ray_address=args.ray)
    summary = {"job": args.job, **summary}
    if args.json:
        print(dumps_strict(summary))
        return 0
    rate = f"{summary['logs_per_min']:.1f} logs/min" if summary["logs_per_min"] else "-"
    print(
        f"batch {args.job}: {summary['inputs']} logs, {summary['skipped']} already done, {summary['ran']} run "
        f"({summary['ok']} ok, {summary['failed']} failed) in {summary['seconds']:.1f} s ({rate}; "
        f"{summary['backend']}, workers {summary['workers'] or 'cluster CPUs'})"
    )
    print(f"results: {summary['out']}")
    if summary["failed"]:
        print(f'{summary["failed"]} log(s) failed: see their "error" lines (a rerun retries them)')
    return 0
