"""Tests of the independent rigid-body cart log generator (studies/testbeds/rigid_sim.py)."""

from __future__ import annotations

import json
import math
import pathlib
import sys

import numpy as np
import pytest
from scipy.integrate import solve_ivp

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `studies` is not an installed package
    sys.path.insert(0, str(ROOT))

from cart.logs import read_log  # noqa: E402
from studies.testbeds import rigid_sim as rs  # noqa: E402


def _random_cart(rng: np.random.Generator) -> rs.RigidCart:
    m = float(rng.uniform(5, 150))
    return rs.RigidCart(
        m=m,
        dx=float(rng.uniform(0.05, 0.6)),
        dy=float(rng.uniform(-0.15, 0.15)),
        I=m * float(rng.uniform(0.15, 0.45)) ** 2,
        c_v=float(rng.uniform(0.5, 15)),
        c_w=float(rng.uniform(0.2, 5)),
    )


def _random_state(rng: np.random.Generator) -> np.ndarray:
    return np.array([*rng.uniform(-2, 2, 2), rng.uniform(-math.pi, math.pi), rng.uniform(-1, 1), rng.uniform(-1, 1)])


def _world_kinetic_energy(q: np.ndarray, qd: np.ndarray, cart: rs.RigidCart) -> float:
    """T from the world-frame CoM velocity of p_com = (x, y) + R(theta) (dx, dy) (independent of the module)."""
    c, s = math.cos(q[2]), math.sin(q[2])
    vcx = qd[0] - qd[2] * (s * cart.dx + c * cart.dy)
    vcy = qd[1] + qd[2] * (c * cart.dx - s * cart.dy)
    return 0.5 * cart.m * (vcx**2 + vcy**2) + 0.5 * cart.I * qd[2] ** 2


def _qd_of(state: np.ndarray) -> np.ndarray:
    return np.array([state[3] * math.cos(state[2]), state[3] * math.sin(state[2]), state[4]])


@pytest.mark.parametrize("seed", range(5))
def test_energy_balance_finite_difference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    cart = _random_cart(rng)
    y0 = _random_state(rng)
    gamma = rng.uniform(-50, 50, 3)
    f = lambda t, y: rs.dynamics(y, gamma, cart)  # noqa: E731
    h = 1e-4
    ends = []
    for t1 in (h, -h):
        sol = solve_ivp(f, (0.0, t1), y0, method="DOP853", rtol=1e-12, atol=1e-14)
        ends.append(sol.y[:, -1])
    T = [_world_kinetic_energy(y[:3], _qd_of(y), cart) for y in ends]
    dT = (T[0] - T[1]) / (2 * h)
    qd = _qd_of(y0)
    power = gamma @ qd - cart.c_v * (qd[0] ** 2 + qd[1] ** 2) - cart.c_w * qd[2] ** 2
    scale = abs(gamma @ qd) + cart.c_v * qd[:2] @ qd[:2] + cart.c_w * qd[2] ** 2
    assert abs(dT - power) <= 1e-6 * scale
    assert rs.kinetic_energy(y0, cart) == pytest.approx(_world_kinetic_energy(y0[:3], qd, cart), rel=1e-12)
    assert rs.power(y0, gamma, cart) == pytest.approx(power, rel=1e-12)


def _lagrangian_kkt_qdd(q: np.ndarray, qd: np.ndarray, gamma: np.ndarray, cart: rs.RigidCart) -> np.ndarray:
    """qdd of eq. 1-3 from a numerically differentiated Lagrangian (the KKT system with Lambda = [-s, c, 0])."""
    T = lambda q_, qd_: _world_kinetic_energy(q_, qd_, cart)  # noqa: E731
    e = np.eye(3)
    hv, hq = 1e-3, 1e-5
    # M = d2T/dqd2 (T is quadratic in qd: central differences are exact up to rounding)
    M = np.array(
        [
            [
                (
                    T(q, qd + hv * (e[i] + e[j]))
                    - T(q, qd + hv * (e[i] - e[j]))
                    - T(q, qd - hv * (e[i] - e[j]))
                    + T(q, qd - hv * (e[i] + e[j]))
                )
                / (4 * hv * hv)
                for j in range(3)
            ]
            for i in range(3)
        ]
    )
    dT_dqd = lambda q_: np.array(
        [
            (T(q_, qd + hv * e[i]) - T(q_, qd - hv * e[i])) / (2 * hv)  # noqa: E731
            for i in range(3)
        ]
    )
    # d/dt (dT/dqd) = M qdd + (d2T/dqd dq) qd
    mixed = np.column_stack([(dT_dqd(q + hq * e[j]) - dT_dqd(q - hq * e[j])) / (2 * hq) for j in range(3)])
    dT_dq = np.array([(T(q + hq * e[i], qd) - T(q - hq * e[i], qd)) / (2 * hq) for i in range(3)])
    damping = -np.array([cart.c_v * qd[0], cart.c_v * qd[1], cart.c_w * qd[2]])
    c, s = math.cos(q[2]), math.sin(q[2])
    lam = np.array([-s, c, 0.0])
    lam_dot = np.array([-c * qd[2], -s * qd[2], 0.0])
    kkt = np.zeros((4, 4))
    kkt[:3, :3] = M
    kkt[:3, 3] = -lam
    kkt[3, :3] = lam
    rhs = np.concatenate([gamma + damping - mixed @ qd + dT_dq, [-lam_dot @ qd]])
    return np.linalg.solve(kkt, rhs)[:3]


