"""The online estimator started far from the cart (a user's cart file: the push starts from the default guess):
converging from the guess is not a load change."""

from __future__ import annotations

from cart.params import CartParams
from studies.online_estimation_study import replay_online, rigid_load_case
from studies.testbeds import rigid_sim


def test_a_start_from_a_guess_at_15_percent_of_the_mass_reports_no_change():
    """Seed 7005 (29.4 kg, no load change), guess 4.4 kg: the GLR sees the estimate leave the guess in the first
    second, on samples before the onset that do not excite the mass; the side before is the guess, 4 prior stds
    and more from the mass after: the guess was wrong (flag ``guess_far``), no load change, and the mass converges."""
    case, _, _ = rigid_load_case(7005, change=False)
    log, _ = rigid_sim.simulate(case)
    c = case.cart
    guess = CartParams(0.15 * c.m, c.dx, 0.0, 0.15 * c.I, 1.0, 1.0)
    std = [case.pos_std, case.pos_std, case.theta_std, case.vel_std, case.vel_std, case.omega_std]
    est = replay_online(log, guess, std)
    assert est.events == ()
    assert [f.kind for f in est.flags if f.kind in ("guess_far", "change_not_confirmed")][:1] == ["guess_far"]
    assert abs(est.params().m / c.m - 1.0) < 0.05
