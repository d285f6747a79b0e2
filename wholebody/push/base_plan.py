"""A mobile base's place behind the cart, planned ahead over the desired motion within its wheel speeds.

Held rigidly behind the handle, a mecanum base cannot follow the paper's Traj. 2 through its turns (0.8 m/s,
1.05 rad/s): its rim speed |vx| + |vy| + (lx + ly)|omega| reaches 2.5 m/s against a 1.1 m/s limit, the base
falls behind and the arm straightens. Where the rigid place asks too much, `plan_base` finds a path of the
base (x, y, heading per knot of `BasePlanSettings.step` s) over the known desired cart motion that

    min  rho + w_a sum_k |(p_{k+1} - 2 p_k + p_{k-1}) / h^2|^2 h
    s.t. |H R(theta_k+1/2)^T (p_{k+1} - p_k) / h| <= margin * wheel limit    (each wheel, both signs)
         r_min <= |mount_k - wrist_k| <= rho                                 (the arm's horizontal stretch)
         heading_k . (wrist_k - mount_k) >= cos(max_reach_angle) |wrist_k - mount_k|
         x of each footprint corner in {b} <= handle x + front_reach         (the base stays behind the cart)

with ``mount`` the arm's first joint axis and ``wrist`` the wrist centre of the grasp on the desired cart, and
the window's first two and last two knots at the rigid place (the plan joins the rigid reference). The heading
is free: the base lets it lag the cart's (the arm's seven joints absorb the difference), which leaves the wheels
the speed to translate. The arm's posture along the plan comes from the grasp IK, knot by knot
(`wholebody.push.robot.solve_grasp_ik`), and the whole-body QP pulls the arm to it (`BasePlan.posture`).
The base's place is kept relative to the cart (`BasePlan.target`): the plan follows the cart where it is.

A nonholonomic base (a differential drive: `blocked_twists`) gets the same plan with two more row sets: its body
twist along the blocked directions is zero on every segment with a free knot (equality rows; a differential
drive's step is an arc, WMRA paper eq. 4-7, whose chord lies along the mean heading, so v_lateral = 0 there is
exact), and its wheel rates change by at most the profile's `wheel_acceleration_limit` per second (its tracker's
bound); its windows also open where the rigid place moves it sideways (`BasePlanSettings.lateral_tolerance`).
On a straight push the rigid place has no sideways speed: no window, the plan is the rigid place.
`PushController` plans only holonomic bases: with this plan the WMRA still loses the MuJoCo Traj. 2, and the
plan costs about 140 s CPU there (two windows of 71 and 141 knots for SLSQP), docs/mujoco.md.

A window whose plan cannot meet the wheel limits at the desired speed (a handle far from the cart's axle swings
the base through a turn faster than its wheels go) is planned again for the reference read slower (`PLAN_RATES`):
at a rate r of the desired speed the wheel rates of the same path are r times those per unit of reference time,
so the plan meets limit / r. The window's rate (`BasePlan.rates`) caps the reference clock's there
(`BasePlan.rate_cap`). Only when no rate down to the slowest gives a plan within the limits (the arm cannot reach
the handle from any place the base can take) does `plan_base` raise, naming the window.

The solver is scipy's SLSQP on the rows above with their exact Jacobians (`WindowProblem`: each row depends on
one knot or on the two or three of a segment, in closed form through the headings' sines and cosines; checked
against finite differences in tests/wholebody/push/test_base_plan_jacobian.py). SLSQP's dense subproblem costs
about (rows) x (variables)^2 per iteration; it takes the rows that can bind (`WindowProblem.screened`: not a
wheel's row for the sign opposite to its rate at the rigid place, nor a heading row far from its bound), and the
plan is checked on every row (solved again with all of them when a row left out is broken). On Traj. 2 this keeps
374 of 685 rows and gives the same plan as finite differences on all rows (places within 1e-9) in 7.3-7.6 s CPU
instead of 13.3-14.1 (Ridgeback + iiwa, `build_controller(PushConfig(robot="ridgeback_iiwa", trajectory=2,
plant="mujoco", contact="fixed"))`, three windows; two runs of each, interleaved on the shared 2-core machine). SLSQP stays (rather than an SQP on a sparse QP solver) because
the tracking figures were measured with its plan: its 40 iterations find the optimal reach but stop short of
the optimal smoothing (the places move up to 0.13 m by 300 iterations).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin
from scipy.optimize import minimize

from wholebody.errors import WholeBodyError
from wholebody.motion.bases import MobileBase
from wholebody.push.base_settings import BasePlanSettings
from wholebody.push.robot import MobileManipulator, base_target, grasp_target, handle_point, solve_grasp_ik

#: the rates (shares of the desired speed) at which a window is planned, from the top, until its plan meets the
#: wheel limits (module docstring); the reference clock's slowest is 0.1 (`reference_clock.TimeScaling.rate_min`)
PLAN_RATES = (1.0, 0.8, 0.6, 0.45, 0.3, 0.2, 0.15, 0.1)


@dataclass(frozen=True)
class ArmReach:
    """The arm's geometry the plan needs: mount (x, y) in the base frame, wrist centre (x, y) in {b}, footprint."""

    mount: np.ndarray
    wrist_b: np.ndarray
    #: (4, 2) corners of the base's collision boxes' planar bounding box, in the base frame
    footprint: np.ndarray
    nominal: float


