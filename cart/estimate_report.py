"""The verdict of `cartpush estimate` as a library result: :func:`estimate_log` -> :class:`EstimateReport`.

Everything `cartpush estimate --json` prints is computed here (the command line only formats it, and
`cartpush batch` calls the same function): the parameters and their std, ``model_fits`` with
``nis_mean`` (the paper's EKF, eq. 8-20, run over the log with the parameters held), the warnings,
the log's sensor streams (:mod:`cart.streams`), the unit check (:mod:`cart.units`), the parameters
the log cannot identify (``null`` with a reason) and the load segments (:mod:`cart.segments`).

``method="ekf"`` runs the paper's EKF; its answer is checked against the least-squares estimate
(whose wrench-noise bias is zero): a difference beyond ``EKF_BIAS_Z`` combined std means the EKF's std
does not cover its bias, and ``model_fits`` is false with a warning naming the bias.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cart.errors import CartError, NumericalError, ParameterError
from cart.logs import CartLog, read_log
from cart.noise_model import SpectralNoise, lag_correlation
from cart.params import CartParams
from cart.streams import Streams, box_average, split_streams
from cart.units import (
    check_declared_units,
    check_torque_origin,
    torque_origin_warning,
    check_units,
    check_wrench_frame,
    wrench_frame_warning,
)

#: Mean NIS above which the EKF's innovations do not fit the 6-dof measurement (about 6 expected).
NIS_MISFIT = 18.0
#: An EKF answer this many combined std from the least-squares one is a bias its std does not cover.
EKF_BIAS_Z = 3.0
#: Mass or inertia whose std exceeds this share of the value (its ± larger than itself): not identified.
MAX_RELATIVE_STD = 1.0
#: Mass whose std exceeds this share of the value: known only roughly, and a warning says so (:func:`weak_mass_note`).
WEAK_MASS_STD = 0.05
#: Half-size (m) of the largest cart (a hospital bed) when the log cannot give the body's size.
MAX_HALF_SIZE = 1.0
#: Samples beyond which the EKF check runs on CHECK_CHUNKS evenly spaced stretches of this total length.
CHECK_SAMPLES = 8_000
CHECK_CHUNKS = 4
#: Largest --mass-guess (kg) and |--com-guess| coordinate (m): `cartpush push`'s bounds on its own guesses.
MAX_MASS_GUESS = 1e4
MAX_COM_GUESS = 5.0
#: Largest --sigma-guess (N s/m, N m s/rad): a hundred times a loaded hospital bed's rolling resistance.
MAX_SIGMA_GUESS = 1e4
#: An EKF answer beyond these has diverged (:func:`ekf_divergence`): a mass above this multiple of its guess,
#: a CoM farther than this (m) from {b}'s origin, an inertia above this (kg m^2).
DIVERGED_MASS_RATIO = 100.0
DIVERGED_COM = 10.0
DIVERGED_INERTIA = 1e6
#: ... or a mass this many times (or this fraction of) the least-squares one where that fit weighs the cart
#: to within a tenth: no bias of the EKF's errors in variables comes near (sim1: 58.4 kg for 55.1)
DIVERGED_LS_RATIO = 10.0


@dataclass(frozen=True)
class EstimateReport:
    """The result of :func:`estimate_log`: what `cartpush estimate --json` prints (:meth:`to_dict`).

    ``params``/``std``: the estimate and its 1-sigma std; ``not_identified``: parameter name -> reason
    (printed as ``null``); ``fields``: the method's own diagnostics (residual_ratio, cutoff_hz, ...);
    ``segments``: one entry per stretch of constant load (one for a log without a load change).
    """

    method: str
    params: CartParams
    std: Mapping[str, Any]
    nis_mean: float
    model_fits: bool
    warnings: tuple[str, ...]
    not_identified: dict[str, str] = field(default_factory=dict)
    fields: dict[str, Any] = field(default_factory=dict)
    streams: Streams | None = field(default=None, repr=False)
    segments: tuple[dict[str, Any], ...] = ()

    def value(self, name: str) -> Any:
        """Return the JSON value of parameter ``name`` (None when it is not identified)."""
        if name in self.not_identified:
            return None
        p = self.params
        if name == "com":
            return com_value(p, self.not_identified)
        return {"mass": p.m, "com": [p.dx, p.dy], "inertia": p.I, "sigma": p.sigma, "sigma_yaw": p.sigma_yaw}[name]

    def to_dict(self) -> dict[str, Any]:
        """Return the JSON fields of `cartpush estimate --json` (existing names kept, new ones added)."""
        out: dict[str, Any] = {"method": self.method}
        for name in ("mass", "com", "inertia", "sigma", "sigma_yaw"):
            out[name] = self.value(name)
        out["std"] = self.std
        out["nis_mean"] = self.nis_mean
        out["model_fits"] = self.model_fits
        out.update(self.fields)
        out["not_identified"] = dict(self.not_identified)
        out["streams"] = self.streams.to_dict() if self.streams is not None else None
        out["segments"] = list(self.segments)
        out["warnings"] = list(self.warnings)
        return out


def com_scale(params: CartParams, std: Mapping[str, Any]) -> float:
    """Return the std (m) of a CoM coordinate known only to lie within the body: the most the log must beat.

    A CoM spread uniformly over a body of half-size ``h`` has std ``h / sqrt(3)``; the body's half-size is a
    uniform bar's, ``sqrt(3)`` radii of gyration, from the largest inertia the log allows (the estimate plus 2
    std) and at most ``MAX_HALF_SIZE``: the scale is ``min(sqrt((I + 2 std_I) / m), MAX_HALF_SIZE / sqrt(3))``.
    """
    i_upper = params.I + 2.0 * std["inertia"]
    return min(MAX_HALF_SIZE / math.sqrt(3.0), math.sqrt(max(i_upper, 0.0) / params.m))


def not_identified(params: CartParams, std: Mapping[str, Any]) -> dict[str, str]:
    """Return parameter -> reason for the parameters whose std is larger than the object allows.

    Mass and inertia: std above ``MAX_RELATIVE_STD`` times the value. Each CoM coordinate (``dx``, ``dy``)
    on its own: std above :func:`com_scale` (the log says less about it than that the CoM lies within the
    body); ``com`` too when neither is identified.
    """
    out: dict[str, str] = {}
    if std["mass"] > MAX_RELATIVE_STD * params.m:
        out["mass"] = f"std {std['mass']:.3g} kg for {params.m:.3g} kg: little forward acceleration above the noise"
    if std["inertia"] > MAX_RELATIVE_STD * params.I:
        out["inertia"] = (
            f"std {std['inertia']:.3g} kg m^2 for {params.I:.3g} kg m^2: little yaw acceleration above the noise"
        )
    scale = max(com_scale(params, std), 1e-3)
    for name, s_k, why in zip(
        ("dx", "dy"), std["com"], ("the cart does not turn enough", "the cart does not turn or accelerate enough")
    ):
        if s_k > scale:
            out[name] = (
                f"std {s_k:.3g} m, more than a CoM known only to lie within the body ({scale:.3g} m): {why} "
                "above the noise"
            )
    if "dx" in out and "dy" in out:
        out["com"] = f"dx: {out['dx']}; dy: {out['dy']}"
    return out


def com_value(params: CartParams, unknown: Mapping[str, str]) -> list[float | None] | None:
    """Return the JSON CoM: [dx, dy] with a coordinate not identified as None; None when neither is."""
    if "com" in unknown:
        return None
    return [None if "dx" in unknown else params.dx, None if "dy" in unknown else params.dy]


#: The reader's plausibility notes that a jump of the pose explains (:func:`cart.logs.plausibility_warnings`).
_JUMP_NOTES = ("heading changes by", "the pose moves at", "the pose accelerates at")


def log_notes(log: CartLog, streams: Streams) -> list[str]:
    """Return the reader's notes on ``log``, less those on fast steps when the pose jumps (the jump's note names them:
    a step of a joined jump is neither a heading in degrees nor positions in millimetres)."""
    if not streams.jumps:
        return list(log.warnings)
    return [n for n in log.warnings if not n.startswith(_JUMP_NOTES)]


def stream_notes(streams: Streams) -> list[str]:
    """Return the streams' notes (:meth:`Streams.warnings`) and, in a single-rate table, the rows that repeated a
    pose while the cart moved (a dropout written as a held pose, or a stuck pose), left out of the pose."""
    notes = streams.warnings()
    if streams.held_rows and not streams.multi_rate:
        notes.append(
            f"{streams.held_rows} rows repeat a pose while the cart moved (a motion-capture dropout or a stuck "
            "pose): left out of the pose"
        )
    return notes


def check_log(log: CartLog, streams: Streams) -> CartLog:
    """Return the log the EKF check runs on: at the pose instants, the wrench averaged over each interval.

    A log whose table already is one stream per row (nothing held, stuck or dropped) is returned as is.
    """
    if not (streams.multi_rate or streams.held_rows or streams.stuck or streams.glitches or streams.jumps):
        return log
    t = streams.pose.t
    dt = streams.pose.period
    w = streams.wrench
    g = (
        box_average(w.t, w.values, t, dt)
        if w.period < dt / 1.5
        else np.column_stack([np.interp(t, w.t, w.values[:, i]) for i in range(3)])
    )
    keep = np.ones(len(t), dtype=bool)
    for t0, t1 in streams.stuck:
        keep &= ~((t >= t0) & (t <= t1))
    qd = log.qd[streams.pose.rows] if (log.qd is not None and not streams.multi_rate and not streams.jumps) else None
    return CartLog(
        t=t[keep],
        q=streams.pose.values[keep],
        gamma=g[keep],
        qd=None if qd is None else qd[keep],
        source=log.source,
        metadata=log.metadata,
    )


def _innovation(log: CartLog, streams: Streams, params: CartParams, noise: dict[str, float]) -> tuple[float, int, str]:
    """Return (mean NIS, rejected samples, a warning or "") of the EKF check with ``params`` held."""
    from cart.identify import innovation_check
    from cart.segments import slice_log

    clog = check_log(log, streams)
    n = len(clog)
    if n <= CHECK_SAMPLES:
        stretches = [clog]
    else:  # a long log: the check on evenly spaced stretches (time linear in CHECK_SAMPLES, not in the log)
        size = CHECK_SAMPLES // CHECK_CHUNKS
        starts = np.linspace(0, n - size, CHECK_CHUNKS).astype(int)
        stretches = [slice_log(clog, clog.t[i], clog.t[i + size - 1]) for i in starts]
    try:
        runs = [innovation_check(part, params, noise) for part in stretches]
    except (CartError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return float("nan"), 0, f"the EKF innovation check could not run on this log ({exc})"
    means = [m for m, _ in runs if math.isfinite(m)]
    return (float(np.mean(means)) if means else float("nan")), int(sum(r for _, r in runs)), ""


def push_work(streams: Streams, cart_frame: bool = False) -> float:
    """Return the work (J) the logged wrench does on the cart: the integral of fx vx + fy vy + tau omega
    (``cart_frame``: with (fx, fy) read in {b} and rotated into {s} by the heading).

    A passive cart (paper eq. 4: inertia and dissipation) takes the work that changes its kinetic energy
    and what its resistance dissipates: over a push that starts and ends near rest, the work is positive.
    Velocities from the pose stream (local polynomial fits), the wrench interpolated onto its times.
    """
    from cart.logs import estimate_velocities

    t, q = streams.pose.t, streams.pose.values
    if len(t) < 5:
        return 0.0
    qd = estimate_velocities(t, q)
    g = np.column_stack([np.interp(t, streams.wrench.t, streams.wrench.values[:, k]) for k in range(3)])
    if cart_frame:
        c, s = np.cos(q[:, 2]), np.sin(q[:, 2])
        g = np.column_stack([c * g[:, 0] - s * g[:, 1], s * g[:, 0] + c * g[:, 1], g[:, 2]])
    power = np.sum(g * qd, axis=1)
    return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(t)))


def _noise_json(model: SpectralNoise, dt: float, fc: float) -> dict[str, float]:
    """Return the wrench noise model (:class:`cart.noise_model.SpectralNoise`) as --json shows it.

    ``std``: the raw noise's std; ``lag1_corr``: its correlation at one grid step; ``low_frequency_std``: the
    std of the white noise with the same mean power below the cut-off ``fc``; ``psd_white``, ``psd_power``,
    ``alpha``, ``f_ref``: the one-sided PSD ``psd_white + psd_power (f / f_ref)^-alpha`` (units^2 / Hz).
    """
    return {
        "std": model.sigma,
        "lag1_corr": lag_correlation(model, dt),
        "low_frequency_std": model.band_white_std(fc),
        "psd_white": model.white,
        "psd_power": model.power,
        "alpha": model.alpha,
        "f_ref": model.f_ref,
    }


def _no_mass_error(log: CartLog, streams: Streams, exc: Exception) -> CartError:
    """Return the error for a log whose fit gives no positive mass: a flipped wrench sign when the push
    does negative work on the cart as logged and, read in {b}, no more positive work than that
    (:func:`push_work`), otherwise a push that does not match the motion."""
    work = push_work(streams)
    if work < 0.0 and push_work(streams, cart_frame=True) < -work:  # read in {b} no clearer push: not a frame
        return CartError(
            f"{log.source}: the fit gives no positive mass and the logged wrench does {work:.4g} J of work on "
            "the cart (a passive cart is pushed with positive work): the wrench's sign looks flipped (the "
            "sensor's reading of the force on the robot?); negate fx, fy and tau (LOG_FORMAT: the wrench "
            "applied to the cart)"
        )
    return CartError(
        f"{log.source}: the fit gives no positive mass ({exc}): the wrench does not match the motion "
        "(check the columns' order, frames and units against LOG_FORMAT)"
    )


def _run_ls(log: CartLog, streams: Streams) -> EstimateReport:
    """Return the least-squares report (identify + EKF innovation check + segments)."""
    from cart.identify import FIT_RATIO, IdentifiabilityError, identify
    from cart.segments import find_segments

    try:
        res = identify(log, streams=streams)
    except ParameterError as exc:
        raise _no_mass_error(log, streams, exc) from None
    # a fit accepted only as slow (coloured) sensor noise is checked too: a wrench in {b} misfits at low frequency
    fits_as_white = res.model_fits and res.residual_ratio[0] <= FIT_RATIO
    check_wrench_frame(log.source, res.residual_ratio, None if fits_as_white else res.cart_frame)
    check_torque_origin(log.source, res.residual_ratio, res.torque_origin)
    n_independent = 2.0 * res.cutoff_hz * res.samples_used * res.grid_dt  # rows band-limited to the cut-off
    frame_note = wrench_frame_warning(res.residual_ratio, res.cart_frame, n_independent)
    if res.wrench_noise is None:
        raise IdentifiabilityError(f"{log.source}: the least-squares fit gave no wrench-noise model")
    segments, seg_notes = find_segments(log, streams, res)
    split = len(segments) > 1
    # a load change: one cart cannot fit the whole log, so the verdict and the fit's warnings are the segments'
    whole = _segment_fit_notes(segments) if split else list(res.warnings)
    origin_note = None if split else torque_origin_warning(res.residual_ratio, res.torque_origin)
    notes = [n for n in (frame_note, origin_note) if n]
    warnings = log_notes(log, streams) + stream_notes(streams) + whole + notes
    f_noise, t_noise = res.wrench_noise
    noise = {"force": f_noise.band_white_std(res.cutoff_hz), "torque": t_noise.band_white_std(res.cutoff_hz)}
    nis, rejected, note = _innovation(log, streams, res.params, noise)
    warnings += [note] if note else []
    fits = res.model_fits
    if math.isfinite(nis) and nis > NIS_MISFIT and fits and not split:
        fits = False
        warnings.append(f"the EKF's innovations do not fit (mean NIS {nis:.1f}, ~6 expected); run `cartpush diagnose`")
    warnings += seg_notes
    params, std = res.params, res.std
    if split:
        last = segments[-1]
        params, std = last["params"], last["std"]
        fits = all(s["model_fits"] for s in segments)
    fields = _ls_fields(res, rejected)
    if split:  # the residual of the parameters shown: the last segment's fit
        fields["whole_log_residual_ratio"] = fields["residual_ratio"]
        fields["residual_ratio"] = list(segments[-1]["residual_ratio"])
    unknown = not_identified(params, std)
    return EstimateReport(
        method="ls",
        params=params,
        std=std,
        nis_mean=nis,
        model_fits=fits,
        warnings=_final_notes(warnings, params, std, unknown, fits),
        not_identified=unknown,
        fields=fields,
        streams=streams,
        segments=tuple(_segment_json(s) for s in segments),
    )


def _segment_fit_notes(segments: Sequence[Mapping[str, Any]]) -> list[str]:
    """Return the fit warnings of a log split at load changes: the last segment's (its parameters are the ones
    shown) and a line for each earlier segment the model does not fit. The whole log's fit averages two carts: its
    warnings (a misfit read as slow sensor noise, weak excitation) describe no cart that was pushed."""
    notes = []
    for k, seg in enumerate(segments[:-1], start=1):
        if not seg["model_fits"]:
            r = seg["residual_ratio"]
            notes.append(
                f"segment {k} (t {seg['t0']:.2f}-{seg['t1']:.2f} s) does not fit: residual wrench {r[0]:.1f}x (force) "
                f"and {r[1]:.1f}x (torque) what the sensor noise explains; run `cartpush diagnose` on that stretch"
            )
    last = segments[-1]
    prefix = f"last segment (t {last['t0']:.2f}-{last['t1']:.2f} s): "
    return notes + [prefix + w for w in last.get("warnings", ())]


def _ls_fields(res, rejected: int) -> dict[str, Any]:
    """Return the least-squares fit's extra JSON fields (residual, cut-off, noise model, offsets, casters, rows)."""
    f_noise, t_noise = res.wrench_noise
    return {
        "residual_ratio": list(res.residual_ratio),
        "cutoff_hz": res.cutoff_hz,
        "coulomb_resistance": {"force": res.coulomb["force"], "torque": res.coulomb["torque"]},
        "noise_std": res.noise,
        "noise_model": {
            "force": _noise_json(f_noise, res.grid_dt, res.cutoff_hz),
            "torque": _noise_json(t_noise, res.grid_dt, res.cutoff_hz),
            "grid_dt": res.grid_dt,
        },
        "wrench_offsets": res.offsets,
        "caster_swivel": _caster_json(res.casters),
        "samples_used": res.samples_used,
        "gaps": res.gaps,
        "rejected_samples": rejected,
    }


