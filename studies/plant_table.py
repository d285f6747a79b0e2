"""Both plants x both robots x Traj. 1 and 2 x with and without estimation: the table of docs/push.md.

python -m studies.plant_table [--duration 30] [--workers 2]
"""

from __future__ import annotations

import argparse
import itertools
from concurrent.futures import ProcessPoolExecutor

from wholebody.push import PushConfig, run_push

ROBOTS = ("ridgeback_iiwa", "wmra")


def one(case: tuple[str, str, int, bool, float]) -> dict:
    """Return the row of one run (an error message in place of numbers when it cannot run)."""
    plant, robot, traj, est, duration = case
    contact = "fixed" if plant == "mujoco" else "optimal"
    row = {"plant": plant, "robot": robot, "traj": traj, "estimation": est}
    try:
        r = run_push(
            PushConfig(trajectory=traj, duration=duration, plant=plant, robot=robot, estimation=est, contact=contact)
        )
    except Exception as exc:  # a study: report what stopped the run
        return {**row, "error": f"{type(exc).__name__}: {exc}"[:80]}
    m, rep = r.metrics, r.plant_report or {}
    return {
        **row,
        "track_rms_mm": m.tracking_rms_mm,
        "mass_err_kg": m.mass_error_final_kg,
        "com_err_cm": 100 * m.com_error_final_m,
        "tau_ratio": m.arm_torque_limit_ratio,
        "wrench_err": rep.get("wrench_error_rms_n"),
        "hand_f_rms": rep.get("hand_force_rms_n", m.ee_force_rms_n),
        "slip_mm": None if rep.get("grasp_slip_max_m") is None else 1e3 * rep["grasp_slip_max_m"],
        "wheel_slip": rep.get("base_wheel_slip_max_m_s"),
        "rtf": rep.get("real_time_factor"),
    }


def _f(v, fmt: str) -> str:
    return "-" if v is None else fmt.format(v)


def table(rows: list[dict]) -> str:
    """Return the markdown table of the rows."""
    head = "| plant | robot | traj | estimation | track RMS [mm] | mass err [kg] | CoM err [cm] | tau/limit | wrench err / hand F RMS [N] | grip slip [mm] | wheel slip [m/s] | real time x |"
    out = [head, "|" + "---|" * 12]
    for r in rows:
        if "error" in r:
            out.append(f"| {r['plant']} | {r['robot']} | {r['traj']} | {r['estimation']} | {r['error']} |" + " |" * 7)
            continue
        we = "-" if r["wrench_err"] is None else f"{r['wrench_err']:.2f} / {r['hand_f_rms']:.2f}"
        out.append(
            f"| {r['plant']} | {r['robot']} | {r['traj']} | {'on' if r['estimation'] else 'off'} | "
            f"{_f(r['track_rms_mm'], '{:.1f}')} | {_f(r['mass_err_kg'], '{:.2f}')} | {_f(r['com_err_cm'], '{:.1f}')} | "
            f"{_f(r['tau_ratio'], '{:.2f}')} | {we} | {_f(r['slip_mm'], '{:.2f}')} | {_f(r['wheel_slip'], '{:.3f}')} | "
            f"{_f(r['rtf'], '{:.1f}')} |"
        )
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    cases = [
        (p, rb, t, e, a.duration)
        for p, rb, t, e in itertools.product(("kinematic", "mujoco"), ROBOTS, (1, 2), (True, False))
    ]
    with ProcessPoolExecutor(a.workers) as pool:
        rows = list(pool.map(one, cases))
    print(table(rows))


if __name__ == "__main__":
    main()
