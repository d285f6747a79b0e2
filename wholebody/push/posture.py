"""The push posture of a robot its profile does not tune: grasp, base placement and arm posture by IK.

`solve_push_placement` searches the grasp orientation (pitch and roll about the tool axis), the base's
place behind the handle and the arm's posture that hold the handle's contact point with the largest
joint-limit margin and the least gravity torque: a bounded least-squares IK (scipy) per candidate, then
the exact grasp IK (`wholebody.push.robot.solve_grasp_ik`) with the base at the place found.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from robots.profiles import RobotProfile
from wholebody.contacts.handle import contact_grid
from wholebody.contacts.placement import REACH_MIN_SIGMA
from wholebody.errors import WholeBodyError
from wholebody.motion.kinematics import WholeBody

#: Lateral offset (m) of each base beyond its contact when two robots push side by side (`wholebody.push.robot`).
TWO_ARM_BASE_SPREAD = 0.25

#: Grasp pitches (rad) and rolls about the tool axis (rad) tried when the profile gives none.
PITCHES = (0.8, 0.4, 0.0, 1.2)
ROLLS = (0.0, math.pi / 2, math.pi, -math.pi / 2)
#: Base x relative to the handle, in {b} (m): searched in this range (the base stays behind the handle).
BASE_X_RANGE = (-1.4, -0.45)
#: Lateral base offset searched (m).
BASE_Y_RANGE = (-0.6, 0.6)
#: Joint-limit margin (rad or m) of the search: above the reach map's (`REACH_JOINT_MARGIN`, 0.15 rad).
SEARCH_MARGIN = 0.2
#: Weight of the base's lateral offset from its contact in the search (per m; the joint pull is 0.05 per half range).
BASE_Y_WEIGHT = 0.5
#: Weight of the base's distance behind the closest place (per m): a base close to the handle swings less
#: sideways when the cart turns (a differential base must follow that swing with its wheels alone).
BASE_X_WEIGHT = 0.3
#: How many of the best placements of a fixed base are ranked by the handle length they reach.
REACH_CANDIDATES = 4
#: Base places (m behind the handle, in {b}) tried one by one when the free search finds no posture: its pull
#: to the closest place can end where the arm is stretched (below `REACH_MIN_SIGMA`) while a place farther back
#: holds the handle with room to move.
FALLBACK_BASE_X = (-0.6, -0.75, -0.9, -1.05, -1.2)


@dataclass(frozen=True)
class Placement:
    """One solved push placement: grasp, base offset in {b}, arm posture and its score."""

    pitch: float
    roll: float
    base_x: float
    base_dy: float
    arm: np.ndarray
    margin: float
    gravity_ratio: float
    #: length (m) of the handle the arm holds with margin from this base place (0 for a base that follows)
    reach: float = 0.0

    @property
    def score(self) -> float:
        """Return the ranking score: reachable handle length (m) + joint-limit margin (fraction of range) less
        any gravity load above half the limits."""
        return (
            self.reach
            + self.margin
            - max(0.0, self.gravity_ratio - 0.5)
            - BASE_X_WEIGHT * (BASE_X_RANGE[1] - self.base_x)
        )


def joint_margin(wb: WholeBody, q: np.ndarray) -> float:
    """Return the smallest distance of the arm joints to their limits, as a fraction of each joint's range."""
    span = wb.arm_upper - wb.arm_lower
    return float(np.min(np.minimum(q - wb.arm_lower, wb.arm_upper - q) / span))


def arm_sigma(wb: WholeBody, x: np.ndarray) -> float:
    """Return the smallest singular value of the arm's part of the hand Jacobian at state x."""
    return float(np.linalg.svd(wb.combined_jacobian(x)[:, : wb.n_arm], compute_uv=False)[-1])


