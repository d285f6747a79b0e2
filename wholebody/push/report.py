"""Reports of the closed-loop push: comparison table, figures, Meshcat page, log, and the demo.

`run_demo(out_dir)` is what `cartpush demo` runs: Traj. 2 with estimation and an
optimized contact point, the same without estimation (wrong initial mass), the
comparison table, and a report directory (figures, ``scene.html``, ``push_log.csv``).
"""

from __future__ import annotations

import math
import textwrap
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING
from collections.abc import Sequence

import numpy as np

from cart.errors import CartError
from cart.logs import CartLog, write_log
from wholebody.push.config import LOST_TRACKING_M, PushConfig, PushResult
from wholebody.push.figure_axes import FIGURE_DPI, Trace, mark_time, robust_ylim
from wholebody.push.load_change import LoadChange
from wholebody.push.loop import run_push

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from wholebody.viz import Scene

#: Columns of the comparison table: (metrics key, header, format, factor from the metric's unit). Human
#: output uses one unit per quantity: mm for tracking, cm for the CoM (the JSON keeps the metrics' units).
TABLE_COLUMNS = (
    ("tracking_rms_mm", "track RMS [mm]", "{:.2f}", 1.0),
    ("tracking_max_mm", "track max [mm]", "{:.2f}", 1.0),
    ("arm_torque_rms_nm", "tau RMS [Nm]", "{:.2f}", 1.0),
    ("arm_torque_peak_nm", "tau peak [Nm]", "{:.1f}", 1.0),
    ("arm_torque_limit_ratio", "tau/limit peak", "{:.2f}", 1.0),
    ("arm_push_torque_rms_nm", "J^T w RMS [Nm]", "{:.2f}", 1.0),
    ("ee_force_rms_n", "|f| RMS [N]", "{:.2f}", 1.0),
    ("ee_force_peak_n", "|f| peak [N]", "{:.1f}", 1.0),
    ("ee_torque_rms_nm", "|n| RMS [Nm]", "{:.2f}", 1.0),
    ("mass_error_final_kg", "m err [kg]", "{:.3f}", 1.0),
    ("com_error_final_m", "CoM err [cm]", "{:.2f}", 100.0),
    ("mass_error_max_after_5s_kg", "m err max >5s [kg]", "{:.2f}", 1.0),
    ("time_mass_within_1kg_s", "t m within 1 kg [s]", "{:.1f}", 1.0),
    ("com_error_max_after_5s_m", "CoM err max >5s [cm]", "{:.2f}", 100.0),
)


@dataclass(frozen=True)
class DemoResult:
    """The demo's runs (label -> result), its table (text), report directory and wall time."""

    runs: dict[str, PushResult]
    table: str
    out_dir: Path
    seconds: float


def describe(config: PushConfig) -> str:
    """Return a short label of a run configuration."""
    names = {"online": "online LS", "ekf": "EKF"}
    est = names[config.estimator] if config.estimation else f"no estimation (m={config.initial_mass:g})"
    contact = (
        "optimal CP" if config.contact == "optimal" else f"fixed CP y={','.join(f'{v:g}' for v in config.contact_y0())}"
    )
    robot = "" if config.robot == "ridgeback_iiwa" else f"{config.robot}, "
    loads = "".join(f", load {c.mass:+g} kg at {c.t:g} s" for c in sorted(config.load_changes, key=lambda c: c.t))
    arms = f"{config.n_arms} arm{'s' if config.n_arms > 1 else ''}"
    return f"{robot}Traj.{config.trajectory} {arms}, {est}, {contact}{loads}"


#: the `before_loss` figure shown in a lost run's second row, per `TABLE_COLUMNS` key (the others: "-")
BEFORE_LOSS_COLUMNS = {
    "tracking_rms_mm": "tracking_rms_mm",
    "tracking_max_mm": "tracking_max_mm",
    "arm_torque_limit_ratio": "arm_torque_limit_ratio",
    "mass_error_final_kg": "mass_error_kg",
    "com_error_final_m": "com_error_m",
}


def _table_rows(label: str, r: PushResult) -> list[list[str]]:
    """Return a run's table row; a lost run's is marked as the whole run's and followed by its row before the loss."""
    metrics = r.metrics.as_dict()
    row = [fmt.format(factor * metrics[k]) for k, _, fmt, factor in TABLE_COLUMNS]
    t_lost = r.metrics.tracking_lost_at_s
    if t_lost is None:
        return [[label] + row]
    b = before_loss(r)
    before = [
        fmt.format(factor * b[BEFORE_LOSS_COLUMNS[k]]) if k in BEFORE_LOSS_COLUMNS else "-"
        for k, _, fmt, factor in TABLE_COLUMNS
    ]
    return [[f"{label} (whole run: a failed push)"] + row, [f"{label} before the loss at {t_lost:.2f} s"] + before]


def comparison_table(runs: dict[str, PushResult], markdown: bool = False) -> str:
    """Return the metrics of several runs as a text (or Markdown) table, one row per run (two for a lost run:
    the whole run, marked as a failed push, and the figures before the loss, `before_loss`)."""
    heads = ["run"] + [h for _, h, _, _ in TABLE_COLUMNS]
    rows = [row for label, r in runs.items() for row in _table_rows(label, r)]
    if markdown:
        lines = ["| " + " | ".join(heads) + " |", "|" + "|".join("---" for _ in heads) + "|"]
        lines += ["| " + " | ".join(row) + " |" for row in rows]
        return "\n".join(lines)
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(heads)]
    fmt_row = lambda row: "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths)))
    return "\n".join([fmt_row(heads)] + [fmt_row(r) for r in rows])


def _spans(spans: Sequence[Sequence[float]]) -> str:
    """Return intervals as '3.0-27.3 s, ...' ('none' when empty)."""
    return ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in spans) if spans else "none"


def unobservable_note(runs: dict[str, PushResult]) -> str:
    """Return, per estimating run, the stretches where the mass / CoM were unobservable and what that meant.

    A stretch is where the estimate's 1-sigma of the parameter grew for >= 1 s
    (`wholebody.push.loop.unobservable_intervals`): the pushes there carried no
    new information about it (steady motion), so the estimate was held by the
    filter's memory, not updated by the data. The note says how the 1-sigma
    grew and how often the error stayed within 1 kg / 1 cm there: a held
    estimate may still be right.
    """
    lines = []
    for label, r in runs.items():
        if not r.config.estimation:
            continue
        m = r.metrics
        lines.append(
            f"{label}: unobservable (the estimate's 1-sigma growing >= 1 s: no new information from the pushes, the estimate "
            f"is held from earlier data, not updated): mass {_spans(m.mass_unobservable_s)}"
            f"{_held(r, 0, m.mass_unobservable_s)}; CoM {_spans(m.com_unobservable_s)}"
            f"{_held(r, 1, m.com_unobservable_s)}"
        )
    return "\n".join(lines)


def _errors(result: PushResult) -> tuple[np.ndarray, np.ndarray]:
    """Return the mass error (kg) and the CoM error (cm) of the run's estimate over time (against the truth at
    each instant, `PushResult.truth`)."""
    p, phi = result.truth(), result.phi_hat
    m = phi[:, 0]
    return np.abs(m - p[:, 0]), 100 * np.hypot(phi[:, 1] / m - p[:, 1], phi[:, 2] / m - p[:, 2])


def _held(result: PushResult, which: int, spans: Sequence[Sequence[float]]) -> str:
    """Return ' (1-sigma a -> b unit; error within 1 unit for x % of it)' for parameter 0 (mass) or 1 (CoM)."""
    if not spans:
        return ""
    inside = np.zeros(len(result.t), dtype=bool)
    for a, b in spans:
        inside |= (result.t >= a) & (result.t <= b)
    error = _errors(result)[which][inside]
    unit, factor = ("kg", 1.0) if which == 0 else ("cm", 100.0)
    within = f"error {error.min():.2f}-{error.max():.2f} {unit}, within 1 {unit} for {100 * np.mean(error <= 1.0):.0f} % of it"
    std = None if result.param_std is None else factor * result.param_std[inside, which]
    if std is None or not np.all(np.isfinite(std)):
        return f" ({within})"
    return f" (1-sigma {std[0]:.2f} -> {std[-1]:.2f} {unit}; {within})"


def torque_verdict(result: PushResult) -> tuple[str, bool]:
    """Return (one line on the arm torques against their limits, whether a limit was exceeded).

    The line names the joint and time of the peak |tau| / effortLimit and, when
    it is above 1, how long and at which joints the limit was exceeded: the
    simulated arm produced torques a real one cannot, so the run overstates what
    the robot can push.
    """
    lim = np.broadcast_to(result.effort_limit, result.arm_torque.shape[1:])  # one row per hand when arms differ
    ratio = np.abs(result.arm_torque) / lim
    k, arm, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    peak, tau, limit = float(ratio[k, arm, j]), float(result.arm_torque[k, arm, j]), float(lim[arm, j])
    where = f"joint {j + 1}{f' of arm {arm + 1}' if ratio.shape[1] > 1 else ''}"
    head = (
        f"arm torque peak {peak:.2f} x effortLimit: {where} at {abs(tau):.1f} of {limit:g} N m, t = {result.t[k]:.1f} s"
    )
    if peak <= 1.0:
        return f"{head} (within the limits)", False
    over = ratio > 1.0
    joints = ", ".join(str(i + 1) for i in np.flatnonzero(over.any(axis=(0, 1))))
    seconds = float(over.any(axis=(1, 2)).sum() * result.config.dt)
    return (
        f"{head}: OVER THE LIMIT for {seconds:.2f} s (joints {joints}); a real arm saturates there, "
        f"so this run overstates what the robot can push",
        True,
    )


def push_log(result: PushResult) -> CartLog:
    """Return the run's measured log (LOG_FORMAT): motion-capture pose/velocity, F/T wrench, contact of arm 0."""
    c = result.config
    p = c.true_params
    geo = c.cart_geometry()  # the handle point of arm 0's contact y, in {b} (a cart file's own handle)
    contact = np.array([geo.point(float(y))[:2] for y in result.contact_y[:, 0]])
    meta = {
        "source": "wholebody.push",
        "trajectory": str(c.trajectory),
        "arms": str(c.n_arms),
        "estimation": str(c.estimation),
        "contact": c.contact,
        "dt": repr(c.dt),
        "seed": str(c.seed),
        "true_params": f"m={p.m} dx={p.dx} dy={p.dy} I={p.I:.4f} sigma={p.sigma}",
        "initial_mass": repr(c.initial_mass),
    }
    if result.load_changes_true:  # the truth a log's offline estimate (`cartpush estimate`) can be judged against
        meta["load_changes"] = "; ".join(
            f"t={r['t_applied']:g} mass={r['mass_kg']:+g} -> m={r['mass_after_kg']:g}" for r in result.load_changes_true
        )
    return CartLog(
        t=result.t,
        q=result.z_meas[:, :3],
        gamma=result.gamma_measured,
        qd=result.z_meas[:, 3:],
        contact_b=contact,
        metadata=meta,
    )


