"""MuJoCo cart logs with a load put in or taken out mid-log (issue 27's load-change test bed).

The cart is :mod:`studies.testbeds.mujoco_cart`'s (the library's MuJoCo cart, pushed by the same tracking
controller). The load is a separate free body (a box, no contacts), held by one of two weld equality
constraints: to a mocap body far away (parked) or to the cart at a spot on the deck. The change is physical:

- **put in**: at the change the load is set on the deck at rest (zero velocity in {s}: dropped in by
  someone standing) and welded to the cart; the engine's weld constraint brings it to the cart's velocity
  within a few milliseconds, so the cart and the load exchange momentum (the cart slows down; its wheels
  and casters take their share of the impulse) and the tracker then pushes the heavier cart.
- **taken out**: the weld to the cart is released and the load leaves to the parking spot (lifted out
  by someone: it takes its own momentum with it, the cart's velocity is unchanged at that instant).

The truth before and after is the composite rigid body (cart subtree plus the load when it rides on the
cart): mass, CoM in {b}, yaw inertia about the CoM, and the forward effective mass with the wheels' spin
inertia (``m_effective_forward_incl_wheel_spin``: the mass the forward motion feels).

Run: ``python -m studies.testbeds.mujoco_loads N SEED0`` evaluates ``cartpush estimate``'s segments on N
load-change logs and on the same N carts without a change (the load kept where it starts); ``--dating SEED ...``
sums how many of those seeds' changes the motion allows to be dated within 1 s (:func:`dating_share`). With
``MUJOCO_LOADS_CACHE=DIR`` set, each simulation is kept in ``DIR/SEED_KIND.pkl`` (the log, the truth and the
load's fields) and read back from there on a later run (the simulations, not the evaluation, are most of the time).
"""

from __future__ import annotations

import json
import math
import os
import pickle
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from cart.logs import CartLog
from studies.testbeds import dating
from studies.testbeds import mujoco_cart as mc

try:  # optional dependency, as in mujoco_cart
    import mujoco

    from wholebody.push.mujoco_cart import composite_inertia, yaw_of
except ImportError:  # pragma: no cover
    mujoco = None  # type: ignore[assignment]

LOAD = "load"
PARK = "load_park"


@dataclass(frozen=True)
class LoadChange:
    """A load of ``mass`` (kg, a box of ``size`` m) at ``offset`` (x, y) on the deck, put in or taken out at ``t``.

    ``kind``: "in" (parked at the start, put in at ``t``), "out" (on the cart at the start, taken out at
    ``t``), "none_in" / "none_out" (parked / on the cart throughout: the same cart without a change).
    """

    t: float
    mass: float
    offset: tuple[float, float]
    size: tuple[float, float, float]
    kind: str = "in"

    @property
    def starts_loaded(self) -> bool:
        """Return whether the load rides on the cart at the start."""
        return self.kind in ("out", "none_out")

    @property
    def changes(self) -> bool:
        """Return whether the load moves at ``t``."""
        return self.kind in ("in", "out")


def mjcf_with_load(cart: mc.MujocoCart, load: LoadChange) -> str:
    """Return the MJCF of ``cart`` plus a free load body, a parking mocap body and the two welds."""
    xml = mc.mjcf(cart)
    sx, sy, sz = load.size
    bodies = f"""
    <body name="{PARK}" mocap="true" pos="50 50 1"/>
    <body name="{LOAD}" pos="50 50 1">
      <freejoint name="{LOAD}_root"/>
      <geom name="{LOAD}" type="box" class="body" size="{sx / 2:.17g} {sy / 2:.17g} {sz / 2:.17g}"
            mass="{load.mass:.17g}" rgba="0.2 0.6 0.3 1"/>
    </body>
  </worldbody>
  <equality>
    <weld name="{LOAD}_parked" body1="{PARK}" body2="{LOAD}" active="true"/>
    <weld name="{LOAD}_on_cart" body1="{mc.CART_BODY}" body2="{LOAD}" active="false" solref="0.004 1"/>
  </equality>"""
    return xml.replace("\n  </worldbody>", bodies, 1)


