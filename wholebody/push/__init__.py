"""The closed robot + cart loop: mobile manipulator(s) push the cart, the EKF closes the loop.

>>> from wholebody.push import PushConfig, run_push
>>> result = run_push(PushConfig(duration=5.0))          # doctest: +SKIP
>>> result.metrics.tracking_rms_mm                        # doctest: +SKIP

Modules: `config` (settings, results, interfaces), `plant` (the seam: `Measurement`,
`RobotCommand`, `Plant`), `controller` (`PushController`: measurements in, robot commands out),
`kinematic_plant` (ideal servos, the exact cart model), `robot` (one mobile manipulator: grasp,
tracker, torques, F/T), `scheduler` (contact points on the handle), `loop` (`run_push`: measure ->
controller step -> plant step), `report` (table, figures, scene, log, the demo).
"""

from __future__ import annotations

from wholebody.push.config import (
    PUSH_SENSOR_NOISE,
    TRUE_CART,
    BodyTracker,
    CartController,
    CartControllerName,
    ContactMode,
    ParameterEstimator,
    PushConfig,
    PushMetrics,
    PushResult,
)
from wholebody.push.controller import ControlDecision, PushController
from wholebody.push.kinematic_plant import KinematicPlant
from wholebody.push.loop import (
    PushSetup,
    StepRecord,
    build_controller,
    make_estimator,
    run_loop,
    run_push,
    unobservable_intervals,
)
from wholebody.push.plant import Measurement, Plant, RobotCommand, RobotReading, SimulatedPlant
from wholebody.push.plants import kinematic_plant, make_plant
from wholebody.push.report import (
    DemoResult,
    build_scene,
    comparison_table,
    demo_configs,
    describe,
    push_log,
    run_demo,
    save_figures,
    save_scene,
    unobservable_note,
    write_report,
)
from wholebody.push.robot import (
    BASE_OFFSET_X,
    GRASP_PITCH,
    PUSH_CONTROLLER,
    MobileManipulator,
    WholeBodyQPTracker,
    base_target,
    cart_se3,
    ft_measurement,
    ft_to_cart_gamma,
    grasp_rotation,
    grasp_target,
    handle_point,
    solve_grasp_ik,
)
from wholebody.push.scheduler import ContactScheduler

__all__ = [
    "ControlDecision",
    "KinematicPlant",
    "Measurement",
    "Plant",
    "SimulatedPlant",
    "PushController",
    "PushSetup",
    "RobotCommand",
    "RobotReading",
    "StepRecord",
    "build_controller",
    "kinematic_plant",
    "make_plant",
    "run_loop",
    "BASE_OFFSET_X",
    "GRASP_PITCH",
    "PUSH_CONTROLLER",
    "PUSH_SENSOR_NOISE",
    "TRUE_CART",
    "BodyTracker",
    "CartController",
    "CartControllerName",
    "ContactMode",
    "ContactScheduler",
    "DemoResult",
    "MobileManipulator",
    "ParameterEstimator",
    "PushConfig",
    "PushMetrics",
    "PushResult",
    "WholeBodyQPTracker",
    "base_target",
    "build_scene",
    "cart_se3",
    "comparison_table",
    "demo_configs",
    "describe",
    "ft_measurement",
    "ft_to_cart_gamma",
    "grasp_rotation",
    "grasp_target",
    "handle_point",
    "make_estimator",
    "push_log",
    "run_demo",
    "run_push",
    "save_figures",
    "save_scene",
    "solve_grasp_ik",
    "unobservable_intervals",
    "unobservable_note",
    "write_report",
]
