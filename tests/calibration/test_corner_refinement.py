"""Corners by point symmetry (calibration/board/corner_refinement.py), on its own, away from any detector.

tests/calibration/test_corners.py measures the whole corner finder on rasterized boards
(hard edges box-filtered into pixels). Here the refinement meets corners whose true centre
is known exactly and whose image is exactly point-symmetric about it before sampling:
smooth X-corners 0.5 + 0.4 tanh(u / w) tanh(v / w) under a shear (a tilted board), with a
blur scale w of 1.2 and 2.5 px (sharp and lens-blurred), at random sub-pixel centres,
twelve in one view. Asserted, each tolerance from the measurement beside it:

* accuracy: within TOLERANCE_BLURRED_PX of the true centre (measured 0.050 px at w = 1.2,
  0.061 px at w = 2.5). This is the interpolant's bias, not noise: Keys' kernel with
  a = -0.75 (the module's choice, best on box-filtered boards) is first-order accurate on
  smooth images, a = -0.5 (Keys' third-order kernel) measured 0.016 and 0.006 px here;
* the answer does not depend on the start: from 0.8 px off and from the truth the fit
  ends within TOLERANCE_SAME_POINT_PX (measured 1.2e-5 px);
* what the criterion promises to ignore is ignored: a monotone response (gamma 2.2;
  measured 0.005 px, sampling breaks the exact invariance) and a linear shading across
  the disc (the h term; measured 0.0006 px) move the result by at most TOLERANCE_RESPONSE_PX
  and TOLERANCE_SHADING_PX;
* a corner whose disc lies mostly outside the image is not trusted and comes back where
  it went in.
"""

from __future__ import annotations

import numpy as np
import pytest

from calibration.board.corner_refinement import refine_by_symmetry

TOLERANCE_BLURRED_PX = 0.07
TOLERANCE_SAME_POINT_PX = 1e-3
TOLERANCE_RESPONSE_PX = 0.01
TOLERANCE_SHADING_PX = 0.002
SHAPE = (120, 150)
SPACING_PX = 14.0  # disc radius 0.7 x 14 = 9.8 px, well inside each corner's 30 px cell
SHEAR = np.array([[1.0, 0.35], [-0.2, 0.8]])


def _centres() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    grid = np.array([[30.0 + 30 * i, 30.0 + 30 * j] for j in range(3) for i in range(4)])
    centres = grid + rng.uniform(-0.5, 0.5, grid.shape)
    return centres, centres + rng.uniform(-0.8, 0.8, grid.shape)


def _x_corners(centres: np.ndarray, blur_px: float, response=None, shading=None) -> np.ndarray:
    """X-corners point-symmetric about each centre (pixel centres at integer coordinates)."""
    y, x = np.mgrid[0:SHAPE[0], 0:SHAPE[1]].astype(float)
    image = np.full(SHAPE, 0.5)
    for cx, cy in centres:
        u = SHEAR[0, 0] * (x - cx) + SHEAR[0, 1] * (y - cy)
        v = SHEAR[1, 0] * (x - cx) + SHEAR[1, 1] * (y - cy)
        near = (np.abs(x - cx) < 15) & (np.abs(y - cy) < 15)
        image = np.where(near, 0.5 + 0.4 * np.tanh(u / blur_px) * np.tanh(v / blur_px), image)
    if shading is not None:
        image = image * shading(x, y)
    if response is not None:
        image = response(image)
    return image.astype(np.float32)


def _refine(image: np.ndarray, start: np.ndarray) -> np.ndarray:
    q, trusted = refine_by_symmetry(image, start, np.full(len(start), SPACING_PX))
    assert trusted.all()
    return q


def _worst(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b, axis=1).max())


@pytest.mark.parametrize("blur_px", [1.2, 2.5])
def test_blurred_corners_are_found_and_the_start_does_not_matter(blur_px):
    centres, start = _centres()
    image = _x_corners(centres, blur_px)
    found = _refine(image, start)
    assert _worst(found, centres) < TOLERANCE_BLURRED_PX
    assert _worst(found, _refine(image, centres)) < TOLERANCE_SAME_POINT_PX


@pytest.mark.parametrize("blur_px", [1.2, 2.5])
def test_a_monotone_response_and_linear_shading_do_not_move_the_corners(blur_px):
    centres, start = _centres()
    plain = _refine(_x_corners(centres, blur_px), start)
    gamma = _refine(_x_corners(centres, blur_px, response=lambda i: i**2.2), start)
    shaded = _refine(_x_corners(centres, blur_px, shading=lambda x, y: 1 + 0.004 * (x - 60) + 0.003 * (y - 60)), start)
    assert _worst(gamma, plain) < TOLERANCE_RESPONSE_PX
    assert _worst(shaded, plain) < TOLERANCE_SHADING_PX


def test_a_corner_off_the_image_is_not_trusted():
    centres, _ = _centres()
    start = np.array([[1.0, 1.0], [148.5, 60.0]])  # three quarters and half of their discs outside
    q, trusted = refine_by_symmetry(_x_corners(centres, 1.2), start, np.full(2, SPACING_PX))
    assert not trusted.any()
    np.testing.assert_array_equal(q, start)
