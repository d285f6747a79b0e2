"""The push comparison of docs/push.md: estimation on/off x fixed/optimal contact, two arms, Traj. 1.

Run: ``python -m studies.push_comparison`` (about a dozen 30 s closed-loop runs), or
``python -m studies.push_comparison --figures docs/img`` for the holonomic (Ridgeback + iiwa) vs
nonholonomic (WMRA) comparison: its table and the figures ``wmra_vs_ridgeback_*.png`` (`robot_figures`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from wholebody.push import PushConfig, comparison_table, describe, run_push
from wholebody.push.report import unobservable_note

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from wholebody.push import PushResult


def study_configs(duration: float = 30.0, estimator: str = "online") -> dict[str, PushConfig]:
    """Return the comparison study of docs/push.md: estimation on/off x fixed/optimal contact, two arms, Traj. 1."""
    base = PushConfig(trajectory=2, duration=duration, estimator=estimator)
    fixed = replace(base, contact="fixed", fixed_contact_y=(-0.2,))
    two = replace(base, n_arms=2, fixed_contact_y=(-0.2, 0.2))
    t1 = replace(base, trajectory=1)
    runs = [
        base,
        replace(base, estimation=False),
        fixed,
        replace(fixed, estimation=False),
        replace(fixed, fixed_contact_y=(0.15,)),
        two,
        replace(two, estimation=False),
        replace(two, contact="fixed"),
        t1,
        replace(t1, estimation=False),
        replace(t1, contact="fixed", fixed_contact_y=(-0.25,)),
        replace(t1, contact="fixed", fixed_contact_y=(0.15,)),
    ]
    return {describe(c): c for c in runs}


#: Columns of the holonomic vs nonholonomic table (docs/push.md, README "The whole loop").
ROBOT_COLUMNS = (
    ("tracking_rms_mm", "track RMS [mm]", 1.0),
    ("tracking_max_mm", "track max [mm]", 1.0),
    ("ee_force_rms_n", "hand F RMS [N]", 1.0),
    ("arm_torque_rms_nm", "tau RMS [N m]", 1.0),
    ("arm_torque_peak_nm", "tau peak [N m]", 1.0),
    ("arm_torque_limit_ratio", "tau/limit peak", 1.0),
    ("arm_torque_step_max_nm", "max dtau/sample [N m]", 1.0),
    ("base_wheel_speed_rms_rad_s", "wheel RMS [rad/s]", 1.0),
    ("base_wheel_speed_max_rad_s", "wheel max [rad/s]", 1.0),
    ("base_lateral_speed_max_m_s", "base lateral max [m/s]", 1.0),
    ("mass_error_final_kg", "m err final [kg]", 1.0),
    ("mass_error_rms_kg", "m err RMS [kg]", 1.0),
    ("mass_error_max_after_5s_kg", "m err max >5 s [kg]", 1.0),
    ("time_mass_within_1kg_s", "t within 1 kg [s]", 1.0),
    ("com_error_max_after_5s_m", "CoM err max >5 s [cm]", 100.0),
)


def robot_configs(duration: float = 30.0, estimator: str = "online") -> dict[str, PushConfig]:
    """Return holonomic (Ridgeback) vs nonholonomic (WMRA) base, both trajectories, with/without estimation."""
    out = {}
    for robot in ("ridgeback_iiwa", "wmra"):
        for traj in (1, 2):
            for est in (True, False):
                label = f"{robot} traj {traj} {estimator if est else 'no est.'}"
                out[label] = PushConfig(
                    robot=robot, trajectory=traj, estimation=est, duration=duration, estimator=estimator
                )
    return out


def robot_table(results: dict[str, object]) -> str:
    """Return the markdown table of `robot_configs` results."""
    head = "| run | " + " | ".join(h for _, h, _ in ROBOT_COLUMNS) + " |"
    rows = [head, "|" + "---|" * (len(ROBOT_COLUMNS) + 1)]
    for label, res in results.items():
        m = res.metrics.as_dict()
        cells = []
        for key, _, scale in ROBOT_COLUMNS:
            v = m[key] * scale
            cells.append(f"{v:.3g}" if key == "base_lateral_speed_max_m_s" else f"{v:.2f}")
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def robot_results(
    duration: float = 30.0, workers: int = 4, progress: bool = False, estimator: str = "online"
) -> dict[str, PushResult]:
    """Run `robot_configs` (in parallel processes) and return label -> result (with its time histories).

    ``progress``: a bar of finished runs on stderr (`wholebody.progress`).
    """
    from concurrent.futures import ProcessPoolExecutor

    from wholebody.progress import progress_bar

    cfgs = robot_configs(duration, estimator)
    with ProcessPoolExecutor(workers) as pool:
        done = progress_bar(
            pool.map(run_push, cfgs.values()), desc="push runs", total=len(cfgs), unit="run", enabled=progress
        )
        return dict(zip(cfgs, done))


def run_robot_comparison(duration: float = 30.0, workers: int = 4, estimator: str = "online") -> str:
    """Run `robot_configs` (in parallel processes) and return its table."""
    return robot_table(robot_results(duration, workers, estimator=estimator))


#: Line style of each robot (colour) and estimation (solid = EKF, dashed = no estimation) in `robot_figures`.
ROBOT_STYLE = {"ridgeback_iiwa": ("C0", "Ridgeback + iiwa (holonomic)"), "wmra": ("C3", "WMRA (differential drive)")}


def _traj_axes(fig: Figure, results: dict[str, PushResult], ylabel: str, signal, limit=None) -> None:
    """Draw `signal(result)` over time, one panel per trajectory, every robot x estimation run in it.

    `limit(result)`: an optional limit per robot, drawn once per distinct value (dotted; black and named
    "limit (all robots)" when the robots share it, else in the robot's colour). One legend, beside the
    first panel, with each run and each limit once.
    """
    trajs = sorted({r.config.trajectory for r in results.values()})
    axes = fig.subplots(len(trajs), 1, sharex=True, squeeze=False)[:, 0]
    for ax, traj in zip(axes, trajs):
        limits: dict[float, list[str]] = {}
        for label, r in results.items():
            c = r.config
            if c.trajectory != traj:
                continue
            colour, name = ROBOT_STYLE.get(c.robot, ("C7", c.robot))
            ax.plot(
                r.t,
                signal(r),
                "-" if c.estimation else "--",
                color=colour,
                lw=1.1 if c.estimation else 0.9,
                label=f"{name}, {'EKF' if c.estimation else 'no estimation'}",
            )
            if limit is not None and c.robot not in {n for names in limits.values() for n in names}:
                limits.setdefault(round(float(limit(r)), 9), []).append(c.robot)
        _limit_lines(ax, limits)
        ax.set_title(f"Traj. {traj}", fontsize=9)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1].set_xlabel("t [s]")


def _limit_lines(ax, limits: dict[float, list[str]]) -> None:
    """Draw one dotted line per distinct limit value; shared by every robot drawn: black, else the robot's colour."""
    for value, robots in limits.items():
        if len(limits) == 1:
            colour, label = "k", f"limit {value:g} ({'all robots' if len(robots) > 1 else ROBOT_STYLE[robots[0]][1]})"
        else:
            colour, name = ROBOT_STYLE.get(robots[0], ("C7", robots[0]))
            label = f"{' = '.join(ROBOT_STYLE.get(r, ('', r))[1] for r in robots)} limit {value:.3g}"
        ax.axhline(value, color=colour, ls=":", lw=1.2, label=label)


def robot_figures(results: dict[str, PushResult]) -> dict[str, Figure]:
    """Return the holonomic vs nonholonomic figures of `robot_results`, name -> Matplotlib Figure.

    One panel per trajectory, Ridgeback + iiwa blue and WMRA red, with estimation solid and without dashed:
    ``tracking`` the cart's tracking error, ``force`` the hand force |f|, ``torque`` the largest
    |tau_j| / effortLimit_j over the 7 arm joints, ``wheels`` the largest |wheel rate| with each robot's
    wheel-speed limit (dotted). No backend is selected: the caller saves or shows them.
    """
    from matplotlib.figure import Figure

    def tracking(r):
        return 1e3 * np.hypot(*(r.q_true[:, :2] - r.q_desired[:, :2]).T)

    def force(r):
        return np.linalg.norm(r.wrenches[:, 0, :3], axis=1)

    def torque_ratio(r):
        return np.max(np.abs(r.arm_torque[:, 0, :]) / r.effort_limit, axis=1)

    def wheels(r):
        return np.max(np.abs(r.wheel_rates[:, 0, :]), axis=1)

    panels = (
        ("tracking", "cart tracking error [mm]", tracking, None),
        ("force", "hand force |f| [N]", force, None),
        ("torque", "max_j |tau_j| / limit_j", torque_ratio, lambda r: 1.0),
        ("wheels", "max |wheel speed| [rad/s]", wheels, lambda r: float(np.min(r.wheel_velocity_limit))),
    )
    figs = {}
    for name, ylabel, signal, limit in panels:
        fig = Figure(figsize=(9, 5.5), layout="constrained")
        _traj_axes(fig, results, ylabel, signal, limit)
        figs[name] = fig
    return figs


def save_robot_figures(results: dict[str, PushResult], out_dir: Path, prefix: str = "wmra_vs_ridgeback_") -> list[Path]:
    """Write `robot_figures` as ``<prefix><name>.png`` in `out_dir`; return the paths."""
    from wholebody.push.report import save_figure_dict

    return save_figure_dict(robot_figures(results), out_dir, prefix)


def main(argv: list[str] | None = None) -> int:
    """CLI: the push study table, or with ``--figures DIR`` the robot comparison's table and figures."""
    import argparse

    p = argparse.ArgumentParser(prog="python -m studies.push_comparison", description=__doc__.splitlines()[0])
    p.add_argument(
        "--figures",
        type=Path,
        metavar="DIR",
        help="run the holonomic vs nonholonomic comparison (8 runs), print its table and write "
        "DIR/wmra_vs_ridgeback_{tracking,force,torque,wheels}.png",
    )
    p.add_argument("--duration", type=float, default=30.0, help="seconds per run (default 30)")
    p.add_argument("--workers", type=int, default=4, help="parallel processes for --figures (default 4)")
    p.add_argument("--estimator", default="online", choices=("online", "ekf"), help="the loop's estimator")
    args = p.parse_args(argv)
    from wholebody.progress import progress_bar, show_progress

    if args.figures is None:
        cfgs = study_configs(args.duration, args.estimator)
        runs = {label: run_push(cfgs[label]) for label in progress_bar(cfgs, desc="push runs", unit="run")}
        print(comparison_table(runs, markdown=True))
        print(unobservable_note(runs))
        return 0
    results = robot_results(args.duration, args.workers, progress=show_progress(), estimator=args.estimator)
    print(robot_table(results))
    for path in save_robot_figures(results, args.figures):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":  # python -m studies.push_comparison [--figures DIR]
    raise SystemExit(main())
