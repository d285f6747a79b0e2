"""`cartpush estimate LOG`: the cart's mass, CoM, inertia and viscous coefficients from a measured log."""

from __future__ import annotations

import argparse
import ctypes
import importlib
import os
import threading
from typing import TYPE_CHECKING, Any

from cartpush.cli.import_bag import add_topic_options, topic_options

if TYPE_CHECKING:
    from cart.logs import CartLog


DESCRIPTION = """\
Estimate the cart's inertial parameters (mass, CoM, inertia about the CoM) and its
two viscous coefficients (forward/lateral N s/m, yaw N m s/rad) from a log in the
project's cart log format (CSV or .csv.gz; velocity columns optional).

--method ls (default): filtered-regressor least squares over the whole log; the
  noisy logged wrench is the regression's output, so wrench noise does not bias
  the estimate; noise levels, filter band and uncertainty come from the log itself.
--method ekf: the paper's augmented-state EKF (eq. 8-20) with a multi-start; the
  wrench is its input, so wrench noise biases the mass upwards. It runs the same
  log checks as ls; a run that diverges (a CoM beyond 10 m, an inertia above
  1e6 kg m^2, a mass 100 times the guess or above 10000 kg) is refused (exit 2).

The output says whether the model fits the log (`model_fits`, `nis_mean`: the
EKF's mean normalized innovation with these parameters, ~6 when it fits) and
lists warnings (weak excitation, misfit: then run `cartpush diagnose`). A
parameter the log cannot identify is printed "not identified" (null in --json).
Multi-rate tables (a pose held on every F/T row, or F/T averaged per pose row)
are split into their pose and wrench streams (`streams` in --json); a load
change splits the log into segments (`segments`). Positions in mm, heading in
degrees or time in ms are refused (exit 2) with the conversion named.

A ROS bag (ROS 1 .bag, ROS 2 folder, .mcap) is converted in memory with the same
options as `cartpush import` (--pose-topic, --wrench-topic, ...).

Example:
  cartpush estimate push.csv --json
  cartpush estimate run.bag --pose-topic /mocap/cart --wrench-topic /ft_sensor/wrench
  cartpush estimate push.csv --method ekf --mass-guess 25 --com-guess 0.3 0
"""


