"""Recorded cases of the resolved-rate controller (inputs and outputs), for `test_control_reference.py`.

Each case runs the controller in closed loop and records, per step, the inputs of `step` and its
outputs, plus the QP's box and inequalities (`bounds`, `inequalities`). The reference file
`tests/wholebody/motion/data/control_reference.npz` holds the outputs of the controller as built before it was
composed from tasks and limits; regenerate it (only when the controller's behaviour is meant to change) with
`.venv/bin/python -m tests.wholebody.motion.control_reference`.
"""

from __future__ import annotations

import json
from collections import defaultdict
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin

import robots
from wholebody.motion.experiments import initial_state
from wholebody.motion import control, qp
from wholebody.motion.control import ControllerConfig, ResolvedRateController, SafetyBand
from wholebody.motion.kinematics import wholebody_for

REFERENCE = Path(__file__).parent / "data" / "control_reference.npz"

#: name -> (robot, base input, ControllerConfig overrides, SafetyBand kwargs or None, steps, target kind)
CASES: dict[str, tuple[str, str, dict, dict | None, int, str]] = {
    "wmra_default": ("wmra", "wheels", {}, None, 30, "circle"),
    "wmra_manipulability": (
        "wmra",
        "wheels",
        {"secondary": "manipulability", "secondary_weight": 1e-2},
        None,
        10,
        "circle",
    ),
    "wmra_band": ("wmra", "wheels", {}, {"radius": 0.3}, 120, "far"),
    "wmra_band_moving": ("wmra", "wheels", {"secondary": "none"}, {"radius": 0.25, "lookahead": 0.05}, 60, "far"),
    "wmra_push_like": (
        "wmra",
        "wheels",
        {
            "gain": 20.0,
            "damping": 1e-7,
            "secondary_weight": 1e-4,
            "max_linear_speed": 3.0,
            "max_angular_speed": 3.0,
            "limit_margin": 0.05,
            "solver": "daqp",
            "fallback_solver": "proxqp",
            "base_weight": 1e-3,
            "base_lookahead": 0.2,
            "wheel_acceleration_limit": 5.0,
        },
        None,
        40,
        "circle",
    ),
    "wmra_limits": ("wmra", "wheels", {"secondary": "none"}, None, 20, "joint_limit"),
    "ridgeback_twist_far": ("ridgeback_iiwa", "twist", {}, None, 20, "far"),
    "ridgeback_wheels_base": (
        "ridgeback_iiwa",
        "wheels",
        {"base_weight": 1e-2, "wheel_acceleration_limit": 20.0},
        {"radius": 0.4},
        40,
        "circle",
    ),
    "ridgeback_twist_push": (
        "ridgeback_iiwa",
        "twist",
        {
            "damping": 1e-7,
            "secondary_weight": 1e-4,
            "limit_margin": 0.05,
            "solver": "daqp",
            "fallback_solver": "proxqp",
            "base_weight": 1e-3,
        },
        None,
        40,
        "circle",
    ),
}

#: StepResult fields recorded per step
FIELDS = (
    "u",
    "position_error",
    "orientation_error",
    "residual",
    "sigma_min",
    "singular",
    "saturated",
    "solver_ok",
    "fallback_used",
)


#: The solvers the reference was recorded with, unless a case names its own: ProxQP, daqp as fallback.
RECORDED_SOLVERS = {"solver": "proxqp", "fallback_solver": "daqp"}


def build(name: str, warm_start: bool = False) -> ResolvedRateController:
    """Return a fresh controller of case `name` (cold ProxQP solves by default: those the reference recorded)."""
    robot, base_input, cfg, band, _, _ = CASES[name]
    wb = wholebody_for(robots.load(robot), base_input)
    config = replace(ControllerConfig(warm_start=warm_start), **{**RECORDED_SOLVERS, **cfg})
    return ResolvedRateController(wb, config, band=None if band is None else SafetyBand(**band))


def capture_qps(monkeypatch) -> list[tuple]:
    """Make every `SolverChoice.solve` record a copy of its QP (H, c, G, h, lb, ub); return the growing list."""
    qps = []
    real = qp.SolverChoice.solve

    def spy(self, H, c, G, h, lb, ub, G_changed=True):
        qps.append(tuple(None if a is None else a.copy() for a in (H, c, G, h, lb, ub)))
        return real(self, H, c, G, h, lb, ub, G_changed)

    monkeypatch.setattr(qp.SolverChoice, "solve", spy)
    return qps