def push_figures(runs: dict[str, PushResult]) -> dict[str, Figure]:
    """Return the figures comparing the runs, name -> matplotlib Figure (no backend is selected or touched).

    ``path``: the cart's path of each run and the base of each of its robots (same
    colour, a line style per robot), the first run drawn on top, where a cart was lost
    marked; ``tracking_estimation``: tracking error (mm), mass and CoM (cm) errors
    over time with the estimate's 1-sigma, the 1 kg / 1 cm bands and the stretches
    where the 1-sigma grew (no new information), hand force, one legend under the
    panels; ``estimate``: the estimated mass and CoM with their 1-sigma band
    against the plant's truth, the detected load changes and run-off flags marked
    (`_estimate_figure`); ``hand_wrenches``: the cart wrench the hands were
    allocated against the one they produced (the first MuJoCo run's, else the
    first run's; `_wrench_figure`); ``arm_torques``: each joint's torque as a share
    of its limit, the limits at +-100 %, legend outside the axes. A lost cart's
    loss time is a labelled red line on every time plot. The y ranges of the time
    plots come from the data before any loss (`figure_axes.robust_ylim`): a spike
    they clip is named on its panel.
    """
    physics = [label for label, r in runs.items() if _is_physics(r)]
    shown = physics[0] if physics else next(iter(runs))
    return {
        "path": _path_figure(runs),
        "tracking_estimation": _estimation_figure(runs),
        "estimate": _estimate_figure(runs),
        "hand_wrenches": _wrench_figure(runs[shown], shown),
        "arm_torques": _torque_figure(runs),
    }


def _style(i: int) -> tuple[str, str]:
    """Return (colour, line style) of run i: the first solid, the others dashed."""
    return f"C{i % 10}", "-" if i == 0 else "--"


#: line style of robot k's base on the path figure (robot 1 dotted, robot 2 dash-dotted, ...)
BASE_STYLES = (":", "-.", (0, (1, 3)), (0, (6, 2, 1, 2, 1, 2)))


def _distinct_bases(robot_x: np.ndarray) -> list[int]:
    """Return the robots (indices into ``robot_x``'s second axis) whose base drove its own path: one base holding
    several hands is listed once."""
    kept: list[int] = []
    for k in range(robot_x.shape[1]):
        if not any(np.allclose(robot_x[:, k, :2], robot_x[:, j, :2], atol=1e-6) for j in kept):
            kept.append(k)
    return kept


def _run_paths(ax, i: int, label: str, r: PushResult) -> list:
    """Draw run i's cart path, each robot's base path (same colour, `BASE_STYLES`) and where the cart was lost;
    return the drawn lines in legend order."""
    c, ls = _style(i)
    lw, z = (1.2, 4) if i == 0 else (2.4, 3)
    lines = ax.plot(r.q_true[:, 0], r.q_true[:, 1], ls, color=c, lw=lw, zorder=z, label=f"cart, {label}")
    for k in _distinct_bases(r.robot_x):
        style = BASE_STYLES[k % len(BASE_STYLES)]
        x, y = r.robot_x[:, k, 0], r.robot_x[:, k, 1]
        lines += ax.plot(x, y, ls=style, color=c, lw=lw, zorder=z, label=f"robot {k + 1} base, {label}")
    t_lost = r.metrics.tracking_lost_at_s
    if t_lost is not None:
        x, y = r.q_true[min(int(np.searchsorted(r.t, t_lost)), len(r.t) - 1), :2]
        lines += ax.plot(x, y, "X", color="r", mec="k", ms=10, zorder=6, label=f"cart lost at {t_lost:.2f} s, {label}")
        ax.annotate(
            f"cart lost {t_lost:.2f} s", (x, y), xytext=(6, 6), textcoords="offset points", color="r", fontsize=7
        )
    return lines


def _path_figure(runs: dict[str, PushResult]) -> Figure:
    """Return the cart and base paths; the first run is drawn last (on top), thinner, so none hides another."""
    from matplotlib.figure import Figure

    first = next(iter(runs.values()))
    fig = Figure(figsize=(7, 5.5), layout="constrained")
    ax = fig.subplots()
    handles = ax.plot(first.q_desired[:, 0], first.q_desired[:, 1], "k-", lw=4, alpha=0.2, label="desired cart path")
    drawn = {i: _run_paths(ax, i, label, r) for i, (label, r) in reversed(list(enumerate(runs.items())))}
    handles += [line for i in sorted(drawn) for line in drawn[i]]  # the first run listed first
    ax.legend(handles=handles, fontsize=7, loc="best")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.set_title("paths (world frame); the carts differ by mm: see tracking_estimation.png", fontsize=9)
    return fig


def _std_lines(axes, result: PushResult, colour: str, label: str) -> None:
    """Draw the estimate's 1-sigma of the mass (kg) and of the CoM (cm) as dotted lines (`PushResult.param_std`)."""
    if result.param_std is None or not np.any(np.isfinite(result.param_std)):
        return
    axes[0].plot(result.t, result.param_std[:, 0], ":", color=colour, lw=1.0, label=f"1-sigma, {label}")
    axes[1].plot(result.t, 100 * result.param_std[:, 1], ":", color=colour, lw=1.0, label=f"1-sigma, {label}")


def _shade(ax, spans: Sequence[Sequence[float]], colour: str, label: str) -> None:
    """Shade the stretches [t0, t1] of a run (one legend entry)."""
    for j, (a, b) in enumerate(spans):
        ax.axvspan(a, b, color=colour, alpha=0.12, lw=0, label=label if j == 0 else None)


#: Colour of the load changes the estimator found (a figure's vertical lines): in no run's palette (C0-C9), so
#: a found change never reads as a run's estimate or error line; a triangle at its top in the run's colour says whose.
LOAD_CHANGE_FOUND_COLOUR = "k"


def _load_change_lines(axes, r: PushResult, colour: str, label: str, slot: int = 0) -> list[dict]:
    """Draw each detected load change on every axis (`LOAD_CHANGE_FOUND_COLOUR`; solid: its onset, with a
    triangle of the run's `colour` near the top, lower for each later run `slot` so runs that found the same
    change all show; dashed: its detection); return the run-off flags of the run's estimator report."""
    report = r.estimator_report or {}
    top = 1.0 - 0.07 * (slot % 8)
    for j, c in enumerate(report.get("load_changes", [])):
        for ax in axes:
            ax.plot(
                [c["t_change"]] * 3,
                [0.0, top, 1.0],
                "-v",
                color=LOAD_CHANGE_FOUND_COLOUR,
                mfc=colour,
                ms=6,
                lw=1.2,
                markevery=[1],
                transform=ax.get_xaxis_transform(),  # x in data, y from the bottom (0) to the top (1) of the axes
                clip_on=False,
                label=f"load change found, {label}" if j == 0 else None,
            )
            ax.axvline(c["t_detected"], color=LOAD_CHANGE_FOUND_COLOUR, lw=0.8, ls="--")
    return list(report.get("runoff_flags", []))


def _estimator_events(axes, r: PushResult, colour: str, label: str, slot: int = 0) -> None:
    """Mark the load changes the estimator detected (solid: the change, dashed: its detection) and its run-off flags."""
    flags = _load_change_lines(axes, r, colour, label, slot)
    for j, f in enumerate(flags):
        axes[0].plot(
            f["t"], 0.0, "x", color="r", ms=5, label=f"run-off flagged (estimate held), {label}" if j == 0 else None
        )


#: the tracking_estimation panels: y label, unit of a clipping note, seconds from the start left out of the y range
#: (the estimate's convergence; the metrics' "after 5 s"), and the least top of the range (the bands show)
ESTIMATION_PANELS = (
    ("tracking error [mm]", "mm", 0.0, 0.0),
    ("mass error |m_hat - m| [kg]", "kg", 5.0, 3.0),
    ("CoM error [cm]", "cm", 5.0, 5.0),
    ("hand force |f| [N]", "N", 0.0, 0.0),
)


def _estimation_series(r: PushResult) -> tuple[np.ndarray, ...]:
    """Return the run's tracking error [mm], mass error [kg], CoM error [cm] and hand force [N] over time."""
    mass_error, com_error = _errors(r)
    tracking = 1e3 * np.hypot(*(r.q_true[:, :2] - r.q_desired[:, :2]).T)
    return tracking, mass_error, com_error, np.linalg.norm(r.wrenches[:, 0, :3], axis=1)


def _before_loss_mask(r: PushResult) -> np.ndarray:
    """Return which samples of the run come before the cart was lost (all of them when it was not)."""
    return r.t < (r.metrics.tracking_lost_at_s or math.inf)


def _estimation_run(axes, i: int, label: str, r: PushResult) -> None:
    """Draw one run on the tracking_estimation panels: its errors and force, the estimate's 1-sigma, the
    unobservable stretches, the estimator's events and the loss of the cart."""
    c, ls = _style(i)
    for ax, y in zip(axes, _estimation_series(r)):
        ax.plot(r.t, y, ls, color=c, label=label)
    if r.config.estimation:
        _std_lines(axes[1:3], r, c, label)
        _shade(axes[1], r.metrics.mass_unobservable_s, c, f"mass unobservable (estimate held), {label}")
        _shade(axes[2], r.metrics.com_unobservable_s, c, f"CoM unobservable (estimate held), {label}")
        _estimator_events(axes[1:3], r, c, label, slot=i)
    for ax in axes:
        _mark_loss(ax, r, label=True, slot=i)


def _estimation_limits(axes, runs: dict[str, PushResult]) -> None:
    """Set each panel's y range from the runs' samples after its settling time and before any loss
    (`figure_axes.robust_ylim`: what it clips is named on the panel)."""
    series = {label: _estimation_series(r) for label, r in runs.items()}
    for k, (ax, (_, unit, settle, least)) in enumerate(zip(axes, ESTIMATION_PANELS)):
        traces = [Trace(r.t, series[label][k], _before_loss_mask(r) & (r.t >= settle)) for label, r in runs.items()]
        robust_ylim(ax, traces, unit, zero_bottom=True, at_least=least)


def _estimation_figure(runs: dict[str, PushResult]) -> Figure:
    """Return tracking error [mm], mass error [kg], CoM error [cm] and hand force over time; one legend under the
    panels (beside them it took a third of their width)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 10), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    for i, (label, r) in enumerate(runs.items()):
        _estimation_run(axes, i, label, r)
    for a, unit in ((axes[1], "1 kg"), (axes[2], "1 cm")):
        a.axhspan(0.0, 1.0, color="g", alpha=0.12, lw=0, label=f"within {unit}")
    _estimation_limits(axes, runs)
    for a, (name, *_) in zip(axes, ESTIMATION_PANELS):
        a.set_ylabel(name), a.grid(alpha=0.3)
    _figure_legend(fig, axes, 6)
    fig.suptitle(
        "errors over time (y ranges from the data after the start transient and before any loss: a clipped peak "
        "is named on its panel)\ndotted: the estimate's 1-sigma; "
        "black vertical lines: load changes found (triangle: the run's colour; dashed: when detected)\n"
        "shaded: the 1-sigma grew for >= 1 s "
        "(no new information from the pushes: the estimate is held, not updated; it may still be right)",
        fontsize=8,
    )
    axes[-1].set_xlabel("t [s]")
    return fig


def _is_physics(result: PushResult) -> bool:
    """Return whether the run's plant was the MuJoCo physics engine."""
    return (result.plant_report or {}).get("plant") == "mujoco"