@pytest.mark.parametrize("seed", range(5))
def test_dynamics_match_constrained_lagrange(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    cart = _random_cart(rng)
    y = _random_state(rng)
    gamma = rng.uniform(-50, 50, 3)
    yd = rs.dynamics(y, gamma, cart)
    th, v, w, vdot, wdot = y[2], y[3], y[4], yd[3], yd[4]
    qdd = np.array([vdot * math.cos(th) - v * w * math.sin(th), vdot * math.sin(th) + v * w * math.cos(th), wdot])
    ref = _lagrangian_kkt_qdd(y[:3], _qd_of(y), gamma, cart)
    assert np.allclose(qdd, ref, rtol=1e-6, atol=1e-6 * np.abs(ref).max())
    np.testing.assert_allclose(rs.mass_matrix(cart), [[cart.m, -cart.m * cart.dy], [-cart.m * cart.dy, cart.J]])


@pytest.fixture(scope="module")
def long_case():
    case = rs.random_case(
        11, duration=30.0, rate_hz=50.0, jitter=0.2, vel_std=0.005, omega_std=0.01, pos_std=2e-3, theta_std=3e-3
    )
    log, truth = rs.simulate(case)
    return case, log, truth


def test_lateral_slip_constraint(long_case) -> None:
    _, _, truth = long_case
    c = truth["clean"]
    th = c["q"][:, 2]
    lateral = -np.sin(th) * c["qd"][:, 0] + np.cos(th) * c["qd"][:, 1]
    assert np.abs(lateral).max() < 1e-9
    # the integrated pose obeys it too: finite differences of a 1 kHz clean trajectory
    case = rs.random_case(3, duration=4.0, rate_hz=1000.0, jitter=0.0, speed_scale=1.0)
    _, tr = rs.simulate(case)
    q, t = tr["clean"]["q"], tr["clean"]["t"]
    qd_fd = (q[2:] - q[:-2]) / (t[2:, None] - t[:-2, None])
    th = q[1:-1, 2]
    lat_fd = -np.sin(th) * qd_fd[:, 0] + np.cos(th) * qd_fd[:, 1]
    assert np.abs(lat_fd).max() < 1e-5
    np.testing.assert_allclose(qd_fd, tr["clean"]["qd"][1:-1], atol=1e-5)


def test_noise_std_matches_configuration(long_case) -> None:
    case, log, truth = long_case
    c = truth["clean"]
    assert len(log) >= 1400
    np.testing.assert_array_equal(log.t, c["t"])
    stds = {
        "x": log.q[:, 0] - c["q"][:, 0],
        "y": log.q[:, 1] - c["q"][:, 1],
        "theta": log.q[:, 2] - c["q"][:, 2],
        "fx": log.gamma[:, 0] - c["gamma"][:, 0],
        "fy": log.gamma[:, 1] - c["gamma"][:, 1],
        "tau": log.gamma[:, 2] - c["gamma"][:, 2],
        "vx": log.qd[:, 0] - c["qd"][:, 0],
        "vy": log.qd[:, 1] - c["qd"][:, 1],
        "omega": log.qd[:, 2] - c["qd"][:, 2],
    }
    assert set(stds) == set(truth["noise_std"])
    for key, err in stds.items():
        assert np.std(err) == pytest.approx(truth["noise_std"][key], rel=0.1), key
        assert abs(np.corrcoef(err[1:], err[:-1])[0, 1]) < 0.1, key  # white
    assert np.ptp(np.diff(log.t)) > 0.1 / case.rate_hz  # irregular sampling


def test_wrench_changes_within_a_sample_period(long_case) -> None:
    case, _, truth = long_case
    c = truth["clean"]
    t_w, g_w = c["t_wrench"], c["gamma_wrench"]
    # the logged wrench is the 1 ms-held wrench at the sample time (not an average)
    k = np.floor(c["t"] / rs.WRENCH_PERIOD + 1e-9).astype(int)
    np.testing.assert_array_equal(c["gamma"], g_w[k])
    # ... which differs from a zero-order hold of the logged samples
    zoh = c["gamma"][np.searchsorted(c["t"], t_w, side="right") - 1]
    diff = g_w - zoh
    assert np.sqrt(np.mean(diff[:, :2] ** 2)) > 0.05
    assert np.sqrt(np.mean(diff[:, 2] ** 2)) > 0.005
    per_interval = np.split(g_w[:, 0], np.searchsorted(t_w, c["t"][1:]))
    changing = np.mean([np.ptp(p) > 1e-6 for p in per_interval if len(p) > 1])
    assert changing > 0.9


def test_excitation_is_rich(long_case) -> None:
    case, _, truth = long_case
    c = truth["clean"]
    v, w = c["v"], c["qd"][:, 2]
    ss = case.speed_scale
    assert v.max() > 0.2 * ss and v.min() < -0.1 * ss  # push and pull
    assert w.max() > 0.1 * ss and w.min() < -0.1 * ss  # turns both ways
    assert np.abs(v).max() < 1.3 * ss and np.abs(w).max() < 1.1 * ss
    for seed in range(20):  # the references: a stop after moving, a reversal, both turns
        rng = np.random.default_rng(seed)
        v_ref, w_ref = rs.make_references(rng, 30.0, 1.0)
        t = np.arange(0, 30.0, 0.01)
        vr, wr = v_ref(t)[0], w_ref(t)[0]
        moving = np.abs(vr) > 0.15
        first, last = np.argmax(moving), len(t) - np.argmax(moving[::-1])
        assert np.any(np.abs(vr[first:last]) < 1e-9), seed
        signs = np.sign(vr[np.abs(vr) > 0.1])
        assert np.any(signs[1:] != signs[:-1]), seed
        assert wr.max() > 0.15 and wr.min() < -0.15, seed
        assert abs(vr[-1]) < 1e-12 and abs(wr[-1]) < 1e-12, seed


def test_reproducible_from_seed() -> None:
    assert rs.random_case(5) == rs.random_case(5)
    assert rs.random_case(5) != rs.random_case(6)
    case = rs.random_case(5, duration=3.0)
    a, ta = rs.simulate(case)
    b, tb = rs.simulate(case)
    for x, y in ((a.t, b.t), (a.q, b.q), (a.gamma, b.gamma)):
        np.testing.assert_array_equal(x, y)
    c, _ = rs.simulate(rs.random_case(6, duration=3.0))
    assert len(c) != len(a) or not np.array_equal(c.q, a.q)


def test_integrators_agree() -> None:
    case = rs.random_case(2, duration=1.5, rate_hz=100.0)
    _, t1 = rs.simulate(case)
    _, t2 = rs.simulate(case, integrator="solve_ivp")
    np.testing.assert_allclose(t1["clean"]["q"], t2["clean"]["q"], atol=1e-9)
    np.testing.assert_allclose(t1["clean"]["qd"], t2["clean"]["qd"], atol=1e-9)


def test_random_case_ranges_and_overrides() -> None:
    cases = [rs.random_case(s) for s in range(200)]
    m = np.array([c.cart.m for c in cases])
    assert m.min() >= 5 and m.max() <= 150 and np.median(m) < 50  # log-uniform
    assert all(0.05 <= c.cart.dx <= 0.6 and abs(c.cart.dy) <= 0.15 for c in cases)
    assert all(0.5 <= c.cart.c_v <= 15 and 0.2 <= c.cart.c_w <= 5 for c in cases)
    assert all(30 <= c.duration <= 60 and 50 <= c.rate_hz <= 250 and c.jitter <= 0.3 for c in cases)
    assert 0.3 < np.mean([c.has_velocities for c in cases]) < 0.7
    assert 0.3 < np.mean([c.jitter == 0 for c in cases]) < 0.7
    assert abs(np.corrcoef([c.cart.c_v for c in cases], [c.cart.c_w for c in cases])[0, 1]) < 0.2
    c = rs.random_case(1, m=20.0, duration=31.0, vel_std=None)
    assert c.cart.m == 20.0 and c.duration == 31.0 and not c.has_velocities
    with pytest.raises(TypeError):
        rs.random_case(1, bogus=1)


def test_write_case_and_generate(tmp_path) -> None:
    case = rs.random_case(4, duration=3.0, vel_std=None, wrap_theta=True)
    truth = rs.write_case(case, tmp_path / "one.csv")
    log = read_log(tmp_path / "one.csv")
    assert not log.has_velocities and len(log) > 100
    assert log.metadata["log"] == "one"
    json.dumps(truth)
    out = rs.generate(2, 40, tmp_path / "set", duration=3.0)
    on_disk = json.loads((tmp_path / "set" / "truth.json").read_text())
    assert on_disk == json.loads(json.dumps(out))
    assert sorted(on_disk) == ["rigid00", "rigid01"]
    for name, rec in on_disk.items():
        assert {"m", "dx", "dy", "I_about_com", "viscous_damping", "noise_std", "hidden_effects"} <= set(rec)
        assert set(rec["viscous_damping"]) == {"forward_and_lateral_N_s_per_m", "yaw_N_m_s_per_rad"}
        assert rec["hidden_effects"] == []
        log = read_log(tmp_path / "set" / f"{name}.csv.gz")
        assert log.has_velocities == ("vx" in rec["noise_std"])


def test_command_line_overrides_are_parsed_and_checked():
    from studies.testbeds.rigid_sim import parse_overrides, random_case

    over = parse_overrides(["rate_hz=30", "vel_std=null", "m=2.5"])
    assert over == {"rate_hz": 30, "vel_std": None, "m": 2.5}
    case = random_case(3, **over)
    assert case.rate_hz == 30 and not case.has_velocities and case.cart.m == 2.5
    for bad in ("rate_hz", "seed=4", "bogus=1"):
        with pytest.raises(ValueError, match="FIELD=VALUE"):
            parse_overrides([bad])