def _targets(kind: str, T0: pin.SE3, k: int, dt: float) -> tuple[pin.SE3, np.ndarray | None]:
    t = k * dt
    if kind == "circle":
        r, w = 0.05, 3.0
        p = T0.translation + r * np.array([np.sin(w * t), 1 - np.cos(w * t), 0.2 * t])
        v = np.r_[r * w * np.cos(w * t), r * w * np.sin(w * t), 0.2 * r, 0.0, 0.0, 0.1]
        return pin.SE3(pin.exp3(np.array([0.0, 0.0, 0.1 * t])) @ T0.rotation, p), v
    if kind == "far":
        return pin.SE3(pin.exp3(np.array([0.3, -0.2, 0.5])) @ T0.rotation, T0.translation + [2.0, 1.0, 0.3]), None
    return T0, None  # joint_limit: the feed-forward is set by the caller


@contextmanager
def _qp_spy():
    """Yield a list receiving each step's QP (Hessian, linear term).

    Taken from the per-step `_solve(P, q, ...)` of the controller before the task/limit split (which wrote
    the reference file), else from the workspace's stacked cost.
    """
    log: list[tuple[np.ndarray, np.ndarray]] = []
    owner, attr = (control, "_solve") if hasattr(control, "_solve") else (qp.QPWorkspace, "objective")
    real = getattr(owner, attr)

    def spy(*args):
        out = real(*args)
        P, q = args[:2] if attr == "_solve" else out
        log.append((P.copy(), q.copy()))
        return out

    setattr(owner, attr, spy)
    try:
        yield log
    finally:
        setattr(owner, attr, real)


def _step_inputs(name: str, kind: str, wb, x: np.ndarray, T0: pin.SE3, k: int) -> dict:
    """Return the keyword inputs of step k of a case."""
    dt = 0.01 if k % 3 else 0.02
    T_des, v = _targets(kind, T0, k, dt)
    if kind == "joint_limit":
        v = wb.combined_jacobian(x)[:, 5] * 0.9
    moving = name.endswith("moving")
    return dict(
        T_des=T_des,
        v_des=v,
        dt=dt,
        band_center=np.array([0.01 * k * dt, -0.02 * k * dt]) if moving else np.zeros(2),
        band_center_velocity=np.array([0.01, -0.02]) if moving else np.zeros(2),
        base_target=np.array([x[0] - 0.1 + 0.2 * k * dt, x[1] + 0.05, x[2] + 0.1]),
        base_target_velocity=np.array([0.2, 0.0, 0.05]),
    )


def record(name: str) -> dict[str, np.ndarray]:
    """Run case `name` in closed loop; return its per-step inputs and outputs as arrays."""
    ctrl = build(name)
    wb = ctrl.wb
    kind = CASES[name][5]
    x = initial_state(wb)
    if kind == "joint_limit":
        x[3 + 5] = wb.arm_upper[5] - 2e-3
    T0 = wb.ee_placement(x)
    rows: dict[str, list] = defaultdict(list)
    empty_G, empty_h = np.zeros((0, wb.n_u)), np.zeros(0)
    with _qp_spy() as qp_log:
        for k in range(CASES[name][4]):
            a = _step_inputs(name, kind, wb, x, T0, k)
            bc, bcv, dt = a["band_center"], a["band_center_velocity"], a["dt"]
            rows["lb"].append(ctrl.bounds(x, dt)[0])
            rows["ub"].append(ctrl.bounds(x, dt)[1])
            for suffix, relax in (("", False), ("_relax", True)):
                G, h = ctrl.inequalities(x, dt, bc, bcv, relax=relax)
                rows["G" + suffix].append(empty_G if G is None else G)
                rows["h" + suffix].append(empty_h if h is None else h)
            res = ctrl.step(x, **a)
            rows["x"].append(x.copy())
            for key, val in a.items():
                if key == "T_des":
                    val = val.homogeneous
                rows[key].append(np.full(6, np.nan) if val is None else val)
            for f in FIELDS:
                rows[f].append(getattr(res, f))
            rows["P"].append(qp_log[-1][0])
            rows["q"].append(qp_log[-1][1])
            x = wb.integrate(x, res.u, dt)
    return {k: np.asarray(v) for k, v in rows.items()}


def main() -> None:
    """Record every case into REFERENCE."""
    out = {"cases": np.array(json.dumps(list(CASES)))}
    for name in CASES:
        for k, v in record(name).items():
            out[f"{name}/{k}"] = v
    REFERENCE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(REFERENCE, **out)
    print(f"wrote {REFERENCE}")


if __name__ == "__main__":
    main()
