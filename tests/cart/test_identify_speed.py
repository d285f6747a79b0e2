"""The fast paths of `estimate` and `diagnose` against the implementations they replace (scipy, one-by-one fits).

`cart._kernels_identify` stands in for scipy.signal / scipy.stats on the estimate path, the closed-form
chi-square tail for scipy.stats in the replay test, the batched fits of `cart.diagnose.fit_models` for
one `fit_model` call per grid point. Each is compared with the independent computation it replaces.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy import signal, stats

from cart import _kernels_identify as kernels
from cart.diagnose import _solve, fit_model, fit_models
from cart.diagnose_replay import chi2_sf_3
from cart.effects import CasterSwivel, PayloadChange, PayloadMassStep, TimeDelay
from cart.log_signals import signals_from_log, velocity_change_noise, window_edges, window_integrals
from studies.testbeds.hidden_effects import random_case


@pytest.mark.parametrize("wn", [2e-3, 0.013, 0.1, 0.37, 0.8])
def test_butterworth_sections_match_scipy(wn):
    np.testing.assert_allclose(
        kernels.butter_lowpass_sos(4, wn), signal.butter(4, wn, output="sos"), rtol=1e-13, atol=0.0
    )


@pytest.mark.parametrize("wn", [3e-3, 0.05, 0.4])
@pytest.mark.parametrize("shape", [(6001, 3), (12001, 3), (6001,), (40, 2), (4,)])
def test_zero_phase_filter_matches_scipy(wn, shape):
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.standard_normal(shape), axis=0) + 5.0
    sos = signal.butter(4, wn, output="sos")
    pad = min(15, shape[0] - 1)
    ref = signal.sosfiltfilt(sos, x, axis=0, padlen=pad)
    np.testing.assert_allclose(kernels.sosfiltfilt(sos, x, pad), ref, rtol=0.0, atol=1e-10 * np.max(np.abs(ref)))


@pytest.mark.parametrize("dof", [1, 2, 3, 5, 9, 10, 40])
def test_student_t_quantile_matches_scipy(dof):
    for p in (0.6, 0.975, 0.999):
        assert kernels.student_t_quantile(p, dof) == pytest.approx(stats.t.ppf(p, dof), rel=1e-12)


def test_chi2_tail_matches_scipy():
    x = np.concatenate([[0.0, np.inf, np.nan], np.geomspace(1e-6, 1500.0, 500)])
    ref = stats.chi2.sf(x, 3)
    got = chi2_sf_3(x)
    assert np.isnan(got[2]) and got[0] == 1.0 and got[1] == 0.0
    np.testing.assert_allclose(got[3:], ref[3:], rtol=1e-12, atol=1e-300)


def test_window_integrals_match_the_cumulative_trapezoid():
    rng = np.random.default_rng(2)
    t = np.cumsum(rng.uniform(0.005, 0.015, 900))
    y = rng.standard_normal((900, 3, 2))
    edges = np.array([4, 30, 31, 400, 899])
    cum = np.concatenate([np.zeros((1, 3, 2)), np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t)[:, None, None], 0)])
    np.testing.assert_allclose(window_integrals(t, y, edges), cum[edges[1:]] - cum[edges[:-1]], atol=1e-12)


def test_batched_solve_equals_one_problem_at_a_time():
    rng = np.random.default_rng(3)
    g, n, p = 4, 60, 7
    d = rng.standard_normal((g, n, 3, p))
    y = np.einsum("gnrp,gp->gnr", d, rng.standard_normal((g, p))) + 0.1 * rng.standard_normal((g, n, 3))
    lv, lw = 0.1 * rng.standard_normal((2, g, n, 3, p))
    batch = _solve(d, y, lv, lw, 0.01, 0.02)
    for k in range(g):
        one = _solve(d[k : k + 1], y[k : k + 1], lv[k : k + 1], lw[k : k + 1], 0.01, 0.02)
        for a, b in zip(batch, one):
            np.testing.assert_allclose(a[k], b[0], rtol=1e-9, atol=1e-12)


@pytest.fixture(scope="module")
def caster_signals():
    h = random_case("caster_swivel", np.random.default_rng(70_000), duration=20.0, caster_form="swivel")
    sig = signals_from_log(h.measured)
    edges = window_edges(sig.t, 2.0 * sig.half_window)
    sig.extras["noise_dv"] = velocity_change_noise(sig, edges)
    return sig, edges


@pytest.mark.parametrize(
    "effect", [PayloadChange(), PayloadMassStep(), TimeDelay(), CasterSwivel(2.0)], ids=lambda e: type(e).__name__
)
def test_batched_grid_fits_equal_one_by_one_fits(caster_signals, effect):
    sig, edges = caster_signals
    nominal = fit_model(sig, edges, [])
    grid = effect.nl_grid(sig)[::4]
    it = 3 if (effect.uses_phi or effect.set_valued) else 1
    batched = fit_models(sig, edges, [[(effect, nl)] for nl in grid], nominal.phi, max_iter=it)
    for nl, fb in zip(grid, batched):
        fo = fit_model(sig, edges, [(effect, nl)], nominal.phi, max_iter=it)
        assert fb.m2ll == pytest.approx(fo.m2ll, rel=1e-9, abs=1e-9)
        np.testing.assert_allclose(fb.x, fo.x, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(fb.thetas[-1], fo.thetas[-1], rtol=1e-8, atol=1e-10)


def test_estimate_path_imports_neither_scipy_signal_nor_stats(tmp_path):
    from cart.logs import write_log
    from studies.testbeds import rigid_sim

    log, _ = rigid_sim.simulate(rigid_sim.random_case(3, duration=20.0, rate_hz=100.0, jitter=0.0, vel_std=None))
    path = tmp_path / "log.csv"
    write_log(path, log)
    code = (
        "import sys\nfrom cart.identify import identify, innovation_check\nfrom cart.logs import read_log\n"
        f"log = read_log({str(path)!r})\nres = identify(log)\ninnovation_check(log, res.params, res.noise)\n"
        "print('HEAVY', sorted(m for m in ('scipy.signal', 'scipy.stats', 'scipy.optimize', 'matplotlib', "
        "'pinocchio') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "HEAVY []" in out, out


def _reference_solve(d, y, lv, lw, s2v, s2w, n_iter=5):
    """The errors-in-variables weighted least squares written out for one problem (y (n, 3), d (n, 3, p))."""
    n, r, p = d.shape
    var_eq = np.array([max(np.var(y[:, k]), 1e-24) for k in range(r)])
    s_k = np.zeros((n, r))
    for _ in range(n_iter):
        sw = np.sqrt(1.0 / (var_eq[None, :] + s_k))
        a2 = (d * sw[:, :, None]).reshape(n * r, p)
        bv = (lv * sw[:, :, None]).reshape(n * r, p)
        bw = (lw * sw[:, :, None]).reshape(n * r, p)
        normal, corr = a2.T @ a2, s2v * (bv.T @ bv) + s2w * (bw.T @ bw)
        col = np.sqrt(np.diag(normal))
        chol = np.linalg.cholesky(normal / np.outer(col, col) + 1e-10 * np.eye(p))
        linv = np.linalg.inv(chol)
        mu, u = np.linalg.eigh(linv @ (corr / np.outer(col, col)) @ linv.T)
        mat = chol @ (u * np.maximum(1.0 - mu, 0.3)) @ u.T @ chol.T
        x = np.linalg.solve(mat, a2.T @ (y * sw).reshape(n * r) / col) / col
        res = y - np.einsum("nrp,p->nr", d, x)
        s_k = s2v * np.einsum("nrp,p->nr", lv, x) ** 2 + s2w * np.einsum("nrp,p->nr", lw, x) ** 2
        var_eq = np.maximum(np.mean(res * res - s_k, axis=0), 0.05 * np.mean(res * res, axis=0) + 1e-24)
    var = var_eq[None, :] + s_k
    a2 = (d / np.sqrt(var)[:, :, None]).reshape(n * r, p)
    return x, var_eq, np.linalg.pinv(a2.T @ a2), float(np.sum(np.log(var) + res * res / var))


def test_solve_matches_the_written_out_fit():
    rng = np.random.default_rng(4)
    n, p = 80, 6
    d = rng.standard_normal((n, 3, p))
    y = d @ rng.standard_normal(p) + 0.2 * rng.standard_normal((n, 3))
    lv, lw = 0.2 * rng.standard_normal((2, n, 3, p))
    got = _solve(d[None], y[None], lv[None], lw[None], 0.03, 0.05)
    for a, b in zip(got, _reference_solve(d, y, lv, lw, 0.03, 0.05)):
        np.testing.assert_allclose(a[0], b, rtol=1e-9, atol=1e-12)


def test_columns_filtered_together_equal_each_filtered_alone():
    """The cut-off search filters its stretches and the unit noise as columns of one array: bit for bit each alone."""
    rng = np.random.default_rng(4)
    sos = signal.butter(4, 0.02, output="sos")
    cols = [np.cumsum(rng.standard_normal(3000)) for _ in range(7)]
    together = kernels.sosfiltfilt(sos, np.column_stack(cols), 15)
    for k, col in enumerate(cols):
        assert np.array_equal(together[:, k], kernels.sosfiltfilt(sos, col, 15))


def test_banded_solve_is_scipys_dtbtrs_bit_for_bit():
    """The ctypes call of LAPACK's dtbtrs (which releases the GIL) gives the f2py wrapper's numbers; a zero on the
    diagonal is an error, not a result."""
    from scipy.linalg.lapack import dtbtrs

    rng = np.random.default_rng(5)
    n = 2001
    band = np.asfortranarray(np.vstack([1.0 + 0.1 * rng.random(n), -1.9 + 0.01 * rng.random(n), 0.9 * np.ones(n)]))
    rhs = np.asfortranarray(rng.standard_normal((n, 5)))
    ref, info = dtbtrs(band, rhs, uplo="L")
    assert info == 0
    assert np.array_equal(kernels._solve_lower_band(band, rhs.copy(order="F")), ref)
    band[0, 7] = 0.0
    with pytest.raises(np.linalg.LinAlgError, match="info 8"):
        kernels._solve_lower_band(band, rhs.copy(order="F"))


def test_threaded_filter_equals_one_thread_bit_for_bit(monkeypatch):
    """Above ``THREADED_VALUES`` half of the columns are filtered on a second thread: the same numbers as one pass."""
    rng = np.random.default_rng(6)
    sos = signal.butter(4, 0.03, output="sos")
    x = np.cumsum(rng.standard_normal((9001, 5)), axis=0)
    threaded = kernels.sosfiltfilt(sos, x, 15)
    monkeypatch.setattr(kernels, "THREADED_VALUES", x.size + 1)
    one = kernels.sosfiltfilt(sos, x, 15)
    assert threaded.flags.c_contiguous and one.flags.c_contiguous
    assert np.array_equal(threaded, one)


@pytest.mark.parametrize("n", [1, 2, 3, 8, 1001, 20000, 20001])
@pytest.mark.parametrize("kind", ["normal", "abs", "ties", "nan", "int", "2d"])
def test_median_is_numpys_median_bit_for_bit(n, kind):
    rng = np.random.default_rng(n)
    x = rng.standard_normal((n, 3) if kind == "2d" else n)
    if kind == "abs":
        x = np.abs(x)
    elif kind == "ties":
        x = np.round(x, 1)
    elif kind == "nan":
        x[n // 3] = np.nan
    elif kind == "int":
        x = np.round(10 * x).astype(int)
    got, ref = kernels.median(x), np.median(x)
    assert np.array_equal(got, ref, equal_nan=True) and np.asarray(got).dtype == np.asarray(ref).dtype
    if kind == "2d":
        assert np.array_equal(kernels.median_columns(x), np.median(x, axis=0))
