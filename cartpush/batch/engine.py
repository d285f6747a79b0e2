"""The batch engine: a job over many logs, one JSON line per log, locally (joblib/loky) or on Ray.

A *job* is any picklable callable ``job(path) -> dict`` (JSON-able). :class:`CommandJob` is the
one `cartpush batch` uses: it builds the arguments of a CLI command (``estimate``, ``diagnose``)
with that command's own parser and calls the command module's ``result_for(log, args)``, the
function the command itself prints, so a batch result is exactly the command's ``--json`` output.

:func:`run_batch` writes one line per log to the output file (JSON Lines) as each finishes,
flushed at once::

    {"path": "/abs/log.csv", "ok": true, "result": {...}, "seconds": 1.23}
    {"path": "/abs/bad.csv", "ok": false, "error": "one line", "seconds": 0.01}

A rerun skips the paths that already have an ``ok: true`` line (a failed log is retried and gets a
new line: the last line of a path wins), so an interrupted run loses nothing that finished. A job
that raises gives an error line, never a crash of the batch.
"""

from __future__ import annotations

import argparse
import glob
import json
import logging
import os
import stat
import sys
import time
import warnings
from dataclasses import dataclass, field
from typing import Any
from collections.abc import Callable, Iterable, Iterator, Sequence

from cart.errors import CartpushError
from cartpush.errors import BatchError

#: File names a directory input contributes (sorted), in that directory only.
LOG_PATTERNS = ("*.csv", "*.csv.gz")
#: Python warning categories that are about library versions, not about a log: not recorded.
_QUIET = (DeprecationWarning, PendingDeprecationWarning, FutureWarning, ImportWarning, ResourceWarning)


def _one_line(text: Any) -> str:
    return " ".join(str(text).split())


# --------------------------------------------------------------------------- inputs and resume


def _is_bag_dir(path: str) -> bool:
    """True when ``path`` is a ROS 2 bag folder (metadata.yaml), to be taken as one input."""
    return os.path.isfile(os.path.join(path, "metadata.yaml"))


def expand_inputs(inputs: Sequence[str]) -> list[str]:
    """Return the absolute paths of the logs named by ``inputs``, in order, without duplicates.

    A file is taken as is; a directory contributes its ``*.csv`` and ``*.csv.gz`` (sorted, not
    recursive; a ROS 2 bag folder is one input); anything else is a glob pattern (``**`` recursive),
    its matches sorted. An input that names nothing is a BatchError (a typo should not silently run
    nothing).
    """
    out: list[str] = []
    seen = set()

    def add(path: str) -> None:
        path = os.path.abspath(path)
        if path not in seen:
            seen.add(path)
            out.append(path)

    for item in inputs:
        item = os.path.expanduser(str(item))
        if os.path.isfile(item):
            add(item)
        elif os.path.isdir(item):
            if _is_bag_dir(item):
                add(item)
                continue
            found = sorted({p for pat in LOG_PATTERNS for p in glob.glob(os.path.join(glob.escape(item), pat))})
            found = [p for p in found if os.path.isfile(p)]
            if not found:
                raise BatchError(f"{item}: the directory holds no *.csv or *.csv.gz log")
            for p in found:
                add(p)
        else:
            found = sorted(p for p in glob.glob(item, recursive=True) if os.path.isfile(p) or _is_bag_dir(p))
            if not found:
                raise BatchError(f"{item}: no such file, directory or matching log")
            for p in found:
                add(p)
    if not out:
        raise BatchError("no input logs given")
    return out


