"""Tests of the MuJoCo shopping-cart test bed (studies/testbeds/mujoco_cart.py)."""

from __future__ import annotations

import json
import math
import pathlib
import sys

import numpy as np
import pytest

from tests.optional import require_module

mujoco = require_module("mujoco")

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `studies` is not an installed package
    sys.path.insert(0, str(ROOT))

from cart.logs import read_log, write_log  # noqa: E402
from studies.testbeds import mujoco_cart as mc  # noqa: E402


def _hand_truth(c: mc.MujocoCart) -> dict:
    """Mass, CoM in {b} and yaw inertia about the CoM from the MJCF parameters (casters trailing)."""
    length = c.wheelbase + 2 * c.chassis_overhang
    parts = [  # (mass, x, y, own yaw inertia)
        (c.chassis_mass, c.wheelbase / 2, 0.0, c.chassis_mass * (length**2 + c.chassis_width**2) / 12),
    ]
    if c.payload_mass > 0:
        sx, sy, _ = c.payload_size
        parts.append((c.payload_mass, *c.payload_offset, c.payload_mass * (sx**2 + sy**2) / 12))
    for sgn in (1.0, -1.0):
        r, w = c.wheel_radius, c.wheel_width
        parts.append((c.wheel_mass, 0.0, sgn * c.half_track, c.wheel_mass * (3 * r**2 + w**2) / 12))
        fl, fw = c.caster_trail + 0.02, 0.04  # fork box: full length along x, full width
        parts.append(
            (
                c.caster_fork_mass,
                c.wheelbase - c.caster_trail / 2,
                sgn * c.caster_half_track,
                c.caster_fork_mass * (fl**2 + fw**2) / 12,
            )
        )
        rc, wc = c.caster_wheel_radius, c.caster_wheel_width
        parts.append(
            (
                c.caster_wheel_mass,
                c.wheelbase - c.caster_trail,
                sgn * c.caster_half_track,
                c.caster_wheel_mass * (3 * rc**2 + wc**2) / 12,
            )
        )
    p = np.array(parts)
    m = p[:, 0].sum()
    dx, dy = (p[:, 0] * p[:, 1]).sum() / m, (p[:, 0] * p[:, 2]).sum() / m
    inertia = (p[:, 3] + p[:, 0] * ((p[:, 1] - dx) ** 2 + (p[:, 2] - dy) ** 2)).sum()
    m_eff = m + c.wheel_mass + c.caster_wheel_mass  # solid cylinders: J / r^2 = m / 2, four wheels
    return {"m": m, "dx": dx, "dy": dy, "I_about_com": inertia, "m_effective_forward_incl_wheel_spin": m_eff}


@pytest.mark.parametrize(
    "cart",
    [mc.MujocoCart(), mc.random_case(5).cart, mc.MujocoCart(payload_mass=0.0)],
    ids=["default", "random5", "no_payload"],
)
def test_truth_matches_hand_computation(cart):
    want = _hand_truth(cart)
    # exactly, with the chassis level and the casters trailing (before settling)
    model, data = mc.build(cart)
    mc.place(model, data, cart, (0.7, -0.4, 2.0))
    level = mc.truth_from_state(model, data)
    for key, value in want.items():
        assert level[key] == pytest.approx(value, rel=1e-9, abs=1e-12), key
    # after 1 s of settling: soft contacts sink by ~1 mm, pitching the chassis by ~1 mrad, so
    # high parts move forward by a fraction of a millimetre; the casters stay trailing
    got = mc.truth(cart)
    assert got["m"] == pytest.approx(cart.total_mass, rel=1e-12)
    assert got["m_effective_forward_incl_wheel_spin"] == pytest.approx(
        want["m_effective_forward_incl_wheel_spin"], rel=1e-12
    )
    assert got["dx"] == pytest.approx(want["dx"], abs=1.5e-3)
    assert got["dy"] == pytest.approx(want["dy"], abs=2e-4)
    assert got["I_about_com"] == pytest.approx(want["I_about_com"], rel=3e-3)
    if cart.payload_mass > 0:
        assert got["dx"] > 0.05  # the CoM is not at the axle