def _mark_loss(ax, result: PushResult, label: bool = True, slot: int = 0) -> None:
    """Shade the time after the cart was lost (`PushMetrics.tracking_lost_at_s`): a failed push, not a result; a red
    line at the loss says when (its label lower for each later run `slot`)."""
    t_lost = result.metrics.tracking_lost_at_s
    if t_lost is not None:
        ax.axvspan(
            t_lost, result.t[-1], color="r", alpha=0.08, lw=0, label="cart lost (a failed push)" if label else None
        )
        mark_time(ax, t_lost, f"cart lost {t_lost:.2f} s", slot=slot)


def _in_b(result: PushResult, gamma: np.ndarray) -> np.ndarray:
    """Return cart wrenches (fx, fy in {s}, tau) with the force in the cart frame {b} (forward, lateral)."""
    c, s = np.cos(result.q_true[:, 2]), np.sin(result.q_true[:, 2])
    return np.column_stack([c * gamma[:, 0] + s * gamma[:, 1], -s * gamma[:, 0] + c * gamma[:, 1], gamma[:, 2]])


def allocated_cart_wrench(result: PushResult) -> np.ndarray:
    """Return the cart wrench the allocation asked of the hands (N, 3): fx, fy in {b}, tau about {b}'s origin.

    Each hand's wrench [f, n] is in its {a}, aligned with {b}, at its handle point p (the grasp map of eq. 23-24):
    Gamma = sum (f_x, f_y, n_z + p_x f_y - p_y f_x).
    """
    from wholebody.push.robot import handle_point

    geometry = result.config.cart_geometry()
    out = np.zeros((len(result.t), 3))
    for k in range(result.wrenches.shape[1]):
        p = np.array([handle_point(float(y), geometry) for y in result.contact_y[:, k]])
        w = result.wrenches[:, k]
        out += np.column_stack([w[:, 0], w[:, 1], w[:, 5] + p[:, 0] * w[:, 1] - p[:, 1] * w[:, 0]])
    return out


def produced_cart_wrench(result: PushResult) -> np.ndarray:
    """Return the cart wrench the hands produced in each period (N, 3): fx, fy in {b}, tau about {b}'s origin.

    The MuJoCo plant reports the noise-free F/T wrench of the period that has just ended
    (`MujocoPlant.cart_wrench`): it is aligned with the allocation of the period before. The kinematic plant
    applies the allocated wrench itself.
    """
    gamma = result.gamma_applied
    if _is_physics(result):
        gamma = np.r_[gamma[1:], gamma[-1:]]
    return _in_b(result, gamma)


