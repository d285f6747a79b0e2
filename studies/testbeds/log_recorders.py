"""How real set-ups record a push: turn a clean run of the independent simulator into such logs.

Starts from :func:`studies.testbeds.rigid_sim.simulate` run noise-free at 1 kHz (states at every wrench
update, the 1 ms held wrench), never from the estimator's code, and writes what a recording set-up
would: an F/T sensor at ``ft_hz`` with coloured AR(1) noise and an offset, motion capture at
``mocap_hz`` with white noise, dropouts and timestamp jitter, merged into one table by

- :func:`held_pose_table`: a naive logger, one row per F/T sample with the last pose repeated;
- :func:`mocap_rows_table`: one row per pose sample with the F/T averaged over the interval;

and the faults of :func:`with_glitch` (one motion-capture sample far off), :func:`with_stuck_wrench`
(the F/T frozen for a stretch) and :func:`in_wrong_units` (mm, degrees, ms).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cart.logs import CartLog
from studies.testbeds import dating, rigid_sim


@dataclass(frozen=True)
class Recording:
    """The two sensor streams of one run: pose samples (t, q) and F/T samples (t, gamma), plus the truth."""

    t_pose: np.ndarray
    q: np.ndarray
    t_ft: np.ndarray
    gamma: np.ndarray
    truth: dict


def _ar1(rng: np.random.Generator, n: int, sigma: float, rho10: float) -> np.ndarray:
    """Return n samples of AR(1) noise with std sigma and lag-10 correlation rho10 (stationary start)."""
    a = rho10**0.1
    e = np.empty(n)
    e[0] = rng.normal(0.0, sigma)
    w = rng.normal(0.0, sigma * math.sqrt(1.0 - a * a), n)
    for i in range(1, n):
        e[i] = a * e[i - 1] + w[i]
    return e


def mass_information_bound(
    t: np.ndarray, q: np.ndarray, ft_hz: float, ft_sigma: tuple[float, float, float], ft_rho10: float
) -> float:
    """Return the Cramer-Rao bound of the mass's std from the F/T noise alone: exact motion, known noise.

    An oracle that knows the true motion (``t``, ``q``: the noise-free run) and the F/T noise's AR(1)
    model fits the forward force and the torque at the F/T rate by generalised least squares (prewhitened
    rows: the efficient estimator); the parameters are the cart's six and the four sensor offsets. No
    estimator that sees only the noisy wrench can do better on average. Written from the planar rigid
    body's equations (forward: m (vdot - dx w^2 - dy wdot) + c_v v; yaw: J wdot + m dx v w - m dy vdot
    + c_w w), not from the estimator's code.
    """
    dt = 1.0 / ft_hz
    tg = np.arange(t[0], t[-1], dt)
    qg = np.column_stack([np.interp(tg, t, q[:, i]) for i in range(3)])
    qd = np.gradient(qg, dt, axis=0)
    th = qg[:, 2]
    v = np.cos(th) * qd[:, 0] + np.sin(th) * qd[:, 1]
    w = qd[:, 2]
    vd, wd = np.gradient(v, dt), np.gradient(w, dt)
    z, one = np.zeros_like(v), np.ones_like(v)
    # columns: m, m dx, m dy, J, c_v, c_w, then the offsets (forward in the sensor, world fx, fy, torque)
    fwd = np.column_stack([vd, -w * w, -wd, z, v, z, one, np.cos(th), np.sin(th), z])
    yaw = np.column_stack([z, v * w, -vd, wd, z, w, z, z, z, one])
    a = ft_rho10**0.1
    k = int(ft_hz)  # one second off each end (the differences' edges)
    info = np.zeros((10, 10))
    for rows, sigma in ((fwd[k:-k], ft_sigma[0]), (yaw[k:-k], ft_sigma[2])):
        white = rows[1:] - a * rows[:-1]
        info += white.T @ white / (sigma**2 * (1.0 - a * a))
    return float(np.sqrt(np.linalg.inv(info)[0, 0]))


def record(
    case: rigid_sim.RigidCase,
    ft_hz: float = 500.0,
    mocap_hz: float = 120.0,
    ft_sigma: tuple[float, float, float] = (2.5, 2.5, 0.5),
    ft_rho10: float = 0.7,
    ft_offset: tuple[float, float, float] = (0.15, -0.1, 0.05),
    dropouts: int = 3,
    jitter: float = 2e-4,
    seed: int = 0,
    load_change: tuple[float, float] | None = None,
) -> Recording:
    """Return the two sensor streams of ``case`` (its pose noise stds are used for the motion capture).

    ``load_change``: (time s, factor): the simulator's load change (``RigidCase.load_time``, ``load_factor``).
    """
    rng = np.random.default_rng(seed)
    clean_case = replace(
        case, rate_hz=1000.0, jitter=0.0, pos_std=0.0, theta_std=0.0, force_std=0.0, torque_std=0.0, vel_std=None
    )
    if load_change is not None:
        clean_case = replace(clean_case, load_time=load_change[0], load_factor=load_change[1])
    log, truth = rigid_sim.simulate(clean_case)
    if load_change is not None:
        truth["m_after"] = truth["load_change"]["m_after"]
    else:
        truth["mass_std_bound"] = mass_information_bound(log.t, log.q, ft_hz, ft_sigma, ft_rho10)
    t_end = float(log.t[-1])
    t_ft = np.arange(0.0, t_end, 1.0 / ft_hz) + rng.uniform(0, 1.0 / ft_hz)
    t_ft = np.sort(t_ft + rng.normal(0, jitter, len(t_ft)))
    t_ft = t_ft[(t_ft > 0) & (t_ft < t_end)]
    tick = np.minimum((t_ft / rigid_sim.WRENCH_PERIOD).astype(int), len(log.t) - 1)
    gamma = log.gamma[tick] + np.column_stack(
        [_ar1(rng, len(t_ft), s, ft_rho10) + o for s, o in zip(ft_sigma, ft_offset)]
    )
    t_m = np.arange(0.0, t_end, 1.0 / mocap_hz) + rng.uniform(0, 1.0 / mocap_hz)
    t_m = np.sort(t_m + rng.normal(0, jitter, len(t_m)))
    t_m = t_m[(t_m > 0) & (t_m < t_end)]
    keep = np.ones(len(t_m), dtype=bool)
    for _ in range(dropouts):
        i0 = int(rng.integers(len(t_m) // 10, len(t_m) * 9 // 10))
        keep[i0 : i0 + int(rng.integers(15, 60))] = False
    t_m = t_m[keep]
    q = np.column_stack([np.interp(t_m, log.t, log.q[:, i]) for i in range(3)])
    q += rng.standard_normal(q.shape) * [case.pos_std, case.pos_std, case.theta_std]
    return Recording(t_m, q, t_ft, gamma, truth)


def held_pose_table(rec: Recording) -> CartLog:
    """Return the naive logger's table: a row per F/T sample, the last pose (held, also through dropouts)."""
    t = rec.t_ft[rec.t_ft >= rec.t_pose[0]]
    idx = np.searchsorted(rec.t_pose, t, side="right") - 1
    g = rec.gamma[rec.t_ft >= rec.t_pose[0]]
    return CartLog(t=np.round(t, 6), q=rec.q[idx], gamma=g, metadata={"merging": "hold_last_mocap"})