def test_composite_inertia_agrees_with_mujoco_subtree():
    cart = mc.random_case(7).cart
    model, data = mc.build(cart)
    mc.settle(model, data, cart, pose=(1.0, -2.0, 2.5))
    mass, com, inertia = mc.composite_inertia(model, data)
    assert mass == pytest.approx(float(model.body_subtreemass[1]), rel=1e-12)
    np.testing.assert_allclose(com, data.subtree_com[1], atol=1e-12)
    # the pose does not change the truth
    ref = mc.truth(cart)
    info = mc.truth_from_state(model, data)
    for key in ("m", "dx", "dy", "I_about_com"):
        assert info[key] == pytest.approx(ref[key], rel=1e-6, abs=1e-6)
    assert inertia == pytest.approx(ref["I_about_com"], rel=1e-6)


def test_torque_about_b_is_the_applied_wrench_moved_exactly():
    """Force + tau_applied at xipos (what xfrc_applied does) == force + tau_b at {b} (at xipos height)."""
    cart = mc.MujocoCart(payload_offset=(0.5, 0.08))
    model, data = mc.build(cart)
    mc.settle(model, data, cart, pose=(0.3, 0.2, 0.9))
    b = 1
    com = data.xipos[b].copy()
    f = np.array([12.0, -7.0, 0.0])
    tau_app = 1.3
    data.xfrc_applied[b] = [*f, 0.0, 0.0, tau_app]
    mujoco.mj_forward(model, data)
    qacc_xfrc = data.qacc.copy()
    x, y = data.xpos[b][:2]
    tau_b = mc.tau_about_b(f[0], f[1], tau_app, (com[0], com[1]), (x, y))
    qfrc = np.zeros(model.nv)
    mujoco.mj_applyFT(model, data, f, np.array([0.0, 0.0, tau_b]), np.array([x, y, com[2]]), b, qfrc)
    data.xfrc_applied[:] = 0.0
    data.qfrc_applied[:] = qfrc
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qacc, qacc_xfrc, rtol=1e-7, atol=1e-9)


@pytest.fixture(scope="module")
def short_run():
    case = mc.random_case(11, duration=20.0, payload_mass=15.0)
    return case, *mc.simulate(case)


def test_reference_has_reversal_and_turns_both_ways(short_run):
    _, _, info = short_run
    v, w = info["true_log"]["v_ref"], info["true_log"]["omega_ref"]
    assert v.max() > 0.25 and v.min() < -0.15
    assert w.max() > 0.05 and w.min() < -0.05
    assert np.abs(v).max() <= 1.0 + 1e-9 and np.abs(w).max() <= 0.6 + 1e-9


def test_rear_axle_midpoint_hardly_slips_and_tracks(short_run):
    _, _, info = short_run
    tl = info["true_log"]
    th, qd = tl["q"][:, 2], tl["qd"]
    fwd = np.cos(th) * qd[:, 0] + np.sin(th) * qd[:, 1]
    lat = -np.sin(th) * qd[:, 0] + np.cos(th) * qd[:, 1]
    moving = np.abs(fwd) > 0.2
    assert moving.sum() > 200
    assert np.max(np.abs(lat[moving]) / np.abs(fwd[moving])) < 0.02
    assert np.sqrt(np.mean((fwd - tl["v_ref"]) ** 2)) < 0.05  # the tracker follows the reference
    assert np.sqrt(np.mean((qd[:, 2] - tl["omega_ref"]) ** 2)) < 0.1


def test_logged_wrench_and_noise(short_run):
    case, log, info = short_run
    tl = info["true_log"]
    np.testing.assert_allclose(
        tl["gamma"][:, 2],
        [
            mc.tau_about_b(g[0], g[1], ta, c, q[:2])
            for g, ta, c, q in zip(tl["gamma"], tl["tau_applied"], tl["chassis_com"], tl["q"])
        ],
        atol=1e-12,
    )
    np.testing.assert_allclose(np.diff(log.t), 1.0 / case.rate_hz, atol=1e-9)
    res_f = log.gamma[:, :2] - tl["gamma"][:, :2]
    assert np.std(res_f) == pytest.approx(case.force_noise, rel=0.1)
    assert np.std(log.gamma[:, 2] - tl["gamma"][:, 2]) == pytest.approx(case.torque_noise, rel=0.1)
    assert np.std(log.q[:, :2] - tl["q"][:, :2]) == pytest.approx(case.position_noise, rel=0.1)
    assert np.std(log.q[:, 2] - tl["q"][:, 2]) == pytest.approx(case.theta_noise, rel=0.1)
    # casters swivel: the CoM moves a little in {b}, within the stats
    lo, _, hi = info["stats"]["dx"]
    assert lo <= info["dx"] + 1e-9 and hi >= info["dx"] - 1e-9 and hi - lo < 0.02


