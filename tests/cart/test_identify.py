"""The one dynamics core and the whole-log least-squares estimator (cart.dynamics, cart.identify)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cart import dynamics, model
from cart.identify import IdentifiabilityError, identify
from cart.logs import CartLog, write_log
from cart.params import CartParams
from studies.testbeds import rigid_sim


def test_core_forward_dynamics_equals_the_matrix_form_with_a_yaw_coefficient():
    rng = np.random.default_rng(3)
    for _ in range(20):
        p = CartParams(
            rng.uniform(5, 80),
            rng.normal(0.3, 0.1),
            rng.normal(0, 0.1),
            rng.uniform(0.5, 5),
            sigma=rng.uniform(0, 8),
            sigma_yaw=rng.uniform(0, 3),
        )
        q, qd, g = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3) * 20
        dense = model.forward_dynamics(q, qd, g, p, exact=True)  # Lagrange multiplier form, paper eq. (4)
        fast = dynamics.forward_dynamics(q[2], *qd, *g, *p.phi, *p.damping)
        np.testing.assert_allclose(fast, dense, rtol=1e-10, atol=1e-10)


def test_regressor_inverts_the_forward_dynamics_on_the_constraint():
    rng = np.random.default_rng(5)
    for _ in range(20):
        phi = np.array([rng.uniform(5, 80), rng.normal(5, 2), rng.normal(0, 2), 0.0])
        phi[3] = (phi[1] ** 2 + phi[2] ** 2) / phi[0] + rng.uniform(0.5, 5)
        damping = rng.uniform(0, 5, size=2)
        th, v, om = rng.normal(), rng.normal(), rng.normal()
        g = rng.normal(size=3) * 20
        xdd, ydd, odot = dynamics.forward_dynamics(th, v * math.cos(th), v * math.sin(th), om, *g, *phi, *damping)
        vdot = math.cos(th) * xdd + math.sin(th) * ydd  # on the constraint, d/dt of the forward speed
        y = dynamics.regressor(v, om, vdot, odot) @ np.r_[phi, damping]
        fu = math.cos(th) * g[0] + math.sin(th) * g[1]
        np.testing.assert_allclose(y, [fu, g[2]], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(
            dynamics.inverse_dynamics(v, om, vdot, odot, *phi, *damping), [fu, g[2]], rtol=1e-9, atol=1e-9
        )


@pytest.fixture(scope="module")
def independent_log():
    case = rigid_sim.random_case(7, duration=30.0, m=42.0, c_v=6.0, c_w=1.0, vel_std=None, jitter=0.2)
    return rigid_sim.simulate(case)


def test_least_squares_is_unbiased_under_wrench_noise_on_an_independent_simulator(independent_log):
    log, truth = independent_log
    res = identify(log)
    p, s = res.params, res.std
    assert res.model_fits, res.warnings
    assert abs(p.m - truth["m"]) < 3 * s["mass"] and abs(p.m / truth["m"] - 1) < 0.03
    assert abs(p.dx - truth["dx"]) < max(3 * s["com"][0], 0.01)
    assert abs(p.dy - truth["dy"]) < max(3 * s["com"][1], 0.01)
    assert abs(p.I - truth["I_about_com"]) < 3 * s["inertia"]
    # two viscous coefficients, each recovered (the scalar sigma of the paper would mix them)
    assert p.sigma == pytest.approx(truth["c_v"], rel=0.15)
    assert p.sigma_yaw == pytest.approx(truth["c_w"], rel=0.3)


def test_a_static_log_is_refused_with_what_is_missing():
    t = np.arange(0, 10, 0.01)
    rng = np.random.default_rng(0)
    q = rng.normal(0, 1e-3, (len(t), 3))
    g = rng.normal(0, 3, (len(t), 3)) + [50.0, 0, 0]
    with pytest.raises(IdentifiabilityError, match="does not move"):
        identify(CartLog(t=t, q=q, gamma=g))


def test_misfit_is_reported_and_covered(independent_log):
    """Add Coulomb friction the nominal model lacks: model_fits must go false or the truth stay within 3 std."""
    log, truth = independent_log
    v = np.gradient(log.q[:, 0], log.t) * np.cos(log.q[:, 2]) + np.gradient(log.q[:, 1], log.t) * np.sin(log.q[:, 2])
    # a 12 N dry friction the cart feels is, seen from the log, a wrench the robot applied on top
    f = 12.0 * np.tanh(v / 0.02)
    g = log.gamma.copy()
    g[:, 0] += f * np.cos(log.q[:, 2])
    g[:, 1] += f * np.sin(log.q[:, 2])
    res = identify(CartLog(t=log.t, q=log.q, gamma=g))
    assert any("Coulomb" in w for w in res.warnings) or not res.model_fits
    assert abs(res.params.m - truth["m"]) < 3 * res.std["mass"]


def test_cli_estimate_json_has_the_contract_fields(tmp_path, independent_log, capsys):
    from cartpush.cli import main

    log, truth = independent_log
    path = tmp_path / "push.csv"
    write_log(path, log)
    assert main(["estimate", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("mass", "com", "inertia", "sigma", "sigma_yaw", "std", "nis_mean", "model_fits", "warnings"):
        assert key in out
    assert out["method"] == "ls" and out["model_fits"] is True
    assert abs(out["mass"] - truth["m"]) < 3 * out["std"]["mass"]
    assert 2.0 < out["nis_mean"] < 12.0
