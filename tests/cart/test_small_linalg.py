"""`cart.small_linalg.solve_small` gives `np.linalg.solve`'s numbers (the same LAPACK routine, called directly)."""

from __future__ import annotations

import numpy as np
import pytest

from cart.small_linalg import solve_small


@pytest.mark.parametrize("n", [3, 6])
def test_the_same_numbers_as_numpy_for_vector_and_column_right_hand_sides(n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(2000):
        a = rng.normal(size=(n, n)) * rng.uniform(0.01, 100.0)
        a = a @ a.T + rng.uniform(1e-3, 10.0) * np.eye(n) if rng.random() < 0.5 else a
        b = rng.normal(size=n) * rng.uniform(0.01, 100.0)
        assert np.array_equal(solve_small(a, b), np.linalg.solve(a, b))
        col = b[:, None]
        assert np.array_equal(solve_small(a, col), np.linalg.solve(a, col))


def test_a_singular_matrix_raises_as_numpy_does() -> None:
    a = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.solve(a, np.ones(3))
    with pytest.raises(np.linalg.LinAlgError):
        solve_small(a, np.ones(3))
