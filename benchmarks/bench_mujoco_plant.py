"""Speed and physics of the MuJoCo plant (`wholebody.push.mujoco_plant.MujocoPlant`).

Two runs per case (robot, trajectory):

- **open loop**: the commands of a kinematic-plant run (today's loop: `build_controller` +
  `kinematic_plant`) are recorded, then replayed into the MuJoCo plant: the plant's own cost (physics at
  500 Hz, arm laws, sensing) as a real-time factor, and the grasp slip and wrench error it makes of
  commands planned for the ideal cart;
- **closed loop**: `run_loop` with the push controller on the MuJoCo plant: tracking, final mass,
  the plant's report (wrench error, slip, wheel slip) and the real-time factor of the whole loop
  (controller included) and of the plant alone;
- **cart only** (``--cart-only``): no robot; the cart controller (true parameters) pushes the MuJoCo cart
  either with its generalized force Gamma_MM applied at {b}, or with the allocated hand wrench applied
  at the handle point (what a perfect arm would do): the cart's own response to the loop's wrenches.

Prints one table; never asserts a time (the real-time factor depends on the machine and its load). The closed
loop's times cover what a user's ``cartpush push --plant mujoco`` runs after its imports: ``build_controller``
(the base plan's SLSQP included), the plant's settling and ``run_loop``; the modules these import on first use (the
base plan's, the online estimator's) are imported with this script, before any timer starts. OpenBLAS runs on one
thread (``OPENBLAS_NUM_THREADS=1`` unless set), as `cartpush push` runs it. ``real_time_factor_loop`` is the
simulated duration over their wall time, ``real_time_factor_cpu`` over their process CPU time (which other
processes' load changes less), ``real_time_factor_loop_cpu`` over the CPU time of the loop's controller and plant
steps alone, ``real_time_factor_plant`` the plant's own (wall, its steps alone). The CPU time
is also given in parts: ``cpu_plan_s`` (``build_controller``: the base plan and the controller's setup),
``cpu_settle_s`` (the plant's construction and settling), ``cpu_loop_s`` (``run_loop``), and within the loop
``cpu_controller_steps_s`` and ``cpu_plant_steps_s`` (the controller's and the plant's ``step`` calls).

Prototypes of changes outside the plant (issue 28), as options: ``--grasp-torque-arm`` (the allocation's
`GraspModel.torque_arm`: the yaw torque the hand may apply, instead of lateral force at the handle's height),
``--force-feedback`` (the torque law's F/T loop gain, 0 = off), ``--no-estimation``, ``--arms 2``; a case's robot
may be a profile file (``path.toml:2``, e.g. with another ``[push] base_x``); ``--until T`` runs the 30 s
trajectory up to T s (a shorter ``--duration`` compresses the paper's trajectories).

    .venv/bin/python benchmarks/bench_mujoco_plant.py [--duration 30] [--cases ridgeback_iiwa:1,ridgeback_iiwa:2]
        [--feedforward smoothed|refreshed|command|bias|dynamics] [--force-feedback 3] [--grasp-torque-arm 0.1] [--arms 1]
        [--no-estimation] [--seed 0] [--until T] [--closed-only] [--cart-only] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # read when numpy loads: as `cartpush push` sets it

import numpy as np

import cart._kernels_identify  # noqa: F401  (imported on first use by `build_controller`: not timed)
import cart.online_estimator  # noqa: F401  (likewise)
import cart.segments  # noqa: F401  (likewise)
import wholebody.push.base_plan  # noqa: F401  (likewise)
from cart.trajectories import CartTrajectory, paper_trajectory
from wholebody.contacts.allocation import ArmLimits
from wholebody.push import PushConfig, build_controller, kinematic_plant
from wholebody.push.arm_control import TorqueArmGains
from wholebody.push.loop import run_loop
from wholebody.push.mujoco_plant import MujocoPlant, MujocoPlantConfig


#: run options besides robot, trajectory and duration (set by `main`): PushConfig fields, and ``until``
OPTIONS: dict = {}


def _config(robot: str, trajectory: int, duration: float) -> PushConfig:
    opts = dict(OPTIONS)
    until = opts.pop("until", None)
    traj: int | CartTrajectory = trajectory
    if until is not None:  # the trajectory of `duration`, run up to `until`
        traj, duration = paper_trajectory(trajectory, duration), until
    # plant="mujoco": the controller's MuJoCo defaults (base plan, tip-over bound), as `cartpush push --plant mujoco`
    return PushConfig(robot=robot, trajectory=traj, duration=duration, plant="mujoco", contact="fixed", **opts)


def open_loop(robot: str, trajectory: int, duration: float, plant_config: MujocoPlantConfig) -> dict:
    """Return the MuJoCo plant's figures under the commands of a kinematic-plant run, replayed open loop."""
    cfg = _config(robot, trajectory, duration)
    setup = build_controller(cfg)
    kin = kinematic_plant(cfg, setup)
    commands = []
    for _ in range(int(round(cfg.duration / cfg.dt))):
        cmds = setup.controller.step(kin.measure())
        commands.append(cmds)
        kin.step(cmds)
    fresh = build_controller(cfg)
    plant = MujocoPlant(fresh.controller.robots, fresh.q0, cfg.true_params, noise=cfg.noise, config=plant_config)
    t0 = time.perf_counter()
    for cmds in commands:
        plant.step(cmds)
    wall = time.perf_counter() - t0
    q_mj, _ = plant.cart_state()
    q_kin, _ = kin.cart_state()
    rep = plant.report()
    return {
        "case": f"{robot} traj {trajectory} open loop",
        "real_time_factor_plant": cfg.duration / wall,
        "grasp_slip_max_mm": 1000 * rep["grasp_slip_max_m"],
        "wrench_error_rms_n": rep["wrench_error_rms_n"],
        "hand_force_rms_n": rep["hand_force_rms_n"],
        "base_wheel_slip_max_m_s": rep["base_wheel_slip_max_m_s"],
        "final_gap_to_kinematic_cart_mm": 1000 * float(np.hypot(*(q_mj[:2] - q_kin[:2]))),
    }


