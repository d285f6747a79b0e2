"""Both plants x both robots x one and two robots x Traj. 1 and 2 x with and without estimation: docs/push.md's table.

PYTHONPATH=. .venv/bin/python -m studies.plant_table --workers 1 [--duration 30] [--arms 1 2]
    [--plants kinematic mujoco] [--robots ridgeback_iiwa wmra] [--base-plan auto|on|off]
    [--tip-bound auto|on|off] [--grip-torque-arm M]

The kinematic plant holds the optimal contact, the MuJoCo plant a fixed grip (y = -0.2 m; two robots -0.2 / +0.2 m,
as `cartpush push --arms 2`). A run that loses the cart (more than 25 cm from its desired place) is reported with
the time of the loss and its figures before it (`wholebody.push.report.before_loss`); its whole-run grip and wheel
slips are left out. A configuration the robots cannot take (a fixed contact out of reach) gets its one-line reason.
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from wholebody.push import PushConfig, run_push
from wholebody.push.config import PUSH_ARM_LIMITS
from wholebody.push.base_settings import BasePlanSettings
from wholebody.push.report import base_lateral_speed, before_loss

ROBOTS = ("ridgeback_iiwa", "wmra")
PLANTS = ("kinematic", "mujoco")
#: the two hands' fixed contacts on the handle (m), as `cartpush push --arms 2`
TWO_CONTACTS = (-0.2, 0.2)


@dataclass(frozen=True)
class Case:
    """One row: the plant, the robot and how many, the trajectory, estimation on or off, and the shared options."""

    plant: str
    robot: str
    arms: int
    traj: int
    estimation: bool
    duration: float = 30.0
    base_plan: str = "auto"
    tip_bound: str = "auto"
    grip_torque_arm: float | None = None

    def config(self) -> PushConfig:
        """Return the run's configuration."""
        limits = (
            PUSH_ARM_LIMITS if self.grip_torque_arm is None else PUSH_ARM_LIMITS.with_torque_arm(self.grip_torque_arm)
        )
        return PushConfig(
            trajectory=self.traj,
            duration=self.duration,
            plant="mujoco" if self.plant == "mujoco" else "kinematic",
            robot=self.robot,
            n_arms=self.arms,
            estimation=self.estimation,
            contact="fixed" if self.plant == "mujoco" else "optimal",
            fixed_contact_y=TWO_CONTACTS if self.arms == 2 and self.plant == "mujoco" else None,
            base_plan="auto" if self.base_plan == "auto" else (BasePlanSettings() if self.base_plan == "on" else None),
            tip_bound="auto" if self.tip_bound == "auto" else self.tip_bound == "on",
            arm_limits=limits,
        )


def one(case: Case) -> dict:
    """Return the row of one run (its one-line reason in place of numbers when it cannot run)."""
    row = {"case": case}
    t0 = time.process_time()
    try:
        r = run_push(case.config())
    except Exception as exc:  # a study: report what stopped the run, in one line
        return {**row, "error": f"{type(exc).__name__}: {exc}".splitlines()[0][:160]}
    rep, b = r.plant_report or {}, before_loss(r)
    lost = b["tracking_lost_at_s"] is not None
    slip = rep.get("grasp_slip_max_m")
    return {
        **row,
        **b,
        "physics": rep.get("plant") == "mujoco",
        "grip_slip_mm": None if lost or slip is None else 1e3 * slip,
        "wheel_slip": None if lost else rep.get("base_wheel_slip_max_m_s"),
        "base_lateral": float(np.abs(base_lateral_speed(r)[r.t < b["valid_until_s"] + 1e-9]).max()),
        "rtf": rep.get("real_time_factor"),
        "cpu_s": time.process_time() - t0,
    }


def _f(v: float | None, fmt: str) -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else fmt.format(v)


HEAD = (
    "| plant | robot | arms | traj | estimation | lost at (s) | track RMS / max [mm] | mass err [kg] | CoM err [cm] "
    "| tau/limit | wrench err / hand F RMS [N] | grip slip [mm] | wheel slip [m/s] | base lateral max [m/s] "
    "| real time x |"
)


def _row(r: dict) -> str:
    """Return one markdown row."""
    c: Case = r["case"]
    lead = f"| {c.plant} | {c.robot} | {c.arms} | {c.traj} | {'on' if c.estimation else 'off'} |"
    if "error" in r:
        return lead + f" cannot run: {r['error'].replace('|', '/')} |" + " |" * 9
    wrench = f"{r['wrench_error_rms_n']:.2f} / {r['hand_force_rms_n']:.2f}" if r["physics"] else "-"
    return lead + " ".join(
        (
            f" {_f(r['tracking_lost_at_s'], '{:.2f}')} |",
            f"{r['tracking_rms_mm']:.1f} / {r['tracking_max_mm']:.1f} |",
            f"{r['mass_error_kg']:.2f} |",
            f"{100 * r['com_error_m']:.1f} |",
            f"{r['arm_torque_limit_ratio']:.2f} |",
            f"{wrench} |",
            f"{_f(r['grip_slip_mm'], '{:.2f}')} |",
            f"{_f(r['wheel_slip'], '{:.3f}')} |",
            f"{r['base_lateral']:.3f} |",
            f"{_f(r['rtf'], '{:.1f}')} |",
        )
    )


def table(rows: list[dict]) -> str:
    """Return the markdown table of the rows (a lost run's figures are those before the loss)."""
    return "\n".join([HEAD, "|" + "---|" * HEAD.count(" | ") + "---|"] + [_row(r) for r in rows])


def cases(a: argparse.Namespace) -> list[Case]:
    """Return the table's runs in its row order."""
    return [
        Case(p, rb, n, t, e, a.duration, a.base_plan, a.tip_bound, a.grip_torque_arm)
        for p, rb, n, t, e in itertools.product(a.plants, a.robots, a.arms, (1, 2), (True, False))
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--arms", type=int, nargs="+", default=[1, 2], choices=(1, 2))
    ap.add_argument("--plants", nargs="+", default=list(PLANTS), choices=PLANTS)
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    for flag in ("--base-plan", "--tip-bound"):
        ap.add_argument(flag, default="auto", choices=("auto", "on", "off"), help="as cartpush push (default auto)")
    ap.add_argument("--grip-torque-arm", type=float, default=None, metavar="M", help="as cartpush push")
    a = ap.parse_args()
    t0 = time.process_time()
    with ProcessPoolExecutor(a.workers) as pool:
        rows = list(pool.map(one, cases(a)))
    print(table(rows))
    cpu = time.process_time() - t0 + sum(r.get("cpu_s", 0.0) for r in rows)
    print(f"\n{len(rows)} runs, {cpu:.0f} s CPU in the runs and this process")


if __name__ == "__main__":
    main()