def _wrench_figure(result: PushResult, label: str) -> Figure:
    """Return the cart wrench over time: the controller's desired (eq. 26), the hands' allocated (eq. 25) and
    what they produced (MuJoCo: the F/T sensors; the kinematic plant: the allocation itself)."""
    from matplotlib.figure import Figure

    desired, allocated, produced = (
        _in_b(result, result.gamma_desired),
        allocated_cart_wrench(result),
        produced_cart_wrench(result),
    )
    source = (
        "measured by the F/T sensors (MuJoCo, noise-free)"
        if _is_physics(result)
        else "produced (kinematic plant: exact)"
    )
    fig = Figure(figsize=(7.5, 7.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    names = ("forward force f_x in {b} [N]", "lateral force f_y in {b} [N]", "yaw torque about {b} [N m]")
    before = _before_loss_mask(result)
    for j, (ax, name) in enumerate(zip(axes, names)):
        ax.plot(result.t, desired[:, j], ":", color="k", lw=1.0, label="desired by the cart controller (eq. 26)")
        ax.plot(result.t, allocated[:, j], "-", color="C2", lw=1.6, label="allocated to the hands (eq. 25)")
        ax.plot(result.t, produced[:, j], "-", color="C0", lw=0.8, label=source)
        _mark_loss(ax, result, label=j == 0)
        ax.set_ylabel(name, fontsize=8), ax.grid(alpha=0.3)
        traces = [Trace(result.t, w[:, j], before) for w in (desired, allocated, produced)]
        robust_ylim(ax, traces, "N m" if j == 2 else "N")
    _figure_legend(fig, axes, 7)
    err = np.linalg.norm((produced - allocated)[before, :2], axis=1)
    force = np.linalg.norm(allocated[before, :2], axis=1)
    rms = lambda v: float(np.sqrt(np.mean(v**2))) if v.size else math.nan
    fig.suptitle(
        f"{label}: hand wrenches on the cart\nproduced minus allocated force {rms(err):.2f} N RMS against "
        f"{rms(force):.2f} N RMS allocated{' (before the loss)' if not before.all() else ''}",
        fontsize=8,
    )
    axes[-1].set_xlabel("t [s]")
    return fig


def _estimate_series(result: PushResult) -> tuple[np.ndarray, np.ndarray]:
    """Return the estimate (N, 3): mass [kg], CoM x, y in {b} [cm], and its 1-sigma (N, 3) (NaN when none)."""
    phi = result.phi_hat
    m = np.where(np.abs(phi[:, 0]) > 1e-9, phi[:, 0], np.nan)
    est = np.column_stack([phi[:, 0], 100 * phi[:, 1] / m, 100 * phi[:, 2] / m])
    std = np.full_like(est, np.nan)
    if result.param_std is not None:
        ps = result.param_std
        xy = ps[:, 2:4] if ps.shape[1] >= 4 else np.column_stack([ps[:, 1], ps[:, 1]])  # per axis, else the norm
        std = np.column_stack([ps[:, 0], 100 * xy[:, 0], 100 * xy[:, 1]])
    return est, std


def _estimate_events(axes, result: PushResult, est: np.ndarray, colour: str, label: str, slot: int = 0) -> None:
    """Mark the detected load changes (solid: onset, dashed: detection) and the run-off flags (x on the estimate)."""
    flags = _load_change_lines(axes, result, colour, label, slot)
    kinds = ", ".join(sorted({f["kind"] for f in flags}))
    for j, f in enumerate(flags):
        k = min(int(np.searchsorted(result.t, f["t"])), len(result.t) - 1)
        for i, ax in enumerate(axes):
            ax.plot(
                f["t"], est[k, i], "x", color="r", ms=6, label=f"run-off flagged ({kinds}), {label}" if j == 0 else None
            )


def _estimate_figure(runs: dict[str, PushResult]) -> Figure:
    """Return the estimated mass and CoM (x, y in {b}) over time with their 1-sigma band against the plant's truth.

    The truth is what each run's estimate is judged against at each instant (`PushResult.truth`: a step at each
    load change the plant made, dotted lines; on the MuJoCo plant the cart's effective mass); the y range covers
    the truth and the estimates before any loss of the cart.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 8.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    lows, highs = [np.inf] * 3, [-np.inf] * 3
    for i, (label, r) in enumerate(runs.items()):
        c, ls = _style(i)
        est, std = _estimate_series(r)
        p = r.truth()
        before = r.t < (r.metrics.tracking_lost_at_s or math.inf)
        for j, (ax, truth) in enumerate(zip(axes, (p[:, 0], 100 * p[:, 1], 100 * p[:, 2]))):
            ax.plot(r.t, est[:, j], ls, color=c, lw=1.2, label=f"estimate, {label}")
            if r.config.estimation and np.any(np.isfinite(std[:, j])):
                ax.fill_between(
                    r.t,
                    est[:, j] - std[:, j],
                    est[:, j] + std[:, j],
                    color=c,
                    alpha=0.15,
                    lw=0,
                    label=f"+-1-sigma, {label}",
                )
            ax.plot(r.t, truth, color=c, ls="-", lw=3.0, alpha=0.3, label=f"truth, {label}")  # pale, thick: no dash
            for k, change in enumerate(r.load_changes_true):
                tag = f"load put in / taken out (truth), {label}" if j == 0 and k == 0 else None
                ax.axvline(change["t_applied"], color=c, ls=":", lw=1.0, label=tag)
            _mark_loss(ax, r, label=j == 0 and i == 0, slot=i)
            seen = np.r_[est[before, j], truth]
            lows[j], highs[j] = min(lows[j], np.nanmin(seen)), max(highs[j], np.nanmax(seen))
        if r.config.estimation:
            _estimate_events(axes, r, est, c, label, slot=i)
    for ax, lo, hi, name in zip(axes, lows, highs, ("mass [kg]", "CoM x in {b} [cm]", "CoM y in {b} [cm]")):
        pad = max(0.1 * (hi - lo), 1.0)
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_ylabel(name), ax.grid(alpha=0.3)
    _figure_legend(fig, axes, 6)
    fig.suptitle(
        "the estimate (band: its 1-sigma; the CoM's is the norm over x and y) against the truth (thick pale line);\n"
        "black vertical lines: load changes found (triangle: the run's colour; dashed: when detected);\n"
        "dotted: load changes made (truth); x: run-off flagged (estimate held)",
        fontsize=8,
    )
    axes[-1].set_xlabel("t [s]")
    return fig


def _torque_figure(runs: dict[str, PushResult]) -> Figure:
    """Return each arm joint's torque as a share of its limit (one panel per run), the limits at +-100 %.

    Every joint is drawn against its own effortLimit, so one pair of lines marks
    all seven limits; the legend (outside the axes) gives each joint's limit in N m.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.5, 3 * len(runs)), layout="constrained")
    axes = fig.subplots(len(runs), 1, sharex=True, squeeze=False)
    for a, (label, r) in zip(axes[:, 0], runs.items()):
        lim = np.broadcast_to(r.effort_limit, r.arm_torque.shape[1:])[0]  # the first hand's arm
        ratio = 100 * r.arm_torque[:, 0, :] / lim
        for j in range(ratio.shape[1]):
            a.plot(r.t, ratio[:, j], lw=0.8, label=f"joint {j + 1} (limit {lim[j]:g} N m)")
        a.axhline(100, color="k", ls=":", lw=1.2, label="effort limit (+-100 %)")
        a.axhline(-100, color="k", ls=":", lw=1.2)
        peak = float(np.max(np.abs(ratio)))
        a.set_ylim(-max(110.0, 1.1 * peak), max(110.0, 1.1 * peak))
        a.set_title(f"{label}: peak {peak:.0f} % of a limit", fontsize=8)
        _mark_loss(a, r)
        a.set_ylabel("tau / effortLimit [%]"), a.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1, 0].set_xlabel("t [s]")
    return fig


def save_figure_dict(figs: dict[str, Figure], out_dir: Path, prefix: str = "") -> list[Path]:
    """Write each figure of ``figs`` as ``<prefix><name>.png`` at `FIGURE_DPI` in ``out_dir`` (created); return the
    paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fig in figs.items():
        path = out_dir / f"{prefix}{name}.png"
        fig.savefig(path, dpi=FIGURE_DPI)
        paths.append(path)
    return paths


def save_figures(runs: dict[str, PushResult], out_dir: Path) -> list[Path]:
    """Write the `push_figures` as PNG at `FIGURE_DPI` (path.png, tracking_estimation.png, estimate.png,
    hand_wrenches.png, arm_torques.png); return the paths."""
    return save_figure_dict(push_figures(runs), out_dir)


#: the colour of the page's legend line on the cart's casters (the forks' grey; `wholebody.viz.push_cart`)
CASTER_COLOR = 0x808080
#: a caster turns through at most this fraction of a radian per integration step of `caster_swivel`
_SWIVEL_STEP = 0.2


def caster_swivel(q: np.ndarray, qd: np.ndarray, dt: float, pivots_b: np.ndarray, trail: float) -> np.ndarray:
    """Return each trailing caster's swivel angle (N, n_casters), rad, 0 = wheel behind its pivot (pushed forward).

    A caster whose wheel trails its swivel axis by ``trail`` rolls without sliding sideways: with the pivot's
    velocity v_p in {b} (v_b + omega x p), the fork turns at psi_dot = (-v_px sin psi + v_py cos psi) / trail -
    omega: it settles where its wheel's contact point moves along the wheel, and swings round when the cart
    reverses. Integrated from psi = 0 over the cart's poses ``q`` and velocities ``qd`` in {s} (N, 3),
    sub-stepped so that no step turns it by more than `_SWIVEL_STEP` rad. The page draws this model of the casters
    the kinematic plant moves (it simulates none); a MuJoCo run's cart and robot are drawn with the plant's own
    joint angles (`wholebody.viz.push_cart`).
    """
    c, s = np.cos(q[:, 2]), np.sin(q[:, 2])
    vb = np.column_stack([c * qd[:, 0] + s * qd[:, 1], -s * qd[:, 0] + c * qd[:, 1]])
    w = qd[:, 2]
    psi = np.zeros((len(q), len(pivots_b)))
    for j, (px, py) in enumerate(np.asarray(pivots_b, dtype=float)):
        vp = np.column_stack([vb[:, 0] - w * py, vb[:, 1] + w * px])
        a = 0.0
        for k in range(1, len(q)):
            rate = (np.hypot(*vp[k - 1]) / trail) + abs(w[k - 1])
            n = max(1, math.ceil(rate * dt / _SWIVEL_STEP))
            for _ in range(n):
                a += dt / n * ((-vp[k - 1, 0] * math.sin(a) + vp[k - 1, 1] * math.cos(a)) / trail - w[k - 1])
            psi[k, j] = a
    return psi


def swivel_casters(model, q_rest: np.ndarray, poses: np.ndarray, velocities: np.ndarray, dt: float) -> np.ndarray:
    """Return the joint configurations ``q_rest`` (N, nq - 4) of a planar-rooted model with its casters swivelled.

    Every joint named ``caster_*_swivel`` (a continuous joint on the root body) is turned by `caster_swivel` over
    the root's poses and velocities in {s} (N, 3); its pivot is the joint's place on the root, its trail the
    distance its wheel's joint sits behind it. Other joints are left as given.
    """
    q = np.array(q_rest, dtype=float, copy=True)
    for jid in range(1, model.njoints):
        name = model.names[jid]
        if not (name.startswith("caster_") and name.endswith("_swivel")) or model.nqs[jid] != 2:
            continue
        wheel = next((c for c in range(jid + 1, model.njoints) if model.parents[c] == jid), None)
        trail = -float(model.jointPlacements[wheel].translation[0]) if wheel is not None else 0.0
        if trail <= 0.0:
            continue
        pivot = np.asarray(model.jointPlacements[jid].translation[:2], dtype=float)
        psi = caster_swivel(poses, velocities, dt, pivot[None, :], trail)[:, 0]
        k = model.idx_qs[jid] - 4
        q[:, k], q[:, k + 1] = np.cos(psi), np.sin(psi)
    return q


#: a physics run's measured hand force arrow starts this far (m) above the allocated one's origin (the legend says so)
MEASURED_ARROW_RAISE = 0.06


def _hand_arrows(result: PushResult, idx: np.ndarray) -> tuple[dict, dict]:
    """Return the page's force arrows (name -> (world origins, forces)) and their kinds.

    The kinematic plant applies the allocated wrench: one arrow per hand, its force; a MuJoCo run with several
    hands: each hand's allocated force. A MuJoCo run's one hand:
    the horizontal force the allocation asked for (green) and the one its F/T sensor measured (blue)."""
    from wholebody.push.robot import cart_se3, handle_point

    geometry = result.config.cart_geometry()
    poses = [cart_se3(result.q_true[i], geometry) for i in idx]

    def hand(k: int) -> tuple[np.ndarray, np.ndarray]:
        origins = np.array([T.act(handle_point(result.contact_y[i, k], geometry)) for T, i in zip(poses, idx)])
        return origins, np.array([T.rotation @ result.wrenches[i, k, :3] for T, i in zip(poses, idx)])

    origins, forces = hand(0)
    if not _is_physics(result) or result.wrenches.shape[1] != 1:  # each hand's force (several: allocated only)
        kind = "allocated" if _is_physics(result) else "applied"
        names = ["hand"] + [f"hand{k + 1}" for k in range(1, result.wrenches.shape[1])]
        return {n: hand(k) for k, n in enumerate(names)}, dict.fromkeys(names, kind)
    th = result.q_true[idx, 2]
    measured = produced_cart_wrench(result)[idx]
    c, s = np.cos(th), np.sin(th)
    world = np.column_stack([c * measured[:, 0] - s * measured[:, 1], s * measured[:, 0] + c * measured[:, 1], 0 * c])
    horizontal = forces * np.array([1.0, 1.0, 0.0])
    above = origins + np.array([0.0, 0.0, MEASURED_ARROW_RAISE])  # both visible where they agree
    kinds = {"hand": "measured", "allocated": "allocated"}
    return {"hand": (above, world), "allocated": (origins, horizontal)}, kinds


def _physics_readouts(scene: Scene, result: PushResult, idx: np.ndarray) -> None:
    """Add a MuJoCo run's read-outs: the hand force allocated and measured, the grip slip, when the cart was lost."""
    t = result.t[idx]
    allocated, produced = allocated_cart_wrench(result)[idx], produced_cart_wrench(result)[idx]
    if _is_physics(result):
        scene.add_readout("MuJoCo plant: cart force allocated |f|", "N", t, np.linalg.norm(allocated[:, :2], axis=1))
        scene.add_readout("  ... measured by the F/T sensors |f|", "N", t, np.linalg.norm(produced[:, :2], axis=1))
    else:
        scene.add_readout("hand force |f|", "N", t, np.linalg.norm(result.wrenches[idx, 0, :3], axis=1))
    err = np.hypot(*(result.q_true[idx, :2] - result.q_desired[idx, :2]).T)
    scene.add_readout("cart off its desired place", "mm", t, 1e3 * err)
    t_lost = result.metrics.tracking_lost_at_s
    if t_lost is not None:
        label = f"cart LOST (over {100 * LOST_TRACKING_M:g} cm off) at t"
        scene.add_event_readout(label, "s", t, [t_lost], [t_lost], 2)


def build_scene(result: PushResult, fps: int = 10) -> Scene:
    """Return a Meshcat scene animating the run: the robot(s), the cart, the hand forces, the true and estimated CoM.

    The page plays when opened (pause button and legend bottom left; ``#t=<s>``
    opens it paused at a time), starts on the robot holding the cart, and its
    camera follows the robot and the cart (`wholebody.viz.Scene.animate`). It
    shows the hand force (N; a MuJoCo run: allocated and measured), the mass estimate with its 1-sigma and the
    CoM error (cm) live, the cart (a cart file's own bodies) and the robot with their casters and wheels as the
    MuJoCo plant turned them or, on the kinematic plant, as their motion turns them (`swivel_casters`;
    `wholebody.viz.push_cart`), and when the cart was lost.
    """
    import robots
    from robots.shopping_cart import CART_WHEEL_RADIUS
    from wholebody.motion.kinematics import wholebody_for
    from wholebody.push.robot import cart_se3
    from wholebody.viz import COM_MARKER_Z, Scene
    from wholebody.viz.push_cart import run_cart

    name = result.config.robot  # the robot that ran (Ridgeback + iiwa or WMRA); to_pinocchio_q ignores base_input
    loaded = robots.load(name)
    wb = wholebody_for(loaded, arm=list(result.robot_arms))  # its state holds these arms' joints
    step = max(1, int(round(1.0 / (fps * result.config.dt))))
    idx = np.arange(0, len(result.t), step)
    drawn = _drawn_robots(result, loaded)  # one per robot: side by side, or one base holding every hand
    qj = {n: _robot_frames(result, wb, k, idx) for k, n in enumerate(drawn)}
    poses = [cart_se3(result.q_true[i]) for i in idx]
    z = COM_MARKER_Z - CART_WHEEL_RADIUS  # markers at COM_MARKER_Z above the floor, as Scene.show_com draws them
    p = result.config.true_params
    phi = result.phi_hat[idx]
    truth = result.truth()[idx]
    com_true = np.array([T.act(np.array([c[1], c[2], z])) for T, c in zip(poses, truth)])
    com_est = np.array([T.act(np.array([f[1] / f[0], f[2] / f[0], z])) for T, f in zip(poses, phi)])
    x0, x1 = result.q_true[:, 0].min() - 2, result.q_true[:, 0].max() + 2
    y0, y1 = result.q_true[:, 1].min() - 2, result.q_true[:, 1].max() + 2
    cart = run_cart(result, idx)
    scene = Scene([*drawn.values(), cart.robot], floor=(x0, x1, y0, y1))
    scene.show_com((p.dx, p.dy), (phi[0, 1] / phi[0, 0], phi[0, 2] / phi[0, 0]))
    scene.show_trace("desired", result.q_desired[:, :2], label="cyan line: the cart's desired path")
    _physics_readouts(scene, result, idx)
    _estimate_readouts(scene, result, idx)
    arrows, kinds = _hand_arrows(result, idx)
    scene.animate(
        result.t[idx],
        {**{n: result.robot_x[idx, k, :3] for k, n in enumerate(drawn)}, cart.name: result.q_true[idx]},
        q_joints={**qj, cart.name: cart.joints},
        wrenches=arrows,
        kind=kinds,
        markers={"com/com_true": com_true, "com/com_est": com_est},
        fps=fps,
        follow=(name, cart.name),
    )
    scene.add_legend("casters", CASTER_COLOR, "line", cart.legend)
    if "allocated" in arrows:  # the measured arrow's legend line says where it starts
        e = scene.legend_entry("arrow_measured")
        scene.add_legend(
            "arrow_measured", e.color, e.shape, f"{e.text}; drawn {100 * MEASURED_ARROW_RAISE:g} cm higher"
        )
    scene.frame_robots(margin=0.6)  # the first frame: the robot holding the cart; the camera then follows them
    return scene


def _robot_frames(result: PushResult, wb, k: int, idx: np.ndarray) -> np.ndarray:
    """Return robot `k`'s joint configurations at samples `idx` for the page: as the MuJoCo plant recorded them,
    else its casters turned by the trail model (`wholebody.viz.push_cart.robot_joints`)."""
    from wholebody.viz.push_cart import robot_joints

    rest = np.array([wb.to_pinocchio_q(x)[4:] for x in result.robot_x[:, k]])
    return robot_joints(result, wb.robot.model, rest, idx, k)


def _drawn_robots(result: PushResult, loaded) -> dict:
    """Return the page's robots, name -> what `wholebody.viz.Scene` loads: the run's robot, and for robots side by
    side (one per hand: `wholebody.push.robot.arms_per_robot`) a copy per further hand named ``<name>_<k>``."""
    from dataclasses import replace

    from wholebody.push.robot import arms_per_robot

    name, hands = result.config.robot, int(result.robot_x.shape[1])
    if arms_per_robot(loaded.profile, hands) > 1:  # one base holds every hand
        return {name: name}
    return {name: name, **{f"{name}_{k + 1}": replace(loaded, name=f"{name}_{k + 1}") for k in range(1, hands)}}


def _estimate_readouts(scene, result: PushResult, idx: np.ndarray) -> None:
    """Add the page's live mass estimate (with its 1-sigma), CoM error, the estimator's events and the charts of
    the estimate with its band against the truth over time (`wholebody.viz.push_charts`)."""
    from wholebody.viz.push_charts import estimate_charts
    from wholebody.viz.scene import add_estimator_events

    p, t, phi = result.truth()[idx], result.t[idx], result.phi_hat[idx]
    est = f"{result.config.estimator} estimate" if result.config.estimation else "no estimation, fixed guess"
    masses = [f"{m:g}" for m in (p[0, 0], *(c["mass_after_kg"] for c in result.load_changes_true))]
    scene.add_readout(f"mass ({est}; true {' -> '.join(masses)} kg)", "kg", t, phi[:, 0])
    if result.load_changes_true:  # the truth steps: show it live beside the estimate
        scene.add_readout("  ... true mass now (loads put in / taken out)", "kg", t, p[:, 0])
    if result.config.estimation and result.param_std is not None and np.all(np.isfinite(result.param_std[idx, 0])):
        scene.add_readout("  ... its 1-sigma", "kg", t, result.param_std[idx, 0], digits=2)
    com_error = 100 * np.hypot(phi[:, 1] / phi[:, 0] - p[:, 1], phi[:, 2] / phi[:, 0] - p[:, 2])
    scene.add_readout("CoM error", "cm", t, com_error)
    changes = (result.estimator_report or {}).get("load_changes") or []
    at = [min(int(np.searchsorted(result.t, c["t_detected"])), len(result.t) - 1) for c in changes]
    add_estimator_events(scene, result.estimator_report, t, [float(result.phi_hat[k, 0]) for k in at])
    estimate_charts(scene, result)


def save_scene(result: PushResult, path: Path, fps: int = 10) -> Path:
    """Write a self-contained Meshcat page animating the run (see `build_scene`); return its path."""
    with build_scene(result, fps) as scene:
        return scene.save_html(path)


def write_report(
    runs: dict[str, PushResult], out_dir: Path, scene_run: str | None = None, html: bool = True
) -> list[Path]:
    """Write figures, the first (or `scene_run`) run's log and Meshcat page, and the tables; return the paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    main = runs[scene_run] if scene_run else next(iter(runs.values()))
    paths = save_figures(runs, out_dir)
    log_path = out_dir / "push_log.csv"
    write_log(log_path, push_log(main))
    paths.append(log_path)
    table = out_dir / "comparison.md"
    note = unobservable_note(runs)
    verdicts = "\n".join(f"{label}: {torque_verdict(r)[0]}" for label, r in runs.items())
    table.write_text(comparison_table(runs, markdown=True) + "\n" + (f"\n{note}\n" if note else "") + f"\n{verdicts}\n")
    paths.append(table)
    if html:
        paths.append(save_scene(main, out_dir / "scene.html"))
        physics = next((r for r in runs.values() if _is_physics(r) and r is not main), None)
        if physics is not None:
            paths.append(save_scene(physics, out_dir / PHYSICS_PAGE))
    return paths


#: the report directory's page of its first MuJoCo run (when that run is not the one `scene.html` shows)
PHYSICS_PAGE = "scene_mujoco.html"


def physics_note(label: str, result: PushResult) -> str:
    """Return what a MuJoCo run's plant reports, in one line: the cart's mass, wrench error, slips, speed, and the
    run's outcome (`what_happened`'s first sentence); '' for another plant."""
    rep = result.plant_report or {}
    if not _is_physics(result):
        return ""
    wheel = rep.get("base_wheel_slip_max_m_s")
    return (
        f"{label}: {what_happened(result)[0]}; cart {rep['cart_mass_kg']:.2f} kg ({rep['cart_mass_effective_kg']:.2f} kg "
        f"with its wheels' spin), hand force {rep['hand_force_rms_n']:.2f} N RMS, measured minus allocated "
        f"{rep['wrench_error_rms_n']:.2f} N RMS, grip slip max {1e3 * rep['grasp_slip_max_m']:.2f} mm"
        + ("" if wheel is None else f", base wheel slip max {wheel:.3f} m/s")
        + f", {rep['real_time_factor']:.1f}x real time"
    )


def demo_configs(
    duration: float = 30.0, physics: bool = True, load_changes: tuple[LoadChange, ...] = ()
) -> dict[str, PushConfig]:
    """Return the demo's runs: Traj. 2, optimized contact, with and without estimation (initial mass 16 kg), and
    (``physics``) the same controller against the MuJoCo plant on Traj. 1 (fixed grip: the grips are welds); each
    with the `load_changes` given."""
    base = PushConfig(trajectory=2, duration=duration, contact="optimal", estimation=True, load_changes=load_changes)
    runs = {"with estimation": base, "without estimation": replace(base, estimation=False)}
    if physics:
        runs["MuJoCo plant, Traj. 1"] = replace(base, trajectory=1, plant="mujoco", contact="fixed")
    return runs


def run_demo(
    out_dir: Path,
    duration: float = 30.0,
    html: bool = True,
    verbose: bool = True,
    progress: bool = False,
    load_changes: tuple[LoadChange, ...] = (),
) -> DemoResult:
    """Run the demo's pushes (`demo_configs`), print the comparison table and write the report directory.

    ``progress``: a bar per run on stderr (the CLI passes True only on a terminal without --json);
    ``load_changes``: loads put in or taken out in every run (`wholebody.push.load_change`).
    """
    t0 = time.perf_counter()
    runs = {
        label: run_push(cfg, progress=progress, progress_label=f"demo: {label}")
        for label, cfg in demo_configs(duration, load_changes=load_changes).items()
    }
    table = comparison_table(runs)
    write_report(runs, Path(out_dir), html=html)
    seconds = time.perf_counter() - t0
    if verbose:
        _print_demo(runs, table, Path(out_dir), seconds, html)
    return DemoResult(runs=runs, table=table, out_dir=Path(out_dir), seconds=seconds)


#: lateral speed (m/s) of {b}'s origin above which a run says the cart slid sideways (the cart model has none)
LATERAL_SLIP_M_S = 0.05
#: the online estimator's residual ratio above which the nominal cart model misfits the data
MISFIT_RATIO = 2.0
#: a final CoM estimate farther from the truth than the initial guess by more than this (m) is called out
COM_RUNOFF_M = 0.05
#: share of the trajectory's time the slowed reference must reach for the verdict to read plain "tracked"
SLOWED_VERDICT = 0.9
#: distance (m) of a hand from its handle point above which a run says the hand left the handle
HAND_OFF_HANDLE_M = 0.02


def cart_lateral_speed(result: PushResult) -> np.ndarray:
    """Return the true lateral speed (m/s) of {b}'s origin over time (the no-slip constraint's violation)."""
    th = result.q_true[:, 2]
    return -np.sin(th) * result.qd_true[:, 0] + np.cos(th) * result.qd_true[:, 1]


def what_happened(result: PushResult, load_changes: list[dict] | None = None) -> list[str]:
    """Return plain sentences on how the run went: tracked or lost, saturation, torque limits, slip, model fit.

    The first sentence is the outcome; the others say what the arms could not do (the allocation's binding
    limits, torques at their limits), whether the cart slid sideways (the no-slip model broken), how far the
    grips slipped (MuJoCo), and whether the estimator's model fitted the data. When the cart was lost, the
    binding limits and the slip are those before the loss (what led to it); what came after is a failed push.
    ``load_changes``: :func:`match_load_changes` of ``result`` when the caller has it (it weighs each change not
    found on its own, which takes a second a change).
    """
    m, rep = result.metrics, result.plant_report or {}
    t_end = m.tracking_lost_at_s if m.tracking_lost_at_s is not None else math.inf
    lines = [_outcome(result), *_lost_to_guess(result), *result.setup_notes] + _tipped(rep)
    lines += _hand_off_handle(result, t_end)
    lines += _bases_overlap(result, t_end)
    lines += _saturation(m.saturation or {}, t_end)
    lines += _slowed(result, t_end)
    if m.arm_torque_limit_ratio > 1.0:
        lines.append(f"arm torque at {m.arm_torque_limit_ratio:.2f} x its limit (commanded)")
    if rep.get("arm_torque_saturated_steps"):
        lines.append(f"arm torques clipped at their limits in {rep['arm_torque_saturated_steps']} physics steps")
    lines += _wheels_at_limit(result, t_end)
    lines += _wheel_traction(result, t_end)
    lines.append(_lateral_slip(result, t_end))
    if rep.get("grasp_slip_max_m") is not None:
        lines.append(f"grip slip at most {1e3 * rep['grasp_slip_max_m']:.2f} mm")
    if rep.get("base_wheel_slip_max_m_s") is not None:
        lines.append(f"base wheel slip at most {rep['base_wheel_slip_max_m_s']:.3f} m/s")
    lines += load_change_lines(result, load_changes)
    lines.append(_fit(result))
    lines += _far_guess(result)
    lines += _massless_bodies(result)
    lines += _massless_arm_bodies(result)
    return lines


#: base wheel slip (m/s) on the MuJoCo plant above which the robot's grip on the floor is worth questioning
WHEEL_SLIP_M_S = 0.1


def _massless_bodies(result: PushResult) -> list[str]:
    """Return a sentence when a MuJoCo run was lost or its base's wheels slipped (`WHEEL_SLIP_M_S`) and the robot's
    URDF has bodies without mass (`robots.checks.massless_bodies`: a chassis whose ``<inertial>`` was left out
    makes the robot lighter in the model, its wheels grip less and it tips sooner)."""
    rep = result.plant_report or {}
    slip = rep.get("base_wheel_slip_max_m_s") or 0.0
    if rep.get("plant") != "mujoco" or (result.metrics.tracking_lost_at_s is None and slip <= WHEEL_SLIP_M_S):
        return []
    import robots
    from robots.checks import massless_bodies

    bodies = massless_bodies(robots.urdf_path(result.config.robot).read_text())
    if not bodies:
        return []
    names = ", ".join(f"{n!r} ({1e3 * v:.0f} L of collision geometry)" for n, v in bodies)
    return [
        f"robot model: {names} without mass in the URDF (no <inertial>): the robot is lighter in the model than it is, "
        "its wheels grip less and it tips sooner; give them their mass"
    ]


def _massless_arm_bodies(result: PushResult) -> list[str]:
    """Return a sentence when an arm joint moves a body without mass in the robot's model (its link and the links
    fixed to it have no ``<inertial>``): the arm's torques then leave that weight out. The MuJoCo plant refuses such
    a robot before it runs; the kinematic plant runs it, and this says what its torques miss."""
    import robots
    from robots.checks import massless_moved_bodies

    prof = robots.profile(result.config.robot)
    joints = [n for arm in prof.arms for n in arm.joints]
    bare = massless_moved_bodies(robots.urdf_path(result.config.robot).read_text(), joints)
    if not bare:
        return []
    return [
        f"robot model: the arm joint(s) {', '.join(map(repr, bare))} move bodies without mass in the URDF (no "
        "<inertial> on their links): the arm's torques and torque ratios leave that weight out; give the links "
        "their mass"
    ]


#: an estimate this many times the initial guess (or below its inverse) was far from the guess: say so
FAR_GUESS_RATIO = 3.0
#: an estimate this close to the truth (relative) reached the cart's mass despite a far guess
FAR_GUESS_REACHED = 0.05


def _far_guess(result: PushResult) -> list[str]:
    """Return a sentence when the final mass estimate is `FAR_GUESS_RATIO` or more from the initial guess: the prior
    (50 % of the guess) then holds the estimate back for long; a guess near the cart's mass helps."""
    cfg, m = result.config, result.metrics.mass_final_kg
    if not cfg.estimation or not (m > 0 and math.isfinite(m)):
        return []
    ratio = m / cfg.initial_mass
    if 1.0 / FAR_GUESS_RATIO < ratio < FAR_GUESS_RATIO:
        return []
    flags = (result.estimator_report or {}).get("runoff_flags") or ()
    restart = next((f for f in flags if f.get("kind") == "guess_far"), None)
    if restart is not None:
        return [
            f"the pushes contradicted the initial guess ({cfg.initial_mass:g} kg): the estimate restarted from them at "
            f"t = {restart['t']:.2f} s and ended at {m:.1f} kg; a guess near the cart's mass (--initial-mass, and "
            "--initial-com for its centre of mass) saves the first seconds"
        ]
    truth = float(result.truth()[-1][0])
    if abs(m - truth) <= FAR_GUESS_REACHED * truth:  # the estimate got there (a load change, or pushes that weigh)
        return [
            f"the mass estimate ended {ratio:.1f} x the initial guess, on the cart's mass ({m:.1f} kg for "
            f"{truth:.1f} kg); a guess near it (--initial-mass, and --initial-com for its centre of mass) saves the "
            "first seconds"
        ]
    return [
        f"the mass estimate ended {ratio:.1f} x the initial guess ({m:.1f} kg for {cfg.initial_mass:g} kg): a guess "
        "that far off holds the estimate back; give one near the cart's mass (--initial-mass, and --initial-com "
        "for its centre of mass)"
    ]