def _caster_json(casters) -> dict[str, Any] | None:
    """Return the caster model's test (:mod:`cart.identify_casters`): kept, geometry, Wald and its threshold."""
    if casters is None:
        return None
    return {
        "kept": casters.kept,
        "axle": casters.axle,
        "trail": casters.trail,
        "wald": casters.wald,
        "threshold": casters.threshold if math.isfinite(casters.threshold) else None,
        "half_turns": casters.half_turns,
    }


def _unknown_notes(unknown: dict[str, str]) -> list[str]:
    """Return the warnings naming the parameters not identified (the CoM's coordinates each, not twice)."""
    return [f"{name} not identified: {why}" for name, why in unknown.items() if name != "com"]


def weak_mass_note(params: CartParams, std: Mapping[str, Any], unknown: Mapping[str, str], fits: bool) -> list[str]:
    """Return a warning when the mass's std is above ``WEAK_MASS_STD`` of the mass (and the mass is identified).

    The std is honest (a light cart under heavy F/T noise: 4.01 +- 0.83 kg for 5.23), but a reader of the
    number alone takes it for a few per cent: the warning gives the relative std and its cause. When the model
    fits (``fits``) that is the forward acceleration the log holds against the force noise (the mass's
    information is their ratio squared); otherwise the std also carries the misfit the other warnings name.
    """
    if "mass" in unknown or not (params.m > 0 and std["mass"] > WEAK_MASS_STD * params.m):
        return []
    why = (
        "little forward acceleration for the F/T noise; push with more speed changes, for longer, or with a less "
        "noisy sensor for a closer mass"
        if fits
        else "the std carries the model's misfit (see the other warnings) besides the F/T noise"
    )
    share = 100.0 * std["mass"] / params.m
    return [
        f"the mass is known only to +-{share:.0f} % from this log ({params.m:.4g} +- {std['mass']:.2g} kg, 1 std): {why}"
    ]


