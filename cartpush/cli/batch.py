"""`cartpush batch estimate|diagnose INPUTS... --out RESULTS.jsonl`: one job over many logs, locally or on Ray;
`cartpush batch push --robots ... --masses ... --trajectories ...`: a push campaign, one line per run."""

from __future__ import annotations

import argparse
import os
import shlex
from typing import NoReturn

DESCRIPTION = """\
Run `estimate` or `diagnose` over many logs and write one JSON line per log to RESULTS.jsonl
as each finishes: {"path": ..., "ok": true, "result": <the command's --json output>, "seconds": ...}
or {"path": ..., "ok": false, "error": "one line"}. A bad log is an error line, not a crash.
Exit code 0 when every log run succeeded, 3 when any failed (a summary line on stderr names how many),
2 for bad options or an unusable --out (nothing runs).

INPUTS: files, directories (their *.csv and *.csv.gz, sorted) or glob patterns ('runs/**/*.csv.gz').
A rerun with the same --out skips the logs already done (ok true) and retries the failed ones, so an
interrupted run loses nothing that finished; the last line of a path wins.

Locally the logs run on --workers joblib processes (default 1: in this process). With --ray auto
(or a cluster address, e.g. ray://head:10001) they run as Ray tasks on an existing cluster, at most
--workers in flight (default: the cluster's CPUs); every node must have cartpush installed and see the
logs at the same paths. A progress bar shows on a terminal; the summary (counts, logs per minute)
is printed at the end (--json: one JSON object).

`batch push` runs a push campaign instead: every combination of --robots (registered names or robot
profile files, docs/robots.md), --masses (true cart mass, kg) and --trajectories (1, 2) on --plant
(kinematic, default, or mujoco), one line per run: {"run": {"robot": ..., "mass": ..., "trajectory": ..., ...},
"ok": true, "result": <cartpush push --json>, "seconds": ...}; resumable the same way; a summary table
(tracking, peak torque against the limits, saturated time and the limit that bound most) at the end.

Example:
  cartpush batch push --robots ridgeback_iiwa wmra my_robot.toml --masses 15 20 40 --trajectories 1 2 \
      --out push.jsonl --workers 2
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
    p.add_argument("job", choices=("estimate", "diagnose", "push"), help="the command to run on every log, or push")
    p.add_argument("inputs", nargs="*", metavar="INPUT", help="log files, directories or glob patterns")
    push = p.add_argument_group("batch push (a campaign: every robot x mass x trajectory)")
    push.add_argument("--robots", nargs="+", metavar="NAME|PROFILE.toml", help="robots: names or profile files")
    push.add_argument("--masses", nargs="+", type=float, metavar="KG", help="true cart masses (kg)")
    push.add_argument("--trajectories", nargs="+", type=int, default=[2], metavar="N", help="1 and/or 2 (default 2)")
    push.add_argument("--plant", default="kinematic", help="kinematic (default) or mujoco")
    push.add_argument("--arms", type=int, default=1, help="1 or 2 robots per run (default 1)")
    push.add_argument("--duration", type=float, default=30.0, help="trajectory duration in s (default 30)")
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


def _check_job_args(command: str, argv: tuple[str, ...]) -> None:
    """Raise BatchError naming the bad argument when ``argv`` are no options of ``cartpush COMMAND``.

    The job's own check (`CommandJob.check`) would let the command's parser print its error line before
    its own; this parses first with a parser that raises instead, so the error is one line.
    """
    import importlib

    from cartpush.batch import BatchError
    from cartpush.batch.engine import COMMAND_JOBS
    from cartpush.cli.app import CliParser

    class RaisingParser(CliParser):
        def error(self, message: str) -> NoReturn:
            raise BatchError(
                f"--job-args {' '.join(argv)!r}: {' '.join(message.split())} (see `cartpush {command} --help`)"
            )

    if command not in COMMAND_JOBS or any(a in ("-h", "--help") for a in argv):
        return  # CommandJob.check says so in one line
    parser = RaisingParser(prog=f"cartpush {command}")
    importlib.import_module(f"cartpush.cli.{COMMAND_JOBS[command]}").register(parser.add_subparsers(dest="command"))
    parser.parse_args([command, "LOG", *argv])


def check_results_file(out: str, paths: list[str]) -> None:
    """Raise BatchError when ``--out`` cannot take the results: `check_output`'s refusals (an input log, a
    device, a directory, unwritable), or an existing, non-empty file whose first line is no JSON object
    (a cart log, say: results are appended, so it would be corrupted). A results file of an earlier batch
    (JSON Lines) is fine: the rerun resumes it."""
    import json

    from cartpush.batch import BatchError, check_output

    check_output(out, paths)
    if not os.path.isfile(out):
        return
    with open(out, "rb") as fh:
        first = b""
        while not first.strip():
            first = fh.readline(1 << 20)
            if not first:
                return  # empty, or blank lines only
    text = first.strip().decode("utf-8", errors="replace")
    try:
        is_object = isinstance(json.loads(text), dict)
    except ValueError:  # a line cut by an interrupted run (or longer than 1 MiB) is still a results line
        is_object = text.startswith('{"')
    if not is_object:
        raise BatchError(
            f"--out {out}: exists and is not a JSON Lines results file (its first line is not a JSON object: "
            f"{text[:40]!r}); results are appended to it: give a new .jsonl file or the --out of an earlier batch"
        )


#: the push campaign's options and their defaults: given to `batch estimate` or `batch diagnose`, they are refused
_PUSH_ONLY = (("robots", None), ("masses", None), ("trajectories", [2]), ("plant", "kinematic"), ("arms", 1))


def _no_push_options(args: argparse.Namespace) -> None:
    """Raise BatchError when a `batch push` option is given to `batch estimate` or `batch diagnose` (it would be
    ignored)."""
    from cartpush.batch import BatchError

    given = [f"--{name}" for name, default in _PUSH_ONLY if getattr(args, name, default) != default]
    if args.duration != 30.0:
        given.append("--duration")
    if given:
        raise BatchError(
            f"{', '.join(given)}: {'options' if len(given) > 1 else 'an option'} of batch push only; batch "
            f"{args.job} runs `cartpush {args.job}` on its INPUT logs (its options go in --job-args)"
        )


def run(args: argparse.Namespace) -> int:
    """Run the batch; print the summary; return 0, or ``FAILED_EXIT`` when any log failed (its error line is kept)."""
    from cart.jsonout import dumps_strict
    from cartpush.batch import BatchError, CommandJob, expand_inputs, run_batch

    if args.workers is not None and args.workers < 1:
        raise BatchError(f"--workers must be at least 1, got {args.workers}")
    if args.workers is not None and args.workers > 4 * (os.cpu_count() or 1) and args.ray is None:
        raise BatchError(f"--workers {args.workers}: more than 4x this machine's {os.cpu_count()} CPUs")
    if args.job == "push":
        return _run_push(args)
    _no_push_options(args)
    if not args.inputs:
        raise BatchError(f"batch {args.job} needs at least one INPUT (log files, directories or glob patterns)")
    try:
        job_argv = tuple(shlex.split(args.job_args))
    except ValueError as exc:
        raise BatchError(f"--job-args: {exc}") from None
    _check_job_args(args.job, job_argv)
    job = CommandJob(args.job, job_argv)
    job.check()
    paths = expand_inputs(args.inputs)
    check_results_file(args.out, paths)
    _term_is_interrupt()
    summary = run_batch(job, paths, args.out, workers=args.workers, ray_address=args.ray)
    summary = {"job": args.job, **summary}
    if args.json:
        print(dumps_strict(summary))
        return _exit_code(f"batch {args.job}", summary["failed"], summary["ran"])
    rate = f"{summary['logs_per_min']:.1f} logs/min" if summary["logs_per_min"] else "-"
    print(
        f"batch {args.job}: {summary['inputs']} logs, {summary['skipped']} already done, {summary['ran']} run "
        f"({summary['ok']} ok, {summary['failed']} failed) in {summary['seconds']:.1f} s ({rate}; "
        f"{summary['backend']}, workers {summary['workers'] or 'cluster CPUs'})"
    )
    print(f"results: {summary['out']}")
    return _exit_code(f"batch {args.job}", summary["failed"], summary["ran"])


#: Exit code of a batch in which at least one log (or push run) failed; its error line is in the results.
FAILED_EXIT = 3


def _exit_code(what: str, failed: int, ran: int) -> int:
    """Return 0 when nothing failed, else ``FAILED_EXIT`` after one summary line on stderr."""
    import sys

    if not failed:
        return 0
    share = "all" if failed == ran else ("most" if 2 * failed > ran else "some")
    print(
        f'{what}: {failed} of {ran} failed ({share}): see their "error" lines (a rerun retries them); '
        f"exit code {FAILED_EXIT}",
        file=sys.stderr,
    )
    return FAILED_EXIT


def _run_push(args: argparse.Namespace) -> int:
    """Run a push campaign; print its summary table (or JSON); return 0, or ``FAILED_EXIT`` when any run failed."""
    from cart.jsonout import dumps_strict
    from cartpush.batch import BatchError
    from cartpush.batch.push_campaign import campaign, format_table, run_campaign

    if args.inputs:
        raise BatchError("batch push takes no INPUT logs: give --robots, --masses and --trajectories")
    if not args.robots or not args.masses:
        raise BatchError("batch push needs --robots NAME|PROFILE.toml ... and --masses KG ...")
    if args.arms not in (1, 2):
        raise BatchError(f"--arms must be 1 or 2, got {args.arms}")
    if not 8.0 <= args.duration <= 600.0:
        raise BatchError(f"--duration must be in [8, 600] s, got {args.duration}")
    runs = campaign(args.robots, args.masses, args.trajectories, args.arms, args.plant, args.duration)
    check_results_file(args.out, [])
    _term_is_interrupt()
    summary = run_campaign(runs, args.out, workers=args.workers, ray_address=args.ray)
    if args.json:
        print(dumps_strict({"job": "push", **summary}))
        return _exit_code("batch push", summary["failed"], summary["ran"])
    print(format_table(summary["table"]))
    print(
        f"batch push: {summary['runs']} runs, {summary['skipped']} already done, {summary['ran']} run "
        f"({summary['ok']} ok, {summary['failed']} failed) in {summary['seconds']:.1f} s "
        f"({summary['backend']}, workers {summary['workers'] or 'cluster CPUs'}); results: {summary['out']}"
    )
    return _exit_code("batch push", summary["failed"], summary["ran"])
