"""A raw sensor: linear camera RGB to a noisy, quantized Bayer mosaic (and its statistics).

Model (EMVA Standard 1288, release 4.0, Sec. 2: the linear photon-transfer model): the
mean number of photo-electrons of a pixel is mu_e = camera_rgb * exposure_time * scale
(the render's linear camera RGB per second, times the electrons one unit gives); shot
noise is Poisson in electrons, read noise Gaussian with sigma_read electrons; the digital
value is round(black + gain * electrons) clipped to [0, white], gain in DN per electron.
So a flat patch has mean black + gain mu_e and variance gain^2 (mu_e + sigma_read^2)
(+1/12 for quantization), which tests/datasets_synthetic/test_sensor.py checks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CHANNEL = {"R": 0, "G": 1, "B": 2}


@dataclass(frozen=True)
class SensorModel:
    electrons_per_unit: float = 2000.0   # electrons per linear-camera-RGB unit per second
    gain: float = 1.0                    # DN per electron
    read_noise_e: float = 3.0            # electrons (Gaussian sigma)
    black_level: int = 512
    bits: int = 14
    cfa_pattern: str = "RGGB"

    @property
    def white_level(self) -> int:
        return 2**self.bits - 1

    def mosaic(self, rgb: np.ndarray) -> np.ndarray:
        """Keep, at each pixel, the channel of the Bayer filter above it (2x2 pattern)."""
        h, w, _ = rgb.shape
        out = np.empty((h, w), dtype=float)
        for k, c in enumerate(self.cfa_pattern):
            dy, dx = divmod(k, 2)
            out[dy::2, dx::2] = rgb[dy::2, dx::2, CHANNEL[c]]
        return out

    def expected_electrons(self, rgb: np.ndarray, exposure_time_s: float) -> np.ndarray:
        return np.maximum(self.mosaic(rgb), 0.0) * exposure_time_s * self.electrons_per_unit

    def capture(self, rgb: np.ndarray, exposure_time_s: float, rng: np.random.Generator) -> np.ndarray:
        """One raw frame (uint16 mosaic) of linear camera RGB ``rgb`` (H x W x 3)."""
        mu = self.expected_electrons(rgb, exposure_time_s)
        electrons = rng.poisson(mu) + rng.normal(0.0, self.read_noise_e, mu.shape)
        dn = np.rint(self.black_level + self.gain * electrons)
        return np.clip(dn, 0, self.white_level).astype(np.uint16)

    def expected_dn(self, rgb: np.ndarray, exposure_time_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Mean and variance of the digital values (before clipping), per pixel."""
        mu = self.expected_electrons(rgb, exposure_time_s)
        return self.black_level + self.gain * mu, self.gain**2 * (mu + self.read_noise_e**2) + 1.0 / 12.0
