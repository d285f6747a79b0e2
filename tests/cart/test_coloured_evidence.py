"""An effect's evidence under coloured F/T noise (cart.coloured_evidence): the noise spectrum it rests on, and
what `diagnose` names on logs of the independent simulator with flicker (1 / f) F/T noise."""

from dataclasses import replace

import numpy as np
import pytest

from cart.coloured_evidence import NOISE_KEY, _score_variance, evidence_inflation, fit_wrench_noise
from cart.log_signals import signals_from_log, window_edges
from cart.noise_model import SpectralNoise


def test_the_score_variance_of_window_weights_matches_a_simulation():
    dt, n, length = 0.005, 6000, 60  # 30 s, 0.3 s windows
    t = np.arange(n) * dt
    rng = np.random.default_rng(5)
    w = np.repeat(rng.standard_normal(n // length), length)  # one weight per window, held over it
    model = SpectralNoise(white=0.0, power=0.05, alpha=1.0, f_ref=10.0, f_min=1.0 / (n * dt), f_max=0.5 / dt)
    # the same noise simulated: its spectrum shaped in the frequency domain over a longer record, cut to n
    reps = []
    for _ in range(1500):
        m = 4 * n
        f = np.fft.rfftfreq(m, dt)
        psd = model.psd(f)
        spec = (rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f))) * np.sqrt(psd * m / (4.0 * dt))
        spec[0] = 0.0
        e = np.fft.irfft(spec, m)[:n]
        reps.append(np.sum(w * e) * dt)
    assert np.var(reps) == pytest.approx(_score_variance(model, t, w), rel=0.15)


def _log_with_noise(kind: str, seed: int = 3):
    from studies.testbeds import rigid_sim
    from studies.testbeds.coloured_noise import coloured

    case = rigid_sim.random_case(seed, duration=40.0)
    case = replace(case, rate_hz=200.0, jitter=0.0, force_std=0.0, torque_std=0.0, vel_std=None)
    log, _ = rigid_sim.simulate(case)
    rng = np.random.default_rng(seed)
    dt = float(np.median(np.diff(log.t)))
    if kind == "white":
        noise = rng.standard_normal((len(log.t), 3))
    else:
        noise = np.column_stack([coloured("pink", len(log.t), dt, rng) for _ in range(3)])
    return replace(log, gamma=log.gamma + noise * [2.0, 2.0, 0.2], qd=None)


@pytest.mark.parametrize("kind", ["white", "pink"])
def test_a_slow_contribution_is_inflated_under_flicker_noise_and_not_under_white(kind):
    sig = signals_from_log(_log_with_noise(kind))
    noise = fit_wrench_noise(sig)
    assert noise is not None
    assert (noise.force.alpha > 0.5) == (kind == "pink")
    sig.extras[NOISE_KEY] = noise
    edges = window_edges(sig.t, 0.3)
    slow = np.zeros((sig.n, 3))
    slow[:, 0] = 1.0  # a constant force: a bias, a slope on a straight push
    fast = np.zeros((sig.n, 3))
    fast[:, 0] = np.sign(np.sin(2.0 * np.pi * sig.t / 0.6))  # alternating from window to window
    var_rows = np.array([4.0 * 0.3 * 0.005, 0.04 * 0.3 * 0.005, 1e-6])  # white window variances of the noise
    k_slow = evidence_inflation(sig, edges, slow, var_rows)
    k_fast = evidence_inflation(sig, edges, fast, var_rows)
    if kind == "white":
        assert k_slow == pytest.approx(1.0, abs=0.3) and k_fast == pytest.approx(1.0, abs=0.3)
    else:
        assert k_slow > 20.0 and k_fast < 0.05 * k_slow  # the evidence of a fast change is hardly touched


def test_flicker_noise_alone_is_not_named_as_a_floor_slope(tmp_path):
    from cart.diagnose import diagnose
    from cart.logs import read_log
    from studies.testbeds import coloured_noise

    # seed 5111's effect-free pink log: its slow wander read as a floor slope (Delta BIC 44.2, gap 30 -> 21 mm)
    coloured_noise.generate(1, 5111, str(tmp_path), colours=("white", "ar1", "pink"))
    report = diagnose(read_log(str(tmp_path / "pink_5111.csv.gz")))
    assert report.names == []
    slope = next(v for v in report.not_named if v.name == "floor_slope")
    assert slope.delta_bic < report.threshold


def test_a_payload_change_under_flicker_noise_is_still_named():
    from cart.diagnose import diagnose
    from studies.testbeds import hidden_effects
    from studies.testbeds.coloured_noise import HIDDEN, coloured

    j = HIDDEN.index("payload_change")
    rng = np.random.default_rng([1, j])  # `coloured_noise --hidden`'s pink_payload_change_1
    log = hidden_effects.random_case("payload_change", rng).measured
    dt = float(np.median(np.diff(log.t)))
    level = np.array([rng.uniform(0.5, 3.0), rng.uniform(0.5, 3.0), rng.uniform(0.05, 0.3)])
    pink = np.column_stack([coloured("pink", len(log.t), dt, rng) for _ in range(3)]) * level
    assert diagnose(replace(log, gamma=log.gamma + pink)).names == ["payload_change"]