def arm_reach(mm: MobileManipulator, contact_y: float) -> ArmReach:
    """Return the `ArmReach` of robot `mm` holding the handle at `contact_y` (its state's grasp, base at rest).

    The wrist centre is the origin of the arm's last-but-one joint; it moves rigidly with the hand, so its place
    in {b} follows from the grasp. The footprint bounds the collision boxes on the base's planar joint.
    """
    wb = mm.wb
    data = wb.model.createData()
    pin.forwardKinematics(wb.model, data, wb.to_pinocchio_q(mm.x))
    pin.updateFramePlacements(wb.model, data)
    ids = [wb.model.getJointId(n) for n in wb.arm_joints]
    c, s = math.cos(mm.x[2]), math.sin(mm.x[2])
    base = pin.SE3(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), np.array([mm.x[0], mm.x[1], 0.0]))
    mount = base.actInv(data.oMi[ids[0]]).translation[:2]
    wrist_hand = data.oMf[mm.ee_id].actInv(data.oMi[ids[-2]].translation)
    wrist_b = handle_point(contact_y, mm.geometry) + mm.R_b_ee @ wrist_hand
    nominal = float(np.linalg.norm(wrist_b[:2] - (mm.base_offset_b + mount)))
    return ArmReach(mount, wrist_b[:2], _footprint(mm), nominal)


def _footprint(mm: MobileManipulator) -> np.ndarray:
    """Return the planar bounding box (4 corners, base frame) of the boxes fixed to the base's planar joint."""
    pts = []
    for g in getattr(mm.wb.robot, "collision_model", pin.GeometryModel()).geometryObjects:
        half = getattr(g.geometry, "halfSide", None)
        if g.parentJoint != 1 or half is None:
            continue
        for sx in (-1.0, 1.0):
            for sy in (-1.0, 1.0):
                pts.append((g.placement.rotation @ (half * np.array([sx, sy, 0.0])) + g.placement.translation)[:2])
    if not pts:
        return np.zeros((4, 2))
    lo, hi = np.min(pts, axis=0), np.max(pts, axis=0)
    return np.array([[hi[0], hi[1]], [hi[0], lo[1]], [lo[0], hi[1]], [lo[0], lo[1]]])


def _rot(th: np.ndarray) -> np.ndarray:
    """Return the (k, 2, 2) planar rotations of the headings `th`."""
    c, s = np.cos(th), np.sin(th)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def body_twists(poses: np.ndarray, h: float) -> np.ndarray:
    """Return the body twists (k, 3) (vx, vy, omega) of the segments between consecutive poses (k + 1, 3) h apart,
    each at the segment's mean heading. A differential drive's step is an arc (WMRA paper eq. 4-7): its chord
    points along the mean heading, so the arc's twist has vy = 0 exactly, as the drive's own."""
    d = np.diff(poses, axis=0) / h
    th = 0.5 * (poses[1:, 2] + poses[:-1, 2])
    c, s = np.cos(th), np.sin(th)
    return np.c_[c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]]


def rim_rates(poses: np.ndarray, h: float, H: np.ndarray) -> np.ndarray:
    """Return the wheel rates (k, n_wheels) of the segments between consecutive poses (k + 1, 3) h apart:
    H @ body twist (`body_twists`)."""
    return body_twists(poses, h) @ H.T


def blocked_twists(base: MobileBase) -> np.ndarray:
    """Return the body twist directions (3, m) base `base` cannot move along: the orthogonal complement of its
    wheels' twists (range of `wheel_to_body_twist`). A differential drive: (0, 1, 0), its lateral velocity
    (WMRA paper eq. 4-7: no sideways step); a holonomic base: none (3, 0)."""
    U, sv, _ = np.linalg.svd(base.wheel_to_body_twist())
    rank = int(np.sum(sv > 1e-9 * max(1.0, float(sv.max(initial=0.0)))))
    return U[:, rank:]