def register(subparsers) -> None:
    """Add the `estimate` subcommand."""
    parser = subparsers.add_parser(
        "estimate",
        help="estimate cart mass/CoM/inertia/damping from a log",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("log", metavar="LOG", help="cart log (.csv or .csv.gz) or a ROS bag (with the topic options)")
    parser.add_argument(
        "--method",
        choices=("ls", "ekf"),
        default="ls",
        help="ls: whole-log least squares (default); ekf: the paper's EKF",
    )
    parser.add_argument(
        "--mass-guess",
        type=float,
        default=20.0,
        metavar="KG",
        help="EKF only: initial mass, at most 10000 (default 20)",
    )
    parser.add_argument(
        "--com-guess",
        type=float,
        nargs=2,
        default=(0.0, 0.0),
        metavar=("DX", "DY"),
        help="EKF only: initial CoM in the cart frame {b}, each within +-5 m (default 0 0)",
    )
    parser.add_argument(
        "--sigma-guess",
        type=float,
        default=1.0,
        metavar="NS_PER_M",
        help="EKF only: initial viscous coefficients, 0 to 10000 (default 1)",
    )
    parser.add_argument("--json", action="store_true", help="print only JSON")
    add_topic_options(parser)
    parser.set_defaults(func=run)


def check_args(args: argparse.Namespace) -> None:
    """Raise a CartpushError for options the command cannot use (before reading any log): the EKF's guesses
    out of their bounds (:func:`cart.estimate_report.check_guesses`)."""
    from cart.estimate_report import check_guesses

    check_guesses(args.mass_guess, tuple(args.com_guess), args.sigma_guess)


def report_for(log, args: argparse.Namespace):
    """Return the library's :class:`cart.estimate_report.EstimateReport` for ``log`` with the command's options."""
    from cart.estimate_report import estimate_log

    return estimate_log(
        log,
        method=args.method,
        mass_guess=args.mass_guess,
        com_guess=tuple(args.com_guess),
        sigma_guess=args.sigma_guess,
    )


def result_for(log, args: argparse.Namespace) -> dict[str, Any]:
    """Return the JSON dict `cartpush estimate --json` prints for ``log`` (``estimate_log(...).to_dict()``)."""
    return report_for(log, args).to_dict()


def fit_verdict(out: dict[str, Any], nis_text: str) -> str:
    """Return the fit verdict with its reason: the residual wrench against what the sensor noise explains."""
    ratio = out.get("residual_ratio") or [None, None]
    if None in ratio:
        why = f"mean NIS {nis_text}"
    else:
        why = f"residual wrench {ratio[0]:.1f}x (force) and {ratio[1]:.1f}x (torque) what the sensor noise explains"
    if out["model_fits"]:
        return f"model fits yes: {why}"
    from cart.estimate_report import NIS_MISFIT

    nis = out.get("nis_mean")
    if None in ratio and isinstance(nis, (int, float)) and nis <= NIS_MISFIT:  # the EKF: refused on another count
        return f"model fits NO: {why} is within the noise, but the least-squares check is not (see the warnings)"
    return f"model fits NO: {why} (above the noise: an effect the model lacks; run `cartpush diagnose`)"


def _print_table(path: str, log, out: dict[str, Any]) -> None:
    s, why = out["std"], out["not_identified"]
    print(f"log        {path} ({len(log)} samples, {log.t[-1] - log.t[0]:.2f} s; method {out['method']})")
    st = out.get("streams")
    if st and (st["held_rows"] or st["dropouts"] or st["glitches"] or st["stuck_wrench_s"]):
        print(
            f"streams    pose {st['pose_hz']:.4g} Hz, wrench {st['wrench_hz']:.4g} Hz, {st['held_rows']} "
            f"{'interpolated' if st.get('interpolated') else 'held'} rows, "
            f"{st['dropouts']} dropouts, {st['glitches']} glitches, stuck wrench {st['stuck_wrench_s']:.3g} s"
        )

    def row(label: str, key: str, value, std, unit: str, fmt: str) -> None:
        if value is None:
            print(f"{label:<10} not identified: {why.get(key, 'see warnings')}")
        else:
            print(f"{label:<10} {value:9{fmt}} +- {std:{fmt}} {unit}")

    com = out["com"] or [None, None]
    row("mass", "mass", out["mass"], s["mass"], "kg", ".3f")
    cm = [None if v is None else 100.0 * v for v in com]  # one unit for the CoM in human output: cm
    row("CoM dx", "dx", cm[0], 100.0 * s["com"][0], "cm  (in the cart frame {b})", ".2f")
    row("CoM dy", "dy", cm[1], 100.0 * s["com"][1], "cm", ".2f")
    row("inertia", "inertia", out["inertia"], s["inertia"], "kg m^2 (about the CoM)", ".4f")
    row("sigma", "sigma", out["sigma"], s["sigma"], "N s/m (forward/lateral)", ".4f")
    row("sigma_yaw", "sigma_yaw", out["sigma_yaw"], s["sigma_yaw"], "N m s/rad (yaw)", ".4f")
    nis = out["nis_mean"]
    nis_text = f"{nis:.2f}" if nis is not None else "n/a"
    print(fit_verdict(out, nis_text))
    segs = out.get("segments") or []
    if len(segs) > 1:
        for k, g in enumerate(segs):
            mass = "not identified" if g["mass"] is None else f"{g['mass']:.3f} +- {g['std']['mass']:.3f} kg"
            print(f"segment {k + 1}  t {g['t0']:.2f}-{g['t1']:.2f} s: mass {mass}")
    for w in out["warnings"]:
        print(f"warning: {w}")


def _one_blas_thread() -> None:
    """Run OpenBLAS on one thread unless ``OPENBLAS_NUM_THREADS`` says otherwise (read when numpy loads).

    The fits' matrices are tall and thin (rows x 16 columns): a second thread saves nothing and, on a busy
    machine, spins waiting for a core (the 20-minute tiled log of benchmarks/malformed_suite.py: 4.2 s of
    CPU with the default threads, 3.3 s with one).
    """
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


#: glibc's ``mallopt`` parameters (malloc.h) and the values `_reuse_freed_arrays` gives them.
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
MMAP_THRESHOLD_BYTES, TRIM_THRESHOLD_BYTES = 32 * 2**20, 2**30


def _reuse_freed_arrays() -> None:
    """Let glibc's malloc keep freed arrays for the next ones rather than return them to the kernel (unless the
    ``MALLOC_*_`` variables say otherwise; nothing where ``mallopt`` does not exist).

    Arrays of the log's length (240000 rows: 2-20 MB) are allocated and freed by the hundred; each returned to the
    kernel comes back as fresh zero pages, one page fault per 4 KB (the 20-minute log of bench_estimate.py: 0.2 s
    of system time, 101000 faults; 75000 with these thresholds, the same peak memory).
    """
    if "MALLOC_MMAP_THRESHOLD_" in os.environ or "MALLOC_TRIM_THRESHOLD_" in os.environ:
        return
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc
        return
    mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)  # below it: the heap (32 MB, glibc's own top)
    mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)  # the heap's free top is kept up to 1 GB


