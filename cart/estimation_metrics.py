"""How well an estimate followed the truth over a run: one definition for Table I and the push loop."""

from __future__ import annotations

import numpy as np


def estimation_errors(
    t: np.ndarray,
    mass_hat: np.ndarray,
    com_hat: np.ndarray,
    mass_true: np.ndarray | float,
    com_true: np.ndarray,
    after: float = 5.0,
) -> dict[str, float]:
    """Return the time-resolved estimation errors of a run (the truth may change during it, Table I test 11).

    RMS of |m_hat - m| (kg) and of the CoM error (m) over the whole run, their maxima after `after` s, and
    the time (s, summed over samples) within 1 kg / 1 cm. ``com_hat`` is (N, 2); ``com_true`` (2,) or (N, 2).
    Samples whose CoM estimate is not finite (a zero mass estimate) are left out of the CoM figures.
    """
    t = np.asarray(t, dtype=float)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    e_m = np.abs(np.asarray(mass_hat, dtype=float) - mass_true)
    e_c = np.hypot(*(np.asarray(com_hat, dtype=float) - com_true).T)
    late = t >= after
    late = late if late.any() else np.ones_like(late)
    return {
        "mass_error_rms_kg": float(np.sqrt(np.mean(e_m**2))),
        "mass_error_max_after_5s_kg": float(e_m[late].max()),
        "com_error_rms_m": float(np.sqrt(np.nanmean(e_c**2))),
        "com_error_max_after_5s_m": float(np.nanmax(e_c[late])),
        "time_mass_within_1kg_s": float(np.sum(e_m <= 1.0) * dt),
        "time_com_within_1cm_s": float(np.sum(e_c <= 0.01) * dt),
    }
