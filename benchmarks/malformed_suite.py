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
    bad[20] = bad[19]
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
    return cases


# -- running ------------------------------------------------------------------------------------
def _strict_json(text: str):
    def refuse(name):
        raise ValueError(f"non-strict constant {name}")

    return json.loads(text, parse_constant=refuse)


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
    if "--json" in case.argv and proc.returncode == 0:
        try:
            obj = _strict_json(proc.stdout)
            if isinstance(obj, dict) and obj.get("warnings"):
                r["warnings"] += [str(w) for w in obj["warnings"]]
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
    metrics = ("traceback", "wrong_code", "invalid_json", "multiline_error", "hang")
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