def _lost_to_guess(result: PushResult) -> list[str]:
    """Return a sentence when the cart was lost while the controller's mass (its estimate, or the frozen guess) was
    `FAR_GUESS_RATIO` or more from the cart's: the feedforward pushed a cart of another mass, and the loss came
    before the estimate could correct it (a guess in the wrong unit, or a bed taken for a shopping cart)."""
    t_lost = result.metrics.tracking_lost_at_s
    if t_lost is None or not len(result.t):
        return []
    k = min(int(np.searchsorted(result.t, t_lost)), len(result.t) - 1)
    used, true = float(result.phi_hat[k, 0]), float(result.truth()[k, 0])
    if not (used > 0 and true > 0) or 1.0 / FAR_GUESS_RATIO < true / used < FAR_GUESS_RATIO:
        return []
    source = (
        f"its estimate, from the initial guess of {result.config.initial_mass:g} kg"
        if result.config.estimation
        else "the initial guess, frozen"
    )
    late = "the loss came before the estimate caught up" if result.config.estimation else "nothing corrected it"
    return [
        f"at the loss the controller took the cart for {used:.1f} kg ({source}); it weighs {true:.1f} kg "
        f"({true / used:.2g} x): {late}; give a guess near the cart's mass (--initial-mass, in kg)"
    ]