#: A mass below this (kg) is lighter than anything a robot pushes as a cart: the wrench may be in kN
LIGHT_MASS_KG = 0.1


def light_mass_note(params: CartParams, unknown: Mapping[str, str]) -> list[str]:
    """Return a warning when the identified mass is below ``LIGHT_MASS_KG``: a wrench logged in kN scales the mass
    by 1e-3 and fits as well, so the log alone cannot refuse it; the reader is told what to check."""
    if "mass" in unknown or not 0.0 < params.m < LIGHT_MASS_KG:
        return []
    return [
        f"the mass is {1e3 * params.m:.3g} g, lighter than a cart: if the wrench is in kN and kN m, convert it "
        "to N and N m as LOG_FORMAT requires (the mass scales with the force's unit)"
    ]


#: The fit's own note on a mass whose std is above half of it (`cart.identify`), which :func:`weak_mass_note` supersedes.
_WEAKLY_EXCITED_MASS = "mass weakly excited"


def _final_notes(
    warnings: list[str], params: CartParams, std: Mapping[str, Any], unknown: dict[str, str], fits: bool
) -> tuple[str, ...]:
    """Return the report's warnings: ``warnings``, the parameters not identified, and the mass's precision
    (:func:`weak_mass_note`, which then replaces the fit's "mass weakly excited": one note on one std), and a
    mass lighter than a cart (:func:`light_mass_note`)."""
    weak = weak_mass_note(params, std, unknown, fits)
    kept = [w for w in warnings if not (weak and w.startswith(_WEAKLY_EXCITED_MASS))]
    return tuple(kept + _unknown_notes(unknown) + weak + light_mass_note(params, unknown))