def mocap_rows_table(rec: Recording) -> CartLog:
    """Return a row per pose sample with the F/T averaged over (previous pose time, this pose time]."""
    edges = np.searchsorted(rec.t_ft, rec.t_pose, side="right")
    csum = np.vstack([np.zeros((1, 3)), np.cumsum(rec.gamma, axis=0)])
    lo = np.r_[max(edges[0] - 4, 0), edges[:-1]]
    cnt = np.maximum(edges - lo, 1)
    g = (csum[edges] - csum[lo]) / cnt[:, None]
    return CartLog(t=np.round(rec.t_pose, 6), q=rec.q, gamma=g, metadata={"merging": "mocap_times_ft_mean"})


def with_glitch(log: CartLog, at: float, size: float = 5.0) -> CartLog:
    """Return ``log`` with one motion-capture sample ``size`` metres off (x) near time ``at``."""
    q = log.q.copy()
    i = int(np.searchsorted(log.t, at))
    q[i, 0] += size
    return replace(log, q=q)


def with_stuck_wrench(log: CartLog, t0: float, seconds: float = 10.0) -> CartLog:
    """Return ``log`` with the wrench frozen at its value at ``t0`` for ``seconds``."""
    g = log.gamma.copy()
    m = (log.t >= t0) & (log.t < t0 + seconds)
    g[m] = g[np.argmax(m)]
    return replace(log, gamma=g)


