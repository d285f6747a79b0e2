"""Malformed-input suite (issue 14): >= 150 CLI invocations with bad or odd input, each in a subprocess.

Generates malformed logs (structure, values, encodings, compression), valid but
unusual logs (static cart, zero wrench, three rows, units in degrees /
millimetres / milliseconds, map coordinates, glitches, long time spans) and
bad option values for every command, runs ``cartpush ...`` for each with a
timeout and counts:

- tracebacks: "Traceback (most recent call last)" on stderr;
- wrong exit codes: the case's expected code(s) (2 for bad input, 0 for a
  valid request; odd-but-valid logs accept 0 or 2) not met, or exit 1 (a bug);
- invalid JSON: with ``--json`` and exit 0, stdout that a strict parser
  rejects (NaN, Infinity) or that is not a single JSON document;
- multi-line errors: exit 2 whose stderr is not exactly one ``error:`` line;
- hangs: the timeout expired;
- warnings: cases that exited 0 with a warning (stderr ``warning:`` lines or a
  non-empty JSON ``warnings`` list), listed by name.

Prints a table per class and the totals (``--json``: one JSON object).
Never asserts. Run: .venv/bin/python benchmarks/malformed_suite.py [--jobs 2] [--json] [--only SUBSTRING]
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import gzip
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cart.logs import CartLog, write_log

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "cartpush.cli"]
HEADER = "t,x,y,theta,fx,fy,tau"


@dataclass
class Case:
    """One invocation: name, class, argv (after `cartpush`), accepted exit codes, timeout (s)."""

    name: str
    klass: str
    argv: list
    expect: tuple = (2,)
    timeout: float = 90.0
    result: dict = field(default_factory=dict)
    #: the cart's true mass (kg) when the log has one: an answer (exit 0) off by more than MASS_TOLERANCE is wrong
    truth_mass: float | None = None


# -- logs ---------------------------------------------------------------------------------------
def _push_arrays(n: int = 600, dt: float = 0.01, seed: int = 0):
    """(t, q, gamma) of a simulated push of the Table I test-5 cart (consistent dynamics, 1 mm noise)."""
    from cart import table1
    from cart.simulate import MeasurementNoise, simulate

    truth = table1.true_params(table1.TESTS[4])

    def ctrl(t, q, qd):
        f = 15.0 + 10.0 * math.sin(2.1 * t)
        return np.array([f * math.cos(q[2]), f * math.sin(q[2]), 3.0 * math.sin(1.7 * t)])

    sim = simulate(
        truth, ctrl, (n - 1) * dt, dt, noise=MeasurementNoise.from_level(0.001), rng=np.random.default_rng(seed)
    )
    m = sim.measured
    return m.t, m.q, m.gamma


def _valid_text(n: int = 60) -> list:
    t, q, g = _push_arrays(n)
    return [HEADER] + [",".join(f"{v:.6g}" for v in (t[k], *q[k], *g[k])) for k in range(n)]


def malformed_logs(d: Path) -> dict:
    """Return name -> path of logs every reader must refuse (exit 2)."""
    out = {}

    def put(name, data, suffix=".csv"):
        p = d / f"bad_{name}{suffix}"
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
        out[name] = p

    lines = _valid_text()
    put("empty", "")
    put("only_comments", "# robot: x\n# note: y\n")
    put("header_only", HEADER + "\n")
    put("two_rows", "\n".join(lines[:3]) + "\n")
    put("missing_tau", "\n".join([HEADER.replace(",tau", "")] + [r.rsplit(",", 1)[0] for r in lines[1:]]) + "\n")
    put("missing_t", "\n".join([HEADER[2:]] + [r.split(",", 1)[1] for r in lines[1:]]) + "\n")
    put("duplicate_column", "\n".join([HEADER + ",x"] + [r + ",0" for r in lines[1:]]) + "\n")
    for name, cell in (
        ("nan_cell", "nan"),
        ("inf_cell", "inf"),
        ("neg_inf_cell", "-inf"),
        ("text_cell", "abc"),
        ("empty_cell", ""),
        ("huge_cell", "1e300"),
        ("neg_huge_cell", "-1e300"),
        ("overflow", "1e999"),
        ("comma_decimal", "1,5"),
    ):
        bad = list(lines)
        f = bad[10].split(",")
        f[4] = cell
        bad[10] = ",".join(f)
        put(name, "\n".join(bad) + "\n")
    bad = list(lines)
    bad[20] = bad[19].rsplit(",", 1)[0] + ",9.5"  # the time of the row before, another value
    put("repeated_time", "\n".join(bad) + "\n")
    put("decreasing_time", "\n".join([lines[0]] + lines[1:][::-1]) + "\n")
    bad = list(lines)
    bad[5] += ",1"
    put("extra_field", "\n".join(bad) + "\n")
    bad = list(lines)
    bad[5] = bad[5].rsplit(",", 1)[0]
    put("missing_field", "\n".join(bad) + "\n")
    put("lone_contact_x", "\n".join([HEADER + ",contact_x"] + [r + ",0.2" for r in lines[1:]]) + "\n")
    put("lone_contact_y", "\n".join([HEADER + ",contact_y"] + [r + ",0.2" for r in lines[1:]]) + "\n")
    put("semicolons", "\n".join(r.replace(",", ";") for r in lines) + "\n")
    put("tabs", "\n".join(r.replace(",", "\t") for r in lines) + "\n")
    put("latin1", ("# operator: J\xfcrgen\n" + "\n".join(lines) + "\n").encode("latin-1"))
    put("utf16", ("\n".join(lines) + "\n").encode("utf-16"))
    put("binary_garbage", bytes(np.random.default_rng(1).integers(0, 256, 400, dtype=np.uint8)))
    put("gzip_truncated", gzip.compress(("\n".join(lines) + "\n").encode())[:-30], ".csv.gz")
    put("gzip_garbage", b"\x1f\x8b\x08\x00garbage-garbage", ".csv.gz")
    put("not_gzip", "\n".join(lines) + "\n", ".csv.gz")
    put(
        "nan_velocity",
        "\n".join(
            [HEADER + ",vx,vy,omega"] + [r + (",nan,0,0" if k == 7 else ",0,0,0") for k, r in enumerate(lines[1:])]
        )
        + "\n",
    )
    out["directory"] = d
    out["missing_file"] = d / "no_such_file.csv"
    return out


def odd_logs(d: Path) -> dict:
    """Return name -> path of valid but unusual logs (a command may answer or refuse, never crash)."""
    out = {}

    def put(name, t, q, g, **kw):
        p = d / f"odd_{name}.csv"
        write_log(p, CartLog(t=t, q=q, gamma=g, **kw))
        out[name] = p

    t, q, g = _push_arrays()
    put("nominal", t, q, g)
    put("static", t, np.tile(q[0], (len(t), 1)), np.zeros_like(g))
    put("static_pushed", t, np.tile(q[0], (len(t), 1)), np.tile([50.0, 0.0, 0.0], (len(t), 1)))
    put("zero_wrench", t, q, np.zeros_like(g))
    put("three_rows", t[:3], q[:3], g[:3])
    put("ten_rows", t[:10], q[:10], g[:10])
    qd = q.copy()
    qd[:, 2] = np.degrees(qd[:, 2])
    put("heading_degrees", t, qd, g)
    qm = q.copy()
    qm[:, :2] *= 1000.0
    put("positions_mm", t, qm, g)
    put("time_ms", t * 1000.0, q, g)
    put("map_coordinates", t, q + [512_345.0, 4_123_456.0, 0.0], g)
    qg = q.copy()
    qg[300, 0] += 5.0
    put("mocap_glitch", t, qg, g)
    rng = np.random.default_rng(2)
    keep = np.sort(rng.choice(len(t), size=len(t) // 5, replace=False))
    put("rows_dropped_80pc", t[keep], q[keep], g[keep])
    gap = np.r_[t[:300], t[300:] + 10.0]
    put("ten_second_gap", gap, q, g)
    put("unix_time", t + 1.7e9, q, g)
    put("tiny_block", t, q * [0.02, 0.02, 0.0], g * 0.01)
    put("heavy_bed", t, q * 0.3, g * 8.0)
    tl = np.arange(0.0, 30_000.0, 1.0)
    put("long_span", tl, np.column_stack([0.01 * tl, 0 * tl, 0 * tl]), np.tile([1.0, 0, 0], (len(tl), 1)))
    put("long_span_mm", tl, np.column_stack([10.0 * tl, 0 * tl, 0 * tl]), np.tile([1.0, 0, 0], (len(tl), 1)))
    put("with_contact", t, q, g, contact_b=np.tile([-0.5, 0.1], (len(t), 1)))
    put("with_velocities", t, q, g, qd=np.gradient(q, t, axis=0))
    qv = np.gradient(q, t, axis=0)
    qv[::100, 0] += 50.0
    put("velocity_glitches", t, q, g, qd=qv)
    path = d / "odd_gzip.csv.gz"
    write_log(path, CartLog(t=t, q=q, gamma=g))
    out["gzip"] = path
    bom = d / "odd_bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + out["nominal"].read_bytes())
    out["bom"] = bom
    return out


#: relative mass error beyond which an answered (exit 0) recorder log counts as a wrong number
MASS_TOLERANCE = 0.15


def _recorder_base(seed: int = 7):
    """Return (HiddenLog) of an effect-free 40 s push at 100 Hz with turns (the hidden-effect test bed)."""
    sys.path.insert(0, str(ROOT))
    from studies.testbeds.hidden_effects import random_case

    return random_case(None, np.random.default_rng(seed), duration=40.0, rate=100.0, with_velocities=False)


def _text_rows(t, q, g, fmt: str = "{:.9g}") -> list:
    return [",".join(fmt.format(v) for v in (t[k], *q[k], *g[k])) for k in range(len(t))]


def _recorder_text(d: Path, put, t, q, g) -> None:
    """Write the text-level recorder variants (separators, encodings, line ends, headers, rows)."""
    rows = _text_rows(t, q, g)
    body = "\n".join([HEADER] + rows) + "\n"
    put("crlf", body.replace("\n", "\r\n"))
    put("bom_crlf", b"\xef\xbb\xbf" + body.replace("\n", "\r\n").encode())
    put("cr_only", body.replace("\n", "\r"))
    put("header_spaces", body.replace(HEADER, "t, x, y, theta, fx, fy, tau", 1))
    put("header_upper", body.replace(HEADER, HEADER.upper(), 1))
    put("header_units", body.replace(HEADER, "t [s],x [m],y [m],theta [rad],fx [N],fy [N],tau [Nm]", 1))
    put("trailing_comma", "\n".join([HEADER + ","] + [r + "," for r in rows]) + "\n")
    put("blank_line_inside", "\n".join([HEADER] + rows[:100] + [""] + rows[100:]) + "\n")
    put("comment_inside", "\n".join([HEADER] + rows[:100] + ["# marker: lap 2"] + rows[100:]) + "\n")
    put(
        "decimal_comma_semicolon",
        "\n".join([HEADER.replace(",", ";")] + [r.replace(",", ";").replace(".", ",") for r in rows]) + "\n",
    )
    put("whitespace_only", "   \n\n  \n", truth=False)
    put("one_row", "\n".join([HEADER, rows[0]]) + "\n", truth=False)
    nan_row = ",".join([rows[200].split(",")[0]] + ["nan"] * 6)
    put("nan_row", "\n".join([HEADER] + rows[:200] + [nan_row] + rows[201:]) + "\n")
    inf_row = rows[300].rsplit(",", 1)[0] + ",inf"
    put("inf_in_tau", "\n".join([HEADER] + rows[:300] + [inf_row] + rows[301:]) + "\n")
    swap = list(rows)
    swap[500], swap[501] = swap[501], swap[500]
    put("two_rows_swapped", "\n".join([HEADER] + swap) + "\n")
    order = ["t", "fx", "fy", "tau", "x", "y", "theta"]
    idx = [HEADER.split(",").index(c) for c in order]
    put(
        "columns_reordered",
        "\n".join([",".join(order)] + [",".join(r.split(",")[i] for i in idx) for r in rows]) + "\n",
    )
    put("extra_columns", "\n".join([HEADER + ",battery,mode"] + [r + ",24.1,push" for r in rows]) + "\n")
    put(
        "quoted_numbers",
        "\n".join(['"' + HEADER.replace(",", '","') + '"'] + ['"' + r.replace(",", '","') + '"' for r in rows]) + "\n",
    )
    put("few_digits", "\n".join([HEADER] + _text_rows(t, q, g, "{:.4g}")) + "\n")
    put("ros_time_ns_float", "\n".join([HEADER] + _text_rows(t * 1e9 + 1.7e18, q, g, "{:.19g}")) + "\n")


def recorder_logs(d: Path) -> dict:
    """Return name -> (path, true mass or None) of logs as a user's recorder writes them (issue 30 red team).

    Every log is the same effect-free push written another way: an answer (exit 0) must give the cart's
    mass within MASS_TOLERANCE, or the log must be refused (exit 2). ``None``: no answer is possible
    (one row, no rows) or the log is not the push (``huge_20min`` repeats it, with jumps).
    """
    base = _recorder_base()
    m_true = float(base.params.m)
    t, q, g = base.measured.t, base.measured.q, base.measured.gamma
    out: dict = {}

    def put(name, data, suffix=".csv", truth=True):
        path = d / f"rec_{name}{suffix}"
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
        out[name] = (path, m_true if truth else None)

    def put_log(name, tt, qq, gg, truth=True, **kw):
        path = d / f"rec_{name}.csv"
        write_log(path, CartLog(t=tt, q=qq, gamma=gg, **kw))
        out[name] = (path, m_true if truth else None)

    put_log("clean", t, q, g)
    _recorder_text(d, put, t, q, g)
    half = len(t) // 2
    put_log("time_reset_midway", np.r_[t[:half], t[half:] - t[half]], q, g)
    put_log("time_in_ms", t * 1e3, q, g)
    put_log("time_in_us", t * 1e6, q, g)
    put_log("time_in_minutes", t / 60.0, q, g)
    put_log("positions_cm", t, q * [100.0, 100.0, 1.0], g)
    put_log("positions_inches", t, q * [39.37, 39.37, 1.0], g)
    put_log("heading_degrees", t, q * [1.0, 1.0, 180.0 / math.pi], g)
    put_log("heading_gradians", t, q * [1.0, 1.0, 200.0 / math.pi], g)
    put_log("wrench_sign_flipped", t, q, -g)
    put_log("forces_lbf_declared", t, q, g / 4.4482216, metadata={"units": "fx fy lbf, tau lbf ft"})
    put_log("positions_mm_heading_deg", t, q * [1000.0, 1000.0, 180.0 / math.pi], g)
    gaps = np.ones(len(t), bool)
    for k in (800, 1800, 2800):
        gaps[k : k + 50] = False
    put_log("gaps_half_second", t[gaps], q[gaps], g[gaps])
    jit = t + np.random.default_rng(3).normal(0.0, 0.002, len(t))
    put_log("jitter_2ms_sorted", np.sort(jit), q, g)
    held = q.copy()
    held[1::2] = held[::2][: len(held[1::2])]
    put_log("held_pose_every_other_row", t, held, g)
    put_log("wrench_lag_half_second", t, q, np.r_[g[50:], np.repeat(g[-1:], 50, axis=0)])
    cart = (lambda c, s_: np.column_stack([c * g[:, 0] + s_ * g[:, 1], -s_ * g[:, 0] + c * g[:, 1], g[:, 2]]))(
        np.cos(q[:, 2]), np.sin(q[:, 2])
    )
    put_log("wrench_in_cart_frame", t, q, cart)
    put_log("map_offset", t, q + [634_512.3, 5_432_101.7, 0.0], g)
    put_log("heading_wrapped_pi", t, np.column_stack([q[:, :2], np.angle(np.exp(1j * q[:, 2]))]), g)
    put_log("heading_offset_2pi_x5", t, q + [0.0, 0.0, 10 * math.pi], g)
    put_log("unix_seconds", t + 1.732e9, q, g)
    flip = q.copy()
    flip[(t > 17.0) & (t < 18.5), 2] += math.pi  # a symmetric marker set read turned for 1.5 s
    put_log("heading_flipped_pi_1s", t, flip, g)
    clip = g.copy()
    lim = 0.7 * float(np.max(np.abs(g[:, :2])))
    clip[:, :2] = np.clip(g[:, :2], -lim, lim)  # a saturated F/T axis
    put_log("force_clipped_70pc", t, q, clip)
    tl = np.arange(0.0, 1200.0, 0.005)
    reps = int(math.ceil(len(tl) / len(t)))
    huge = CartLog(t=tl, q=np.tile(q, (reps, 1))[: len(tl)], gamma=np.tile(g, (reps, 1))[: len(tl)])
    write_log(d / "rec_huge_20min.csv.gz", huge)
    out["huge_20min"] = (d / "rec_huge_20min.csv.gz", None)
    return out


# -- cases --------------------------------------------------------------------------------------
def build_cases(d: Path) -> list:
    """Return the suite's cases (files are created under `d`)."""
    bad, odd = malformed_logs(d), odd_logs(d)
    cases = []
    for name, p in bad.items():
        cases.append(Case(f"estimate/{name}", "bad log", ["estimate", str(p), "--json"]))
        cases.append(Case(f"diagnose/{name}", "bad log", ["diagnose", str(p), "--json"]))
        cases.append(Case(f"view/{name}", "bad log", ["view", str(p), "--html", str(d / f"v_bad_{name}.html")]))
    for name, p in odd.items():
        cases.append(Case(f"estimate/{name}", "odd log", ["estimate", str(p), "--json"], (0, 2)))
        cases.append(Case(f"diagnose/{name}", "odd log", ["diagnose", str(p), "--json"], (0, 2), timeout=240))
        cases.append(
            Case(f"view/{name}", "odd log", ["view", str(p), "--html", str(d / f"v_{name}.html")], (0, 2), timeout=120)
        )
    blocker = d / "a_file"
    blocker.write_text("x")
    nominal = str(odd["nominal"])
    option_cases = [
        ("diagnose --threshold nan", ["diagnose", nominal, "--threshold", "nan", "--json"]),
        ("diagnose --threshold -1", ["diagnose", nominal, "--threshold", "-1", "--json"]),
        ("diagnose --threshold inf", ["diagnose", nominal, "--threshold", "inf"]),
        ("diagnose --threshold abc", ["diagnose", nominal, "--threshold", "abc"]),
        ("diagnose --out unwritable", ["diagnose", nominal, "--out", str(blocker / "x")]),
        ("estimate --mass-guess 0", ["estimate", nominal, "--mass-guess", "0"]),
        ("estimate --mass-guess -5", ["estimate", nominal, "--mass-guess", "-5"]),
        ("estimate --mass-guess nan", ["estimate", nominal, "--mass-guess", "nan"]),
        ("estimate --mass-guess inf", ["estimate", nominal, "--mass-guess", "inf"]),
        ("estimate --com-guess nan 0", ["estimate", nominal, "--com-guess", "nan", "0"]),
        ("estimate --sigma-guess nan", ["estimate", nominal, "--sigma-guess", "nan"]),
        ("reproduce --seed -1", ["reproduce", "--seed", "-1"]),
        ("reproduce --duration inf", ["reproduce", "--duration", "inf"]),
        ("reproduce --duration nan", ["reproduce", "--duration", "nan"]),
        ("reproduce --duration 1e7", ["reproduce", "--duration", "1e7"]),
        ("reproduce --duration 4.9", ["reproduce", "--duration", "4.9"]),
        ("reproduce --duration -1", ["reproduce", "--duration", "-1"]),
        ("reproduce --duration 0", ["reproduce", "--duration", "0"]),
        ("reproduce --tests 0", ["reproduce", "--tests", "0"]),
        ("reproduce --tests 12", ["reproduce", "--tests", "12"]),
        ("reproduce --tests x", ["reproduce", "--tests", "x"]),
        ("reproduce --tests ,", ["reproduce", "--tests", ","]),
        ("reproduce --out unwritable", ["reproduce", "--tests", "1", "--out", str(blocker)]),
        ("reproduce --controller bad", ["reproduce", "--controller", "bad"]),
        ("push --seed -1", ["push", "--seed", "-1"]),
        ("push --duration inf", ["push", "--duration", "inf"]),
        ("push --duration 1e7", ["push", "--duration", "1e7"]),
        ("push --duration 2", ["push", "--duration", "2"]),
        ("push --trajectory 3", ["push", "--trajectory", "3"]),
        ("push --arms 3", ["push", "--arms", "3"]),
        ("push --arms 0", ["push", "--arms", "0"]),
        ("push --contact best", ["push", "--contact", "best"]),
        ("push --contact-y nan", ["push", "--contact", "fixed", "--contact-y", "nan"]),
        ("push --contact-y 1", ["push", "--contact", "fixed", "--contact-y", "1"]),
        ("push --initial-mass 0", ["push", "--initial-mass", "0"]),
        ("push --initial-mass nan", ["push", "--initial-mass", "nan"]),
        ("push --out unwritable", ["push", "--out", str(blocker / "x")]),
        ("push --html unwritable", ["push", "--html", str(blocker / "x.html")]),
        ("demo --duration inf", ["demo", "--duration", "inf"]),
        ("demo --duration nan", ["demo", "--duration", "nan"]),
        ("demo --duration 1e7", ["demo", "--duration", "1e7"]),
        ("demo --duration 2", ["demo", "--duration", "2"]),
        ("demo --out unwritable", ["demo", "--out", str(blocker / "r")]),
        ("track --band 0", ["track", "line", "--band", "0"]),
        ("track --band -1", ["track", "line", "--band", "-1"]),
        ("track --band nan", ["track", "line", "--band", "nan"]),
        ("track --duration inf", ["track", "line", "--duration", "inf"]),
        ("track --duration 1e7", ["track", "line", "--duration", "1e7"]),
        ("track --duration 0", ["track", "line", "--duration", "0"]),
        ("track --rate 0", ["track", "line", "--rate", "0"]),
        ("track --rate 1e9", ["track", "line", "--rate", "1e9"]),
        ("track --rate nan", ["track", "line", "--rate", "nan"]),
        ("track bad path", ["track", "circle"]),
        ("track --robot bad", ["track", "line", "--robot", "r2d2"]),
        ("track --out unwritable", ["track", "line", "--duration", "1", "--out", str(blocker / "x.csv")]),
        ("track --out directory", ["track", "line", "--duration", "1", "--out", str(d)]),
        (
            "plan-contacts --min-spacing nan",
            ["plan-contacts", "--wrench", "10", "0", "0", "--arms", "2", "--min-spacing", "nan"],
        ),
        (
            "plan-contacts --min-spacing -1",
            ["plan-contacts", "--wrench", "10", "0", "0", "--arms", "2", "--min-spacing", "-1"],
        ),
        ("plan-contacts --wrench nan", ["plan-contacts", "--wrench", "nan", "0", "0"]),
        ("plan-contacts --wrench inf", ["plan-contacts", "--wrench", "inf", "0", "0"]),
        ("plan-contacts --wrench 2 values", ["plan-contacts", "--wrench", "1", "0"]),
        ("plan-contacts --wrench -400 infeasible", ["plan-contacts", "--wrench", "-400", "0", "0"]),
        ("plan-contacts --wrench 1e9", ["plan-contacts", "--wrench", "1e9", "0", "0"]),
        ("plan-contacts --arms 0", ["plan-contacts", "--wrench", "10", "0", "0", "--arms", "0"]),
        ("plan-contacts --arms 100", ["plan-contacts", "--wrench", "10", "0", "0", "--arms", "100"]),
        ("plan-contacts --handle-width -1", ["plan-contacts", "--wrench", "10", "0", "0", "--handle-width", "-1"]),
        ("plan-contacts --handle-width nan", ["plan-contacts", "--wrench", "10", "0", "0", "--handle-width", "nan"]),
        ("plan-contacts --grip-force nan", ["plan-contacts", "--wrench", "10", "0", "0", "--grip-force", "nan"]),
        ("plan-contacts --max-force 0", ["plan-contacts", "--wrench", "10", "0", "0", "--max-force", "0"]),
        ("plan-contacts --solver bad", ["plan-contacts", "--wrench", "10", "0", "0", "--solver", "nosuch"]),
        ("view --scenario 0", ["view", "--scenario", "0", "--html", str(d / "s0.html")]),
        ("view --scenario 12", ["view", "--scenario", "12", "--html", str(d / "s12.html")]),
        (
            "view --scenario 3 --duration inf",
            ["view", "--scenario", "3", "--duration", "inf", "--html", str(d / "s3.html")],
        ),
        (
            "view --scenario 3 --duration nan",
            ["view", "--scenario", "3", "--duration", "nan", "--html", str(d / "s3.html")],
        ),
        ("view --robot bad", ["view", "--robot", "r2d2", "--html", str(d / "r.html")]),
        ("view --html unwritable", ["view", "--robot", "wmra", "--html", str(blocker / "r.html")]),
        ("view --html directory", ["view", "--robot", "wmra", "--html", str(d)]),
        ("view no source", ["view", "--html", str(d / "n.html")]),
        ("unknown command", ["frobnicate"]),
        ("no command", []),
        ("unknown option", ["estimate", nominal, "--frobnicate"]),
    ]
    cases += [Case(name, "bad option", argv) for name, argv in option_cases]
    good = [
        ("help", ["--help"]),
        *[
            (f"{c} --help", [c, "--help"])
            for c in ("demo", "track", "reproduce", "estimate", "plan-contacts", "diagnose", "push", "view")
        ],
        ("plan-contacts --wrench -1e2 0 0", ["plan-contacts", "--wrench", "-1e2", "0", "0", "--json"]),
        ("plan-contacts --wrench=-40,0,-2 style", ["plan-contacts", "--wrench", "-40", "0", "-2", "--json"]),
        ("plan-contacts --wrench 40 0 -2e0", ["plan-contacts", "--wrench", "40", "0", "-2e0", "--json"]),
        ("track line short", ["track", "line", "--duration", "1", "--json"]),
        (
            "track sine band 0.001 (leaves the band: warns)",
            ["track", "sine", "--band", "0.001", "--duration", "3", "--json"],
        ),
        ("track out new dir", ["track", "line", "--duration", "0.5", "--out", str(d / "new" / "run.csv")]),
        ("demo --robots-only", ["demo", "--robots-only", "--json"]),
        ("view --robot wmra", ["view", "--robot", "wmra", "--html", str(d / "wmra.html")]),
        ("reproduce --duration 6 --tests 1", ["reproduce", "--duration", "6", "--tests", "1", "--json"]),
        ("--debug estimate nominal", ["--debug", "estimate", nominal, "--json"]),
        (
            "estimate --mass-guess 1e-9 (the guess is only a start)",
            ["estimate", nominal, "--mass-guess", "1e-9", "--json"],
        ),
    ]
    cases += [Case(name, "valid request", argv, (0,), timeout=180) for name, argv in good]
    for name, (path, m_true) in recorder_logs(d).items():
        for cmd in ("estimate", "diagnose"):
            cases.append(
                Case(
                    f"recorder/{cmd}/{name}", "recorder log", [cmd, str(path), "--json"], (0, 2), 240, truth_mass=m_true
                )
            )
    return cases