def _segment_json(seg: dict[str, Any]) -> dict[str, Any]:
    """Return the JSON entry of one segment."""
    p, s = seg["params"], seg["std"]
    unknown = not_identified(p, s)
    val = {"mass": p.m, "inertia": p.I}
    out = {"t0": seg["t0"], "t0_range": seg.get("t0_range"), "t1": seg["t1"]}
    out.update({k: (None if k in unknown else v) for k, v in val.items()})
    out["com"] = com_value(p, unknown)
    out.update(
        sigma=p.sigma,
        sigma_yaw=p.sigma_yaw,
        std=s,
        model_fits=seg["model_fits"],
        residual_ratio=list(seg["residual_ratio"]),
        not_identified=unknown,
    )
    return out


def _ekf_bias(est_params: CartParams, est_std: Mapping[str, Any], ls) -> tuple[dict[str, float], list[str]]:
    """Return (EKF - LS differences, warnings naming the ones beyond ``EKF_BIAS_Z`` combined std)."""
    pairs = {
        "mass": (est_params.m, ls.params.m, est_std["mass"], ls.std["mass"], "kg"),
        "com_dx": (est_params.dx, ls.params.dx, est_std["com"][0], ls.std["com"][0], "m"),
        "com_dy": (est_params.dy, ls.params.dy, est_std["com"][1], ls.std["com"][1], "m"),
        "inertia": (est_params.I, ls.params.I, est_std["inertia"], ls.std["inertia"], "kg m^2"),
    }
    diffs, notes = {}, []
    for name, (e, ref, se, sr, unit) in pairs.items():
        diffs[name] = e - ref
        z = abs(e - ref) / max(math.hypot(se, sr), 1e-300)
        if z > EKF_BIAS_Z:
            notes.append(
                f"the EKF's {name} {e:.4g} +- {se:.2g} {unit} is {z:.1f} std from the least-squares "
                f"{ref:.4g} +- {sr:.2g} {unit}: a bias its std does not cover (the EKF takes the noisy wrench "
                "as an exact input: errors in variables); use --method ls"
            )
    return diffs, notes