def test_constant_force_straight_push_accelerates_at_f_over_m_eff_minus_rolling_resistance():
    cart = mc.MujocoCart(payload_offset=(0.35, 0.0), rolling_friction=1e-3)
    tr = mc.truth(cart)
    model, data = mc.build(cart)
    mc.settle(model, data, cart)
    normal = {}
    for i in range(data.ncon):
        f6 = np.zeros(6)
        mujoco.mj_contactForce(model, data, i, f6)
        normal[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, data.contact[i].geom2)] = f6[0]
    rear = normal["tyre_left"] + normal["tyre_right"]
    front = normal["caster_tyre_left"] + normal["caster_tyre_right"]
    assert rear + front == pytest.approx(tr["m"] * mc.GRAVITY, rel=1e-3)
    f_roll = cart.rolling_friction * (rear / cart.wheel_radius + front / cart.caster_wheel_radius)
    force = 40.0
    ts, vs = [], []
    for k in range(2000):
        data.xfrc_applied[1, 0] = force
        mujoco.mj_step(model, data)
        ts.append(data.time)
        vs.append(data.qvel[0])
    ts, vs = np.array(ts), np.array(vs)
    sel = ts > 0.5
    accel = np.polyfit(ts[sel], vs[sel], 1)[0]
    expected = (force - f_roll) / tr["m_effective_forward_incl_wheel_spin"]
    assert f_roll > 0.05 * force  # rolling resistance is not negligible here
    assert accel == pytest.approx(expected, rel=0.03)
    assert accel < force / tr["m_effective_forward_incl_wheel_spin"]
    assert abs(data.qpos[1]) < 1e-6  # straight


def test_log_round_trips_through_read_log(short_run, tmp_path):
    _, log, _ = short_run
    path = tmp_path / "mj.csv.gz"
    write_log(path, log)
    back = read_log(path)
    np.testing.assert_array_equal(back.t, log.t)
    np.testing.assert_array_equal(back.q, log.q)
    np.testing.assert_array_equal(back.gamma, log.gamma)
    np.testing.assert_array_equal(back.qd, log.qd)
    np.testing.assert_array_equal(back.contact_b, log.contact_b)
    assert back.metadata["source"].startswith("MuJoCo")
    assert back.contact_b[0, 0] < 0  # the handle is behind the axle


def test_reproducible_from_seed_and_options():
    case = mc.random_case(3, duration=3.0, rate_hz=200.0, jitter=0.3, with_velocities=False, with_contact=False)
    a, ia = mc.simulate(case)
    b, ib = mc.simulate(case)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.gamma, b.gamma)
    assert ia["m"] == ib["m"] and a.qd is None and a.contact_b is None
    assert np.all(np.diff(a.t) > 0) and np.std(np.diff(a.t)) > 0  # jittered, strictly increasing
    c, _ = mc.simulate(mc.random_case(4, duration=3.0))
    assert c.q.shape != a.q.shape or not np.array_equal(c.q, a.q)
    assert mc.random_case(3) == mc.random_case(3)
    assert mc.random_case(3).cart != mc.random_case(4).cart


def test_random_cases_span_the_stated_ranges():
    carts = [mc.random_case(s) for s in range(40)]
    masses = np.array([c.cart.total_mass for c in carts])
    assert masses.min() >= 10.0 - 1e-9 and masses.max() <= 80.0 + 1e-9 and np.ptp(masses) > 40
    assert all(30.0 <= c.duration <= 60.0 for c in carts)
    assert np.ptp([c.cart.payload_offset[0] for c in carts]) > 0.3


def test_generate_writes_logs_and_truth(tmp_path):
    mc.generate(2, 20, tmp_path, duration=2.0)
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert sorted(truth) == ["mj20", "mj21"]
    for name, entry in truth.items():
        log = read_log(tmp_path / f"{name}.csv.gz")
        assert len(log) == pytest.approx(200, abs=2)
        assert {"m", "dx", "dy", "I_about_com", "m_effective_forward_incl_wheel_spin", "noise_std"} <= set(entry)
        assert entry["m_effective_forward_incl_wheel_spin"] > entry["m"]
        assert math.isfinite(entry["I_about_com"]) and entry["I_about_com"] > 0