# -- running ------------------------------------------------------------------------------------
def _strict_json(text: str):
    def refuse(name):
        raise ValueError(f"non-strict constant {name}")

    return json.loads(text, parse_constant=refuse)


def _answer_mass(obj) -> tuple[float | None, float]:
    """Return (mass, its std) an answer gives: estimate's ``mass``, diagnose's final (or nominal) model ``m``."""
    if not isinstance(obj, dict):
        return None, 0.0
    if isinstance(obj.get("mass"), (int, float)):
        std = obj.get("std", {}).get("mass") if isinstance(obj.get("std"), dict) else None
        return float(obj["mass"]), float(std) if isinstance(std, (int, float)) else 0.0
    for key in ("final_model", "nominal"):
        model = obj.get(key)
        if isinstance(model, dict) and isinstance(model.get("m"), (int, float)):
            std = model.get("m_std")
            return float(model["m"]), float(std) if isinstance(std, (int, float)) else 0.0
    return None, 0.0


def _wrong_mass(case: Case, obj) -> bool:
    """Return True when a log of known mass was answered (exit 0) with a mass off by more than MASS_TOLERANCE
    and 3 of its std (or with none); logs without a known mass are not judged."""
    if case.truth_mass is None:
        return False
    m, std = _answer_mass(obj)
    return m is None or abs(m - case.truth_mass) > max(MASS_TOLERANCE * case.truth_mass, 3.0 * std)