def ekf_divergence(p: CartParams, guess: CartParams) -> str:
    """Return why the EKF's answer ``p`` from ``guess`` is no answer ("" when it is one): a value not finite, a
    mass above ``DIVERGED_MASS_RATIO`` times the guess or above ``MAX_MASS_GUESS``, a CoM beyond ``DIVERGED_COM`` m
    of {b}'s origin (no cart is that large) or an inertia above ``DIVERGED_INERTIA`` kg m^2."""
    values = {"mass": p.m, "dx": p.dx, "dy": p.dy, "inertia": p.I, "sigma": p.sigma, "sigma_yaw": p.sigma_yaw}
    bad = [name for name, v in values.items() if not math.isfinite(v)]
    if bad:
        return f"{', '.join(bad)} not finite"
    if p.m > DIVERGED_MASS_RATIO * guess.m:
        return f"mass {p.m:.4g} kg, more than {DIVERGED_MASS_RATIO:g} times the guess"
    if p.m > MAX_MASS_GUESS:
        return f"mass {p.m:.4g} kg, above the {MAX_MASS_GUESS:g} kg of the heaviest cart a guess may have"
    if math.hypot(p.dx, p.dy) > DIVERGED_COM:
        return f"CoM ({p.dx:.4g}, {p.dy:.4g}) m, farther than {DIVERGED_COM:g} m from the cart's origin"
    if p.I > DIVERGED_INERTIA:
        return f"inertia {p.I:.4g} kg m^2, above {DIVERGED_INERTIA:g}"
    return ""


