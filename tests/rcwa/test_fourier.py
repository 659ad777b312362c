"""Exact shape transforms checked against each other and against the profile they describe.

Tolerances: a rectangle given as a polygon equals the rectangle transform (both closed
forms: 1e-12); a 720-gon approximates a circle to its area defect (2e-5 relative); a
painted profile's Fourier series, summed to 2000 harmonics, returns the profile's value
away from its edges to the series' truncation error (2e-3), and its mean exactly (1e-12).
"""

import numpy as np
import pytest

from rcwa import fourier


def test_polygon_transform_of_a_rectangle_is_exact():
    qx, qy = np.meshgrid(np.linspace(-20, 20, 9), np.linspace(-15, 15, 7), indexing="ij")
    rect = fourier.rectangle_transform((0.3, 0.2), (0.5, 0.25), qx, qy)
    vertices = np.array([[0.05, 0.075], [0.55, 0.075], [0.55, 0.325], [0.05, 0.325]])
    assert np.allclose(fourier.polygon_transform(vertices, qx, qy), rect, atol=1e-12)
    assert np.allclose(fourier.polygon_transform(vertices[::-1], qx, qy), rect, atol=1e-12)  # orientation-free


def test_circle_transform_matches_a_fine_polygon():
    qx, qy = np.meshgrid(np.linspace(-30, 30, 7), np.linspace(-30, 30, 7), indexing="ij")
    angles = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    ring = np.stack([0.1 + 0.3 * np.cos(angles), -0.2 + 0.3 * np.sin(angles)], axis=1)
    exact = fourier.circle_transform((0.1, -0.2), 0.3, qx, qy)
    assert np.allclose(fourier.polygon_transform(ring, qx, qy), exact, atol=2e-5 * np.pi * 0.09)


def test_profile_coefficients_reconstruct_the_profile():
    segments = fourier.paint_intervals(1.0, 2.0, [(0.8, 1.3, 5.0), (0.1, 0.2, 3.0)])
    expected = [(0.0, 0.1, 5.0), (0.1, 0.2, 3.0), (0.2, 0.3, 5.0), (0.3, 0.8, 2.0), (0.8, 1.0, 5.0)]
    assert [(pytest.approx(a), pytest.approx(b), v) for a, b, v in expected] == segments
    g = np.arange(-2000, 2001)
    c = fourier.profile_coefficients(segments, 1.0, g)
    x = 0.55  # away from the edges, the Fourier series converges to the value
    assert np.real(np.sum(c * np.exp(2j * np.pi * g * x))) == pytest.approx(2.0, abs=2e-3)
    assert c[2000] == pytest.approx(0.1 * 3.0 + 0.5 * 2.0 + 0.4 * 5.0, abs=1e-12)


def test_convolution_matrix_sign_convention():
    """C[m, n] = c(n - m) for harmonics k_m = k_inc - m G (module docstring)."""
    c = {-1: 1.0, 0: 2.0, 1: 3.0}
    m = np.array([-1, 0, 1])
    C = fourier.toeplitz(lambda d: np.vectorize(lambda k: c.get(k, 0.0))(d), m)
    assert C[0, 1] == 3.0 and C[1, 0] == 1.0