def run_case(case: Case, cwd: Path) -> Case:
    """Run one case in a subprocess; fill case.result."""
    env = dict(os.environ, PYTHONWARNINGS="default", MPLBACKEND="Agg")
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(CLI + case.argv, capture_output=True, text=True, timeout=case.timeout, cwd=cwd, env=env)
    except subprocess.TimeoutExpired:
        case.result = {"hang": True, "seconds": case.timeout}
        return case
    wall = time.perf_counter() - t0
    err_lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    r = {
        "hang": False,
        "code": proc.returncode,
        "seconds": wall,
        "traceback": "Traceback (most recent call last)" in proc.stderr,
        "wrong_code": proc.returncode not in case.expect or proc.returncode == 1,
        "invalid_json": False,
        "multiline_error": False,
        "warnings": [],
        "stderr": proc.stderr.strip()[-400:],
    }
    if proc.returncode == 2:
        errors = [ln for ln in err_lines if ": error:" in ln]
        r["multiline_error"] = not (len(err_lines) == 1 and len(errors) == 1)
    r["wrong_number"] = False
    if "--json" in case.argv and proc.returncode == 0:
        try:
            obj = _strict_json(proc.stdout)
            if isinstance(obj, dict) and obj.get("warnings"):
                r["warnings"] += [str(w) for w in obj["warnings"]]
            r["wrong_number"] = _wrong_mass(case, obj)
        except ValueError as exc:
            r["invalid_json"] = True
            r["json_error"] = str(exc)[:200]
    if proc.returncode == 0:
        r["warnings"] += [ln for ln in err_lines if "warning:" in ln]
    case.result = r
    return case