def _check_against_ls(log: CartLog, p: CartParams, guess: CartParams, ls: Any) -> None:
    """Raise NumericalError when the EKF's mass is ``DIVERGED_LS_RATIO`` times the least-squares mass or less than
    its ``1 / DIVERGED_LS_RATIO``, the least-squares one being within a tenth (its std) on a fitting model."""
    m_ls, sd = float(ls.params.m), float(ls.std.get("mass") or math.inf)
    if not (ls.model_fits and m_ls > 0 and sd < 0.1 * m_ls):
        return
    ratio = p.m / m_ls
    if 1.0 / DIVERGED_LS_RATIO < ratio < DIVERGED_LS_RATIO:
        return
    raise _diverged(log, guess, f"its mass {p.m:.4g} kg is {ratio:.3g} x the least-squares {m_ls:.4g} +- {sd:.2g} kg")


def _diverged(log: CartLog, guess: CartParams, why: str) -> NumericalError:
    """Return the error of an EKF run that diverged from ``guess``: ``why``, and the options that help."""
    return NumericalError(
        f"{log.source}: the EKF diverged from the guesses (mass {guess.m:g} kg, CoM ({guess.dx:g}, {guess.dy:g}) "
        f"m): {why}; use the default method (--method ls), or closer --mass-guess / --com-guess"
    )