class _Load:
    """Moves the load between the parking spot and the deck of the cart (see the module docstring)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, cart: mc.MujocoCart, load: LoadChange) -> None:
        self.model, self.data, self.load = model, data, load
        self.body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, LOAD)
        self.cart_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, mc.CART_BODY)
        jnt = int(model.body_jntadr[self.body])
        self.qadr, self.vadr = int(model.jnt_qposadr[jnt]), int(model.jnt_dofadr[jnt])
        self.eq_park = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, f"{LOAD}_parked")
        self.eq_cart = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, f"{LOAD}_on_cart")
        self.rel = np.array(
            [load.offset[0], load.offset[1], cart.payload_z + 0.5 * (load.size[2] - cart.payload_size[2])]
        )
        self.on_cart = False

    def put_in(self) -> None:
        """Set the load on the deck at rest in {s} and weld it to the cart (the weld does the momentum exchange)."""
        d = self.data
        mujoco.mj_kinematics(self.model, d)
        rot = d.xmat[self.cart_body].reshape(3, 3)
        d.qpos[self.qadr : self.qadr + 3] = d.xpos[self.cart_body] + rot @ self.rel
        d.qpos[self.qadr + 3 : self.qadr + 7] = d.xquat[self.cart_body]
        d.qvel[self.vadr : self.vadr + 6] = 0.0
        # weld data: anchor (3), pose of body2 in body1 (pos 3, quat 4), torque scale
        self.model.eq_data[self.eq_cart, 0:10] = (0, 0, 0, *self.rel, 1, 0, 0, 0)
        self.model.eq_data[self.eq_cart, 10] = 1.0
        d.eq_active[self.eq_park], d.eq_active[self.eq_cart] = 0, 1
        self.on_cart = True

    def take_out(self) -> None:
        """Release the load from the cart and put it back at the parking spot, at rest."""
        d = self.data
        d.qpos[self.qadr : self.qadr + 7] = (50, 50, 1, 1, 0, 0, 0)
        d.qvel[self.vadr : self.vadr + 6] = 0.0
        d.eq_active[self.eq_park], d.eq_active[self.eq_cart] = 1, 0
        self.on_cart = False

    def truth(self) -> dict[str, float]:
        """Return the cart's composite truth now (the load included when it rides on the cart)."""
        model, data = self.model, self.data
        mujoco.mj_forward(model, data)
        extra = (self.body,) if self.on_cart else ()
        mass, com, inertia = composite_inertia(model, data, self.cart_body, extra)
        th = yaw_of(data.xquat[self.cart_body])
        rel = com[:2] - data.xpos[self.cart_body][:2]
        c, s = math.cos(th), math.sin(th)
        spins = mc.wheel_spin_inertias(model)
        return {
            "m": mass,
            "dx": float(c * rel[0] + s * rel[1]),
            "dy": float(-s * rel[0] + c * rel[1]),
            "I_about_com": inertia,
            "m_effective_forward_incl_wheel_spin": mass + sum(j / r**2 for j, r in spins.values()),
        }


def random_load_case(seed: int, kind: str | None = None) -> tuple[mc.MujocoCase, LoadChange]:
    """Return (the MuJoCo case of ``seed``, a load of 30-60 % of its mass on the deck, changed at 35-65 % of the log).

    ``kind`` None: "in" for even seeds, "out" for odd ones.
    """
    case = mc.random_case(seed, duration=float(np.random.default_rng([seed, 0x10AD]).uniform(40.0, 60.0)))
    rng = np.random.default_rng([seed, 0x10AD, 1])
    cart = case.cart
    size = (rng.uniform(0.15, 0.35), rng.uniform(0.15, 2 * cart.half_track - 0.06), rng.uniform(0.08, 0.3))
    x = rng.uniform(size[0] / 2 - 0.05, cart.wheelbase - size[0] / 2 + 0.05)
    y = rng.uniform(-1.0, 1.0) * max(cart.half_track - size[1] / 2 - 0.02, 0.0)
    mass = float(rng.uniform(0.3, 0.6) * cart.total_mass)
    t = float(rng.uniform(0.35, 0.65) * case.duration)
    kind = kind or ("in" if seed % 2 == 0 else "out")
    return case, LoadChange(t, mass, (float(x), float(y)), tuple(float(v) for v in size), kind)  # type: ignore[arg-type]


