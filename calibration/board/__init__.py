"""Calibration boards in photographs: checkerboard and ChArUco corners, the board's description."""
