"""Effect-free logs of the independent simulator with F/T noise of four colours, and their evaluation.

python -m studies.testbeds.coloured_noise N SEED0 DIR   # DIR/{white,ar1,pink,brown}_SEED.csv.gz, DIR/truth.json
python -m studies.testbeds.coloured_noise --evaluate DIR
python -m studies.testbeds.coloured_noise --slow N SEED0 DIR     # DIR/{ar1_slow,drift}_SEED.csv.gz, DIR/truth.json
python -m studies.testbeds.coloured_noise --hidden N SEED0 DIR   # hidden-effect logs, and with pink F/T noise added

Each seed: one :func:`studies.testbeds.rigid_sim.random_case` cart (40-60 s), run noise-free at 1 kHz; for each
colour the F/T is sampled at 200-500 Hz with noise of 0.5-3 N (force) and 0.05-0.3 N m (torque) and offsets up
to 0.3 N / 0.03 N m: white; AR(1) with a correlation time of 0.05-2 s (log-uniform); pink (1 / f, white noise
shaped by 1 / sqrt(f) in the frequency domain); brown (a random walk, its RMS the level). Written alternately
as a single-rate table (the pose at the F/T instants) and as mocap rows (120 Hz motion capture, the F/T averaged
over each interval: :func:`studies.testbeds.log_recorders.mocap_rows_table`). Nothing here uses the
estimator's code.
"""

from __future__ import annotations

import json
import math
import os
import sys
from dataclasses import replace

import numpy as np

from cart.logs import CartLog, write_log
from studies.testbeds import log_recorders, rigid_sim

COLOURS = ("white", "ar1", "pink", "brown")
#: Slowly decorrelating F/T noise (``--slow``): AR(1) with a correlation time of 0.5, 1, 2 or 5 s (one per seed,
#: in turn), and white noise plus a random-walk offset drift of 0.5-2 N (its RMS over the log).
SLOW_COLOURS = ("ar1_slow", "drift")
SLOW_TAUS = (0.5, 1.0, 2.0, 5.0)


def _clean(seed: int) -> tuple[CartLog, dict, rigid_sim.RigidCase]:
    """Return the noise-free 1 kHz run of seed's random case, its truth and the case (pose noise stds)."""
    rng = np.random.default_rng(seed + 777)
    case = rigid_sim.random_case(seed, duration=float(rng.uniform(40.0, 60.0)))
    clean = replace(
        case, rate_hz=1000.0, jitter=0.0, pos_std=0.0, theta_std=0.0, force_std=0.0, torque_std=0.0, vel_std=None
    )
    log, truth = rigid_sim.simulate(clean)
    return log, {k: truth[k] for k in ("m", "dx", "dy", "I_about_com")}, case


