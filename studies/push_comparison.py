"""The push comparison of docs/push.md: estimation on/off x fixed/optimal contact, two arms, Traj. 1.

Run: ``python -m studies.push_comparison`` (about a dozen 30 s closed-loop runs).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Dict

from wholebody.push import PushConfig, comparison_table, describe, run_push


def study_configs(duration: float = 30.0) -> Dict[str, PushConfig]:
    """Return the comparison study of docs/push.md: estimation on/off x fixed/optimal contact, two arms, Traj. 1."""
    base = PushConfig(trajectory=2, duration=duration)
    fixed = replace(base, contact="fixed", fixed_contact_y=(-0.2,))
    two = replace(base, n_arms=2, fixed_contact_y=(-0.2, 0.2))
    t1 = replace(base, trajectory=1)
    runs = [base, replace(base, estimation=False), fixed, replace(fixed, estimation=False),
            replace(fixed, fixed_contact_y=(0.15,)), two, replace(two, estimation=False),
            replace(two, contact="fixed"), t1, replace(t1, estimation=False),
            replace(t1, contact="fixed", fixed_contact_y=(-0.25,)), replace(t1, contact="fixed", fixed_contact_y=(0.15,))]
    return {describe(c): c for c in runs}


if __name__ == "__main__":  # python -m studies.push_comparison: the table of docs/push.md
    print(comparison_table({label: run_push(cfg) for label, cfg in study_configs().items()}, markdown=True))


#: Columns of the holonomic vs nonholonomic table (docs/push.md, README "The whole loop").
ROBOT_COLUMNS = (("tracking_rms_m", "track RMS [mm]", 1e3), ("tracking_max_m", "track max [mm]", 1e3),
                 ("ee_force_rms_n", "hand F RMS [N]", 1.0), ("arm_torque_rms_nm", "tau RMS [N m]", 1.0),
                 ("arm_torque_peak_nm", "tau peak [N m]", 1.0), ("arm_torque_limit_ratio", "tau/limit peak", 1.0),
                 ("arm_torque_step_max_nm", "max dtau/sample [N m]", 1.0),
                 ("base_wheel_speed_rms_rad_s", "wheel RMS [rad/s]", 1.0),
                 ("base_wheel_speed_max_rad_s", "wheel max [rad/s]", 1.0),
                 ("base_lateral_speed_max_m_s", "base lateral max [m/s]", 1.0),
                 ("mass_error_final_kg", "m err final [kg]", 1.0), ("mass_error_rms_kg", "m err RMS [kg]", 1.0),
                 ("mass_error_max_after_5s_kg", "m err max >5 s [kg]", 1.0),
                 ("time_mass_within_1kg_s", "t within 1 kg [s]", 1.0),
                 ("com_error_max_after_5s_m", "CoM err max >5 s [cm]", 100.0))


def robot_configs(duration: float = 30.0) -> Dict[str, PushConfig]:
    """Return holonomic (Ridgeback) vs nonholonomic (WMRA) base, both trajectories, with/without estimation."""
    out = {}
    for robot in ("ridgeback_iiwa", "wmra"):
        for traj in (1, 2):
            for est in (True, False):
                label = f"{robot} traj {traj} {'EKF' if est else 'no est.'}"
                out[label] = PushConfig(robot=robot, trajectory=traj, estimation=est, duration=duration)
    return out


def robot_table(results: Dict[str, object]) -> str:
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


def run_robot_comparison(duration: float = 30.0, workers: int = 4) -> str:
    """Run `robot_configs` (in parallel processes) and return its table."""
    from concurrent.futures import ProcessPoolExecutor

    cfgs = robot_configs(duration)
    with ProcessPoolExecutor(workers) as pool:
        results = dict(zip(cfgs, pool.map(run_push, cfgs.values())))
    return robot_table(results)