def match_load_changes(result: PushResult) -> list[dict]:
    """Return each load change the plant made (`PushResult.load_changes_true`) with what the estimator found of it.

    A true change is found by the first change the estimator reported (``load_changes`` of its report) detected after
    it and before the next true change (or the run's end), dated from 1 s before it on: ``found``, the estimator's
    onset ``t_change_est`` (``t_change_censored``: the onset may lie earlier,
    `cart.online_estimator.LoadChange.censored`) and ``t_detected`` (s), ``time_error_s`` (onset minus the true
    time), ``mass_after_est_kg``
    (the estimator's mass after it; for its last reported change followed by a true change it did not find, the
    loop's estimate just before that change: the estimator's own is its estimate at the run's end) and its error
    (kg, % of the true mass after; the truth's mass: on the MuJoCo plant the effective mass); found or not,
    ``mass_settled_kg`` and ``mass_settled_error_pct``: the loop's estimate just before the next change (or at the
    run's end) against the mass after; not found, ``mass_alone_before_kg``, ``mass_alone_after_kg`` and their
    ``_std_kg``: what the pushes from the change before it (or the start) to it, and from it to the next one (or
    the end), weigh on their own (:func:`weighed_alone`; None when they say nothing): was it there to see."""
    reported = sorted((result.estimator_report or {}).get("load_changes") or (), key=lambda c: c["t_detected"])
    true = list(result.load_changes_true)
    ends = [c["t_applied"] for c in true[1:]] + [math.inf]
    starts = [0.0] + [c["t_applied"] for c in true[:-1]]
    log: CartLog | None = None  # the run's log, built for the first change not found
    out = []
    for c, start, end in zip(true, starts, ends):
        t0 = c["t_applied"]
        hit = next((e for e in reported if t0 <= e["t_detected"] < end and e["t_change"] >= t0 - 1.0), None)
        settled = float(result.phi_hat[int(np.searchsorted(result.t, end - 1e-9)) - 1, 0])
        row = {
            **c,
            "found": hit is not None,
            "mass_settled_kg": settled,
            "mass_settled_error_pct": 100.0 * (settled - c["mass_after_kg"]) / c["mass_after_kg"],
        }
        if hit is None:  # what the pushes on each side weigh on their own: could the change have been seen?
            log = log if log is not None else push_log(result)
            for side, (a, b) in (("before", (start, t0)), ("after", (t0, min(end, float(result.t[-1]))))):
                alone = weighed_alone(log, a, b)
                row[f"mass_alone_{side}_kg"], row[f"mass_alone_{side}_std_kg"] = alone or (None, None)
        if hit is not None:
            # the estimator's last change weighs it with its estimate at the run's end: after a later change it did
            # not find, the loop's estimate before that change is what the pushes after this one weighed
            last = hit is reported[-1] and math.isfinite(end)
            weighed = settled if last else hit["mass_after"]
            err = weighed - c["mass_after_kg"]
            row.update(
                t_change_est=hit["t_change"],
                t_change_censored=bool(hit.get("censored", False)),
                t_detected=hit["t_detected"],
                time_error_s=hit["t_change"] - t0,
                mass_after_est_kg=weighed,
                mass_after_error_kg=err,
                mass_after_error_pct=100.0 * err / c["mass_after_kg"],
            )
        out.append(row)
    return out


#: a change is there to see when it is at least this many stds of the difference of the masses the pushes on its two
#: sides weigh on their own
CHANGE_SEEN_SIGMA = 3.0


def weighed_alone(log: CartLog, t0: float, t1: float) -> tuple[float, float] | None:
    """Return (mass, std) in kg that a run's pushes from ``t0`` to ``t1`` give on their own (the offline least
    squares, :func:`cart.identify.identify`, on that stretch of the run's :func:`push_log`); None when they say
    nothing of the mass (too short, no motion above the noise)."""
    from cart.identify import identify
    from cart.segments import slice_log

    try:
        res = identify(slice_log(log, t0, t1))
    except CartError:
        return None
    return float(res.params.m), float(res.std["mass"])


def _information_after(row: dict) -> str:
    """Return why a load change may have gone unseen: what the pushes on each side weigh on their own
    (``mass_alone_before_kg``, ``mass_alone_after_kg`` and their stds, :func:`match_load_changes`) against the
    change's size."""
    size = abs(row["mass_kg"])
    values = [row.get(f"mass_alone_{side}{k}") for side in ("before", "after") for k in ("_kg", "_std_kg")]
    known = [float(v) for v in values if v is not None]
    if len(known) < 4:
        return "the pushes on one side of it say nothing of the mass (too short, or no motion above the noise)"
    m_b, s_b, m_a, s_a = known
    std = math.hypot(s_a, s_b)
    weighed = f"the pushes before and after it weigh the cart {m_b:.1f} +- {s_b:.1f} and {m_a:.1f} +- {s_a:.1f} kg on their own"
    verdict = "too little motion to tell it" if size < CHANGE_SEEN_SIGMA * std else "there to see"
    return f"{weighed}: a {size:g} kg change is {size / std:.1f} std of their difference, {verdict}"


def load_change_lines(result: PushResult, rows: list[dict] | None = None) -> list[str]:
    """Return one sentence per load change the plant made (found or not: when, the mass after) and one naming the
    changes the estimator reported where none was made (none without load changes and reports). ``rows``:
    :func:`match_load_changes` of ``result``, computed here when not given."""
    rows = match_load_changes(result) if rows is None else rows
    lines = []
    for r in rows:
        what = (
            f"load {'put in' if r['mass_kg'] > 0 else 'taken out'} ({r['mass_kg']:+g} kg) at {r['t_applied']:.2f} s, "
            f"truth {r['mass_before_kg']:.1f} -> {r['mass_after_kg']:.1f} kg"
        )
        settled = f"the estimate {r['mass_settled_kg']:.1f} kg ({r['mass_settled_error_pct']:+.1f} %) before the next change or the end"
        if not r["found"]:
            lines.append(f"{what}: NOT found by the estimator; {settled}; {_information_after(r)}")
            continue
        dated = f"{r['t_change_est']:.2f} s" + (
            " or earlier (the data the estimator kept do not bound it)" if r.get("t_change_censored") else ""
        )
        lines.append(
            f"{what}: found, dated {dated} ({r['time_error_s']:+.2f} s), detected "
            f"{r['t_detected']:.2f} s, weighed {r['mass_after_est_kg']:.1f} kg ({r['mass_after_error_kg']:+.1f} kg, "
            f"{r['mass_after_error_pct']:+.1f} %); {settled}"
        )
    used = {r["t_detected"] for r in rows if r["found"]}
    extra = [
        e["t_change"] for e in (result.estimator_report or {}).get("load_changes") or () if e["t_detected"] not in used
    ]
    if extra and rows:
        lines.append(f"the estimator also reported load changes where none was made: t = {_times(extra)} s")
    elif extra:
        lines.append(f"no load was put in or taken out; the estimator reported changes at t = {_times(extra)} s")
    return lines