def _run_ekf(log: CartLog, streams: Streams, guess: CartParams) -> EstimateReport:
    """Return the EKF report, its verdict checked against the least-squares estimate."""
    from cart.ekf import estimate_from_log
    from cart.identify import check_estimable

    check_estimable(log, streams)  # the least-squares fit's checks: a log that says nothing is refused
    ekf_log = check_log(log, streams)
    try:
        est = estimate_from_log(ekf_log, guess, estimate_sigma=True)
    except (ArithmeticError, TypeError) as exc:
        raise NumericalError(f"{log.source}: the EKF diverged on this log ({exc}); use --method ls") from None
    p = est.params
    why = ekf_divergence(p, guess)
    if why:
        raise _diverged(log, guess, why)
    fits = bool(math.isfinite(est.mean_nis) and est.mean_nis < NIS_MISFIT)
    warnings = log_notes(log, streams) + stream_notes(streams)
    if not fits:
        warnings.append(
            f"the EKF's innovations do not fit (mean NIS {est.mean_nis:.1f}, ~6 expected): "
            "the std understates the error; run `cartpush diagnose`"
        )
    diffs, notes = _least_squares_check(log, streams, est, guess)
    fits = fits and not notes
    warnings += notes
    unknown = not_identified(p, est.std)
    return EstimateReport(
        method="ekf",
        params=p,
        std=est.std,
        nis_mean=est.mean_nis,
        model_fits=fits,
        warnings=_final_notes(warnings, p, est.std, unknown, fits),
        not_identified=unknown,
        fields={
            "velocities_estimated": est.velocities_estimated,
            "rejected_samples": int(getattr(est, "rejected_samples", 0)),
            "gaps": int(getattr(est, "gaps", 0)),
            "ekf_minus_ls": diffs,
        },
        streams=streams,
    )