def main() -> None:
    """Build and run the suite; print the table (or JSON)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--only", default=None, help="run only cases whose name contains this")
    ap.add_argument("--keep", action="store_true", help="keep the temporary directory")
    args = ap.parse_args()
    d = Path(tempfile.mkdtemp(prefix="cartpush_malformed_"))
    try:
        cases = build_cases(d)
        if args.only:
            cases = [c for c in cases if args.only in c.name]
        t0 = time.perf_counter()
        with cf.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            list(pool.map(lambda c: run_case(c, d), cases))
        wall = time.perf_counter() - t0
    finally:
        if not args.keep:
            shutil.rmtree(d, ignore_errors=True)
    metrics = ("traceback", "wrong_code", "invalid_json", "multiline_error", "hang", "wrong_number")
    classes = sorted({c.klass for c in cases})
    table = {k: {m: sum(bool(c.result.get(m)) for c in cases if c.klass == k) for m in metrics} for k in classes}
    for k in classes:
        table[k]["cases"] = sum(c.klass == k for c in cases)
        table[k]["warned"] = sum(bool(c.result.get("warnings")) for c in cases if c.klass == k)
    totals = {m: sum(table[k][m] for k in classes) for m in (*metrics, "cases", "warned")}
    problems = [
        {
            "name": c.name,
            "argv": c.argv,
            **{m: c.result.get(m) for m in metrics},
            "code": c.result.get("code"),
            "stderr": c.result.get("stderr", ""),
        }
        for c in cases
        if any(c.result.get(m) for m in metrics)
    ]
    warned = [{"name": c.name, "warnings": c.result["warnings"][:3]} for c in cases if c.result.get("warnings")]
    slowest = sorted(cases, key=lambda c: -c.result.get("seconds", 0))[:5]
    if args.json:
        print(json.dumps({"totals": totals, "by_class": table, "problems": problems, "warned": warned, "wall_s": wall}))
        return
    head = ["class", "cases", *metrics, "warned"]
    print("  ".join(f"{h:>15}" for h in head))
    for k in classes + ["TOTAL"]:
        row = totals if k == "TOTAL" else table[k]
        print("  ".join([f"{k:>15}"] + [f"{row[h]:>15}" for h in head[1:]]))
    print(
        f"\n{len(cases)} cases in {wall:.0f} s; slowest: "
        + ", ".join(f"{c.name} {c.result.get('seconds', 0):.1f} s" for c in slowest)
    )
    if problems:
        print("\nproblems:")
        for p in problems:
            flags = [m for m in metrics if p[m]]
            print(f"  {p['name']}: {', '.join(flags)} (exit {p['code']}): {p['stderr'][-200:]!r}")
    if warned:
        print("\ncases that answered with a warning:")
        for w in warned:
            print(f"  {w['name']}: {w['warnings'][0][:160]}")


if __name__ == "__main__":
    main()
