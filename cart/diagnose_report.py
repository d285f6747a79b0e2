"""The report of :func:`cart.diagnose.diagnose`: named effects with their reasons, verdicts, windows, figures.

``DiagnosisReport`` (``to_dict`` is the JSON of ``cartpush diagnose --json``, ``summary`` its table),
``NamedEffect`` (with the ``reason`` it was named), ``Verdict`` (why another candidate was not),
``DiscrepancyWindow``, the parameter formatting of the table, and the figures (``diagnosis_figures``,
``plot_diagnosis``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from cart.diagnose_replay import Replay
from cart.effects import N_NOMINAL
from cart.errors import DiagnoseError


@dataclass(frozen=True)
class NamedEffect:
    """An effect the workflow named: contract name, fitted parameters and stds, Delta BIC, windows [(t0, t1)]."""

    name: str
    parameters: dict[str, float]
    uncertainties: dict[str, float]
    evidence: float
    windows: tuple[tuple[float, float], ...]
    #: why it was named (evidence, gap, the rule that put it first, the stronger candidates passed over)
    reason: str = ""

    def to_dict(self) -> dict:
        """Return the JSON form: name, parameters, uncertainties, evidence, windows, reason."""
        return {
            "name": self.name,
            "parameters": _clean(self.parameters),
            "uncertainties": _clean(self.uncertainties),
            "evidence": round(float(self.evidence), 3),
            "windows": [[round(a, 3), round(b, 3)] for a, b in self.windows],
            "reason": self.reason,
        }


@dataclass(frozen=True)
class DiscrepancyWindow:
    """A time window where the nominal replay disagrees significantly: [t0, t1], activity, max chi2."""

    t0: float
    t1: float
    activity: str
    chi2: float


@dataclass(frozen=True)
class DiagnosisReport:
    """Result of :func:`diagnose`: named effects (most significant first), gaps, windows, fitted models."""

    effects: tuple[NamedEffect, ...]
    gap_before: float
    gap_after: float
    gap_metric: str
    windows: tuple[DiscrepancyWindow, ...]
    nominal: dict[str, float]
    final_model: dict[str, float]
    candidates: tuple[tuple[str, float], ...]
    threshold: float
    source: str = "<memory>"
    rms_before: float = float("nan")
    rms_after: float = float("nan")
    noise_floor: float = float("nan")
    replay_before: Replay | None = field(default=None, repr=False, compare=False)
    replay_after: Replay | None = field(default=None, repr=False, compare=False)
    flagged: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: why each candidate that was ranked was not named (strongest first)
    not_named: tuple[Verdict, ...] = ()
    #: what was changed or bounded to diagnose the log (streams, averaging, a constrained nominal fit)
    warnings: tuple[str, ...] = ()
    #: the log's first time stamp: reported times are on the log's time axis, replays start at 0
    time_offset: float = 0.0
    #: sideways travel of {b} per window over what the pose noise predicts (~1 when eq. 3 holds)
    lateral_slip_ratio: float = float("nan")

    @property
    def names(self) -> list[str]:
        """Return the named effects' names, most significant first (empty: the nominal model explains the log)."""
        return [e.name for e in self.effects]

    def to_dict(self) -> dict:
        """Return the JSON form of ``cartpush diagnose --json``."""
        return {
            "effects": [e.to_dict() for e in self.effects],
            "gap_before": round(self.gap_before, 6),
            "gap_after": round(self.gap_after, 6),
            "gap_metric": self.gap_metric,
            "rms_before": round(self.rms_before, 6),
            "rms_after": round(self.rms_after, 6),
            "noise_floor": round(self.noise_floor, 6),
            "windows": [
                {"t0": round(w.t0, 3), "t1": round(w.t1, 3), "activity": w.activity, "chi2": round(w.chi2, 2)}
                for w in self.windows
            ],
            "nominal": _clean(self.nominal),
            "final_model": _clean(self.final_model),
            "candidates": [
                {"name": n, "delta_bic": round(s, 3) if math.isfinite(s) else None} for n, s in self.candidates
            ],
            "threshold": self.threshold,
            "not_named": [v.to_dict() for v in self.not_named],
            "warnings": list(self.warnings),
            "lateral_slip_ratio": round(self.lateral_slip_ratio, 3) if math.isfinite(self.lateral_slip_ratio) else None,
            "time_offset": self.time_offset,
        }

    def summary(self) -> str:
        """Return a readable multi-line summary: fit, windows, named effects with their reasons, the others, gap."""
        lines = [f"diagnosis of {self.source}"]
        lines.extend(f"warning: {w}" for w in self.warnings)
        nm = self.nominal
        lines.append(
            f"nominal fit: m = {nm['m']:.2f} kg, CoM = ({nm['dx']:.3f}, {nm['dy']:.3f}) m, "
            f"I = {nm['I']:.2f} kg m^2, sigma = {nm['sigma']:.2f} N s/m, "
            f"sigma_yaw = {nm['sigma_yaw']:.2f} N m s/rad"
        )
        lines.append(f"significant discrepancy windows: {len(self.windows)}")
        for w in self.windows[:12]:
            lines.append(f"  [{w.t0:7.2f}, {w.t1:7.2f}] s  {w.activity:<28} chi2 max {w.chi2:8.1f}")
        if len(self.windows) > 12:
            lines.append(f"  ... {len(self.windows) - 12} more")
        if not self.effects:
            lines.append(
                "named effects: none (the nominal model explains the log)"
                if not self.windows
                else f"named effects: none (no candidate explains the {len(self.windows)} significant discrepancy "
                "window(s): the log holds something the effects listed below do not model)"
            )
        for i, e in enumerate(self.effects, 1):
            ps = ", ".join(_format_parameter(k, v, e.uncertainties.get(k)) for k, v in e.parameters.items())
            nw = len(e.windows)
            lines.append(f"{i}. {e.name}: {ps}  (Delta BIC {e.evidence:.1f}, {nw} window{'s' if nw != 1 else ''})")
            if e.reason:
                lines.append(f"   why: {e.reason}")
        for v in self.not_named:
            lines.append(f"not named: {v.name}: {v.reason}")
        lines.append(_gap_line(self))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