def in_wrong_units(log: CartLog, mistake: str) -> CartLog:
    """Return ``log`` with one unit mistake: ``"mm"`` positions, ``"deg"`` heading, ``"ms"`` time."""
    if mistake == "mm":
        return replace(log, q=log.q * [1000.0, 1000.0, 1.0], qd=None)
    if mistake == "deg":
        return replace(log, q=np.column_stack([log.q[:, :2], np.degrees(log.q[:, 2])]), qd=None)
    if mistake == "ms":
        return replace(log, t=log.t * 1000.0, qd=None)
    raise ValueError(f"unknown unit mistake {mistake!r} (mm, deg, ms)")


def generate(n: int, seed0: int, out_dir: str) -> dict[str, dict]:
    """Write, for seeds seed0 .. seed0 + n - 1, the held-pose and mocap-rows tables of one random case each,
    the mocap-rows table with a 5 m glitch and with the F/T stuck for 10 s, and ``truth.json``; return the truth."""
    import json
    import os

    from cart.logs import write_log

    os.makedirs(out_dir, exist_ok=True)
    truth: dict[str, dict] = {}
    for i in range(n):
        case = rigid_sim.random_case(seed0 + i, duration=45.0)
        rng = np.random.default_rng(seed0 + i)
        rec = record(case, ft_rho10=float(rng.uniform(0.6, 0.8)), seed=seed0 + i)
        rows = mocap_rows_table(rec)
        logs = {
            f"held{i:02d}": held_pose_table(rec),
            f"rows{i:02d}": rows,
            f"glitch{i:02d}": with_glitch(rows, float(rng.uniform(10, 35))),
            f"stuck{i:02d}": with_stuck_wrench(rows, float(rng.uniform(10, 25))),
        }
        for name, log in logs.items():
            write_log(os.path.join(out_dir, name + ".csv.gz"), log)
            rec_truth = {k: v for k, v in rec.truth.items() if k != "clean"}
            truth[name] = {k: rec_truth[k] for k in ("m", "dx", "dy", "I_about_com", "mass_std_bound")}
    with open(os.path.join(out_dir, "truth.json"), "w", encoding="utf-8") as fh:
        json.dump(truth, fh, indent=1)
    return truth


def evaluate(out_dir: str) -> dict[str, dict[str, float]]:
    """Return, per kind of log written by :func:`generate` (held, rows, glitch, stuck), the share of logs with
    the mass within 5 % / the truth within 3 std / model fits, and the largest mass error (%), from
    :func:`cart.estimate_report.estimate_log`; glitch and stuck also against the clean rows log.

    Against the information in the log (``mass_std_bound``, :func:`mass_information_bound`): the share of
    logs whose bound is above 2.5 % of the mass (5 % is then within 2 bound-std: no estimator gets within
    5 % on all of them), the share within 5 % among the others, the share within 3 bounds of the truth,
    and the median ratio of the reported std to the bound."""
    import json
    import os

    from cart.estimate_report import estimate_log

    with open(os.path.join(out_dir, "truth.json"), encoding="utf-8") as fh:
        truth = json.load(fh)
    res = {name: estimate_log(os.path.join(out_dir, name + ".csv.gz")) for name in sorted(truth)}
    out: dict[str, dict[str, float]] = {}
    for kind in ("held", "rows", "glitch", "stuck"):
        names = [n for n in res if n.startswith(kind)]
        err = [res[n].params.m / truth[n]["m"] - 1 for n in names]
        z = [abs(res[n].params.m - truth[n]["m"]) / res[n].std["mass"] for n in names]
        vs_rows = [abs(res[n].params.m / res["rows" + n[len(kind) :]].params.m - 1) for n in names]
        out[kind] = {
            "logs": len(names),
            "within_5pct": float(np.mean(np.abs(err) < 0.05)),
            "within_3std": float(np.mean(np.array(z) < 3)),
            "model_fits": float(np.mean([res[n].model_fits for n in names])),
            "max_abs_error_pct": float(100 * np.max(np.abs(err))),
            "max_change_vs_rows_pct": float(100 * np.max(vs_rows)),
            **_against_bound(names, res, truth),
        }
    return out