def _timed_step(obj, into: list[float]) -> None:
    """Wrap `obj.step` so that each call adds its process CPU time to ``into[0]``."""
    step = obj.step

    def timed(*args, **kwargs):
        c = time.process_time()
        try:
            return step(*args, **kwargs)
        finally:
            into[0] += time.process_time() - c

    obj.step = timed


def closed_loop(robot: str, trajectory: int, duration: float, plant_config: MujocoPlantConfig) -> dict:
    """Return tracking, estimate and plant diagnostics of a closed-loop run on the MuJoCo plant, and its CPU times:
    the setup (``build_controller``, the base plan included, and the plant's settling) and the loop, whose controller
    and plant steps are also timed apart."""
    cfg = _config(robot, trajectory, duration)
    t0, c0 = time.perf_counter(), time.process_time()
    setup = build_controller(cfg)
    c_plan = time.process_time()
    plant = MujocoPlant(
        setup.controller.robots, setup.q0, cfg.true_params, noise=cfg.noise, seed=cfg.seed, config=plant_config
    )
    c_loop = time.process_time()
    ctrl_cpu, plant_cpu = [0.0], [0.0]
    _timed_step(setup.controller, ctrl_cpu)
    _timed_step(plant, plant_cpu)
    res = run_loop(cfg, setup.controller, plant)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    rep, m = plant.report(), res.metrics
    err = np.hypot(*(res.q_true[:, :2] - res.q_desired[:, :2]).T)
    lost = res.t[np.argmax(err > 0.05)] if (err > 0.05).any() else None
    return {
        "case": f"{robot} traj {trajectory} closed loop"
        + (f" {cfg.n_arms} arms" if cfg.n_arms > 1 else "")
        + ("" if cfg.estimation else " no estimation"),
        "real_time_factor_loop": cfg.duration / wall,
        "real_time_factor_cpu": cfg.duration / cpu,
        "real_time_factor_loop_cpu": cfg.duration / max(ctrl_cpu[0] + plant_cpu[0], 1e-9),
        "real_time_factor_plant": rep["real_time_factor"],
        "cpu_total_s": cpu,
        "cpu_plan_s": c_plan - c0,
        "cpu_settle_s": c_loop - c_plan,
        "cpu_loop_s": c0 + cpu - c_loop,
        "cpu_controller_steps_s": ctrl_cpu[0],
        "cpu_plant_steps_s": plant_cpu[0],
        "tracking_rms_mm": m.tracking_rms_mm,
        "tracking_max_mm": m.tracking_max_mm,
        "time_error_over_5cm_s": lost,
        "mass_final_kg": m.mass_final_kg,
        "cart_mass_effective_kg": rep["cart_mass_effective_kg"],
        "com_error_final_m": m.com_error_final_m,
        "grasp_slip_max_mm": 1000 * rep["grasp_slip_max_m"],
        "wrench_error_rms_n": rep["wrench_error_rms_n"],
        "hand_force_rms_n": rep["hand_force_rms_n"],
        "wrench_error_pct": 100 * rep["wrench_error_rms_n"] / max(rep["hand_force_rms_n"], 1e-9),
        "plant_arm_torque_limit_ratio": rep["plant_arm_torque_limit_ratio"],
        "base_wheel_limit_ratio": m.base_wheel_limit_ratio,
        "base_wheel_slip_max_m_s": rep["base_wheel_slip_max_m_s"],
    }