def gravity_ratio(wb: WholeBody, x: np.ndarray) -> float:
    """Return max_j |g_j(q)| / tau_max_j of the arm at state x (gravity alone against the URDF's limits)."""
    g = pin.computeGeneralizedGravity(wb.model, wb.model.createData(), wb.to_pinocchio_q(x))[wb.arm_idx_v]
    lim = wb.arm_effort_limit
    return float(np.max(np.abs(g) / np.where(lim > 0, lim, np.inf)))


def _search(
    wb: WholeBody, prof: RobotProfile, R_b_ee: np.ndarray, contact_y: float, seed: np.ndarray, bx0: float
) -> np.ndarray | None:
    """Return [bx, dy, q...] of a bounded least-squares IK with a pull to mid-range, or None."""
    from scipy.optimize import least_squares

    from wholebody.push.robot import base_target, grasp_target, handle_point

    zero = np.zeros(3)
    target, _ = grasp_target(zero, zero, contact_y, 0.0, R_b_ee)
    hx = handle_point(contact_y)[0]
    margin = np.minimum(SEARCH_MARGIN, 0.25 * (wb.arm_upper - wb.arm_lower))  # short prismatic joints: a quarter
    lo_q, hi_q = wb.arm_lower + margin, wb.arm_upper - margin
    mid, half = 0.5 * (wb.arm_lower + wb.arm_upper), 0.5 * (wb.arm_upper - wb.arm_lower)
    fix_x, fix_y = prof.push_base_x, prof.push_base_y
    lo = np.r_[BASE_X_RANGE[0], BASE_Y_RANGE[0], lo_q]
    hi = np.r_[BASE_X_RANGE[1], BASE_Y_RANGE[1], hi_q]
    x = np.zeros(3 + wb.n_arm)

    def state(z: np.ndarray) -> np.ndarray:
        bx = z[0] if fix_x is None else fix_x
        by = contact_y + z[1] if fix_y is None else fix_y
        x[:3] = base_target(zero, zero, np.array([hx + bx, by]))[0]
        x[3:] = z[2:]
        return x

    def residual(z: np.ndarray) -> np.ndarray:
        err = pin.log6(wb.ee_placement(state(z)).actInv(target)).vector
        return np.r_[
            10.0 * err, 0.05 * (z[2:] - mid) / half, BASE_Y_WEIGHT * z[1], BASE_X_WEIGHT * (z[0] - BASE_X_RANGE[1])
        ]

    z0 = np.clip(np.r_[bx0, 0.0, seed], lo + 1e-9, hi - 1e-9)
    sol = least_squares(residual, z0, bounds=(lo, hi), xtol=1e-10, ftol=1e-10, max_nfev=400)
    return sol.x if np.linalg.norm(sol.fun[:6]) < 1e-3 else None


def _contact_y(prof: RobotProfile) -> float:
    """Return the profile's push contact point y (m); `push_profile` sets it before the posture search."""
    if prof.push_contact_y is None:
        raise WholeBodyError(f"robot {prof.name!r}: the push posture search needs the profile's contact_y")
    return prof.push_contact_y


def _reach_length(wb: WholeBody, prof: RobotProfile, p: Placement) -> float:
    """Return the length (m) of the handle an arm holds with margin from a placement's base pose (`reach_map`)."""
    from wholebody.contacts.placement import reach_map
    from wholebody.push.robot import base_target, grasp_rotation, grasp_target, handle_point

    zero = np.zeros(3)
    y0, qa = _contact_y(prof), p.arm
    pose = base_target(zero, zero, np.array([handle_point(y0)[0] + p.base_x, y0 + p.base_dy]))[0]
    R_b_ee = grasp_rotation(p.pitch, p.roll, prof.arms[0].tool_axis or "z")
    ys = contact_grid()
    try:
        rm = reach_map(wb, lambda y: pose, lambda y: grasp_target(zero, zero, float(y), 0.0, R_b_ee)[0], ys, qa, y0)
    except WholeBodyError:
        return 0.0
    ok = rm.y[rm.reachable]
    return float(ok.max() - ok.min()) if ok.size else 0.0