def rigid_poses(cart: np.ndarray, offset_b: np.ndarray) -> np.ndarray:
    """Return the base poses (k, 3) rigidly at `offset_b` (x, y in {b}) behind the cart poses `cart` (k, 3)."""
    return np.c_[cart[:, :2] + np.einsum("kij,j->ki", _rot(cart[:, 2]), offset_b), cart[:, 2]]


def wheel_windows(
    t: np.ndarray, rates: np.ndarray, limit: np.ndarray, s: BasePlanSettings, sideways: np.ndarray | None = None
) -> list[tuple[int, int]]:
    """Return the knot ranges [i0, i1] to plan: where the rigid place's wheel rates `rates` (len(t) - 1, n) pass
    `speed_margin` x `limit` or its speeds along the base's blocked twists `sideways` (len(t) - 1, m) pass
    `lateral_tolerance`, widened by `lead` before and `tail` after, merged when they overlap."""
    over = np.any(np.abs(rates) > s.speed_margin * limit, axis=1)
    if sideways is not None:
        over |= np.any(np.abs(sideways) > s.lateral_tolerance, axis=1)
    over = np.flatnonzero(over)
    out: list[tuple[int, int]] = []
    lead, tail = int(round(s.lead / s.step)), int(round(s.tail / s.step))
    for k in over:
        i0, i1 = max(0, int(k) - lead), min(len(t) - 1, int(k) + 1 + tail)
        if out and i0 <= out[-1][1]:
            out[-1] = (out[-1][0], i1)
        else:
            out.append((i0, i1))
    return out


@dataclass(frozen=True)
class BaseWheels:
    """What the plan keeps a base's wheels within (`base_wheels`)."""

    #: (n_wheels, 3) body twist -> wheel rates
    H: np.ndarray
    #: (n_wheels,) wheel speed limits (rad/s)
    limit: np.ndarray
    #: (3, m) body twist directions the base cannot move along (`blocked_twists`; m = 0: holonomic)
    blocked: np.ndarray
    #: wheel acceleration limit (rad/s^2) the plan bounds, or None
    acceleration: float | None = None


def base_wheels(mm: MobileManipulator) -> BaseWheels:
    """Return robot `mm`'s `BaseWheels`. A nonholonomic base's plan also bounds its wheel accelerations by the
    profile's `wheel_acceleration_limit`, the bound its tracker puts on the wheel rates of a differential drive (a
    holonomic base's tracker bounds its body twist's, which the plan leaves to it)."""
    base = mm.wb.base
    blocked = blocked_twists(base)
    acc = mm.profile.wheel_acceleration_limit if blocked.shape[1] else None
    limit = np.asarray(mm.wb.wheel_velocity_limit, dtype=float)
    return BaseWheels(base.twist_to_wheels(), limit, blocked, None if acc is None else float(acc))


def plan_window(
    cart: np.ndarray,
    nominal: np.ndarray,
    reach: ArmReach,
    wheels: BaseWheels,
    s: BasePlanSettings,
    front_x: float | None,
    free_end: bool = False,
) -> tuple[np.ndarray, float]:
    """Return (base poses (k, 3), largest mount-wrist distance rho) over one window of desired cart poses `cart`
    (k, 3) (module docstring); the first two knots stay at the rigid `nominal` poses, and so do the last two
    unless `free_end` (a window the run's end cuts: the base need not be back at its rigid place there). A
    nonholonomic base: no twist along its blocked directions on a segment with a free knot, bounded accelerations."""
    w = WindowProblem(cart, nominal, reach, wheels, s, front_x, free_end)
    kept = w.screened()
    res = _slsqp(w, kept)
    worst = w.worst(res.x)
    if worst > 1e-3 and w.worst(res.x, kept) <= 1e-3:  # a row left out is broken: again with every row
        res = _slsqp(w, None)
        worst = w.worst(res.x)
    if worst > 1e-3:  # rad/s, m, m/s: within the solver's tolerance
        raise WholeBodyError(f"the base plan breaks its limits by {worst:.3g} ({res.message})")
    return w.poses(res.x), float(res.x[-1])


