"""Photo and render brought to one linear camera RGB, region masks, and one display transform.

* Photos: decoded by the calibration package (calibration.raw.decode), as the calibration
  read them: raw files (DNG and whatever LibRaw reads) to linear camera RGB, black level
  subtracted per channel, 1 at the white level, no white balance, no gamma, bilinear
  demosaicing; a pixel is clipped where a raw sample it was made from reached the white
  level. Linear float images (EXR, float TIFF) as they are; the EXR ``workbench decode`` writes
  of a raw file as that raw file (its ``saturated`` channel the clipped pixels, its header's
  colour pattern the mosaic). A JPEG, PNG or integer TIFF
  through the inverse of the calibration's fitted response (calibration.json's
  ``response``); without one it is refused.
* Renders: EXR, linear camera RGB (renderer.render), read with OpenImageIO.
* Regions: renderer.regions.region_masks (each pixel's centre ray cast into the Mitsuba
  scene, named by the shape it meets first), re-exported here for the report's modules; the
  targeted render (renderer.render_target) samples the same regions.
* Photometric alignment: one scale, the median over wall pixels (eroded by one pixel) of
  photo / render (channel sums), which is robust to the photo's noise and to a few wrong
  pixels; the CD is left out (it is what is being checked).
* Display: camera RGB -> CIE XYZ by the 3 x 3 matrix that best maps the camera's
  sensitivities onto the CIE 1931 2-degree colour matching functions (least squares over
  wavelength: the Luther condition, met as closely as a linear map can), white-balanced
  on the scene's light (von Kries in the Bradford cone space, the light's XYZ to D65's),
  -> linear sRGB ([IEC 61966-2-1]). One matrix for photo and render.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration.raw.decode import bilinear_demosaic, cfa_channels, check_image_size, decode, is_raw
from renderer.regions import WALL_REGIONS
from renderer.regions import region_masks as region_masks  # re-exported: the report's modules take it from here
from renderer.spectra import camera_sensitivities, light_camera_rgb
from workbench.core.errors import UserInputError

MIN_WALL_PIXELS = 50
BRADFORD = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]])
XYZ_TO_SRGB = np.array([[3.2404542, -1.5371385, -0.4985314], [-0.9692660, 1.8760108, 0.0415560],
                        [0.0556434, -0.2040259, 1.0572252]])
D65_XYZ = np.array([0.95047, 1.0, 1.08883])


@dataclass
class Photo:
    """Linear camera RGB (H, W, 3) and the clipped pixels (H, W)."""

    rgb: np.ndarray
    clipped: np.ndarray
    source: str
    kind: str  # "raw" or "linear"
    channel: np.ndarray | None = None  # (H, W) the Bayer site's channel (0 R, 1 G, 2 B) of a raw photo
    clip_level: float | None = None  # the value a saturated site reads, where the photo has some
    decoding: dict | None = None  # calibration.raw.decode's record (levels, CFA, demosaicing, response, EXIF)


def read_linear(path: str | Path, what: str) -> np.ndarray:
    """A float image (H, W, 3) through OpenImageIO."""
    import OpenImageIO as oiio  # deferred: start-up time

    path = Path(path)
    if not path.is_file():
        raise UserInputError("no such file", field=what, got=str(path))
    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise UserInputError(f"cannot read the image ({buf.geterror().strip()})", field=what, got=str(path))
    spec = buf.spec()  # the header only: pixels are read on demand
    check_image_size(spec.width, spec.height, spec.nchannels, path)
    pixels = buf.get_pixels(oiio.FLOAT)
    if pixels is None or pixels.ndim != 3 or pixels.shape[2] < 3:
        raise UserInputError("not an RGB image", field=what, expected="3 or more channels",
                             got=None if pixels is None else list(pixels.shape))
    rgb = np.asarray(pixels[..., :3], np.float32)
    if not np.all(np.isfinite(rgb)):
        raise UserInputError("the image holds NaN or infinite values", field=what, got=str(path))
    return rgb


def read_photo(path: str | Path, response: dict | None = None, what: str = "--photo") -> Photo:
    """A photo as linear camera RGB through calibration.raw.decode (see the module docstring).

    ``response`` is the calibration's fitted response (calibration.json's ``response``,
    ``points`` of normalised irradiance and value): a JPEG, PNG or integer TIFF is taken
    through its inverse; without one such a photo is refused (it is not linear). A linear
    float image ignores it."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError("no such file", field=what, got=str(path))
    raw = is_raw(path)
    decoded = decode(path, response=None if raw else response, response_for_codes_only=True)
    # A raw file, or the EXR `workbench decode` wrote of one (its header restores the colour
    # pattern, and its values keep 1 at the white level): a sensor's mosaic and clip level.
    sensor = raw or decoded.info.source == "raw"
    if not decoded.info.linear:
        raise UserInputError("the photo is not linear and the calibration holds no response curve to invert",
                             field=what, got=str(path),
                             expected="a raw file (DNG, ...), a linear float image (EXR, float TIFF), or a "
                                      "calibration.json with a response (calibrate with a bracket)")
    rgb = decoded.rgb(path, what)
    channel = cfa_channels(decoded.info.cfa, rgb.shape[:2]) if sensor else None
    clip_level = 1.0 if sensor and decoded.saturated.any() else None  # decode: 1 is the white level
    return Photo(rgb, np.asarray(decoded.saturated, bool), str(path), "raw" if sensor else "linear", channel,
                 clip_level, decoded.info.to_json())