def simulate_with_load(case: mc.MujocoCase, load: LoadChange) -> tuple[CartLog, dict[str, Any]]:
    """Simulate ``case`` with ``load``; return (the noisy log, truth: ``before``, ``after``, ``t_change``, ``kind``)."""
    mc._require_mujoco()
    rng = np.random.default_rng([case.seed, 0x5EED])
    model = mujoco.MjModel.from_xml_string(mjcf_with_load(case.cart, load))
    data = mujoco.MjData(model)
    mover = _Load(model, data, case.cart, load)
    mc.place(model, data, case.cart, case.q0 if case.q0 is not None else (0.0, 0.0, 0.0))
    if load.starts_loaded:
        mover.put_in()
    for _ in range(int(round(mc.SETTLE_TIME / model.opt.timestep))):
        mujoco.mj_step(model, data)
    before = mover.truth()
    data.time = 0.0
    dt = model.opt.timestep
    n_steps = int(round(case.duration / dt)) + 1
    ref = mc._Reference.draw(case, rng, dt)
    tracker = mc._Tracker.guessing(case, before, ref, rng)
    samples = mc._sample_steps(case, n_steps, rng)
    i_change = int(round(load.t / dt)) if load.changes else -1
    after: dict[str, float] = {}

    def on_step(i: int) -> None:
        if i == i_change:
            mover.take_out() if mover.on_cart else mover.put_in()
            after.update(mover.truth())

    out = mc._run(model, data, tracker, n_steps, samples, on_step)
    if not np.all(np.isfinite(out.rec)):
        raise RuntimeError(f"{case.name}: the simulation diverged")
    log = mc._noisy_log(case, out.rec, tracker.handle, rng)
    truth = {"before": before, "after": after or before, "t_change": load.t if load.changes else None}
    return log, {**truth, "kind": load.kind, "load_mass": load.mass, "v": out.rec[:, 7:9]}


def simulated(seed: int, case: mc.MujocoCase, load: LoadChange) -> tuple[CartLog, dict[str, Any]]:
    """Return :func:`simulate_with_load`'s (log, truth), kept in and read from ``$MUJOCO_LOADS_CACHE`` when set."""
    cache = os.environ.get("MUJOCO_LOADS_CACHE")
    path = os.path.join(cache, f"{seed}_{load.kind}.pkl") if cache else None
    if path is not None and os.path.exists(path):
        with open(path, "rb") as f:
            log, truth, _ = pickle.load(f)  # noqa: S301 (a file this function wrote)
        return log, truth
    log, truth = simulate_with_load(case, load)
    if path is not None:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path + ".tmp", "wb") as f:
            pickle.dump((log, truth, asdict(load)), f)  # a dict: a module run would pickle __main__.LoadChange
        os.replace(path + ".tmp", path)
    return log, truth


def _row(seed: int, kind: str, t_change: float | None, truth: dict[str, Any], segs: list[dict[str, Any]]) -> dict:
    """Return one evaluation row: the change, the truth after it and the last segment of ``estimate``."""
    last = segs[-1]
    return {
        "seed": seed,
        "kind": kind,
        "t_change": t_change,
        "segments": len(segs),
        "t0_last": last["t0"],
        "t0_range_last": last.get("t0_range"),
        "mass_last": last["mass"],
        "m_before": truth["before"]["m"],
        "m_after": truth["after"]["m"],
        "m_eff_after": truth["after"]["m_effective_forward_incl_wheel_spin"],
        "refused": last.get("refused"),
    }


def in_wide_stretch(segs: list[dict[str, Any]], t_change: float, m_after: float) -> bool:
    """Return whether ``estimate`` reports the change in a stretch wider than ``dating.WIDE_STRETCH_S`` holding ``t_change``.

    The motion there (a cruise, a standstill) does not excite the mass, so the log cannot date the change
    more closely; counted apart when the time is more than 1 s off but the stretch holds it and the after-mass
    is within 5 %.
    """
    if len(segs) < 2 or segs[-1]["t0_range"] is None or segs[-1]["mass"] is None:
        return False
    lo, hi = segs[-1]["t0_range"]
    return bool(hi - lo > dating.WIDE_STRETCH_S and lo <= t_change <= hi and abs(segs[-1]["mass"] / m_after - 1) < 0.05)


def estimated_segments(log: CartLog) -> list[dict[str, Any]]:
    """Return ``estimate``'s segments of ``log``; a log ``estimate`` refuses (:class:`cart.errors.CartError`, e.g. its
    torque-origin check) gives one segment without a mass, marked ``refused`` with the message (counted, not fatal)."""
    from cart.errors import CartError
    from cart.estimate_report import estimate_log

    try:
        return list(estimate_log(log).segments)
    except CartError as exc:
        return [{"t0": float(log.t[0]), "t0_range": None, "mass": None, "refused": str(exc)}]


def holds_truth(segs: list[dict[str, Any]], t_change: float) -> bool:
    """Return whether the last segment's reported ``t0_range`` holds ``t_change`` (any width)."""
    rng = segs[-1]["t0_range"] if len(segs) >= 2 else None
    return bool(rng is not None and rng[0] <= t_change <= rng[1])