def _times(ts: Sequence[float]) -> str:
    return ", ".join(f"{t:.2f}" for t in ts)


def _saturation(saturation: dict, t_end: float) -> list[str]:
    """Return one sentence per allocation limit that bound before `t_end` (the loss), one for those after."""
    rows = sorted(saturation.items(), key=lambda kv: -kv[1]["total_s"])
    lines = [
        f"saturated: {k} from t = {v['first_s']:.2f} s ({v['total_s']:.2f} s in all): the arms could not give the "
        "wrench the cart needed"
        for k, v in rows
        if v["first_s"] < t_end
    ]
    after = [k for k, v in rows if v["first_s"] >= t_end]
    return lines + ([f"after the loss also saturated: {', '.join(after)}"] if after else [])


def _slowed(result: PushResult, t_end: float) -> list[str]:
    """Return how far the reference was slowed before `t_end` (the loss; `wholebody.push.reference_clock`), or
    nothing when it never was: its slowest rate (when), the time below the desired speed, how far behind it was."""
    rate, s = result.reference_rate, result.reference_time
    if rate is None or s is None:
        return []
    inside = np.flatnonzero((result.t < t_end) & (rate < 1.0))
    if inside.size == 0:
        return []
    k = int(inside[np.argmin(rate[inside])])
    if rate[k] >= 0.995:  # slowed by less than the sentence's precision (it would read "to 100 %")
        return []
    last = int(np.flatnonzero(result.t < t_end)[-1])
    when = " before the loss" if math.isfinite(t_end) else ""
    ends = "was" if math.isfinite(t_end) else "ends"
    return [
        f"saturation: reference slowed{when} to {100 * rate[k]:.0f} % of the desired speed (t = {result.t[k]:.2f} s), "
        f"slower for {inside.size * result.config.dt:.2f} s in all; it {ends} {result.t[last] - s[last]:.2f} s behind "
        "the desired timing (the tracking error is against the slowed reference)" + _slowed_in_turns(result, inside)
    ]


#: a reference turning faster than this (rad per second of reference time) is in a turn
TURN_RATE = 0.05


def _slowed_in_turns(result: PushResult, slowed: np.ndarray) -> str:
    """Return a clause when the slowing came in the turns while a grip's yaw torque bound: the turns are why.

    ``slowed``: the periods the reference ran below the desired speed. The clause is given when at least 70 %
    of them are where the desired motion turns (`TURN_RATE`) and a grip torque limit about the vertical
    (``tau_z``) bound during the run: turning the cart takes more yaw torque than the grips twist (a large
    yaw inertia, casters swinging round, wheels that scrub in a turn).
    """
    sat = result.metrics.saturation or {}
    tau_z = [v["total_s"] for k, v in sat.items() if "grip torque limit (tau_z)" in k]
    s = result.reference_time
    if not tau_z or s is None or slowed.size < 2:
        return ""
    traj = result.config.make_trajectory()
    yaw_rate = np.array([abs(traj.sample(float(v))[1][2]) for v in s[slowed]])
    share = float(np.mean(yaw_rate > TURN_RATE))
    if share < 0.7:
        return ""
    return (
        f"; {100 * share:.0f} % of the slowing came in the turns, where the grips' yaw torque bound "
        f"(tau_z, {max(tau_z):.2f} s): turning this cart takes more yaw torque than the grips twist (a large yaw "
        "inertia, casters swinging round, or wheels that scrub in a turn: fixed axles front and rear, a solid axle)"
    )


#: The base's wheels at this share of their speed limit or more run as fast as they go.
WHEEL_AT_LIMIT = 0.999
#: Time (s) at the wheel speed limit worth a sentence.
WHEEL_LIMIT_TIME = 0.5


def _wheels_at_limit(result: PushResult, t_end: float) -> list[str]:
    """Return a sentence when a base's wheels ran at their speed limit for `WHEEL_LIMIT_TIME` or more before `t_end`.

    The whole-body QP keeps the wheels within their limits: at the limit the base goes no faster and the arm
    takes up the rest of the hand's motion (a weak arm then runs into its torque limits on a physics plant).
    """
    if result.wheel_rates is None or result.wheel_velocity_limit is None:
        return []
    ratio = np.abs(result.wheel_rates) / np.asarray(result.wheel_velocity_limit)
    at = (ratio.reshape(len(result.t), -1).max(axis=1) >= WHEEL_AT_LIMIT) & (result.t < t_end)
    total = float(at.sum()) * result.config.dt
    if total < WHEEL_LIMIT_TIME:
        return []
    first = float(result.t[np.argmax(at)])
    return [
        f"base: the wheels ran at their speed limit for {total:.2f} s from t = {first:.2f} s (the base as fast as it "
        "goes; the arm took up the rest of the hand's motion)"
    ]


#: window (s) over which the base's forward force is averaged before it is compared with the wheels' traction
WHEEL_FORCE_WINDOW = 0.2