def cart_only(trajectory: int, duration: float, at_handle: bool) -> dict:
    """Return the tracking of the MuJoCo cart pushed by the cart controller alone (no robot, true parameters)."""
    import math

    import mujoco

    from cart import model as cart_model
    from cart.control import make_controller
    from wholebody.contacts.allocation import WrenchAllocator
    from wholebody.push import mujoco_cart as mc
    from wholebody.push.robot import handle_point

    cfg = _config("ridgeback_iiwa", trajectory, duration)
    traj = cfg.make_trajectory()
    ctrl = make_controller(cfg.controller, traj)
    cart = mc.shopping_cart(cfg.true_params)
    model, data = mc.build(cart)
    q0 = traj.sample(0.0)[0]
    mc.settle(model, data, cart, tuple(q0), 0.2)
    p = handle_point(cfg.contact_y0()[0])
    alloc = WrenchAllocator([p], cfg.arm_limits, only_motion_directions=True)
    th, th_prev, errs, lateral = q0[2], q0[2], [], []
    for k in range(int(round(duration / cfg.dt))):
        t = k * cfg.dt
        yaw = mc.yaw_of(data.xquat[1])
        th += math.remainder(yaw - th_prev, 2 * math.pi)
        th_prev = yaw
        R = data.xmat[1].reshape(3, 3)
        q = np.array([data.xpos[1][0], data.xpos[1][1], th])
        qd = np.array([data.qvel[0], data.qvel[1], (R @ data.qvel[3:6])[2]])
        gamma = ctrl.gamma(t, q, qd, cfg.true_params)
        errs.append(float(np.hypot(*(q[:2] - traj.sample(t)[0][:2]))))
        lateral.append(abs(-math.sin(th) * qd[0] + math.cos(th) * qd[1]))
        if at_handle:
            w = alloc.solve(cart_model.generalized_to_body(q, gamma), raise_on_infeasible=False).wrenches_ee[0]
            f, n, point = R @ w[:3], R @ w[3:], data.xpos[1] + R @ p
        else:
            f, n, point = np.array([gamma[0], gamma[1], 0.0]), np.array([0.0, 0.0, gamma[2]]), data.xpos[1].copy()
        for _ in range(int(round(cfg.dt / model.opt.timestep))):
            data.qfrc_applied[:] = 0.0
            mujoco.mj_applyFT(model, data, f, n, point, 1, data.qfrc_applied)
            mujoco.mj_step(model, data)
    e = np.array(errs)
    return {
        "case": f"cart only traj {trajectory} " + ("hand wrench at the handle" if at_handle else "Gamma at {b}"),
        "tracking_rms_mm": 1000 * float(np.sqrt(np.mean(e**2))),
        "tracking_max_mm": 1000 * float(e.max()),
        "rear_axle_lateral_speed_max_m_s": float(max(lateral)),
    }


def _row(d: dict) -> str:
    return "  ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in d.items())


def _set_options(args: argparse.Namespace) -> None:
    """Fill `OPTIONS` from the command line (the PushConfig fields the cases share)."""
    OPTIONS.clear()
    OPTIONS.update(n_arms=args.arms, estimation=not args.no_estimation, seed=args.seed)
    if args.grasp_torque_arm is not None:
        OPTIONS["arm_limits"] = ArmLimits().with_torque_arm(args.grasp_torque_arm)
    if args.until is not None:
        OPTIONS["until"] = args.until


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--cases", default="ridgeback_iiwa:1,ridgeback_iiwa:2")
    parser.add_argument(
        "--feedforward",
        default=TorqueArmGains.feedforward,
        choices=["smoothed", "refreshed", "command", "bias", "dynamics"],
    )
    parser.add_argument("--force-feedback", type=float, default=TorqueArmGains.force_feedback)
    parser.add_argument("--grasp-torque-arm", type=float, default=None, help="allocation GraspModel.torque_arm (m)")
    parser.add_argument("--arms", type=int, default=1)
    parser.add_argument("--no-estimation", action="store_true")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--until", type=float, default=None, help="run the trajectory of --duration up to T s")
    parser.add_argument("--closed-only", action="store_true", help="skip the open-loop replay")
    parser.add_argument("--cart-only", action="store_true", help="also push the cart alone (no robot)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    _set_options(args)
    gains = TorqueArmGains(feedforward=args.feedforward, force_feedback=args.force_feedback)
    plant_config = MujocoPlantConfig(torque_gains=gains)
    rows = []
    for case in filter(None, args.cases.split(",")):
        robot, traj = case.rsplit(":", 1)
        if not args.closed_only:
            rows.append(open_loop(robot, int(traj), args.duration, plant_config))
        rows.append(closed_loop(robot, int(traj), args.duration, plant_config))
    if args.cart_only:
        for traj in (1, 2):
            rows += [cart_only(traj, args.duration, at_handle) for at_handle in (False, True)]
    if args.json:
        print(json.dumps(rows, indent=1))
    else:
        for r in rows:
            print(_row(r))


if __name__ == "__main__":
    main()
