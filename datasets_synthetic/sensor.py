"""A raw sensor: linear camera RGB to a noisy, quantized Bayer mosaic (and its statistics).

Model ([EMVA 1288, Sec. 2]: the linear photon-transfer model): the
mean number of photo-electrons of a pixel is mu_e = camera_rgb * exposure_time * scale
(the render's linear camera RGB per second, times the electrons one unit gives); shot
noise is Poisson in electrons, read noise Gaussian with sigma_read electrons; the digital
value is round(black + gain * electrons) clipped to [0, white], gain in DN per electron.
So a flat patch has mean black + gain mu_e and variance gain^2 (mu_e + sigma_read^2)
(+1/12 for quantization), which tests/datasets_synthetic/test_sensor.py checks.

Vignetting (optional, ``vignetting_power``): before the photo-electrons are counted, each
channel c is multiplied by the lens's relative illumination cos^p_c(theta), theta the
angle between the pixel's chief ray and the optical axis (the pixel undistorted through
the camera's own model). p = 4 is the natural vignetting of an ideal lens, the "cos^4
law" [Ray, "Applied Photographic Optics", 3rd ed. 2002, Sec. 18.2]; real lenses add
mechanical vignetting and differ by colour, which a p per channel stands in for.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core.errors import UserInputError

CHANNEL = {"R": 0, "G": 1, "B": 2}


@dataclass(frozen=True)
class SensorModel:
    electrons_per_unit: float = 2000.0   # electrons per linear-camera-RGB unit per second
    gain: float = 1.0                    # DN per electron
    read_noise_e: float = 3.0            # electrons (Gaussian sigma)
    black_level: int = 512
    bits: int = 14
    cfa_pattern: str = "RGGB"
    vignetting_power: tuple[float, float, float] | None = None  # p per channel (R, G, B) of cos^p(theta); None: none

    @property
    def white_level(self) -> int:
        return 2**self.bits - 1

    def relative_illumination(self, camera) -> np.ndarray:
        """(H, W, 3) cos^p_c(theta) for ``camera`` (renderer.camera.CameraModel); ones without vignetting."""
        ones = np.ones((camera.height, camera.width, 3))
        if self.vignetting_power is None:
            return ones
        v, u = np.mgrid[0:camera.height, 0:camera.width]
        x = camera.normalized(np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64))  # through the lens model
        cos_theta = (1.0 / np.sqrt(1.0 + (x**2).sum(axis=1))).reshape(camera.height, camera.width)
        return ones * cos_theta[..., None] ** np.asarray(self.vignetting_power, float)

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



def auto_exposure(rgb: np.ndarray, sensor: SensorModel) -> float:
    """An exposure time that puts the 99th percentile of ``rgb`` (linear camera RGB per second)
    at 70 % of ``sensor``'s raw range (before the seeded 'off by a factor' the photographer
    could not control, datasets_synthetic.synth)."""
    level = np.percentile(rgb.max(axis=-1), 99.0)
    usable = sensor.white_level - sensor.black_level
    return float(0.7 * usable / (sensor.gain * sensor.electrons_per_unit * max(level, 1e-12)))


def checked_vignetting(powers) -> tuple[float, float, float]:
    """``powers`` as SensorModel.vignetting_power, or a UserInputError naming --vignetting."""
    try:
        values = tuple(float(q) for q in powers)
    except (TypeError, ValueError):
        values = ()
    if len(values) != 3 or not all(0.0 <= q <= 20.0 for q in values):
        raise UserInputError("needs three powers p (R, G, B) of cos^p, each in 0..20", field="--vignetting", got=powers)
    return values


# ------------------------------------------------------------------------------------ colour tags
#
# What a raw developer needs to show the camera's RGB as colour ([DNG 1.4],
# chapter 6 "Mapping Camera Color Space to CIE XYZ Space"): AsShotNeutral, the
# camera's response to a neutral surface under the light the photo was taken in, and
# ColorMatrix1, XYZ to camera RGB under CalibrationIlluminant1 (D65). Both follow from the
# camera's spectral sensitivities S_c(lambda), the renderer's data: a surface of spectral
# reflectance rho lit by a spectrum E gives camera RGB c = integral E rho S_c dlambda
# (the render's film, renderer.mitsuba_scene.sensor_dict, integrates the same product).

COLOUR_CHECKER = "ColorChecker N Ohta"   # colour-science's measured reflectances of the 24 patches
CMFS = "CIE 1931 2 Degree Standard Observer"


def _on(wavelengths_nm: np.ndarray, source_nm, values) -> np.ndarray:
    return np.interp(wavelengths_nm, np.asarray(source_nm, float), np.asarray(values, float), left=0.0, right=0.0)


def camera_rgb(wavelengths_nm: np.ndarray, sensitivities: np.ndarray, spectrum: np.ndarray) -> np.ndarray:
    """Camera RGB of the spectral radiance ``spectrum`` (..., N) on ``wavelengths_nm`` (N,):
    the integral of radiance x sensitivity (``sensitivities`` (3, N)), trapezoidal; (..., 3)."""
    return np.trapezoid(np.asarray(spectrum, float)[..., None, :] * np.asarray(sensitivities, float), wavelengths_nm, axis=-1)


def as_shot_neutral(wavelengths_nm: np.ndarray, sensitivities: np.ndarray, light: np.ndarray) -> tuple[float, float, float]:
    """DNG AsShotNeutral: the camera RGB of a perfectly white diffuse surface (reflectance 1
    at every wavelength) lit by the spectrum ``light``, normalised so G = 1. A developer's
    white balance divides each channel by it, so a neutral surface comes out grey."""
    rgb = camera_rgb(wavelengths_nm, sensitivities, light)
    if not np.all(rgb > 0):
        raise ValueError(f"the camera sees no light of this spectrum in some channel (camera RGB {rgb})")
    r, g, b = (float(v) for v in rgb / rgb[1])
    return r, g, b


def xyz_to_camera(wavelengths_nm: np.ndarray, sensitivities: np.ndarray) -> tuple[float, ...]:
    """DNG ColorMatrix1 for CalibrationIlluminant1 D65, row-major: the 3 x 3 matrix M with
    camera RGB = M XYZ, least squares over the 24 ColorChecker patches lit by D65 (a
    camera's sensitivities are not a linear mix of the CIE 1931 colour matching functions,
    so no matrix is exact: the Luther condition), scaled as the DNG SDK scales its
    matrices, so that D65's white (Y = 1) maps to a camera RGB whose largest channel is 1."""
    import colour  # deferred: start-up time (seconds)

    wl = np.asarray(wavelengths_nm, float)
    d65 = colour.SDS_ILLUMINANTS["D65"]
    illuminant = _on(wl, d65.wavelengths, d65.values)
    cmfs = colour.MSDS_CMFS[CMFS]
    xyz_bar = np.stack([_on(wl, cmfs.wavelengths, cmfs.values[:, i]) for i in range(3)])
    patches = np.stack([_on(wl, sd.wavelengths, sd.values) for sd in colour.SDS_COLOURCHECKERS[COLOUR_CHECKER].values()])
    xyz = camera_rgb(wl, xyz_bar, patches * illuminant)
    cam = camera_rgb(wl, sensitivities, patches * illuminant)
    white_y = camera_rgb(wl, xyz_bar, illuminant)[1]
    matrix = np.linalg.lstsq(xyz / white_y, cam, rcond=None)[0].T  # cam = M xyz, Y of the white = 1
    white = matrix @ (camera_rgb(wl, xyz_bar, illuminant) / white_y)
    return tuple(float(v) for v in (matrix / white.max()).ravel())