def _base_forward_force(result: PushResult, mass: float) -> np.ndarray:
    """Return (N, n_robots) the forward force (N) each base needs: its robot's mass times the base's forward
    acceleration plus its hands' push on the cart (their reaction; the hands' forces in the cart's axes, the base
    behind the cart), averaged over `WHEEL_FORCE_WINDOW`."""
    twist = np.asarray(result.base_twist, dtype=float)
    dt = result.config.dt
    accel = np.gradient(twist[:, :, 0], dt, axis=0)
    hands = np.asarray(result.wrenches, dtype=float)[:, :, 0]
    per = max(1, hands.shape[1] // twist.shape[1])
    push = hands.reshape(len(result.t), twist.shape[1], per).sum(axis=2)
    n = max(1, int(round(WHEEL_FORCE_WINDOW / dt)))
    kernel = np.ones(n) / n
    force = mass * accel + push
    return np.stack([np.convolve(f, kernel, mode="same") for f in force.T], axis=1)


def _wheel_traction(result: PushResult, t_end: float) -> list[str]:
    """Return a sentence when a base needed more forward force than its driven wheels' URDF effort limits give at
    their rims (the sum of the limits over the wheel radius) before `t_end`.

    The kinematic plant moves the base as commanded whatever its wheels' torques; the MuJoCo plant clips them at
    their limits, and the base then lags the hand (the cart lost, the wheels slipping). Either way a robot with
    such wheels cannot make this push. Nothing is said when a wheel's effort limit is not given (0 or infinite).
    """
    if result.base_twist is None or not len(result.t):
        return []
    import pinocchio as pin

    import robots
    from wholebody.motion.kinematics import wholebody_for

    loaded = robots.load(result.config.robot)
    wb = wholebody_for(loaded, arm=list(result.robot_arms))
    effort = np.asarray(wb.model.effortLimit[wb.wheel_idx_v], dtype=float)
    if not effort.size or not np.all(np.isfinite(effort)) or np.any(effort <= 0.0):
        return []
    radius = float(wb.base.wheel_radius)
    capacity = float(effort.sum()) / radius
    mass = float(pin.computeTotalMass(wb.model))
    need = np.abs(_base_forward_force(result, mass))[result.t < t_end]
    if not need.size or float(need.max()) <= capacity:
        return []
    k = np.unravel_index(int(np.argmax(need)), need.shape)
    return [
        f"base: the push needed up to {float(need[k]):.0f} N of forward force at the wheels (t = "
        f"{float(result.t[k[0]]):.2f} s; the robot's {mass:.0f} kg accelerated and the hands' push), but their effort "
        f"limits ({', '.join(f'{e:g}' for e in effort)} N m on {radius:.3g} m wheels) give at most {capacity:.0f} N: "
        "wheels that weak cannot make this push (raise the URDF's wheel <limit effort>, or push a lighter cart slower)"
    ]


def _lateral_slip(result: PushResult, t_end: float) -> str:
    """Return whether {b} slid sideways faster than `LATERAL_SLIP_M_S` before `t_end`: when, how fast, how long."""
    inside = result.t < t_end
    if not inside.any():
        return "lateral slip: not measured (the cart was lost at the start)"
    lat = np.abs(cart_lateral_speed(result))[inside]
    k, slid = int(np.argmax(lat)), float(np.sum(lat > LATERAL_SLIP_M_S) * result.config.dt)
    when = " before the loss" if math.isfinite(t_end) else ""
    if slid == 0:
        return f"no lateral slip of the cart{when} (at most {lat[k]:.3f} m/s)"
    return (
        f"slip: the cart slid sideways{when} at up to {lat[k]:.2f} m/s (t = {result.t[k]:.2f} s), faster than "
        f"{LATERAL_SLIP_M_S:g} m/s for {slid:.2f} s in all (its model assumes no lateral slip)"
    )


#: samples of a run between two checks of whether robots' bases overlap (`_bases_overlap`)
OVERLAP_STRIDE = 5


def _box_corners(pose: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
    """Return the (4, 2) world corners of a base footprint `box` (base frame) at planar `pose` (x, y, yaw)."""
    x0, x1, y0, y1 = box
    c, s = math.cos(pose[2]), math.sin(pose[2])
    local = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    return local @ np.array([[c, s], [-s, c]]) + pose[:2]


def _overlap_depth(a: np.ndarray, b: np.ndarray) -> float:
    """Return how deep (m) two convex polygons (corners in order) overlap: the least overlap of their projections
    on the edges' normals (separating-axis test); 0 when they are apart."""
    depth = math.inf
    for poly in (a, b):
        for k in range(len(poly)):
            edge = poly[(k + 1) % len(poly)] - poly[k]
            n = np.array([-edge[1], edge[0]]) / (math.hypot(*edge) or 1.0)
            pa, pb = a @ n, b @ n
            depth = min(depth, min(pa.max(), pb.max()) - max(pa.min(), pb.min()))
            if depth <= 0.0:
                return 0.0
    return float(depth)


def _bases_overlap(result: PushResult, t_end: float) -> list[str]:
    """Return a sentence when two robots' bases (their footprints, `robot.base_footprint_box`) overlapped before
    `t_end`: each base is planned behind its own contact, nothing keeps two bases apart, and neither plant makes
    robots collide, so the push as run is not one two real robots could make."""
    twist = result.base_twist
    x = np.asarray(result.robot_x, dtype=float)
    if twist is None or np.shape(twist)[1] < 2 or x.shape[1] != np.shape(twist)[1]:
        return []
    import robots
    from wholebody.push.robot import base_footprint_box

    box = base_footprint_box(robots.load(result.config.robot))
    if box is None:
        return []
    idx = np.arange(0, len(result.t), OVERLAP_STRIDE)
    idx = idx[result.t[idx] < t_end]
    depth = np.array([_overlap_depth(_box_corners(x[k, 0, :3], box), _box_corners(x[k, 1, :3], box)) for k in idx])
    if not np.any(depth > 0.0):
        return []
    over = idx[depth > 0.0]
    k = int(idx[int(np.argmax(depth))])
    return [
        f"ROBOTS OVERLAP: the two robots' bases overlapped for {len(over) * OVERLAP_STRIDE * result.config.dt:.2f} s "
        f"from t = {float(result.t[over[0]]):.2f} s, by up to {100 * float(depth.max()):.0f} cm (t = "
        f"{float(result.t[k]):.2f} s): each base follows its own contact and nothing keeps them apart; two real "
        "robots could not push so (one robot with --arms 1, or contacts farther apart)"
    ]


def _tipped(rep: dict) -> list[str]:
    """Return a sentence when the MuJoCo plant's cart tipped (its body tilted past the standing check's limit)."""
    t = rep.get("cart_tipped_at_s")
    if t is None:
        return []
    return [
        f"the cart TIPPED: its body tilted past {rep.get('cart_tilt_limit_deg', 10.0):g} deg at t = {t:.2f} s "
        f"({rep.get('cart_tilt_max_deg', 0.0):.0f} deg at most); the planar cart model no longer holds (a cart that stands on its own wheels only while held, or "
        "one pushed harder than its wheelbase holds, cannot be pushed this way)"
    ]


def _hand_off_handle(result: PushResult, t_end: float) -> list[str]:
    """Return, per hand that was more than `HAND_OFF_HANDLE_M` from its handle point before `t_end`, for how
    long, from when and how far at most: the cart then moved while the hand did not hold it where it should
    (an arm near a singular pose or out of reach), so the push as run is not one a real grip would make."""
    err = np.asarray(result.grasp_error, dtype=float)
    if err.ndim == 1:
        err = err[:, None]
    inside = result.t < t_end
    out = []
    for i in range(err.shape[1]):
        e = err[inside, i]
        off = e > HAND_OFF_HANDLE_M
        if not off.any():
            continue
        k, t = int(np.argmax(e)), result.t[inside]
        hand = f"hand {i + 1} was" if err.shape[1] > 1 else "the hand was"
        out.append(
            f"HAND OFF THE HANDLE: {hand} more than {1e3 * HAND_OFF_HANDLE_M:g} mm from its handle point for "
            f"{float(np.sum(off)) * result.config.dt:.2f} s from t = {float(t[np.argmax(off)]):.2f} s, at most "
            f"{1e3 * float(e[k]):.0f} mm (t = {float(t[k]):.2f} s): the arm could not follow the handle there"
        )
    return out


def _outcome(result: PushResult) -> str:
    """Return 'tracked: ...', 'tracked the slowed reference: ...' (it reached less than `SLOWED_VERDICT` of the
    trajectory's time), 'cart on its path but NOT HELD there: ...' (a hand was off its handle point: the kinematic
    plant moves the cart by the planned wrench wherever the hand is) or 'LOST the cart at t = ...' (with the
    tracking RMS up to then)."""
    m, t_lost = result.metrics, result.metrics.tracking_lost_at_s
    s = result.reference_time
    if t_lost is None and s is not None and s[-1] < SLOWED_VERDICT * result.t[-1]:
        return (
            f"tracked the slowed reference: {m.tracking_rms_mm:.1f} mm RMS, {m.tracking_max_mm:.1f} mm max, but the "
            f"cart reached only the trajectory's t = {s[-1]:.1f} s of {result.t[-1]:.1f} s"
        )
    if t_lost is None and _hand_off_handle(result, math.inf):
        return (
            f"cart on its path but NOT HELD there: {m.tracking_rms_mm:.1f} mm RMS, {m.tracking_max_mm:.1f} mm max "
            "with a hand off its handle point (below): a real grip would not have pushed it so"
        )
    if t_lost is None:
        return f"tracked: {m.tracking_rms_mm:.1f} mm RMS, {m.tracking_max_mm:.1f} mm max"
    err = np.hypot(*(result.q_true[:, :2] - result.q_desired[:, :2]).T)[result.t < t_lost]
    before = f"{1e3 * float(np.sqrt(np.mean(err**2))):.1f} mm RMS before" if err.size else "from the start"
    return (
        f"LOST the cart at t = {t_lost:.2f} s (more than {100 * LOST_TRACKING_M:g} cm from its desired place; {before})"
    )


def _com_ran_off(result: PushResult) -> str:
    """Return a clause when the final CoM estimate is farther from the truth than the initial guess by more than
    ``COM_RUNOFF_M``: whichever estimator ran, its CoM did worse than not estimating it."""
    cfg, err = result.config, result.metrics.com_error_final_m
    truth = result.truth()[-1]
    guess = float(np.hypot(cfg.initial_com[0] - truth[1], cfg.initial_com[1] - truth[2]))
    if not cfg.estimation or not err > guess + COM_RUNOFF_M:
        return ""
    return f"; CoM estimate {100 * err:.0f} cm from the truth, farther than the initial guess ({100 * guess:.0f} cm)"


def _fit(result: PushResult) -> str:
    """Return whether the estimator's cart model fitted the data (residual ratio, misfit flags) and its mass."""
    est, truth = result.estimator_report or {}, result.truth()[-1]
    mass = f"mass estimate {result.metrics.mass_final_kg:.1f} kg (truth {truth[0]:.1f} kg)" + _com_ran_off(result)
    ratios = [r for r in est.get("residual_ratio") or () if r is not None]
    if not result.config.estimation or not ratios:
        return mass
    flags = [f["t"] for f in est.get("runoff_flags") or () if f.get("kind") == "misfit"]
    flagged = f", flagged {len(flags)} time(s) from t = {min(flags):.2f} s" if flags else ""
    worst = max(ratios)
    com = [n for n in est.get("unexcited") or () if n in ("dx", "dy")]
    if com:
        mass += f"; CoM {' and '.join(com)} not identified by these pushes (kept near the initial guess)"
    if worst > MISFIT_RATIO:
        return f"misfit: the cart model does not explain the pushes (final residual ratio {worst:.1f} > {MISFIT_RATIO:g}{flagged}); {mass}"
    return f"the cart model fits the pushes (final residual ratio {worst:.2f}{flagged}); {mass}"


#: legend entries longer than this (characters) get a column of their own, wrapped at twice it
LEGEND_COLUMN_CHARS = 48


def _figure_legend(fig, axes, fontsize: int) -> None:
    """Put the `axes`' legend entries (each label once) under the figure: two columns of short entries, else one of
    entries wrapped to fit (a run label with a load change or a profile path ran off both sides of the figure)."""
    entries: dict[str, object] = {}
    for ax in axes:
        for handle, text in zip(*ax.get_legend_handles_labels()):
            entries.setdefault(text, handle)
    labels = list(entries)
    wide = any(len(t) > LEGEND_COLUMN_CHARS for t in labels)
    labels = [textwrap.fill(t, 2 * LEGEND_COLUMN_CHARS) for t in labels] if wide else labels
    fig.legend(list(entries.values()), labels, loc="outside lower center", ncols=1 if wide else 2, fontsize=fontsize)


def _print_demo(runs: dict[str, PushResult], table: str, out_dir: Path, seconds: float, html: bool) -> None:
    """Print the demo's table, notes and verdicts, the MuJoCo run's plant report and where its pages are."""
    cfg = runs["with estimation"].config
    p = cfg.true_params
    others = ", ".join(label for label in runs if label != "with estimation")
    print(f"Push loop, {describe(cfg)} vs {others} (true cart m={p.m:g} kg, CoM ({100 * p.dx:g}, {100 * p.dy:g}) cm):")
    print(table)
    print(unobservable_note(runs))
    for label, run in runs.items():
        print(f"{label}: {torque_verdict(run)[0]}")
        for line in load_change_lines(run) if run.config.load_changes else ():
            print(f"{label}: {line}")
        if _is_physics(run):
            print(physics_note(label, run))
    print(f"report: {out_dir.resolve()}  ({seconds:.1f} s)")
    if not html:
        return
    print(
        "  scene.html plays when opened (pause: the button in its bottom-left corner or the space bar; "
        "scene.html#t=12 opens it paused at 12 s); push_log.csv is the run's log: "
        "`cartpush estimate push_log.csv`, `cartpush view push_log.csv`"
    )
    if any(_is_physics(r) for r in runs.values()):
        print(
            f"  {PHYSICS_PAGE}: the MuJoCo run (the hand force the allocation asked for and the one its F/T sensor "
            f"measured, the casters swivelling); {out_dir.resolve() / PHYSICS_PAGE}"
        )


def before_loss(result: PushResult) -> dict:
    """Return the run's figures up to the loss of the cart, or over the whole run when it was never lost.

    A lost cart (`PushMetrics.tracking_lost_at_s`) makes every whole-run figure describe a failed push: this
    returns ``tracking_lost_at_s`` and, over t < that time, the tracking RMS and max (mm), the mass and CoM errors
    of the estimate at that time (kg, m), the peak arm torque over its limit, and the hand force allocated and
    the cart wrench's measured-minus-allocated force (RMS, N; `produced_cart_wrench`). ``valid_until_s`` is the
    end of the span they cover.
    """
    t_lost = result.metrics.tracking_lost_at_s
    keep = result.t < (t_lost if t_lost is not None else math.inf)
    if not keep.any():
        keep[0] = True
    k = int(np.flatnonzero(keep)[-1])
    err = np.hypot(*(result.q_true[keep, :2] - result.q_desired[keep, :2]).T)
    mass_error, com_error = _errors(result)
    lim = np.broadcast_to(result.effort_limit, result.arm_torque.shape[1:])
    allocated = allocated_cart_wrench(result)[keep, :2]
    produced = produced_cart_wrench(result)[keep, :2]
    rms = lambda v: float(np.sqrt(np.mean(np.sum(v**2, axis=1))))
    return {
        "tracking_lost_at_s": t_lost,
        "valid_until_s": float(result.t[k]),
        "tracking_rms_mm": float(1e3 * np.sqrt(np.mean(err**2))),
        "tracking_max_mm": float(1e3 * err.max()),
        "mass_error_kg": float(mass_error[k]),
        "com_error_m": float(com_error[k] / 100.0),
        "arm_torque_limit_ratio": float(np.max(np.abs(result.arm_torque[keep]) / lim)),
        "hand_force_rms_n": rms(allocated),
        "wrench_error_rms_n": rms(produced - allocated),
    }


def base_lateral_speed(result: PushResult) -> np.ndarray:
    """Return each robot's base speed sideways in its own frame (N, n_robots), m/s, from its recorded poses.

    A differential base (the WMRA) cannot move sideways: on the MuJoCo plant this is its wheels' physical side
    slip; a holonomic base's is its commanded sideways motion. Central differences of the true planar poses.
    """
    pose = result.robot_x[:, :, :3]
    if len(result.t) < 2:
        return np.zeros(pose.shape[:2])
    v = np.gradient(pose[:, :, :2], result.config.dt, axis=0)
    th = pose[:, :, 2]
    return -np.sin(th) * v[:, :, 0] + np.cos(th) * v[:, :, 1]