def _side_margin(
    wb: WholeBody, prof: RobotProfile, R_b_ee: np.ndarray, bx: float, dy: float, seed: np.ndarray
) -> float:
    """Return the joint margin (fraction of range) of the grasp with the base `dy` beside the contact (-1: none)."""
    from wholebody.push.robot import base_target, grasp_target, handle_point, solve_grasp_ik

    zero = np.zeros(3)
    y0 = _contact_y(prof)
    pose = base_target(zero, zero, np.array([handle_point(y0)[0] + bx, y0 + dy]))[0]
    try:
        return joint_margin(wb, solve_grasp_ik(wb, pose, grasp_target(zero, zero, y0, 0.0, R_b_ee)[0], seed))
    except WholeBodyError:
        return -1.0


def _candidates(prof: RobotProfile) -> list[tuple[float, float]]:
    pitches = PITCHES if prof.grasp_pitch is None else (prof.grasp_pitch,)
    rolls = ROLLS if prof.grasp_roll is None else (prof.grasp_roll,)
    return [(p, r) for p in pitches for r in rolls]


def _placement(wb: WholeBody, prof: RobotProfile, pitch: float, roll: float, axis: str) -> Placement | None:
    """Return the best placement of one grasp orientation (two base seeds), or None if the arm cannot reach."""
    from wholebody.push.robot import base_target, grasp_rotation, grasp_target, handle_point, solve_grasp_ik

    y0 = _contact_y(prof)
    R = grasp_rotation(pitch, roll, axis)
    mid = 0.5 * (wb.arm_lower + wb.arm_upper)
    best = None
    for bx0 in (-0.6, -0.9):
        z = _search(wb, prof, R, y0, mid if prof.push_arm_seed is None else np.asarray(prof.push_arm_seed), bx0)
        if z is None:
            continue
        bx = z[0] if prof.push_base_x is None else prof.push_base_x
        dy = z[1] if prof.push_base_y is None else prof.push_base_y - y0
        zero = np.zeros(3)
        pose = base_target(zero, zero, np.array([handle_point(y0)[0] + bx, y0 + dy]))[0]
        try:
            qa = solve_grasp_ik(wb, pose, grasp_target(zero, zero, y0, 0.0, R)[0], z[2:])
        except WholeBodyError:
            continue
        if arm_sigma(wb, np.r_[pose, qa]) < REACH_MIN_SIGMA:  # near full extension: no room to move the hand
            continue
        margin = joint_margin(wb, qa)
        if prof.base == "holonomic":  # two robots side by side stand TWO_ARM_BASE_SPREAD beside their contacts
            side = [_side_margin(wb, prof, R, bx, dy + s * TWO_ARM_BASE_SPREAD, qa) for s in (-1.0, 1.0)]
            margin = min(margin, *side)
        p = Placement(pitch, roll, float(bx), float(dy), qa, margin, gravity_ratio(wb, np.r_[pose, qa]))
        if best is None or p.score > best.score:
            best = p
    return best


#: A handle whose height above (or below) the arm's first joint takes more than this share of the stretched arm is
#: at the edge of its reach (`_why`).
REACH_SHARE = 0.8


def _held_in_the_hand(wb: WholeBody, locked: Sequence[str]) -> list[str]:
    """Return the movable joints between the arm's last joint and its gripper frame that neither the arm nor
    ``locked`` names: held at 0 unlisted, as a wrist joint left out of the arm's list is."""
    model = wb.model
    chain = list(model.supports[model.frames[wb.ee_frame_id].parentJoint])
    last = max(chain.index(model.getJointId(n)) for n in wb.arm_joints)
    return [model.names[j] for j in chain[last + 1 :] if model.joints[j].nv > 0 and model.names[j] not in locked]