def ok_records(out: str | os.PathLike) -> Iterator[dict[str, Any]]:
    """Yield the JSON objects of the results file ``out`` that say ``ok: true`` (none if it does not exist).

    Lines that are not JSON (a line cut by an interruption) and foreign lines are skipped.
    """
    if not os.path.exists(out):
        return
    with open(out, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            try:
                rec = json.loads(line)
            except ValueError:
                continue
            if isinstance(rec, dict) and rec.get("ok") is True:
                yield rec


def done_paths(out: str | os.PathLike) -> set[str]:
    """Return the (absolute) paths that have an ``ok: true`` line in the results file ``out`` (empty if none)."""
    return {os.path.abspath(r["path"]) for r in ok_records(out) if isinstance(r.get("path"), str)}


class OutputPathError(BatchError):
    """``--out`` cannot take the results: one of the input logs, a device or FIFO, a directory, not writable."""


#: directories whose entries are devices or views of open descriptors (``/dev/stdout``, ``/proc/self/fd/1``)
DEVICE_DIRS = ("/dev", "/proc")


def device_path(out: str) -> bool:
    """Return True when ``out``, as written or once its links are followed, lies under a device directory.

    ``/dev/stdout`` follows to whatever the shell redirected it to (a terminal, a pipe, even a regular
    file): the path names a stream, not a results file a rerun could resume from.
    """
    for p in (os.path.abspath(out), os.path.realpath(out)):
        if any(p == d or p.startswith(d + os.sep) for d in DEVICE_DIRS):
            return True
    return False


def check_output(out: str | os.PathLike, paths: Sequence[str]) -> None:
    """Raise OutputPathError unless ``out`` is a writable regular file (or can be created) that is no input log.

    Called before any log is read: appending result lines to an input log would corrupt it, and a
    device (``/dev/full``, ``/dev/null``) or a FIFO is no results file a rerun could resume from.
    """
    out = os.fspath(out)
    if os.path.isdir(out):
        raise OutputPathError(f"--out {out}: is a directory, give a .jsonl file")
    if device_path(out):
        raise OutputPathError(f"--out {out}: is a device (a path under /dev or /proc); give a .jsonl file")
    if os.path.exists(out):
        st = os.stat(out)
        if not stat.S_ISREG(st.st_mode):
            kind = "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "not a regular file"
            raise OutputPathError(f"--out {out}: is {kind}; give a .jsonl file")
        for p in paths:
            try:
                same = os.path.samefile(out, p)
            except OSError:
                same = False
            if same:
                raise OutputPathError(f"--out {out}: is one of the input logs; give a new .jsonl file")
        if not os.access(out, os.W_OK):
            raise OutputPathError(f"--out {out}: is not writable")
        return
    parent = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(parent):
        raise OutputPathError(f"--out {out}: {_missing_directory(parent)}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputPathError(f"--out {out}: cannot create a file in {parent} (not writable)")


def _missing_directory(parent: str) -> str:
    """Return why ``parent`` (the --out file's directory) cannot hold it: missing, or a file on its path."""
    up = parent
    while up and not os.path.exists(up):
        up = os.path.dirname(up)
    if up and not os.path.isdir(up):
        return f"{up} is a file, not a directory"
    return f"the directory {parent} does not exist"


def _open_results(out: str | os.PathLike):
    """Open ``out`` for appending, after a newline if the file ends in a cut line."""
    out = os.fspath(out)
    if os.path.isdir(out):
        raise BatchError(f"--out {out}: is a directory, give a .jsonl file")
    parent = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(parent):
        raise BatchError(f"--out {out}: {_missing_directory(parent)}")
    try:
        needs_newline = False
        if os.path.getsize(out) if os.path.exists(out) else 0:
            with open(out, "rb") as last:
                last.seek(-1, os.SEEK_END)
                needs_newline = last.read(1) != b"\n"
        fh = open(out, "a", encoding="utf-8")
    except OSError as exc:
        raise BatchError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    if needs_newline:
        fh.write("\n")
        fh.flush()
    return fh


# --------------------------------------------------------------------------- jobs


def run_one(job: Callable[[str], dict[str, Any]], path: str) -> dict[str, Any]:
    """Run ``job(path)`` and return its result line (never raises for an ordinary exception).

    Runs in the worker (a loky process or a Ray task). Python warnings of the job are recorded in
    ``python_warnings`` (one line each, at most 5 distinct), not printed.
    """
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = job(path)
            rec: dict[str, Any] = {"path": path, "ok": True, "result": result}
        except Exception as exc:  # noqa: BLE001 - a bad log is an error line, not a crash of the batch
            if isinstance(exc, (CartpushError, OSError)):
                msg = _one_line(exc)
                if isinstance(exc, OSError) and exc.filename is not None:
                    msg = f"{exc.strerror or type(exc).__name__}: {exc.filename}"
            else:
                msg = f"internal error (bug): {type(exc).__name__}: {_one_line(exc)}"
            rec = {"path": path, "ok": False, "error": msg}
    texts: list[str] = []
    for w in caught:
        text = f"{w.category.__name__}: {_one_line(w.message)}"
        if not issubclass(w.category, _QUIET) and text not in texts:
            texts.append(text)
    if texts:
        rec["python_warnings"] = texts[:5]
    rec["seconds"] = round(time.perf_counter() - t0, 4)
    return rec


#: Jobs `cartpush batch` knows: name -> module of cartpush.cli with ``result_for(log, args)``.
COMMAND_JOBS = {"estimate": "estimate", "diagnose": "diagnose"}


def command_args(command: str, path: str, argv: Sequence[str] = ()) -> argparse.Namespace:
    """Parse ``[path, *argv]`` with the parser of the CLI command ``command`` (its defaults, its validation)."""
    import importlib

    from cartpush.cli.app import CliParser

    if command not in COMMAND_JOBS:
        raise BatchError(f"unknown job {command!r}; one of {', '.join(COMMAND_JOBS)}")
    module = importlib.import_module(f"cartpush.cli.{COMMAND_JOBS[command]}")
    parser = CliParser(prog=f"cartpush batch {command} --job-args")
    module.register(parser.add_subparsers(dest="command"))
    if any(a in ("-h", "--help") for a in argv):
        raise BatchError(f"--job-args: see `cartpush {command} --help` for the options")
    try:
        args = parser.parse_args([command, path, *argv])
    except SystemExit:  # CliParser printed its one line already
        raise BatchError(f"--job-args {' '.join(argv)!r}: not options of `cartpush {command}`") from None
    return args


@dataclass(frozen=True)
class CommandJob:
    """The job of a CLI command: ``CommandJob("estimate", ("--method", "ekf"))(path)`` is its ``--json`` dict.

    The log is read as the command reads it (a CSV, or a ROS bag with the topic options when the
    command takes them) and the command module's ``result_for(log, args)`` builds the result.
    """

    command: str
    argv: tuple[str, ...] = field(default_factory=tuple)

    def check(self) -> None:
        """Raise a BatchError / CartpushError if the job's options are unusable (before any log is read)."""
        import importlib

        args = command_args(self.command, "LOG", self.argv)
        if getattr(args, "out", None):
            raise BatchError(f"--job-args: --out (plots) is not supported by `cartpush batch {self.command}`")
        module = importlib.import_module(f"cartpush.cli.{COMMAND_JOBS[self.command]}")
        check = getattr(module, "check_args", None)
        if check is not None:
            check(args)

    def __call__(self, path: str) -> dict[str, Any]:
        import importlib

        args = command_args(self.command, path, self.argv)
        module = importlib.import_module(f"cartpush.cli.{COMMAND_JOBS[self.command]}")
        return module.result_for(_load(path, args), args)


def _load(path: str, args: argparse.Namespace):
    """Read the log at ``path`` as the command does: a bag (with its topic options) or a CSV."""
    if hasattr(args, "pose_topic"):  # the command reads bags too
        try:
            from cartpush.cli.import_bag import topic_options
            from cartpush.ros import load_any
        except ImportError:
            pass
        else:
            return load_any(path, **topic_options(args))
    from cart.logs import read_log

    return read_log(path)


# --------------------------------------------------------------------------- back ends


def _local_results(job, paths: Sequence[str], workers: int) -> Iterator[dict[str, Any]]:
    """Yield the result lines as they finish, on ``workers`` loky processes (1: in this process)."""
    if workers <= 1:
        for p in paths:
            yield run_one(job, p)
        return
    from joblib import Parallel, delayed

    parallel = Parallel(
        n_jobs=workers, backend="loky", return_as="generator_unordered", batch_size=1, pre_dispatch="2*n_jobs"
    )
    yield from parallel(delayed(run_one)(job, p) for p in paths)


def _ray_connect(address: str, workers: int | None) -> int:
    """Connect to the Ray cluster at ``address`` (unless Ray is initialised already); return the tasks in flight."""
    try:
        import ray
    except ImportError:
        raise BatchError("--ray needs the `ray` package: pip install 'cartpush[cluster]'") from None
    if not ray.is_initialized():
        try:
            ray.init(address=address, logging_level=logging.ERROR, log_to_driver=False)
        except Exception as exc:  # noqa: BLE001 - ConnectionError, RuntimeError, ...: one line
            raise BatchError(f"--ray {address}: cannot connect to the Ray cluster ({_one_line(exc)})") from None
    if workers is None:
        workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
    return workers


def _ray_results(job, paths: Sequence[str], workers: int) -> Iterator[dict[str, Any]]:
    """Yield the result lines as they finish, as Ray tasks (at most ``workers`` running, as many queued)."""
    import ray

    remote = ray.remote(num_cpus=1, max_retries=1)(run_one)
    job_ref = ray.put(job)
    todo = list(paths)
    pending: dict[Any, str] = {}
    window = 2 * workers  # queued + running: bounded so an interruption leaves little in flight
    while todo or pending:
        while todo and len(pending) < window:
            p = todo.pop(0)
            pending[remote.remote(job_ref, p)] = p
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            path = pending.pop(ref)
            try:
                yield ray.get(ref)
            except Exception as exc:  # noqa: BLE001 - a worker that died: an error line for this log
                yield {
                    "path": path,
                    "ok": False,
                    "error": f"the Ray task failed: {type(exc).__name__}: {_one_line(exc)[:300]}",
                }


def _check_workers(workers: int | None, ray_address: str | None) -> int | None:
    """Return the worker count to use: ``workers`` checked, 1 by default locally, the cluster's CPUs on Ray."""
    if workers is not None and workers < 1:
        raise BatchError(f"--workers must be at least 1, got {workers}")
    if ray_address is None and workers is None:
        workers = 1
    if ray_address is not None:
        workers = _ray_connect(ray_address, workers)
    return workers


def _progress_bar(progress: bool | None, total: int) -> Any:
    """Return a tqdm bar on stderr over ``total`` logs, or None (``progress`` None: only on a terminal)."""
    if progress is None:
        progress = bool(getattr(sys.stderr, "isatty", lambda: False)())
    if not (progress and total):
        return None
    from tqdm import tqdm

    return tqdm(total=total, file=sys.stderr, unit="log", dynamic_ncols=True)


def _results(
    job: Callable[[str], dict[str, Any]], todo: Sequence[str], workers: int | None, ray_address: str | None
) -> Iterable[dict[str, Any]]:
    """Return the result lines of ``todo`` as they finish, on Ray or locally."""
    if not todo:
        return ()
    if ray_address is not None:
        return _ray_results(job, todo, int(workers or 1))
    return _local_results(job, todo, int(workers or 1))


@dataclass
class _Tally:
    """Counts of the result lines written: succeeded, failed, and the jobs' own seconds."""

    ok: int = 0
    failed: int = 0
    job_seconds: float = 0.0

    def add(self, rec: dict[str, Any]) -> None:
        if rec.get("ok"):
            self.ok += 1
        else:
            self.failed += 1
        self.job_seconds += float(rec.get("seconds", 0.0))


def _write_results(
    results: Iterable[dict[str, Any]], fh: Any, bar: Any, on_result: Callable[[dict[str, Any]], None] | None
) -> _Tally:
    """Append each result line to ``fh`` (flushed at once), update the bar, call ``on_result``; return the counts."""
    from cart.jsonout import dumps_strict

    tally = _Tally()
    for rec in results:
        fh.write(dumps_strict(rec) + "\n")
        fh.flush()
        tally.add(rec)
        if on_result is not None:
            on_result(rec)
        if bar is not None:
            bar.update(1)
            if tally.failed:
                bar.set_postfix(failed=tally.failed, refresh=False)
    return tally


def run_batch(
    job: Callable[[str], dict[str, Any]],
    paths: Sequence[str],
    out: str | os.PathLike,
    workers: int | None = 1,
    ray_address: str | None = None,
    progress: bool | None = None,
    on_result: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Run ``job`` on every path not yet done in ``out``; append one JSON line per log as each finishes.

    ``workers``: local processes (joblib's loky; 1 runs in this process), or with ``ray_address``
    (``"auto"``, ``"ray://host:10001"``, ``"host:6379"``; an already initialised Ray is used as is)
    the most Ray tasks in flight (None: the cluster's CPUs). ``progress``: a tqdm bar on stderr
    (None: only when stderr is a terminal). Returns the summary: counts, wall time, logs per minute.
    """
    paths = [os.path.abspath(os.fspath(p)) for p in paths]
    check_output(out, paths)
    workers = _check_workers(workers, ray_address)
    done = done_paths(out)
    todo = [p for p in paths if p not in done]
    fh = _open_results(out)
    bar = _progress_bar(progress, len(todo))
    t0 = time.perf_counter()
    try:
        tally = _write_results(_results(job, todo, workers, ray_address), fh, bar, on_result)
    finally:
        fh.close()
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    ran = tally.ok + tally.failed
    return {
        "backend": "ray" if ray_address is not None else "joblib",
        "workers": workers,
        "inputs": len(paths),
        "skipped": len(paths) - len(todo),
        "ran": ran,
        "ok": tally.ok,
        "failed": tally.failed,
        "seconds": round(wall, 3),
        "logs_per_min": round(60.0 * ran / wall, 2) if ran and wall > 0 else None,
        "job_seconds_mean": round(tally.job_seconds / ran, 4) if ran else None,
        "out": os.path.abspath(os.fspath(out)),
    }
