"""The compiled small-matrix routines of the per-frame path against NumPy's LAPACK."""
import numpy as np
import pytest

from localizer.smallmat import inverse, null_vector, solve


@pytest.mark.parametrize("n", [1, 2, 4, 5, 7])
def test_solve_and_inverse_match_lapack(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        A = rng.normal(size=(n, n)) * rng.uniform(0.01, 100.0, n)
        b = rng.normal(size=n)
        A0 = A.copy()
        assert np.allclose(solve(A, b), np.linalg.solve(A, b), rtol=1e-9, atol=1e-12)
        assert np.allclose(inverse(A), np.linalg.inv(A), rtol=1e-9, atol=1e-12)
        assert np.array_equal(A, A0)  # inputs untouched


def test_singular_matrix_raises():
    A = np.array([[1.0, 2.0], [2.0, 4.0]])
    with pytest.raises(ZeroDivisionError):
        solve(A, np.ones(2))
    with pytest.raises(ZeroDivisionError):
        inverse(A)


@pytest.mark.parametrize("shape", [(3, 3), (4, 4), (6, 4)])
def test_null_vector_is_the_last_right_singular_vector(shape):
    rng = np.random.default_rng(7)
    for _ in range(50):
        A = rng.normal(size=shape) * rng.uniform(0.01, 10.0, shape[1])
        v = null_vector(A)
        w = np.linalg.svd(A)[2][-1]
        assert abs(np.linalg.norm(v) - 1.0) < 1e-12
        assert abs(abs(v @ w) - 1.0) < 1e-9
    # an exact null space (rank n - 1): A v = 0
    A = rng.normal(size=(4, 4))
    A[:, 3] = A[:, 0] - 2.0 * A[:, 1]
    v = null_vector(A)
    assert np.linalg.norm(A @ v) < 1e-12
