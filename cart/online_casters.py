"""Swivelling casters in the online regression: their resistance as nuisance columns, switched on by the data.

The online form of :mod:`cart.identify_casters`. A cart on swivelling casters obeys paper eq. 4 only while
the casters trail; whenever the direction in which a swivel axis moves changes (a start, a turn, a stop) the
casters swing round and the swivel bearing's friction, the wheel's scrub and its rolling resistance push the
cart. The swivel angles follow from the cart's motion alone (no-slip rolling of the caster wheel, a first-order
ODE): ``alpha' = -(R / e) sin(alpha - psi) - omega`` with ``(R cos psi, R sin psi) = (v - omega y, omega x)``
the velocity of the swivel axis at ``(x, y)`` in {b} and ``e`` the trail. :class:`CasterBank` steps it for
every geometry of the offline grid (:data:`cart.identify_casters.AXLES` x :data:`cart.identify_casters.TRAILS`)
per period, exactly (``tan(b / 2)`` of the misalignment ``b = alpha - psi`` decays by ``exp(-R dt / e)``),
forms the four resistance columns of :func:`cart.identify_casters.unit_rows` and filters them with the
regression's low-pass (parallel filtering, as the wrench).

The regression (:class:`cart.online_regression.RecursiveRegression`) takes the columns of one geometry as
nuisance parameters (eliminated from the normal equations, :class:`Nuisance`). They are used only while the
data ask for them, by the offline criteria in online form (:meth:`CasterBank.choose`): the modelled casters
have swung at least ``MIN_HALF_TURNS`` half-turns, the four columns are jointly significant (score test on the
accumulated normal equations, the chi-square scaled by the squared residual ratio of the model without them,
Bonferroni over the grid) and they predict the wrench better than without them on data they were not fitted
to (prequential: each sample's residual predicted from the columns' fit on the samples before it). On a cart
without casters, or one whose casters do not swing, the columns stay off and the regression is paper eq. 4.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cart.ekf import chi2_isf
from cart.identify_casters import ALPHA, AXLES, EPS_SHARE, HALF_TRACK, MIN_HALF_TURNS, N_COLUMNS, TRAILS

#: Regularisation of the nuisance block: this share of its diagonal (the columns carry no prior).
RIDGE_SHARE = 1e-6
#: Time constant (s) of the prequential residual sums that compare the models (recent data count most).
COMPARE_TIME_S = 20.0
#: Time constant (s) of the residual ratio of the model without the columns.
MISFIT_TIME_S = 3.0


@dataclass
class Nuisance:
    """Normal-equation blocks of nuisance columns X beside the regressor Y: ``cross = Y^T W X`` (6, k),
    ``info = X^T W X`` (k, k), ``dvec = X^T W y`` (k,)."""

    cross: np.ndarray
    info: np.ndarray
    dvec: np.ndarray

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Return (info + ridge)^-1 rhs (rhs (k,) or (k, n))."""
        ridge = RIDGE_SHARE * np.diag(self.info) + 1e-12
        return np.linalg.solve(self.info + np.diag(ridge), rhs)

    def eliminate(self, d_mat: np.ndarray, d_vec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the normal equations of p with the nuisance parameters eliminated (Schur complement)."""
        x = self.solve(np.column_stack([self.cross.T, self.dvec]))
        return d_mat - self.cross @ x[:, :6], d_vec - self.cross @ x[:, 6]

    def fit(self, p: np.ndarray) -> np.ndarray:
        """Return the nuisance parameters' least-squares fit given p."""
        return self.solve(self.dvec - self.cross.T @ p)


class CasterBank:
    """Swivel angles, filtered caster columns and their normal-equation sums for every grid geometry.

    ``filt``: the regression's low-pass for ``G * 8`` channels (:class:`cart.online_regression.StateVariableFilter`).
    Per period :meth:`raw_columns` steps the angles and :meth:`filtered` filters their columns (G, 2 rows, 4);
    :meth:`accumulate` adds the sample to the sums; :meth:`choose` applies the keep criteria.
    """

    def __init__(self, filt: object) -> None:
        xs, es = np.meshgrid(np.asarray(AXLES, float), np.asarray(TRAILS, float), indexing="ij")
        self.xs, self.es = xs.reshape(-1, 1), es.reshape(-1, 1)  # (G, 1)
        self.ys = np.array([[HALF_TRACK, -HALF_TRACK]])  # (1, 2)
        self.n_geo = self.xs.shape[0]
        self.filter = filt
        self._pq: np.ndarray | None = None  # (2, G, 2): sin, cos of b / 2
        self._psi = np.zeros((self.n_geo, 2))
        self._sq = np.zeros((3, self.n_geo))  # running sums of the squared rates (bearing, wheel, rolling)
        self._count = 0
        self.half_turns = np.zeros(self.n_geo)
        self._alpha = np.zeros((self.n_geo, 2))
        self._rates = np.zeros((3, self.n_geo, 2))  # work arrays of raw_columns
        self._units = np.zeros((N_COLUMNS, self.n_geo, 2))
        self._coef = np.zeros((2, N_COLUMNS, self.n_geo, 2))
        g = self.n_geo
        self.cross = np.zeros((g, 6, N_COLUMNS))
        self.info = np.zeros((g, N_COLUMNS, N_COLUMNS))
        self.dvec = np.zeros((g, N_COLUMNS))
        self._misfit = np.zeros(3)  # EW weight, EW sums of r^2 / expected per row, without the columns
        self._ssr = np.zeros(g + 1)  # prequential weighted SSR: without columns, with each geometry's
        self.active: int | None = None
        self.threshold = chi2_isf(ALPHA / self.n_geo, N_COLUMNS)

    def _swivel(self, v: float, om: float, dt: float) -> tuple[np.ndarray, ...]:
        """Step the swivel angles over one period at forward speed v and yaw rate om; return (alpha, rate, sin
        alpha, cos alpha, px, py) (G, 2), (px, py) the swivel axes' velocity in {b} (broadcast to (G, 2))."""
        px, py = v - om * self.ys, om * self.xs  # (1, 2), (G, 1)
        psi = np.arctan2(py, px)
        if self._pq is None:  # the casters start trailing straight back: alpha = 0, b = -psi
            self._pq = np.stack([np.sin(-0.5 * psi), np.cos(-0.5 * psi)])
        else:
            h = 0.5 * (self._psi - om * dt - psi)
            c, s = np.cos(h), np.sin(h)
            p, q = self._pq
            p_new, q_new = p * c + q * s, q * c - p * s
            self._pq[0], self._pq[1] = p_new, q_new
        self._pq[0] *= np.exp(-np.hypot(px, py) * dt / self.es)
        self._pq /= np.abs(self._pq).sum(axis=0)
        self._psi = psi
        alpha = 2.0 * np.arctan2(self._pq[0], self._pq[1]) + psi
        step = np.abs((alpha - self._alpha + math.pi) % (2.0 * math.pi) - math.pi)  # the angle moved, wrapped
        self.half_turns += step.sum(axis=1) / (2.0 * math.pi)
        self._alpha = alpha
        sa, ca = np.sin(alpha), np.cos(alpha)
        rate = (-px * sa + py * ca) / self.es - om
        return alpha, rate, sa, ca, px, py

    def raw_columns(self, v: float, om: float, dt: float) -> np.ndarray:
        """Return the unfiltered caster columns (G, 2 rows, 4) of :func:`cart.identify_casters.unit_rows`.

        The Coulomb-like columns are regularised by ``EPS_SHARE`` of the running RMS of the rate they act on.
        """
        _, rate, sa, ca, px, py = self._swivel(v, om, dt)
        rates = self._rates
        rates[0], rates[1], rates[2] = rate, rate + om, px * ca + py * sa  # bearing, wheel, rolling
        self._count += 1
        self._sq += np.add.reduce(rates * rates, axis=2) / 2.0  # the mean over the two casters
        eps = EPS_SHARE * np.sqrt(self._sq / self._count) + 1e-12  # (3, G)
        units, coef = self._units, self._coef
        coulomb = np.tanh(rates / eps[:, :, None])
        units[0], units[1], units[2], units[3] = coulomb[0], rate, coulomb[1], coulomb[2]
        arm = (self.xs * ca + self.ys * sa) / self.es
        side = sa / self.es
        coef[0, :3] = -side  # the forward row: the bearing's, viscous and wheel's sideways force, rolling
        coef[0, 3] = ca
        coef[1, 0] = coef[1, 1] = arm - 1.0  # the yaw row
        coef[1, 2] = arm
        coef[1, 3] = self.xs * sa - self.ys * ca
        return np.ascontiguousarray(np.sum(units[None] * coef, axis=3).transpose(2, 0, 1))

    def restart(self, raw: np.ndarray) -> np.ndarray:
        """Restart the filter at rest on the raw columns (G, 2, 4); return them."""
        self.filter.reset(raw.reshape(-1))  # type: ignore[attr-defined]
        return raw

    def filtered(self, raw: np.ndarray, dt: float) -> np.ndarray:
        """Return the filtered caster columns (G, 2, 4) after one period with the raw columns held."""
        return self.filter.step(raw.reshape(-1), dt)[0].reshape(self.n_geo, 2, N_COLUMNS)  # type: ignore[attr-defined]

    def increments(self, Y: np.ndarray, y: np.ndarray, w: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return one sample's (cross (G, 6, 4), info (G, 4, 4), dvec (G, 4)) for rows Y (2, 6), y (2,), weights w."""
        cw = cols * w[None, :, None]
        cw_t = cw.transpose(0, 2, 1)
        return Y.T @ cw, cw_t @ cols, cw_t @ y

    def add(self, inc: tuple[np.ndarray, ...]) -> None:
        """Add one sample's increments to the sums."""
        self.cross += inc[0]
        self.info += inc[1]
        self.dvec += inc[2]

    def carried(
        self,
        after: tuple[np.ndarray, ...],
        h_before: np.ndarray,
        p: np.ndarray,
        before: tuple[np.ndarray, ...] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the sums for a restart on the samples ``after`` (cross, info, dvec per geometry) with what the
        samples before taught about the casters kept as a prior.

        A load change restarts the inertial parameters, not the casters: their fit on the samples before
        (given p, the estimate then) becomes a Gaussian prior with the information the samples before hold
        about them once p is accounted for (``h_before``: p's information (6, 6) from those samples and the prior).
        ``before``: the sums of the samples before (default: the bank's sums less ``after``).
        """
        if before is None:
            before = tuple(s - a for s, a in zip((self.cross, self.info, self.dvec), after))
        cross_b, info_b, dvec_b = before
        ridge = (RIDGE_SHARE * np.einsum("gkk->gk", info_b) + 1e-12)[:, :, None] * np.eye(N_COLUMNS)
        c_old = np.linalg.solve(info_b + ridge, (dvec_b - np.einsum("gik,i->gk", cross_b, p))[:, :, None])
        schur = info_b - np.einsum("gik,gil->gkl", cross_b, np.linalg.solve(h_before, cross_b))
        schur = 0.5 * (schur + np.swapaxes(schur, 1, 2))
        return after[0].copy(), after[1] + schur, after[2] + (schur @ c_old)[:, :, 0]

    def nuisance(self, g: int | None = None) -> Nuisance | None:
        """Return the nuisance block of geometry g (default: the active one; None when the columns are off)."""
        g = self.active if g is None else g
        if g is None:
            return None
        return Nuisance(self.cross[g], self.info[g], self.dvec[g])

    def compare(
        self, r: np.ndarray, w: np.ndarray, cols: np.ndarray, p: np.ndarray, dt: float, expected: np.ndarray
    ) -> None:
        """Add one sample's prequential squared residuals: r (2,) without the columns, r - X c with each geometry's.

        ``c`` is each geometry's fit on the samples before this one (given the estimate p before it);
        ``expected`` (2,): the residual variance the noise model explains (for the misfit without the columns).
        """
        lam_m = math.exp(-dt / MISFIT_TIME_S)
        mf = self._misfit
        mf *= lam_m
        mf[0] += 1.0
        mf[1:] += r * r / expected
        c = np.linalg.solve(self._ridged(self.info), (self.dvec - p @ self.cross)[:, :, None])
        e = r[None, :] - (cols @ c)[:, :, 0]
        lam = math.exp(-dt / COMPARE_TIME_S)
        self._ssr *= lam
        self._ssr[0] += float(w @ (r * r))
        self._ssr[1:] += (e * e) @ w

    def _ridged(self, info: np.ndarray, mat: np.ndarray | None = None) -> np.ndarray:
        """Return ``mat`` (default ``info``; (G, k, k)) plus the ridge of ``info``'s diagonal (``RIDGE_SHARE``)."""
        diag = info.diagonal(axis1=1, axis2=2)
        out = (info if mat is None else mat).copy()
        out.reshape(out.shape[0], -1)[:, :: N_COLUMNS + 1] += RIDGE_SHARE * diag + 1e-12
        return out

    def nominal_misfit(self) -> float:
        """Return the residual ratio (largest row, windowed) of the model without the columns (1 before data)."""
        m = self._misfit
        return math.sqrt(max(m[1], m[2]) / m[0]) if m[0] > 0.0 else 1.0

    def choose(self, p: np.ndarray, cov: np.ndarray, misfit: float, fits: float) -> int | None:
        """Return the geometry whose columns are kept (None: off); see the module docstring.

        ``p``, ``cov``: the regression's estimate and its covariance (the columns' score is taken at p, its
        variance is the columns' information less what p explains); ``misfit``: residual ratio (at least 1) of the
        model, by whose square the chi-square threshold grows; ``fits``: residual ratio of the model without the
        columns up to which it counts as fitting (the columns stay off).
        """
        swung = self.half_turns >= MIN_HALF_TURNS
        if not (swung.any() and self.nominal_misfit() > fits):  # a model that fits needs no more columns
            self.active = None
            return None
        rhs = (self.dvec - p @ self.cross)[:, :, None]
        schur = self.info - self.cross.transpose(0, 2, 1) @ (cov @ self.cross)
        score = (rhs.transpose(0, 2, 1) @ np.linalg.solve(self._ridged(self.info, schur), rhs))[:, 0, 0]
        ok = swung & (score > self.threshold * max(misfit, 1.0) ** 2)
        ok &= self._ssr[0] - self._ssr[1:] > self.threshold  # predicts better, by more than chance allows
        if not ok.any():
            self.active = None
        else:
            self.active = int(np.argmin(np.where(ok, self._ssr[1:], np.inf)))
        return self.active