def _gap_line(r: DiagnosisReport) -> str:
    """Return the gap line of the summary, saying what a gap of 0 means."""
    raw = f"raw RMS {r.rms_before * 1000:.1f} -> {r.rms_after * 1000:.1f} mm, noise floor {r.noise_floor * 1000:.1f} mm"
    if r.gap_before <= 0.0 and r.gap_after <= 0.0:
        return (
            f"gap 0 mm before and after: the nominal replay error ({raw}) is at the level the noise alone "
            "predicts, so no effect has anything to explain"
        )
    return f"gap before {r.gap_before * 1000:.1f} mm -> after {r.gap_after * 1000:.1f} mm (RMS replay error over the noise floor; {raw})"


#: Units of the effects' parameters in :meth:`DiagnosisReport.summary` (names of cart.effects' ``describe``).
PARAMETER_UNITS: dict[str, str] = {
    "force": "N",
    "torque": "N m",
    "distance": "m",
    "shape": "1",
    "torque_sharp": "N m",
    "torque_soft": "N m",
    "damping": "N m s/rad",
    "trail": "m",
    "fx": "N",
    "tau": "N m",
    "angle": "rad",
    "direction": "rad",
    "gx": "m/s^2",
    "gy": "m/s^2",
    "delta_m": "kg",
    "delta_m_dx": "kg m",
    "delta_m_dy": "kg m",
    "delta_J": "kg m^2",
    "time": "s",
    "mass_before": "kg",
    "mass_after": "kg",
    "com_x_after": "m",
    "com_y_after": "m",
    "delay": "s",
    "compliance": "m/(s N)",
    "friction": "N",
    "slide_speed": "m/s",
    "friction_coefficient": "1",
}


def _format_parameter(name: str, value: float, std: float | None) -> str:
    """Return 'name = value ± std [unit]', the value rounded where its std's 2nd significant digit falls.

    Without a std (or a grid-chosen one, std 0) the value has 3 significant digits.
    """
    unit = PARAMETER_UNITS.get(name, "?")
    if value is None or not math.isfinite(value):
        return f"{name} = n/a [{unit}]"
    has_std = std is not None and math.isfinite(std) and std > 0.0
    ref, digits = (std, 2) if std is not None and has_std else (abs(value), 3)
    decimals = min(8, max(0, digits - 1 - int(math.floor(math.log10(ref))))) if ref > 0 else 2
    v = f"{value:.{decimals}f}"
    if float(v) == 0.0:
        v = f"{0.0:.{decimals}f}"  # no "-0.00"
    return f"{name} = {v} ± {std:.{decimals}f} [{unit}]" if has_std else f"{name} = {v} [{unit}]"


def _clean(d: dict[str, float]) -> dict[str, float | None]:
    """Return d with non-finite values replaced by None (valid JSON)."""
    return {k: (float(v) if v is not None and math.isfinite(float(v)) else None) for k, v in d.items()}