def _why(wb: WholeBody, locked: Sequence[str] = ()) -> str:
    """Return why no posture was found, as far as the arm's geometry tells: a joint left out of the arm between it
    and the gripper, the handle out of the arm's reach (its straight-line length from the first arm joint) at any
    base place, or else what to give the search."""
    from wholebody.push.robot import cart_se3, handle_point

    held = _held_in_the_hand(wb, locked)
    if held:
        return (
            f"the joint(s) {', '.join(map(repr, held))} between the arm's last joint and its gripper frame are neither "
            "in the arm's joints nor in [locked] (held at 0): list them in the arm's joints, base to tip"
        )
    model, data = wb.model, wb.model.createData()
    pin.forwardKinematics(model, data, wb.to_pinocchio_q(np.r_[np.zeros(3), 0.5 * (wb.arm_lower + wb.arm_upper)]))
    pin.updateFramePlacements(model, data)
    ids = [model.getJointId(n) for n in wb.arm_joints]
    chain = [data.oMi[j].translation for j in ids] + [data.oMf[wb.ee_frame_id].translation]
    length = float(sum(np.linalg.norm(b - a) for a, b in zip(chain[:-1], chain[1:])))
    shoulder, handle = float(chain[0][2]), float((cart_se3(np.zeros(3)) * handle_point(0.0))[2])
    if abs(handle - shoulder) > length:
        return (
            f"the handle is {handle:.2f} m high and the arm's first joint {shoulder:.2f} m, farther than the arm's "
            f"length ({length:.2f} m, first joint to gripper frame): mount the arm higher or push a lower handle"
        )
    rise = abs(handle - shoulder)
    if rise > REACH_SHARE * length:  # the height takes most of the arm: little is left to reach past the base
        return (
            f"the handle is {handle:.2f} m high and the arm's first joint {shoulder:.2f} m: {rise:.2f} m of the arm's "
            f"{length:.2f} m (first joint to gripper frame, stretched) go to the height, leaving at most "
            f"{math.sqrt(max(length**2 - rise**2, 0.0)):.2f} m to reach forward past the base and bend the wrist onto "
            "the bar: mount the arm higher or push a lower handle"
        )
    if wb.n_arm < 6:
        return (
            f"an arm of {wb.n_arm} joints holds the handle only in a few orientations: give [push] grasp_pitch and "
            "grasp_roll (and base_x, the arm's push_seed) in its profile"
        )
    return "give [push] base_x and the arm's push_seed in its profile"


def solve_push_placement(prof: RobotProfile, wbs: Sequence[WholeBody]) -> RobotProfile:
    """Return `prof` with its grasp, base placement and arm push postures found by IK (see the module docstring).

    Arm 0 sets the grasp and the base place; the other arms get the posture that holds the handle's
    mirror point from the same base. Raises `WholeBodyError` when no candidate reaches the handle.
    """
    wb = wbs[0]
    axis = prof.arms[0].tool_axis or "z"
    found = [p for p in (_placement(wb, prof, pitch, roll, axis) for pitch, roll in _candidates(prof)) if p]
    for bx in FALLBACK_BASE_X if prof.push_base_x is None else ():
        if found:
            break
        at = replace(prof, push_base_x=bx)
        found = [p for p in (_placement(wb, at, pitch, roll, axis) for pitch, roll in _candidates(at)) if p]
    if not found:
        locked = [name for name, _ in prof.locked]
        raise WholeBodyError(
            f"robot {prof.name!r}: no arm posture reaches the cart handle from behind it; {_why(wb, locked)}"
        )
    if prof.base != "holonomic":  # a base at a fixed place: rank the best few by the handle length they reach
        found = sorted(found, key=lambda p: p.score)[-REACH_CANDIDATES:]
        found = [replace(p, reach=_reach_length(wb, prof, p)) for p in found]
    best = max(found, key=lambda p: p.score)
    if best.gravity_ratio > 1.0:
        raise WholeBodyError(
            f"robot {prof.name!r}: its arm's own weight needs {best.gravity_ratio:.2f} x a joint's effort limit at "
            "the best push posture found; the arm cannot hold itself there (check the URDF's <limit effort>)"
        )
    arms = list(prof.arms)
    arms[0] = replace(arms[0], push_seed=tuple(float(v) for v in best.arm))
    fixed_base = prof.base != "holonomic"
    return replace(
        prof,
        arms=tuple(arms),
        grasp_pitch=best.pitch,
        grasp_roll=best.roll,
        push_base_x=best.base_x,
        push_base_y=(_contact_y(prof) + best.base_dy) if fixed_base else prof.push_base_y,
        push_base_dy=0.0 if fixed_base else best.base_dy,
    )