def through_photo_sensor(render: np.ndarray, photo: Photo) -> np.ndarray:
    """The render as the photo's sensor would record it: each pixel's Bayer channel kept, clipped
    at the photo's saturation level, demosaiced bilinearly (calibration.raw.decode.bilinear_demosaic).
    So a band that saturates the photo saturates the render alike, and both are blurred by the
    same demosaicing: their band edges stay comparable (reports.fringes.band_edges). The render must be in
    the photo's units (photometric_scale). A photo that is not raw: the render as it is."""
    if photo.channel is None:
        return render
    h, w = photo.channel.shape
    mosaic = np.take_along_axis(np.asarray(render, np.float32)[:h, :w], photo.channel[..., None], axis=2)[..., 0]
    if photo.clip_level is not None:
        mosaic = np.minimum(mosaic, photo.clip_level)
    return bilinear_demosaic(mosaic, photo.channel)


# ---------------------------------------------------------------- regions


def photometric_scale(photo: np.ndarray, render: np.ndarray, masks: dict[str, np.ndarray],
                      clipped: np.ndarray | None = None) -> tuple[float, int]:
    """One scale s (photo ~ s render) from the walls: the median of the ratio of channel sums
    over wall pixels (eroded by one pixel, unclipped, lit in both). (scale, pixels used)."""
    walls = np.zeros(photo.shape[:2], bool)
    for name in WALL_REGIONS:
        if name in masks:
            walls |= masks[name]
    walls = cv2.erode(walls.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    if clipped is not None:
        walls &= ~clipped
    p, r = photo.sum(axis=2), render.sum(axis=2)
    use = walls & (r > 0) & (p > 0)
    if use.sum() < MIN_WALL_PIXELS:
        raise UserInputError("too few wall pixels to align the photo's brightness with the render's",
                             field="--photo", expected=f"at least {MIN_WALL_PIXELS} wall pixels seen in both",
                             got=int(use.sum()))
    return float(np.median(p[use] / r[use])), int(use.sum())


# ---------------------------------------------------------------- display


def camera_to_xyz(sensitivities: str) -> np.ndarray:
    """The 3 x 3 matrix taking camera RGB to CIE XYZ that best maps the camera's
    sensitivities onto the CIE 1931 2-degree observer (least squares over 380-780 nm)."""
    import colour  # deferred: start-up time

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    wl = np.arange(380.0, 781.0, 5.0)
    xyz = np.stack([np.interp(wl, cmfs.wavelengths, cmfs.values[:, i]) for i in range(3)], axis=1)
    cam = np.stack([np.interp(wl, w, s, left=0, right=0) for w, s in camera_sensitivities(sensitivities)], axis=1)
    m, *_ = np.linalg.lstsq(cam, xyz, rcond=None)
    return m.T


def display_matrix(spec) -> np.ndarray:
    """Camera RGB -> linear sRGB, white-balanced on the scene's light (module docstring);
    the light's own camera RGB maps to equal sRGB values of luminance 1."""
    to_xyz = camera_to_xyz(spec.camera.sensitivities)
    light_rgb = light_camera_rgb(spec.light.spectrum, spec.camera.sensitivities)
    light_xyz = to_xyz @ light_rgb
    cone_light, cone_d65 = BRADFORD @ light_xyz, BRADFORD @ D65_XYZ
    adapt = np.linalg.inv(BRADFORD) @ np.diag(cone_d65 / cone_light) @ BRADFORD
    matrix = XYZ_TO_SRGB @ adapt @ to_xyz
    return matrix / float((matrix @ light_rgb).mean())


def to_display(rgb: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Linear camera RGB (H, W, 3) to linear sRGB (negative values clipped to 0)."""
    return np.maximum(rgb @ matrix.T, 0.0).astype(np.float32)