def _physical(x: np.ndarray, cov: np.ndarray | None = None) -> dict[str, float]:
    """Return m, dx, dy, I (about the CoM), sigma, sigma_yaw of x (NaN where phi is not physical) with stds."""
    m, a, b, j, s, s_yaw = (float(v) for v in x[:N_NOMINAL])
    out = {
        "m": m,
        "dx": a / m if m > 0 else float("nan"),
        "dy": b / m if m > 0 else float("nan"),
        "I": j - (a * a + b * b) / m if m > 0 else float("nan"),
        "sigma": s,
        "sigma_yaw": s_yaw,
    }
    if cov is not None:
        out.update(
            {
                "m_std": math.sqrt(max(cov[0, 0], 0)),
                "sigma_std": math.sqrt(max(cov[4, 4], 0)),
                "sigma_yaw_std": math.sqrt(max(cov[5, 5], 0)),
            }
        )
    return out


@dataclass(frozen=True)
class Verdict:
    """Why a candidate effect was not named: contract name, its Delta BIC (when it was last ranked), the reason."""

    name: str
    delta_bic: float
    reason: str

    def to_dict(self) -> dict:
        """Return the JSON form: name, delta_bic (None when not finite), reason."""
        d = float(self.delta_bic)
        return {"name": self.name, "delta_bic": round(d, 3) if math.isfinite(d) else None, "reason": self.reason}


def _mm(x: float) -> str:
    """Return a length in mm with one decimal."""
    return f"{x * 1000:.1f} mm"


def effect_comment(name: str, params: dict[str, float]) -> str:
    """Return a plain-language reading of a named effect's parameters (e.g. the sign of a delay), or ''."""
    if name == "time_delay" and params.get("delay") is not None:
        d = float(params["delay"])
        side = "lags" if d > 0 else "leads"
        return f"delay {d * 1000:.1f} ms: the logged wrench {side} the motion by {abs(d) * 1000:.1f} ms"
    if name == "payload_change" and params.get("mass_after") is not None and params.get("mass_before") is not None:
        dm = float(params["mass_after"]) - float(params["mass_before"])
        return f"{'loaded' if dm > 0 else 'unloaded'} {abs(dm):.1f} kg at t = {params.get('time', float('nan')):.2f} s"
    if name == "lateral_slip" and params.get("compliance") is not None:
        return f"{float(params['compliance']) * 1000:.2f} mm/s of sideways speed per N of lateral force"
    if name == "lateral_slip" and params.get("friction") is not None:
        mu = params.get("friction_coefficient")
        share = f" ({float(mu):.3f} of the weight)" if mu is not None else ""
        return f"the wheels slide sideways beyond a friction force of {float(params['friction']):.1f} N{share}"
    return ""


def _plot_replay_errors(
    ax, report: DiagnosisReport, rb: Replay, ra: Replay, mask: np.ndarray | None, horizon: float
) -> None:
    """Draw the position error of non-overlapping replays before/after, the noise floor and the flagged windows."""
    for rep, colour, label in (
        (rb, "tab:red", "nominal model (before)"),
        (ra, "tab:blue", "with named effects (after)"),
    ):
        picked, last = [], -np.inf
        for k, t0 in enumerate(rep.starts):  # non-overlapping replays, one per horizon
            if t0 >= last + horizon - 1e-9:
                picked.append(k)
                last = t0
        for n, k in enumerate(picked):
            err = np.hypot(*(rep.sim[k, :, :2] - rep.meas[k, :, :2]).T) * 1000
            ax.plot(
                rep.starts[k] + report.time_offset + rep.tau,
                err,
                "-",
                color=colour,
                lw=0.9,
                label=f"{label}: RMS {rep.rms_error(mask) * 1000:.1f} mm" if n == 0 else None,
            )
    ax.plot(rb.starts + report.time_offset, rb.floor * 1000, "k:", lw=1.0, label="noise floor (RMS of a replay)")
    for i, w in enumerate(report.windows):
        ax.axvspan(w.t0, w.t1, color="orange", alpha=0.25, label="flagged windows" if i == 0 else None)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("replay position error [mm]")
    ax.set_title(f"position error of {horizon:.3g} s replays of the fitted model against the log")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")