def arm_posture_near(
    wb: WholeBody, prof: RobotProfile, q_cart: np.ndarray, contact_y: float, base_y: float, R_b_ee: np.ndarray
) -> np.ndarray:
    """Return an arm posture holding the handle at `contact_y` with the base at `base_y` in {b}.

    Tries the profile's push posture, mid-range and eight seeded random postures (fixed seed) as IK seeds;
    raises `WholeBodyError` when none converges.
    """
    from wholebody.push.robot import grasp_configuration

    rng = np.random.default_rng(0)
    seeds = [np.asarray(prof.push_arm_seed), 0.5 * (wb.arm_lower + wb.arm_upper)]
    seeds += [rng.uniform(wb.arm_lower, wb.arm_upper) for _ in range(8)]
    for seed in seeds:
        try:
            return grasp_configuration(wb, prof, q_cart, contact_y, base_y, R_b_ee, seed)[1]
        except WholeBodyError:
            continue
    raise WholeBodyError(
        f"robot {prof.name!r}: the arm cannot hold the handle at y = {contact_y:.3f} m with its base at "
        f"y = {base_y:.3f} m; fix the contact points or give [push] base_x in its profile"
    )


# ---------------------------------------------------------------------------------------------- one base, several arms
@dataclass(frozen=True)
class MultiArmPlacement:
    """Where one base stands for several of its arms to hold the handle, each at its own contact point.

    ``arms``: the profile's arms in the order of the contacts (lowest y first); ``rolls`` and ``postures``
    per arm in that order; the base stands at (handle x + ``base_x``, ``base_y``) in {b}.
    """

    arms: tuple[int, ...]
    contact_y: tuple[float, ...]
    pitch: float
    rolls: tuple[float, ...]
    base_x: float
    base_y: float
    postures: tuple[np.ndarray, ...]
    #: ranking score: the smallest joint-limit margin less gravity load and distance behind the handle
    score: float


def arms_by_side(wbs: Sequence[WholeBody]) -> tuple[int, ...]:
    """Return the arms' indices ordered by the lateral place (y in the base frame) of their first joint."""
    ys = []
    for wb in wbs:
        q = wb.to_pinocchio_q(np.r_[0.0, 0.0, 0.0, np.clip(np.zeros(wb.n_arm), wb.arm_lower, wb.arm_upper)])
        pin.forwardKinematics(wb.model, wb.data, q)
        ys.append(float(wb.data.oMi[wb.model.getJointId(wb.arm_joints[0])].translation[1]))
    return tuple(int(i) for i in np.argsort(ys, kind="stable"))


def _arm_searches(
    wb: WholeBody, prof: RobotProfile, pitch: float, axis: str, contact_y: float
) -> list[tuple[float, np.ndarray]]:
    """Return (roll, [bx, dy, q...]) of every roll whose search reaches `contact_y` (the base's y fixed)."""
    from wholebody.push.robot import grasp_rotation

    rolls = ROLLS if prof.grasp_roll is None else (prof.grasp_roll,)
    mid = 0.5 * (wb.arm_lower + wb.arm_upper)
    out = []
    for roll in rolls:
        R = grasp_rotation(pitch, roll, axis)
        found = [z for z in (_search(wb, prof, R, contact_y, mid, bx0) for bx0 in (-0.6, -0.9)) if z is not None]
        if found:  # the two base seeds of the one-arm search; the larger joint-limit margin
            out.append((roll, max(found, key=lambda z: joint_margin(wb, z[2:]))))
    return out