def _slsqp(w: WindowProblem, rows: np.ndarray | None):
    """Return SLSQP's result on window `w` with its inequality rows `rows` (indices; None: all) and its equality rows,
    from the rigid place, after `BasePlanSettings.max_iterations` iterations at most."""
    ineq = {"type": "ineq", "fun": w.constraints, "jac": w.constraints_jacobian}
    if rows is not None:
        ineq = {
            "type": "ineq",
            "fun": lambda z: w.constraints(z)[rows],
            "jac": lambda z: w.constraints_jacobian(z)[rows],
        }
    cons = [ineq] + (
        [{"type": "eq", "fun": w.sideways, "jac": w.sideways_jacobian}] if w.wheels.blocked.shape[1] else []
    )
    opts = {"maxiter": w.s.max_iterations, "ftol": 1e-9}
    return minimize(w.objective, w.z0, jac=w.gradient, constraints=cons, method="SLSQP", options=opts)


class WindowProblem:
    """One window's plan (`plan_window`) as functions of z (the free knots' poses, then rho) with their exact
    Jacobians: each row depends on one knot (the arm's reach, the footprint) or on the two of a segment (its wheel
    rates, its blocked twist; three for a wheel acceleration), each through the knot's heading's sine and cosine."""

    def __init__(
        self,
        cart: np.ndarray,
        nominal: np.ndarray,
        reach: ArmReach,
        wheels: BaseWheels,
        s: BasePlanSettings,
        front_x: float | None,
        free_end: bool,
    ) -> None:
        self.cart, self.nominal, self.reach, self.wheels, self.s, self.front_x = (
            cart,
            nominal,
            reach,
            wheels,
            s,
            front_x,
        )
        n = len(cart)
        self.n, self.h, self.tail = n, s.step, 0 if free_end else 2
        self.nv = n - 2 - self.tail
        self.wrist = cart[:, :2] + np.einsum("kij,j->ki", _rot(cart[:, 2]), reach.wrist_b)
        self.z0 = np.concatenate([nominal[2 : n - self.tail].ravel(), [reach.nominal]])

    def poses(self, z: np.ndarray) -> np.ndarray:
        """Return the window's poses (n, 3): the fixed knots' nominal ones around the free knots of z."""
        return np.concatenate([self.nominal[:2], z[:-1].reshape(self.nv, 3), self.nominal[self.n - self.tail :]])

    def _free(self, JP: np.ndarray, rho: np.ndarray | None = None) -> np.ndarray:
        """Return the Jacobian over z of rows whose Jacobian over all poses is `JP` (rows, n, 3), and `rho`'s
        column (rows,) (zero when None)."""
        J = np.empty((len(JP), 3 * self.nv + 1))
        J[:, :-1] = JP[:, 2 : 2 + self.nv].reshape(len(JP), -1)
        J[:, -1] = 0.0 if rho is None else rho
        return J

    def objective(self, z: np.ndarray) -> float:
        a = np.diff(self.poses(z), 2, axis=0) / self.h**2
        return float(z[-1] + self.s.weight_acceleration * np.sum(a**2) * self.h)

    def gradient(self, z: np.ndarray) -> np.ndarray:
        """Return the objective's gradient: the acceleration term's 2 w h D2^T D2 P / h^4 on the free knots."""
        a = np.diff(self.poses(z), 2, axis=0)
        g = np.diff(np.pad(a, ((2, 2), (0, 0))), 2, axis=0) * (2.0 * self.s.weight_acceleration / self.h**3)
        return np.concatenate([g[2 : 2 + self.nv].ravel(), [1.0]])

    def _twists(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the segments' body twists (n - 1, 3) (`body_twists`) and their Jacobian (n - 1, 3, 2, 3) over
        the segment's (first, second) knot's pose."""
        h = self.h
        d = np.diff(P, axis=0) / h
        th = 0.5 * (P[1:, 2] + P[:-1, 2])
        c, s = np.cos(th), np.sin(th)
        vx, vy = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]
        J = np.zeros((len(d), 3, 2, 3))
        J[:, 0, 1, 0], J[:, 0, 1, 1], J[:, 1, 1, 0], J[:, 1, 1, 1] = c / h, s / h, -s / h, c / h
        J[:, 0, 0, :2], J[:, 1, 0, :2] = -J[:, 0, 1, :2], -J[:, 1, 1, :2]
        J[:, 0, :, 2] = 0.5 * vy[:, None]
        J[:, 1, :, 2] = -0.5 * vx[:, None]
        J[:, 2, 1, 2], J[:, 2, 0, 2] = 1.0 / h, -1.0 / h
        return np.stack([vx, vy, d[:, 2]], axis=1), J

    def _segments(self, Jseg: np.ndarray) -> np.ndarray:
        """Return the Jacobian over all poses (k * m, n, 3) of per-segment rows whose Jacobian `Jseg` (k, m, 2, 3) is
        over their segment's two knots (segment i: knots i, i + 1)."""
        k, m = Jseg.shape[:2]
        out = np.zeros((k, m, self.n, 3))
        ks = np.arange(k)
        out[ks, :, ks] = Jseg[:, :, 0]
        out[ks, :, ks + 1] = Jseg[:, :, 1]
        return out.reshape(k * m, self.n, 3)

    def _knots(self, Jk: np.ndarray) -> np.ndarray:
        """Return the Jacobian over all poses (n * m, n, 3) of per-knot rows whose Jacobian `Jk` (n, m, 3) is over
        their own knot's pose."""
        n, m = Jk.shape[:2]
        out = np.zeros((n, m, n, 3))
        out[np.arange(n), :, np.arange(n)] = Jk
        return out.reshape(n * m, n, 3)

    def _reach(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Return the mount-wrist vectors v (n, 2), their lengths d, and the Jacobians of d and of the heading's
        component of v (n, 3) over each knot's pose."""
        c, s = np.cos(P[:, 2]), np.sin(P[:, 2])
        mx, my = self.reach.mount
        Rm = np.stack([c * mx - s * my, s * mx + c * my], axis=1)
        v = self.wrist - P[:, :2] - Rm
        d = np.sqrt(v[:, 0] ** 2 + v[:, 1] ** 2)
        u = v / d[:, None]
        # dv/dx, dv/dy = -I; dv/dtheta = -perp(R m) with perp(a) = (-a_y, a_x)
        dv_th = np.stack([Rm[:, 1], -Rm[:, 0]], axis=1)
        Jd = np.stack([-u[:, 0], -u[:, 1], u[:, 0] * dv_th[:, 0] + u[:, 1] * dv_th[:, 1]], axis=1)
        along = c * v[:, 0] + s * v[:, 1]
        Ja = np.stack([-c, -s, -s * v[:, 0] + c * v[:, 1] + c * dv_th[:, 0] + s * dv_th[:, 1]], axis=1)
        return v, d, Jd, np.stack([along, *Ja.T], axis=1)

    def _front(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the footprint corners' x in {b} (n, 4) and their Jacobian (n, 4, 3) over each knot's pose."""
        c, s = np.cos(P[:, 2]), np.sin(P[:, 2])
        f = self.reach.footprint
        rx = c[:, None] * f[:, 0] - s[:, None] * f[:, 1]
        ry = s[:, None] * f[:, 0] + c[:, None] * f[:, 1]
        cc, sc = np.cos(self.cart[:, 2])[:, None], np.sin(self.cart[:, 2])[:, None]
        corners_x, corners_y = P[:, 0:1] + rx - self.cart[:, 0:1], P[:, 1:2] + ry - self.cart[:, 1:2]
        xb = cc * corners_x + sc * corners_y
        J = np.stack([np.broadcast_to(cc, xb.shape), np.broadcast_to(sc, xb.shape), -cc * ry + sc * rx], axis=2)
        return xb, J

    def _rows(self, z: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """Return the inequality rows (module docstring; each >= 0) at z and, if asked, their Jacobian over z."""
        P, rho, s, wh = self.poses(z), z[-1], self.s, self.wheels
        tw, Jt = self._twists(P)
        rates = tw @ wh.H.T
        r, lim = rates.ravel(), np.tile(s.speed_margin * wh.limit, self.n - 1)
        v, d, Jd, head = self._reach(P)
        out = [lim - r, lim + r, rho - d, d - s.min_reach_fraction * self.reach.nominal]
        out.append(head[:, 0] - math.cos(s.max_reach_angle) * d)
        if self.front_x is not None:
            xb, Jf = self._front(P)
            out.append((self.front_x - xb).ravel())
        if wh.acceleration is not None:
            acc = np.diff(rates, axis=0).ravel() / self.h
            out += [s.speed_margin * wh.acceleration - acc, s.speed_margin * wh.acceleration + acc]
        g = np.concatenate(out)
        if not jacobian:
            return g, None
        Jr = self._segments(np.einsum("ij,kjab->kiab", wh.H, Jt))
        Jk = self._knots(np.stack([Jd, head[:, 1:] - math.cos(s.max_reach_angle) * Jd], axis=1))
        Jk = Jk.reshape(self.n, 2, self.n, 3)
        blocks = [-Jr, Jr, -Jk[:, 0], Jk[:, 0], Jk[:, 1]]
        if self.front_x is not None:
            blocks.append(-self._knots(Jf))
        if wh.acceleration is not None:
            nw = len(wh.limit)
            Ja = (Jr[nw:] - Jr[:-nw]) / self.h
            blocks += [-Ja, Ja]
        ones = np.zeros(len(g))
        ones[2 * len(r) : 2 * len(r) + self.n] = 1.0
        return g, self._free(np.concatenate(blocks), ones)

    def constraints(self, z: np.ndarray) -> np.ndarray:
        return self._rows(z, False)[0]

    def constraints_jacobian(self, z: np.ndarray) -> np.ndarray:
        J = self._rows(z, True)[1]
        assert J is not None
        return J

    def screened(self) -> np.ndarray:
        """Return the inequality rows SLSQP takes (`plan_window`): all but a wheel's row for the sign opposite to its
        rate at the rigid place (slack above the wheel's limit there) and the heading rows with slack above half the
        nominal reach there. A row left out would need the plan to move its value by that much to bind; the plan
        checks every row (`worst`)."""
        g0, n, nw = self.constraints(self.z0), self.n, len(self.wheels.limit)
        keep = np.ones(len(g0), dtype=bool)
        nr = (n - 1) * nw
        keep[: 2 * nr] = g0[: 2 * nr] < np.tile(self.s.speed_margin * self.wheels.limit, 2 * (n - 1))
        heading = slice(2 * nr + 2 * n, 2 * nr + 3 * n)
        keep[heading] = g0[heading] < 0.5 * self.reach.nominal
        return np.flatnonzero(keep)

    def worst(self, z: np.ndarray, rows: np.ndarray | None = None) -> float:
        """Return the largest amount by which z breaks the inequality rows `rows` (None: all) or the equality rows."""
        g = self.constraints(z)
        worst = -float(np.min(g if rows is None else g[rows]))
        if self.wheels.blocked.shape[1]:
            worst = max(worst, float(np.abs(self.sideways(z)).max()))
        return worst

    def _sideways_span(self) -> slice:
        return slice(1, min(self.n - 1, self.n - self.tail))

    def sideways(self, z: np.ndarray) -> np.ndarray:
        """Return the equality rows: the body twist along the blocked directions on each segment with a free knot."""
        return (body_twists(self.poses(z), self.h)[self._sideways_span()] @ self.wheels.blocked).ravel()

    def sideways_jacobian(self, z: np.ndarray) -> np.ndarray:
        _, Jt = self._twists(self.poses(z))
        Jb = np.einsum("im,kiab->kmab", self.wheels.blocked, Jt)
        return self._free(self._segments(Jb)[self._rows_of(self._sideways_span(), self.wheels.blocked.shape[1])])

    def _rows_of(self, span: slice, m: int) -> slice:
        return slice(span.start * m, span.stop * m)


@dataclass(frozen=True)
class BasePlan:
    """The planned base place relative to the desired cart, and the arm's posture along it (`plan_base`)."""

    #: knot times (s) of the planned windows, one array per window
    times: tuple[np.ndarray, ...]
    #: per window (k, 3): the base's (x, y) in {b} and its heading minus the cart's
    relative: tuple[np.ndarray, ...]
    #: per window (k, n_arm): the grasp IK's arm postures along the plan
    postures: tuple[np.ndarray, ...]
    #: per window: the largest horizontal mount-wrist distance of the plan (m) and the grasp's nominal one
    stretch: tuple[float, ...]
    nominal_stretch: float
    #: per window: the share of the desired speed its plan meets the wheel limits at (1: the desired speed)
    rates: tuple[float, ...] = ()

    def rate_cap(self, s: float, decel: float) -> float:
        """Return the largest reference rate at reference time `s` from which the reference can slow, at the path
        deceleration `decel` (1/s), to each window's rate by the window's start (1: no slower window ahead)."""
        cap = 1.0
        for ts, r in zip(self.times, self.rates):
            if r >= 1.0 or s > ts[-1]:
                continue
            ahead = max(0.0, float(ts[0]) - s)
            if ahead == 0.0:
                cap = min(cap, r)
            elif math.isfinite(decel):
                cap = min(cap, math.sqrt(r * r + 2.0 * decel * ahead))
        return cap

    def _window(self, t: float) -> int | None:
        for i, ts in enumerate(self.times):
            if ts[0] <= t <= ts[-1]:
                return i
        return None

    def target(
        self, t: float, q: np.ndarray, qd: np.ndarray, offset_b: np.ndarray, rate: float = 1.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return (pose, world rates) of the base at reference time t for the cart at pose q with rates qd: the plan's
        place relative to the cart inside a window, the rigid place `offset_b` outside (`robot.base_target`); the
        place moves along the plan per unit of reference time, so at the reference's `rate` of it per second."""
        i = self._window(t)
        if i is None:
            return base_target(q, qd, offset_b)
        ts, rel = self.times[i], self.relative[i]
        o = np.array([np.interp(t, ts, rel[:, j]) for j in range(3)])
        k = min(int(np.searchsorted(ts, t, side="right")) - 1, len(ts) - 2)
        od = rate * (rel[k + 1] - rel[k]) / (ts[k + 1] - ts[k])
        c, s = math.cos(q[2]), math.sin(q[2])
        R = np.array([[c, -s], [s, c]])
        Ro = R @ o[:2]
        rates = np.concatenate((qd[:2] + qd[2] * np.array([-Ro[1], Ro[0]]) + R @ od[:2], [qd[2] + od[2]]))
        return np.concatenate((q[:2] + Ro, [q[2] + o[2]])), rates

    def posture(self, t: float) -> np.ndarray | None:
        """Return the arm posture of the plan at time t (None outside its windows)."""
        i = self._window(t)
        if i is None:
            return None
        ts, qs = self.times[i], self.postures[i]
        return np.array([np.interp(t, ts, qs[:, j]) for j in range(qs.shape[1])])


def plan_base(
    mm: MobileManipulator, trajectory, contact_y: float, settings: BasePlanSettings | None = None
) -> BasePlan:
    """Return the `BasePlan` of robot `mm` (one hand, at `contact_y`) over the desired cart motion `trajectory`
    (``duration``, ``sample(t)``): planned windows where the rigid place breaks the wheel limits or, for a
    nonholonomic base, moves it along a blocked twist (module docstring)."""
    s = settings or BasePlanSettings()
    if mm.n_hands != 1:
        raise WholeBodyError("the base plan is for a base holding the handle with one hand")
    reach, wheels = arm_reach(mm, contact_y), base_wheels(mm)
    t = np.arange(0.0, float(trajectory.duration) + 0.5 * s.step, s.step)
    cart = np.array([trajectory.sample(float(v))[0] for v in t])
    cart[:, 2] = np.unwrap(cart[:, 2])
    nominal = rigid_poses(cart, mm.base_offset_b)
    front = None if s.front_reach is None else float(handle_point(contact_y, mm.geometry)[0]) + s.front_reach
    sideways = body_twists(nominal, s.step) @ wheels.blocked if wheels.blocked.shape[1] else None
    out: tuple[list, list, list, list, list] = ([], [], [], [], [])
    for i0, i1 in wheel_windows(t, rim_rates(nominal, s.step, wheels.H), wheels.limit, s, sideways):
        C, N = cart[i0 : i1 + 1], nominal[i0 : i1 + 1]
        P, rho, rate, postures = _plan_slowed(
            mm, contact_y, C, N, (reach, wheels, front), s, i1 == len(t) - 1, (t[i0], t[i1])
        )
        rel = np.einsum("kji,kj->ki", _rot(C[:, 2]), P[:, :2] - C[:, :2])
        out[0].append(t[i0 : i1 + 1])
        out[1].append(np.c_[rel, P[:, 2] - C[:, 2]])
        out[2].append(postures)
        out[3].append(rho)
        out[4].append(rate)
    return BasePlan(tuple(out[0]), tuple(out[1]), tuple(out[2]), tuple(out[3]), reach.nominal, tuple(out[4]))


def _plan_slowed(
    mm: MobileManipulator,
    contact_y: float,
    cart: np.ndarray,
    nominal: np.ndarray,
    robot: tuple[ArmReach, BaseWheels, float | None],
    s: BasePlanSettings,
    free_end: bool,
    span: tuple[float, float],
) -> tuple[np.ndarray, float, float, np.ndarray]:
    """Return (poses, rho, rate, arm postures) of one window: `plan_window` at the first of `PLAN_RATES` whose plan
    meets the wheel limits with the reference read at that rate (limits / r, accelerations / r^2: module
    docstring) and whose every knot the grasp IK reaches (`_postures`). `robot`: (reach, wheels, front x)."""
    reach, wheels, front_x = robot
    why = ""
    for rate in PLAN_RATES:
        acc = None if wheels.acceleration is None else wheels.acceleration / rate**2
        try:
            poses, rho = plan_window(
                cart, nominal, reach, replace(wheels, limit=wheels.limit / rate, acceleration=acc), s, front_x, free_end
            )
            return poses, rho, rate, _postures(mm, cart, poses, contact_y)
        except WholeBodyError as exc:
            why = str(exc)
    raise WholeBodyError(
        f"the base cannot keep the hand on the handle from {span[0]:.1f} to {span[1]:.1f} s of the desired motion "
        f"even at {PLAN_RATES[-1]:.0%} of its speed ({why}): this robot cannot push this cart along this path"
    )


def _postures(mm: MobileManipulator, cart: np.ndarray, poses: np.ndarray, contact_y: float) -> np.ndarray:
    """Return the grasp's arm postures along the plan: each continued from the one before by `_continued_ik`
    (from the robot's grasp posture), the bounded least squares `solve_grasp_ik` where that does not converge."""
    qa = mm.x[3:].copy()
    out = []
    for q, p in zip(cart, poses):
        target, _ = grasp_target(q, np.zeros(3), contact_y, 0.0, mm.R_b_ee, mm.geometry)
        step = _continued_ik(mm, p, target, qa)
        if step is None:
            try:
                step = solve_grasp_ik(mm.wb, p, target, qa)
            except WholeBodyError:  # a branch the last posture cannot continue: again from the grasp posture
                step = solve_grasp_ik(mm.wb, p, target, mm.x[3:])
        qa = step
        out.append(qa.copy())
    return np.array(out)


def _continued_ik(
    mm: MobileManipulator, base_pose: np.ndarray, target: pin.SE3, seed: np.ndarray, iterations: int = 20
) -> np.ndarray | None:
    """Return arm joints putting the hand at `target` from `base_pose`, by Gauss-Newton steps (Pinocchio's frame
    Jacobian) from `seed` within the joint limits; None when it does not converge to 1e-9 (log6 norm)."""
    wb = mm.wb
    data = wb.model.createData()
    lo, hi = wb.arm_lower + 0.02, wb.arm_upper - 0.02
    qa = np.clip(seed, lo, hi)
    for _ in range(iterations):
        q = wb.to_pinocchio_q(np.r_[base_pose, qa])
        pin.forwardKinematics(wb.model, data, q)
        pin.updateFramePlacements(wb.model, data)
        err = pin.log6(data.oMf[mm.ee_id].actInv(target)).vector
        if np.linalg.norm(err) < 1e-9:
            return qa
        J = pin.computeFrameJacobian(wb.model, data, q, mm.ee_id, pin.LOCAL)[:, wb.arm_idx_v]
        qa = np.clip(qa + np.linalg.lstsq(J, err, rcond=None)[0], lo, hi)
    return None


def elbow_joint(mm: MobileManipulator) -> int:
    """Return the index (in the arm's joints) of the elbow: the joint that changes the distance from the arm's second
    joint (the shoulder) to its last-but-one (the wrist centre) most at the robot's grasp posture."""
    wb = mm.wb
    data = wb.model.createData()
    ids = [wb.model.getJointId(n) for n in wb.arm_joints]

    def stretch(x: np.ndarray) -> float:
        pin.forwardKinematics(wb.model, data, wb.to_pinocchio_q(x))
        return float(np.linalg.norm(data.oMi[ids[-2]].translation - data.oMi[ids[1]].translation))

    d0, eps = stretch(mm.x), 1e-6
    gains = [abs(stretch(mm.x + eps * np.eye(len(mm.x))[3 + j]) - d0) for j in range(len(ids))]
    return int(np.argmax(gains))


def guard_elbow(mm: MobileManipulator, guard: float) -> int | None:
    """Keep robot `mm`'s elbow (`elbow_joint`) `guard` rad away from straight on the side its grasp posture bends
    it, through the whole-body QP's joint position limit (the arm never passes the stretched singularity).
    Return the joint's index, or None when the tracker has no such limit."""
    from wholebody.motion.limits import JointPositionLimit

    limits = getattr(getattr(mm.tracker, "controller", None), "limits", ())
    limit = next((k for k in limits if isinstance(k, JointPositionLimit)), None)
    if limit is None:
        return None
    j = elbow_joint(mm)
    if mm.x[3 + j] >= 0.0:
        limit.lower[j] = max(limit.lower[j], guard)
    else:
        limit.upper[j] = min(limit.upper[j], -guard)
    return j
