"""The kinematic plant: ideal joint and base servos, hands that apply exactly the commanded wrench,
and the cart's exact constrained dynamics (cart paper eq. 1–7) under that wrench.

It answers a :class:`~wholebody.push.controller.PushController` through the plant seam
(`wholebody.push.plant`): motion capture with white noise, F/T readings (the hand wrench in the
sensor frame, with white noise), joint and base states read off the integrated robots.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from cart.params import CartParams
from cart.simulate import MeasurementNoise, rk4_step
from wholebody.errors import WholeBodyError
from wholebody.motion.kinematics import WholeBody
from wholebody.push.load_change import LoadChange, params_after, velocity_after
from wholebody.push.plant import Measurement, RobotCommand, RobotReading
from wholebody.push.robot import ft_measurement


def hands_to_cart_gamma(q_cart: np.ndarray, hands: Sequence[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Return Gamma_MM (fx, fy in {s}, tau about the {b} origin) of hand wrenches ``(point, [f, n])`` in the world.

    Planar part of the wrench: tau = n_z + (p - o_b) x f (paper eq. 23-24 with the contact at the hand).
    """
    gamma = np.zeros(3)
    for p, w in hands:
        rx, ry = p[0] - q_cart[0], p[1] - q_cart[1]
        gamma += np.array([w[0], w[1], w[5] + rx * w[1] - ry * w[0]])
    return gamma


class KinematicPlant:
    """Robots on ideal servos and the exact cart model (`cart.simulate.rk4_step`), one control period per step.

    ``robots``: one (WholeBody, initial state x = [base pose, arm joints], F/T frame id) per robot; a robot
    holding the handle with several hands (one base, several arms) gives ((hand frame id, F/T frame id), ...)
    instead of the F/T frame id: its commands then carry one hand wrench per hand (rows), its readings one F/T
    reading per hand (rows).

    ``load_changes``: loads put in or taken out (`wholebody.push.load_change`), each at the first period starting at
    or after its time: the cart's parameters compose with the load and its velocity takes the load's impulse.
    """

    def __init__(
        self,
        robots: Sequence[tuple[WholeBody, np.ndarray, int | Sequence[tuple[int, int]]]],
        q_cart: np.ndarray,
        qd_cart: np.ndarray,
        params: CartParams,
        noise: MeasurementNoise,
        dt: float,
        substeps: int = 2,
        seed: int | np.random.Generator = 0,
        load_changes: Sequence[LoadChange] = (),
    ) -> None:
        if dt <= 0 or substeps < 1:
            raise WholeBodyError(f"dt must be > 0 and substeps >= 1, got {dt}, {substeps}")
        self.dt = float(dt)
        self.substeps = int(substeps)
        self.params = params
        self.noise = noise
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.wbs = [wb for wb, _, _ in robots]
        self.hands = [[(wb.ee_frame_id, f)] if isinstance(f, int) else list(f) for wb, _, f in robots]
        self.x = [np.array(x, dtype=float) for _, x, _ in robots]
        self.u = [np.zeros(wb.n_u) for wb in self.wbs]
        self.q = np.array(q_cart, dtype=float)
        self.qd = np.array(qd_cart, dtype=float)
        self.t = 0.0
        self._pending = sorted(load_changes, key=lambda c: c.t)
        #: [(time it took effect, cart parameters from then on)], the first at t = 0
        self.truth_log: list[tuple[float, CartParams]] = [(0.0, params)]
        self._ft = [np.zeros(6) if len(h) == 1 else np.zeros((len(h), 6)) for h in self.hands]
        self._z = self._motion_capture()

    def _motion_capture(self) -> np.ndarray:
        """Return the cart's pose and velocity with the motion-capture noise."""
        return np.r_[self.q, self.qd] + self.rng.normal(0.0, 1.0, 6) * self.noise.measurement_std()

    def measure(self) -> Measurement:
        """Return motion capture, the robots' joint/base states and the F/T readings of the last period."""
        readings = tuple(
            RobotReading(
                base_pose=x[:3].copy(),
                base_twist=wb.wheel_map() @ u[wb.n_arm :],
                q_arm=x[3:].copy(),
                v_arm=u[: wb.n_arm].copy(),
                ft=ft.copy(),
            )
            for wb, x, u, ft in zip(self.wbs, self.x, self.u, self._ft)
        )
        return Measurement(self.t, self._z[:3].copy(), self._z[3:].copy(), readings)

    def cart_wrench(self, commands: Sequence[RobotCommand]) -> np.ndarray:
        """Return the Gamma_MM the hands apply under `commands` (each hand's wrench at its current position)."""
        hands = [
            (wb.frame_placement(x, ee).translation, w)
            for wb, x, c, ids in zip(self.wbs, self.x, commands, self.hands)
            for (ee, _), w in zip(ids, np.reshape(c.hand_wrench, (-1, 6)))
        ]
        return hands_to_cart_gamma(self.q, hands)

    def step(self, commands: Sequence[RobotCommand]) -> None:
        """Apply the commands for one period: the hands' wrench on the cart, the robots' servos, then sense."""
        if len(commands) != len(self.wbs):
            raise WholeBodyError(f"{len(commands)} commands for {len(self.wbs)} robots")
        gamma = self.cart_wrench(commands)
        for i, (wb, c) in enumerate(zip(self.wbs, commands)):
            base_u = c.wheel_rates if wb.base_input == "wheels" else c.base_twist
            u = np.r_[c.arm_velocity, base_u]
            self.x[i] = wb.integrate(self.x[i], u, self.dt)
            self.u[i] = u
            ft = []
            for (ee, fid), w in zip(self.hands[i], np.reshape(c.hand_wrench, (-1, 6))):
                oMee, oMft = wb.frame_placement(self.x[i], ee), wb.frame_placement(self.x[i], fid)
                reading = ft_measurement(w, oMee, oMft, self.rng, self.noise)  # at the period's end
                ft.append(np.r_[reading.linear, reading.angular])
            self._ft[i] = ft[0] if len(ft) == 1 else np.array(ft)
        self._apply_load_changes()
        h = self.dt / self.substeps
        for j in range(self.substeps):
            self.q, self.qd = rk4_step(self.t + j * h, self.q, self.qd, gamma, self.params, h)
        self.t += self.dt
        self._z = self._motion_capture()

    def _apply_load_changes(self) -> None:
        """Put in or take out the loads due at this period's start: new parameters, the load's impulse."""
        while self._pending and self._pending[0].t <= self.t + 1e-9:
            new = params_after(self.params, self._pending.pop(0))
            self.qd = velocity_after(self.q, self.qd, self.params, new)
            self.params = new
            self.truth_log.append((round(self.t, 9), new))

    def truth_schedule(self) -> list[tuple[float, CartParams]]:
        """Return [(t, the cart's parameters from t on)] so far, the first at t = 0."""
        return list(self.truth_log)

    def cart_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the true cart pose and velocity (for metrics; a controller never reads it)."""
        return self.q.copy(), self.qd.copy()

    def robot_states(self) -> list[np.ndarray]:
        """Return the true robot states x = [base pose, arm joints]."""
        return [x.copy() for x in self.x]
