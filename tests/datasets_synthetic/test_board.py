"""The synthetic checkerboard's truth against calibration's own board model.

The two are written independently (datasets_synthetic from the printed squares,
calibration from OpenCV's pattern size), so this test is where a disagreement in
corner order, origin or spacing shows up, instead of cancelling out inside the
calibration test.
"""

from __future__ import annotations

import numpy as np
import pytest

from calibration.intrinsics.calibrate import board_points
from datasets_synthetic.board import Checkerboard

EXACT = 1e-12  # metres: both are sums of a few multiples of the square size


@pytest.mark.parametrize(("inner", "square"), [((9, 6), 0.020), ((7, 5), 0.035), ((4, 11), 0.0125)])
def test_truth_corners_equal_calibrations_board(inner: tuple[int, int], square: float) -> None:
    board = Checkerboard(inner_corners=inner, square_size_m=square)
    truth = board.object_points()
    assert truth.shape == (inner[0] * inner[1], 3)
    np.testing.assert_allclose(truth, board_points(inner, square), atol=EXACT)


def test_truth_corners_lie_on_square_boundaries_of_the_texture() -> None:
    """Each inner corner is where four texels of alternating colour meet in the texture."""
    board = Checkerboard()
    texture = board.texture()[:, :, 0]
    t = board.texels_per_square
    margin = int(round(board.margin_squares * t))
    width_m, height_m = board.size_m
    texels_per_m = texture.shape[1] / width_m
    for x, y, _ in board.object_points():
        col = (x + width_m / 2) * texels_per_m
        row = (y + height_m / 2) * texels_per_m
        assert abs(col - round(col)) < 1e-9 and abs(row - round(row)) < 1e-9
        r, c = int(round(row)), int(round(col))
        assert margin <= r < texture.shape[0] - margin and margin <= c < texture.shape[1] - margin
        quad = texture[r - 1:r + 1, c - 1:c + 1]
        assert quad[0, 0] == quad[1, 1] != quad[0, 1] == quad[1, 0]
