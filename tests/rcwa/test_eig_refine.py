"""Eigen-decompositions refined from a neighbour's eigenvectors (rcwa/cpp/linalg.hpp).

The sweep seeds each k_x's eigen-solve with the previous k_x's eigenvectors and refines
them by Newton's iteration on the decomposition (Dongarra, Moler & Wilkinson 1983). Checked
here against LAPACK's full solve (numpy) on the CD's own matrix E - Kx^2, and for the
cases where it must decline (the guess does not separate a close pair) so that the full
solve takes over.
"""

import numpy as np
import pytest

import rcwa
from rcwa import _core
from rcwa.solver import prepare

# Residual and eigenvalue tolerances: 1e-13 relative is a few hundred ulps for a 61 x 61
# matrix; LAPACK's own backward error is of the same order (n * machine epsilon).
TOLERANCE = 1e-13


def _cd_matrix(kx0: float) -> np.ndarray:
    prep = prepare(rcwa.load_structure("cd"), 550.0, 61)
    E = prep.layers[0].matrices[0]
    return E - np.diag((kx0 + prep.dkx) ** 2)


@pytest.mark.parametrize("step", [1e-3, 2e-2])
def test_refined_decomposition_matches_full_solve(step):
    A = _cd_matrix(0.4)
    _, guess = np.linalg.eig(_cd_matrix(0.4 + step))
    result = _core.eig_from_guess(A, guess)
    assert result is not None, "a neighbour this close must be refined, not declined"
    values, vectors = result.values, result.vectors
    scale = np.abs(A).max()
    assert np.abs(A @ vectors - vectors * values).max() < TOLERANCE * scale
    reference = np.linalg.eigvals(A)
    nearest = np.abs(values[:, None] - reference[None, :]).min(axis=1)
    assert nearest.max() < TOLERANCE * scale
    assert np.allclose(np.linalg.norm(vectors, axis=0), 1.0, atol=1e-12)


def test_exact_guess_is_kept():
    A = _cd_matrix(0.9)
    values, vectors = np.linalg.eig(A)
    result = _core.eig_from_guess(A, vectors)
    assert result is not None
    assert np.abs(np.sort_complex(result.values) - np.sort_complex(values)).max() < TOLERANCE * np.abs(A).max()


def test_declines_a_guess_that_does_not_separate_a_close_pair():
    # Two eigenvalues 1e-4 apart, mixed at 45 degrees: the identity as guess would need a
    # correction of 0.5 / 1e-4, far outside the iteration's reach.
    A = np.array([[1.0, 0.5, 0.0], [0.5, 1.0001, 0.0], [0.0, 0.0, 3.0]], dtype=complex)
    assert _core.eig_from_guess(A, np.eye(3, dtype=complex)) is None


def test_declines_a_singular_guess():
    A = np.diag([1.0, 2.0, 3.0]).astype(complex)
    guess = np.ones((3, 3), dtype=complex)
    assert _core.eig_from_guess(A, guess) is None


def test_declines_a_matrix_with_nan():
    A = np.diag([1.0, 2.0, np.nan]).astype(complex)
    assert _core.eig_from_guess(A, np.eye(3, dtype=complex)) is None