#: The modules the estimate imports after reading the log, in the order it needs them (``python -X importtime``).
COMPUTE_MODULES = (
    "pyarrow",
    "pyarrow.csv",
    "scipy.linalg.lapack",
    "cart.estimate_report",
    "cart.identify",
    "cart.segments",
    "numpy.random",
    "cart.ekf",
)


def _import_modules(names: tuple[str, ...]) -> None:
    """Import ``names``; a module that fails is left to the import that needs it (which raises the error)."""
    for name in names:
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001, S112 - the caller's own import reports it
            return


def _import_in_background(names: tuple[str, ...] = COMPUTE_MODULES) -> threading.Thread:
    """Start importing ``names`` on a second thread and return it: the import (about 0.3 s, holding the GIL)
    overlaps the log's reading, whose decompression and CSV parsing release the GIL (zlib, pyarrow)."""
    thread = threading.Thread(target=_import_modules, args=(names,), name="cartpush-imports", daemon=True)
    thread.start()
    return thread


def _load(args: argparse.Namespace) -> CartLog:
    """Return the log of ``args.log``: a CSV (.csv, .csv.gz) given without topic options is read directly (the ROS
    importer's imports cost start-up time), anything else through :func:`cartpush.ros.load_any`."""
    options = topic_options(args)
    path = os.fspath(args.log)
    given = [k for k, v in options.items() if v is not None and v is not False]
    if path.lower().endswith((".csv", ".csv.gz")) and not os.path.isdir(path) and not given:
        from cart.logs import read_log

        return read_log(path)
    from cartpush.ros import load_any

    return load_any(args.log, **options)


def run(args: argparse.Namespace) -> int:
    """Estimate the parameters of the log and print them; return 0."""
    _one_blas_thread()
    _reuse_freed_arrays()
    import cart.logs  # noqa: F401 - imported here, before the import thread starts: one thread imports each module
    from cart.jsonout import dumps_strict, to_strict

    check_args(args)
    importer = _import_in_background()
    try:
        log = _load(args)
    finally:
        importer.join()  # a bad log's error waits for the imports: no thread is left importing at exit
    out = to_strict(result_for(log, args))
    if args.json:
        print(dumps_strict(out))
        return 0
    _print_table(args.log, log, out)
    return 0