def _against_bound(names: list[str], res: dict, truth: dict) -> dict[str, float]:
    """Return the figures of :func:`evaluate` against each log's mass information bound."""
    if not all("mass_std_bound" in truth[n] for n in names):
        return {}
    bound = np.array([truth[n]["mass_std_bound"] for n in names])
    m = np.array([truth[n]["m"] for n in names])
    est = np.array([res[n].params.m for n in names])
    std = np.array([res[n].std["mass"] for n in names])
    limited = bound / m > 0.025
    within = np.abs(est / m - 1) < 0.05
    return {
        "bound_above_2.5pct": float(np.mean(limited)),
        "within_5pct_where_bound_below_2.5pct": float(np.mean(within[~limited])) if np.any(~limited) else 1.0,
        "within_3_bounds": float(np.mean(np.abs(est - m) < 3 * bound)),
        "median_std_over_bound": float(np.median(std / bound)),
    }


def load_change_case(seed: int) -> rigid_sim.RigidCase:
    """Return :func:`load_change_study`'s case of ``seed``: 40-60 s, a load of factor 0.6, 0.7, 1.4 or 1.6 at
    35-65 % of the log."""
    rng = np.random.default_rng(seed)
    dur = float(rng.uniform(40, 60))
    tc = float(rng.uniform(0.35, 0.65) * dur)
    fac = float(rng.choice([0.6, 0.7, 1.4, 1.6]))
    return rigid_sim.random_case(seed, duration=dur, load_time=tc, load_factor=fac)


def load_change_study(n: int, seed0: int) -> dict[str, float]:
    """Return the share of rigid_sim logs (40-60 s, a load of factor 0.6, 0.7, 1.4 or 1.6 at 35-65 % of the log)
    whose change `estimate` finds within 1 s with the after-mass within 5 %, the number of the others whose change
    lies in a reported stretch wider than 2 s (:func:`studies.testbeds.mujoco_loads.in_wide_stretch`) and of those
    whose ``t0_range`` holds it (:func:`studies.testbeds.mujoco_loads.holds_truth`), and the share of the same carts
    without a change where it reports one; a log ``estimate`` refuses counts as ``refused`` (and as a miss when it has
    a change: :func:`studies.testbeds.mujoco_loads.estimated_segments`). Each change log's line is printed as it comes
    (JSON)."""
    import json

    from studies.testbeds.mujoco_loads import estimated_segments, holds_truth, in_wide_stretch

    found = false = wide = held = refused = 0
    for i in range(n):
        case = load_change_case(seed0 + i)
        tc, dur = float(case.load_time or 0.0), case.duration
        log, truth = rigid_sim.simulate(case)
        segs = estimated_segments(log)
        m_after = truth["load_change"]["m_after"]
        last = segs[-1]
        ok = bool(
            len(segs) >= 2
            and abs(last["t0"] - tc) < 1.0
            and last["mass"] is not None
            and abs(last["mass"] / m_after - 1) < 0.05
        )
        found += ok
        wide += not ok and in_wide_stretch(list(segs), tc, m_after)
        held += not ok and holds_truth(list(segs), tc)
        row = {"seed": seed0 + i, "t_change": tc, "found": ok, "t0": last["t0"], "t0_range": last.get("t0_range")}
        print(json.dumps({**row, "mass": last["mass"], "m_after": m_after, "refused": last.get("refused")}), flush=True)
        log0, _ = rigid_sim.simulate(rigid_sim.random_case(seed0 + i, duration=dur))
        segs0 = estimated_segments(log0)
        false += len(segs0) > 1
        refused += ("refused" in last) + ("refused" in segs0[-1])
    return {
        "logs": n,
        "found_within_1s_5pct": found / n,
        "missed_in_wide_stretch_holding_truth": wide,
        "missed_with_t0_range_holding_truth": held,
        "false_changes": false / n,
        "refused": refused,
    }