def coloured(kind: str, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
    """Return ``n`` samples (period ``dt``) of unit-std noise of colour ``kind`` (see the module's doc)."""
    w = rng.standard_normal(n)
    if kind == "white":
        e = w
    elif kind == "ar1":
        a = math.exp(-dt / math.exp(rng.uniform(math.log(0.05), math.log(2.0))))
        e = np.empty(n)
        e[0] = w[0]
        for i in range(1, n):
            e[i] = a * e[i - 1] + math.sqrt(1.0 - a * a) * w[i]
    elif kind == "pink":
        f = np.fft.rfftfreq(n, dt)
        spec = np.fft.rfft(w)
        spec[1:] /= np.sqrt(f[1:])
        spec[0] = 0.0
        e = np.fft.irfft(spec, n)
    elif kind == "brown":
        e = np.cumsum(w)
        e = e - np.mean(e)
    else:
        raise ValueError(f"unknown colour {kind!r} ({', '.join(COLOURS)})")
    return e / np.std(e)


def slow_noise(kind: str, n: int, dt: float, tau: float, rng: np.random.Generator) -> np.ndarray:
    """Return (n, 3) F/T noise of a ``SLOW_COLOURS`` colour: AR(1) of correlation time ``tau`` s and std 0.5-3 N
    (0.05-0.3 N m), or white noise of that level plus a random-walk drift of RMS 0.5-2 N (0.05-0.2 N m)."""
    scale = np.array([1.0, 1.0, 0.1])
    level = np.array([rng.uniform(0.5, 3.0), rng.uniform(0.5, 3.0), rng.uniform(0.5, 3.0)]) * scale
    if kind == "ar1_slow":
        a = math.exp(-dt / tau)
        w = rng.standard_normal((n, 3)) * math.sqrt(1.0 - a * a)
        e = np.empty((n, 3))
        e[0] = rng.standard_normal(3)
        for i in range(1, n):
            e[i] = a * e[i - 1] + w[i]
        return e * level
    if kind != "drift":
        raise ValueError(f"unknown colour {kind!r} ({', '.join(SLOW_COLOURS)})")
    walk = np.cumsum(rng.standard_normal((n, 3)), axis=0)
    walk = (walk - walk.mean(axis=0)) / walk.std(axis=0)
    return rng.standard_normal((n, 3)) * level + walk * rng.uniform(0.5, 2.0, 3) * scale


def _table(
    run: CartLog, case: rigid_sim.RigidCase, kind: str, mocap_rows: bool, rng: np.random.Generator, tau: float = 0.0
) -> CartLog:
    """Return one log of the clean ``run`` with F/T noise of colour ``kind``, as single-rate or mocap-rows table.

    ``tau``: the correlation time of the ``ar1_slow`` colour; slow colours carry offsets of up to 3 N / 0.3 N m."""
    t, q, g = run.t, run.q, run.gamma
    hz = float(rng.uniform(200.0, 500.0))
    t_ft = np.arange(0.0, float(t[-1]), 1.0 / hz) + rng.uniform(0, 1.0 / hz)
    t_ft = t_ft[t_ft < t[-1]]
    tick = np.minimum((t_ft / rigid_sim.WRENCH_PERIOD).astype(int), len(t) - 1)
    if kind in SLOW_COLOURS:
        offset = np.array([rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0), rng.uniform(-0.3, 0.3)])
        gamma = g[tick] + slow_noise(kind, len(t_ft), 1.0 / hz, tau, rng) + offset
    else:
        level = np.array([rng.uniform(0.5, 3.0), rng.uniform(0.5, 3.0), rng.uniform(0.05, 0.3)])
        offset = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-0.03, 0.03)])
        noise = np.column_stack([coloured(kind, len(t_ft), 1.0 / hz, rng) for _ in range(3)])
        gamma = g[tick] + noise * level + offset
    pose_std = [case.pos_std, case.pos_std, case.theta_std]
    t_pose = t_ft
    if mocap_rows:
        t_pose = np.arange(0.0, float(t[-1]), 1.0 / 120.0) + rng.uniform(0, 1.0 / 120.0)
        t_pose = t_pose[(t_pose > 0) & (t_pose < t[-1])]
    qq = np.column_stack([np.interp(t_pose, t, q[:, i]) for i in range(3)])
    qq = qq + rng.standard_normal(qq.shape) * pose_std
    if mocap_rows:
        return log_recorders.mocap_rows_table(log_recorders.Recording(t_pose, qq, t_ft, gamma, {}))
    return CartLog(t=np.round(t_ft, 6), q=qq, gamma=gamma)


def generate(n: int, seed0: int, out_dir: str, colours: tuple[str, ...] = COLOURS) -> dict[str, dict]:
    """Write the ``colours``' logs of seeds seed0 .. seed0 + n - 1 and ``truth.json``; return the truth."""
    os.makedirs(out_dir, exist_ok=True)
    truth: dict[str, dict] = {}
    for seed in range(seed0, seed0 + n):
        run, tr, case = _clean(seed)
        rng = np.random.default_rng(seed + 4242)
        tau = SLOW_TAUS[seed % len(SLOW_TAUS)]
        for j, kind in enumerate(colours):
            rows = bool((seed + j) % 2)
            name = f"{kind}_{seed}"
            write_log(os.path.join(out_dir, name + ".csv.gz"), _table(run, case, kind, rows, rng, tau))
            truth[name] = {**tr, "kind": kind, "table": "mocap_rows" if rows else "single_rate"}
            if kind == "ar1_slow":
                truth[name]["tau"] = tau
    with open(os.path.join(out_dir, "truth.json"), "w", encoding="utf-8") as fh:
        json.dump(truth, fh, indent=1)
    return truth