def _joint_placement(
    wbs: Sequence[WholeBody], prof: RobotProfile, pitch: float, per_arm: list[tuple[float, np.ndarray]], ys, axes
) -> MultiArmPlacement | None:
    """Return the placement of the arms' grasps from one base x (each arm's own best x, and their mean), or None."""
    from wholebody.push.robot import base_target, grasp_rotation, grasp_target, handle_point, solve_grasp_ik

    zero = np.zeros(3)
    by = float(np.mean(ys))
    best = None
    xs = [float(z[0]) for _, z in per_arm] if prof.push_base_x is None else [prof.push_base_x]
    for bx in sorted(set(xs + [float(np.mean(xs))])):
        pose = base_target(zero, zero, np.array([handle_point(by)[0] + bx, by]))[0]
        qs = []
        for wb, (roll, z), y, axis in zip(wbs, per_arm, ys, axes):
            try:
                qa = solve_grasp_ik(
                    wb, pose, grasp_target(zero, zero, y, 0.0, grasp_rotation(pitch, roll, axis))[0], z[2:]
                )
            except WholeBodyError:
                break
            if arm_sigma(wb, np.r_[pose, qa]) >= REACH_MIN_SIGMA:
                qs.append(qa)
        if len(qs) != len(wbs):
            continue
        grav = max(gravity_ratio(wb, np.r_[pose, qa]) for wb, qa in zip(wbs, qs))
        margin = min(joint_margin(wb, qa) for wb, qa in zip(wbs, qs))
        score = margin - max(0.0, grav - 0.5) - BASE_X_WEIGHT * (BASE_X_RANGE[1] - bx)
        if best is None or score > best.score:
            rolls = tuple(r for r, _ in per_arm)
            best = MultiArmPlacement((), tuple(ys), pitch, rolls, bx, by, tuple(qs), score)
    return best


def solve_multi_arm_placement(
    prof: RobotProfile, wbs: Sequence[WholeBody], contact_y: Sequence[float]
) -> MultiArmPlacement:
    """Return where one base stands for its first ``len(contact_y)`` arms to hold the handle at `contact_y`.

    The arms take the contacts by side (the arm mounted furthest right the lowest y); the base stands centred
    between the contacts. Per grasp pitch, each arm's best roll and base x come from the single-arm search
    (`_search`, the base's y fixed); then one base x for all (each arm's, and their mean) and the exact grasp
    IK of every arm from it, ranked by the smallest joint-limit margin less gravity load and distance. `prof`:
    the profile with its tool axes filled and its own (not computed) base x. Raises `WholeBodyError`.
    """
    n = len(contact_y)
    order = arms_by_side(wbs[:n])
    ys = sorted(float(v) for v in contact_y)
    fixed = replace(prof, push_base_y=float(np.mean(ys)))
    axes = [prof.arms[i].tool_axis or "z" for i in order]
    best = None
    for pitch in PITCHES if prof.grasp_pitch is None else (prof.grasp_pitch,):
        per_arm = []
        for i, y, axis in zip(order, ys, axes):
            found = _arm_searches(wbs[i], fixed, pitch, axis, y)
            if found:
                per_arm.append(max(found, key=lambda rz: joint_margin(wbs[i], rz[1][2:]) + BASE_X_WEIGHT * rz[1][0]))
        p = _joint_placement([wbs[i] for i in order], fixed, pitch, per_arm, ys, axes) if len(per_arm) == n else None
        if p is not None and (best is None or p.score > best.score):
            best = p
    if best is None:
        raise WholeBodyError(
            f"robot {prof.name!r}: its arms cannot hold the handle at y = {', '.join(f'{v:.2f}' for v in ys)} m "
            "from one base behind it; give other contact points (--contact-y) or [push] base_x in its profile"
        )
    return replace(best, arms=order)