def after_mass_row(seed: int) -> dict[str, Any]:
    """Return one load-change log's (:func:`load_change_case`) after-mass errors (% of the truth): ``reported``
    (``estimate``'s last segment), ``at_truth`` (:func:`cart.identify.identify` on the log from the true change
    plus one cut-off period, as ``estimate`` identifies a side) and its ``std``; the before-mass's too; and the
    stretch around the true change that the motion cannot date (:func:`cart.segments.information_stretch`, s
    from the change)."""
    from cart import segments
    from cart.estimate_report import estimate_log
    from cart.identify import identify

    case = load_change_case(seed)
    tc, fac = float(case.load_time or 0.0), case.load_factor
    log, truth = rigid_sim.simulate(case)
    m0, m1 = float(truth["m"]), float(truth["load_change"]["m_after"])
    segs = estimate_log(log).segments
    res = identify(log)
    guard, t0, t1 = 1.0 / res.cutoff_hz, float(log.t[0]), float(log.t[-1])
    after = identify(segments.slice_log(log, tc + guard, t1))
    before = identify(segments.slice_log(log, t0, tc - guard))
    lo, hi = segments.information_stretch_of(res, tc)
    pct = lambda m, truth_m: 100.0 * (m / truth_m - 1.0)  # noqa: E731
    return {
        "seed": seed,
        "factor": fac,
        "t_change": tc,
        "after_s": t1 - tc,
        "m_after": m1,
        "found": len(segs) >= 2,
        "t0_off": float(segs[-1]["t0"]) - tc if len(segs) >= 2 else math.nan,
        "reported": pct(float(segs[-1]["mass"]), m1) if len(segs) >= 2 else math.nan,
        "at_truth": pct(after.params.m, m1),
        "std": 100.0 * after.std["mass"] / m1,
        "before_at_truth": pct(before.params.m, m0),
        "before_std": 100.0 * before.std["mass"] / m0,
        "stretch": (lo - tc, hi - tc),
    }


def after_mass_study(n: int, seed0: int) -> dict[str, float]:
    """Return the after-mass errors of :func:`after_mass_row` over ``n`` load-change logs: mean and median of the
    error at the true change (%), mean and RMS of it over its std (z), the same for the before-mass, the mean of
    ``estimate``'s reported error on the changes it finds, and the share one may expect of a method that dates
    each change at the middle of its :func:`cart.segments.information_stretch` (hit within 1 s with probability
    min(1, 2 / width) for a change anywhere in it) and weighs the after-segment with that std, unbiased (within
    5 % with probability erf(5 / (std sqrt 2))). Each log's row is printed as it comes (JSON)."""
    import json

    rows = []
    for i in range(n):
        r = after_mass_row(seed0 + i)
        print(json.dumps(r), flush=True)
        rows.append(r)
    err, std = np.array([r["at_truth"] for r in rows]), np.array([r["std"] for r in rows])
    err0, std0 = np.array([r["before_at_truth"] for r in rows]), np.array([r["before_std"] for r in rows])
    p_date = np.array([dating.p_date(r["stretch"][1] - r["stretch"][0]) for r in rows])
    p_mass = np.array([dating.p_mass(sd) for sd in std])
    rep = np.array([r["reported"] for r in rows if r["found"]])
    return {
        "logs": n,
        "after_error_mean_pct": float(err.mean()),
        "after_error_median_pct": float(np.median(err)),
        "after_z_mean": float(np.mean(err / std)),
        "after_z_rms": float(np.sqrt(np.mean((err / std) ** 2))),
        "after_within_5pct_at_truth": float(np.mean(np.abs(err) < 5.0)),
        "before_error_mean_pct": float(err0.mean()),
        "before_z_mean": float(np.mean(err0 / std0)),
        "before_z_rms": float(np.sqrt(np.mean((err0 / std0) ** 2))),
        "reported_error_mean_pct": float(rep.mean()) if len(rep) else math.nan,
        "expected_share_dated_and_weighed": float(np.mean(p_date * p_mass)),
    }


if __name__ == "__main__":  # python -m studies.testbeds.log_recorders N SEED0 OUT_DIR | --evaluate OUT_DIR
    import json
    import sys

    if len(sys.argv) == 3 and sys.argv[1] == "--evaluate":
        print(json.dumps(evaluate(sys.argv[2]), indent=1))
    elif len(sys.argv) == 4 and sys.argv[1] == "--after-mass":
        print(json.dumps(after_mass_study(int(sys.argv[2]), int(sys.argv[3])), indent=1))
    elif len(sys.argv) == 4 and sys.argv[1] == "--load-changes":
        print(json.dumps(load_change_study(int(sys.argv[2]), int(sys.argv[3])), indent=1))
    elif len(sys.argv) == 4:
        generate(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3])
    else:
        sys.exit(
            "usage: python -m studies.testbeds.log_recorders N SEED0 OUT_DIR | --evaluate OUT_DIR "
            "| --load-changes N SEED0 | --after-mass N SEED0"
        )