def evaluate(n: int, seed0: int) -> dict[str, Any]:
    """Return the segments found by ``estimate`` on ``n`` load-change logs and on the same carts without a change.

    Each seed gives three logs: the change, the cart as it is before (no change) and as it is after (no
    change). A change is found when the last segment starts within 1 s of the change and its mass is within
    5 % of the mass after: the rigid mass ``m``, the forward effective mass with the wheels' spin inertia
    ``m_eff`` (the mass the forward motion feels), or what ``estimate`` says on the after-cart's own log (the
    estimator's own bias on this engine taken out: the segmentation judged alone). Misses whose change lies in
    a reported ``t0_range`` wider than 2 s, with the after-mass right, are counted apart
    (:func:`in_wide_stretch`: the log cannot date them within 1 s); so are the misses whose ``t0_range``, of any
    width, holds the change (:func:`holds_truth`: the range is honest where ``t0`` misses).
    """
    rows = []
    for seed in range(seed0, seed0 + n):
        case, load = random_load_case(seed)
        got: dict[str, tuple[dict, list]] = {}
        for kind in (load.kind, "none_in", "none_out"):
            log, truth = simulated(seed, case, replace(load, kind=kind))
            got[kind] = (truth, estimated_segments(log))
        truth, segs = got[load.kind]
        row = _row(seed, load.kind, load.t, truth, segs)
        alone = got["none_out" if load.kind == "in" else "none_in"][1][-1]["mass"]
        m, ok_t = row["mass_last"], len(segs) >= 2 and abs(row["t0_last"] - load.t) < 1.0
        for key, ref in (("m", row["m_after"]), ("m_eff", row["m_eff_after"]), ("alone", alone)):
            row["found_" + key] = bool(ok_t and m is not None and ref is not None and abs(m / ref - 1) < 0.05)
        row["in_wide_stretch"] = in_wide_stretch(segs, load.t, row["m_eff_after"])
        row["range_holds_truth"] = holds_truth(segs, load.t)
        row["mass_after_alone"] = alone
        rows.append(row)
        print(json.dumps(row), flush=True)
        for kind in ("none_in", "none_out"):
            rows.append(_row(seed, kind, None, *got[kind]))
            print(json.dumps(rows[-1]), flush=True)
    changed = [r for r in rows if "found_m" in r]
    return {
        "logs_with_change": len(changed),
        "change_found": float(np.mean([r["segments"] > 1 for r in changed])),
        "within_1s": float(np.mean([r["segments"] > 1 and abs(r["t0_last"] - r["t_change"]) < 1.0 for r in changed])),
        **{
            f"found_within_1s_5pct_of_{k}": float(np.mean([r["found_" + k] for r in changed]))
            for k in ("m", "m_eff", "alone")
        },
        "missed_in_wide_stretch_holding_truth": sum(r["in_wide_stretch"] and not r["found_m_eff"] for r in changed),
        "missed_with_t0_range_holding_truth": sum(r["range_holds_truth"] and not r["found_m_eff"] for r in changed),
        "logs_without_change": len(rows) - len(changed),
        "false_changes": float(np.mean([r["segments"] > 1 for r in rows if "found_m" not in r])),
        "refused_with_change": sum(r["refused"] is not None for r in changed),
        "refused_without_change": sum(r["refused"] is not None for r in rows if "found_m" not in r),
    }


def dating_information(seed: int) -> dict[str, Any]:
    """Return what the motion of seed's load-change log (:func:`random_load_case`'s kind) allows in dating its change
    (:func:`studies.testbeds.dating.stretch_row`: the undatable stretch around the true change and ``p_date``)."""
    case, load = random_load_case(seed)
    log, truth = simulated(seed, case, load)
    return {"seed": seed, "kind": load.kind, **dating.stretch_row(log, float(truth["t_change"]))}


def dating_share(seeds: list[int]) -> dict[str, Any]:
    """Return :func:`studies.testbeds.dating.share` of :func:`dating_information` over ``seeds`` (printing each row)."""
    rows = []
    for seed in seeds:
        rows.append(dating_information(seed))
        print(json.dumps(rows[-1]), flush=True)
    return dating.share(rows)


if __name__ == "__main__":  # pragma: no cover
    import sys

    if sys.argv[1] == "--dating":  # python -m studies.testbeds.mujoco_loads --dating SEED [SEED ...]
        print(json.dumps(dating_share([int(a) for a in sys.argv[2:]]), indent=1))
    else:
        print(json.dumps(evaluate(int(sys.argv[1]), int(sys.argv[2])), indent=1))