def _plot_zoom(zx, report: DiagnosisReport, rb: Replay, ra: Replay, w: DiscrepancyWindow, first: bool) -> None:
    """Draw the measured path and the replays before/after from the worst start of flagged window ``w``."""
    starts = rb.starts + report.time_offset
    sel = np.flatnonzero((starts >= w.t0 - 1e-9) & (starts <= w.t1))
    k = int(sel[np.argmax(rb.chi2[sel])]) if len(sel) else int(np.argmin(np.abs(starts - w.t0)))
    meas = rb.meas[k, :, :2]
    zx.plot(meas[:, 0], meas[:, 1], "k.-", ms=2, lw=1.2, label="measured")
    zx.plot(rb.sim[k, :, 0], rb.sim[k, :, 1], "-", color="tab:red", lw=1.2, label="before")
    ka = int(np.argmin(np.abs(ra.starts - rb.starts[k])))
    zx.plot(ra.sim[ka, :, 0], ra.sim[ka, :, 1], "--", color="tab:blue", lw=1.2, label="after")
    zx.plot(*meas[0], "ko", ms=4)
    zx.set_aspect("equal", adjustable="datalim")
    zx.set_xlabel("x [m]")
    zx.set_ylabel("y [m]") if first else None
    zx.set_title(f"replay from t = {starts[k]:.2f} s (window {w.t0:.1f}-{w.t1:.1f} s)", fontsize=9)
    zx.grid(alpha=0.3)
    if first:
        zx.legend(fontsize=7)


def _residual_figure(report: DiagnosisReport, rb: Replay, ra: Replay):
    """Return the figure of the per-replay RMS error and chi-square over time, before and after."""
    from matplotlib.figure import Figure

    tb, ta = rb.starts + report.time_offset, ra.starts + report.time_offset
    res = Figure(figsize=(12, 6), layout="constrained")
    axes = res.subplots(2, 1, sharex=True)
    axes[0].plot(tb, rb.rms * 1000, "r-", label="before")
    axes[0].plot(ta, ra.rms * 1000, "b-", label="after")
    axes[0].plot(tb, rb.floor * 1000, "k:", label="noise floor")
    axes[0].set_ylabel("replay RMS error [mm]")
    axes[0].legend()
    axes[1].semilogy(tb, np.maximum(rb.chi2, 1e-3), "r-", label="before")
    axes[1].semilogy(ta, np.maximum(ra.chi2, 1e-3), "b-", label="after")
    axes[1].set_ylabel("chi2 (3 dof)")
    axes[1].set_xlabel("replay start t [s]")
    for a in axes:
        for w in report.windows:
            a.axvspan(w.t0, w.t1, color="orange", alpha=0.25)
    axes[0].set_title("residuals over time; shaded: windows where the nominal model disagrees significantly")
    return res


def diagnosis_figures(report: DiagnosisReport, max_zooms: int = 3) -> dict:
    """Return the figures of ``report`` as ``{"replay": Figure, "residuals": Figure}`` (no backend is touched).

    ``replay``: top, the position error of the 1 s replays along time (one
    replay every second, so the curve restarts at 0 each second), nominal model
    (before, red) and with the named effects (after, blue), the noise floor
    dotted, flagged windows shaded; below, up to ``max_zooms`` zooms on the
    flagged windows with the largest chi-square: the measured path (black) and
    the replays, in cart-path coordinates (mm-scale errors are visible there).
    ``residuals``: per-replay RMS error and chi-square over time.
    Display them in a notebook with ``display(fig)``; save with ``fig.savefig``.
    """
    from matplotlib.figure import Figure

    rb, ra = report.replay_before, report.replay_after
    if rb is None or ra is None:
        raise DiagnoseError("the report carries no replay data to plot")
    windows = sorted(report.windows, key=lambda w: -w.chi2)[:max_zooms]
    mask = report.flagged if report.flagged is not None and np.any(report.flagged) else None
    fig = Figure(figsize=(12, 7.5 if windows else 4.5), layout="constrained")
    grid = fig.add_gridspec(2 if windows else 1, max(1, len(windows)), height_ratios=[1, 1.3] if windows else [1])
    horizon = float(rb.tau[-1] - rb.tau[0]) if len(rb.tau) > 1 else 1.0
    _plot_replay_errors(fig.add_subplot(grid[0, :]), report, rb, ra, mask, horizon)
    for j, w in enumerate(windows):
        _plot_zoom(fig.add_subplot(grid[1, j]), report, rb, ra, w, j == 0)
    return {"replay": fig, "residuals": _residual_figure(report, rb, ra)}


def plot_diagnosis(report: DiagnosisReport, out_dir: str) -> list[str]:
    """Write ``replay.png`` and ``residuals.png`` of ``report`` (see `diagnosis_figures`) into ``out_dir``; return the paths."""
    os.makedirs(out_dir, exist_ok=True)
    paths = []
    for name, fig in diagnosis_figures(report).items():
        path = os.path.join(out_dir, f"{name}.png")
        fig.savefig(path, dpi=100)
        paths.append(path)
    return paths