HIDDEN = ("coulomb_friction", "lateral_slip", "payload_change", "time_delay")


def hidden(n: int, seed0: int, out_dir: str) -> dict[str, dict]:
    """Write :func:`studies.testbeds.hidden_effects.random_case` logs of each of ``HIDDEN`` for seeds seed0 ..
    seed0 + n - 1, each also with pink F/T noise (0.5-3 N, 0.05-0.3 N m) added (``pink_`` names) and with a
    random-walk offset drift of 0.5-2 N (0.05-0.2 N m) RMS added (``drift_`` names); return the truth."""
    from studies.testbeds import hidden_effects

    os.makedirs(out_dir, exist_ok=True)
    truth: dict[str, dict] = {}
    for seed in range(seed0, seed0 + n):
        for j, effect in enumerate(HIDDEN):
            rng = np.random.default_rng([seed, j])
            case = hidden_effects.random_case(effect, rng)
            log = case.measured
            dt = float(np.median(np.diff(log.t)))
            level = np.array([rng.uniform(0.5, 3.0), rng.uniform(0.5, 3.0), rng.uniform(0.05, 0.3)])
            pink = np.column_stack([coloured("pink", len(log.t), dt, rng) for _ in range(3)]) * level
            walk = np.column_stack([coloured("brown", len(log.t), dt, rng) for _ in range(3)])
            drift = walk * rng.uniform(0.5, 2.0, 3) * np.array([1.0, 1.0, 0.1])
            for prefix, out in (
                ("", log),
                ("pink_", replace(log, gamma=log.gamma + pink)),
                ("drift_", replace(log, gamma=log.gamma + drift)),
            ):
                write_log(os.path.join(out_dir, f"{prefix}{effect}_{seed}.csv.gz"), out)
                truth[f"{prefix}{effect}_{seed}"] = {"m": case.params.m, "kind": prefix + effect}
    with open(os.path.join(out_dir, "truth.json"), "w", encoding="utf-8") as fh:
        json.dump(truth, fh, indent=1)
    return truth


def evaluate(out_dir: str) -> dict[str, dict[str, float]]:
    """Return, per colour, the logs, model fits, mass within 5 %, truth within 3 std and the largest mass error (%)."""
    from cart.errors import CartError
    from cart.estimate_report import estimate_log

    with open(os.path.join(out_dir, "truth.json"), encoding="utf-8") as fh:
        truth = json.load(fh)
    out: dict[str, dict[str, float]] = {}
    for name, tr in sorted(truth.items()):
        row = out.setdefault(
            tr["kind"], {"logs": 0, "model_fits": 0, "within_5pct": 0, "within_3std": 0, "worst_pct": 0}
        )
        row["logs"] += 1
        try:
            rep = estimate_log(os.path.join(out_dir, name + ".csv.gz")).to_dict()
        except CartError:
            continue
        row["model_fits"] += bool(rep["model_fits"])
        if rep["mass"] is None:
            continue
        err = rep["mass"] - tr["m"]
        row["within_5pct"] += abs(err) < 0.05 * tr["m"]
        row["within_3std"] += abs(err) < 3.0 * rep["std"]["mass"]
        row["worst_pct"] = max(row["worst_pct"], round(100.0 * abs(err) / tr["m"], 1))
    return out


if __name__ == "__main__":
    if sys.argv[1] == "--hidden":
        hidden(int(sys.argv[2]), int(sys.argv[3]), sys.argv[4])
    elif sys.argv[1] == "--slow":
        generate(int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], SLOW_COLOURS)
    elif sys.argv[1] == "--evaluate":
        for colour, row in evaluate(sys.argv[2]).items():
            print(colour, row)
    else:
        generate(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3])