def _least_squares_check(
    log: CartLog, streams: Streams, est: Any, guess: CartParams
) -> tuple[dict[str, float], list[str]]:
    """Return (EKF - LS differences, warnings) of the EKF estimate ``est`` checked against the least-squares fit:
    a divergence (raised), a bias beyond the combined std, a load change the EKF averages, a misfit the EKF's std
    does not cover. Any warning makes the EKF's verdict false."""
    from cart.identify import IdentifiabilityError, identify

    p = est.params
    try:
        ls = identify(log, streams=streams)
        _check_against_ls(log, p, guess, ls)
        diffs, notes = _ekf_bias(p, est.std, ls)
    except (IdentifiabilityError, np.linalg.LinAlgError) as exc:
        return {}, [f"the EKF's answer could not be checked against least squares ({exc})"]
    change = _load_change_note(log, streams, ls) if diffs else None
    if change:
        notes.append(change)
    elif diffs and not ls.model_fits:
        notes.append(
            "the least-squares fit of the same model says the model does not fit this log "
            f"(residual {ls.residual_ratio[0]:.1f}x / {ls.residual_ratio[1]:.1f}x the noise): the EKF's std "
            "does not cover that misfit"
        )
    return diffs, notes


def _load_change_note(log: CartLog, streams: Streams, ls: Any) -> str | None:
    """Return a warning when least squares splits the log at load changes (`cart.segments.find_segments`): the
    EKF's one cart then averages the carts before and after (an outside tester's 68 -> 51 kg log: 54.5 kg, the
    model said to fit, no warning)."""
    from cart.segments import find_segments

    segments, _ = find_segments(log, streams, ls)
    if len(segments) < 2:
        return None
    steps = ", ".join(
        f"t = {b['t0']:.2f} s ({a['params'].m:.4g} -> {b['params'].m:.4g} kg)" for a, b in zip(segments, segments[1:])
    )
    return (
        f"the load changes at {steps}: the EKF's one cart averages the carts before and after; the default method "
        "(--method ls) reports each segment"
    )


def check_guesses(mass_guess: float, com_guess: tuple[float, float], sigma_guess: float) -> None:
    """Raise a CartError naming the option when an EKF guess is not a number a cart can have.

    Bounds: mass in (0, ``MAX_MASS_GUESS``] kg, each CoM coordinate within +-``MAX_COM_GUESS`` m (as
    `cartpush push` bounds its guesses), viscous coefficients in [0, ``MAX_SIGMA_GUESS``].
    """
    if not (math.isfinite(mass_guess) and 0.0 < mass_guess <= MAX_MASS_GUESS):
        raise CartError(f"--mass-guess must be a positive number of kg at most {MAX_MASS_GUESS:g}, got {mass_guess}")
    if not all(math.isfinite(v) and abs(v) <= MAX_COM_GUESS for v in com_guess):
        raise CartError(
            f"--com-guess must be two numbers of metres in the cart frame {{b}}, each within +-{MAX_COM_GUESS:g}, "
            f"got {tuple(com_guess)}"
        )
    if not (math.isfinite(sigma_guess) and 0.0 <= sigma_guess <= MAX_SIGMA_GUESS):
        raise CartError(
            f"--sigma-guess must be a number of N s/m from 0 to {MAX_SIGMA_GUESS:g} (carts: about 1-100), "
            f"got {sigma_guess}"
        )


def estimate_log(
    log: CartLog | str | os.PathLike,
    method: str = "ls",
    mass_guess: float = 20.0,
    com_guess: tuple[float, float] = (0.0, 0.0),
    sigma_guess: float = 1.0,
) -> EstimateReport:
    """Return the estimate of a cart log (a CartLog or a LOG_FORMAT file) with its verdict.

    ``method``: ``"ls"`` (whole-log least squares, :func:`cart.identify.identify`) or ``"ekf"``
    (the paper's EKF from the guesses). Raises a :class:`~cart.errors.CartError` for bad input
    (:class:`~cart.units.UnitsError` for a unit mistake, ``IdentifiabilityError`` for a log that
    says nothing).
    """
    if method not in ("ls", "ekf"):
        raise CartError(f"method must be 'ls' or 'ekf', got {method!r}")
    check_guesses(mass_guess, com_guess, sigma_guess)
    if not isinstance(log, CartLog):
        log = read_log(log)
    check_declared_units(log.metadata, log.source)
    streams = split_streams(log)
    check_units(streams, log.source)
    if method == "ls":
        return _run_ls(log, streams)
    guess = CartParams(mass_guess, com_guess[0], com_guess[1], 0.1 * mass_guess, sigma_guess)
    return _run_ekf(log, streams, guess)
