"""The sensor layouts LibRaw reads, each to linear camera values (calibration.raw.decode's raw path).

Every layout is normalised the same way, per channel (raw - black) / (white - black), no
white balance, no colour matrix; what differs is how a pixel gets its channels:

* **2 x 2 Bayer** (any order: RGGB, GRBG, ...): calibration.raw.decode.bilinear_demosaic by
  default (exact, point-symmetric), or LibRaw's own algorithm when asked.
* **Other periodic RGB filter arrays** (Fujifilm X-Trans, 6 x 6): LibRaw's `raw_pattern`
  gives each pixel's colour. ``linear`` is normalised convolution ([Knutsson 1993]) with a
  3 x 3 tent over each channel's own samples, its own sample kept where the pixel has one:
  every 3 x 3 window of an X-Trans array holds all three colours (checked on the pattern
  at run time), so a missing value is the weighted mean of that channel's samples at most
  one pixel away. Other algorithms go to LibRaw: for X-Trans its ``vng`` is VNG, ``ppg``
  Markesteijn's one-pass and ``ahd``, ``dht``, ``aahd`` his three-pass demosaicing
  (LibRaw's xtrans_interpolate; it fails on images smaller than about 512 pixels, which is
  refused naming --demosaic linear). The saturation mask is dilated by the footprint
  measured on a synthetic X-Trans raw (tests/calibration/test_raw_layouts.py): the reach of
  a change of one raw sample into pixels that move by more than one 16-bit code is 1 pixel
  for ours, 2 for VNG, 11 for one-pass and 14 for three-pass Markesteijn (2 codes there),
  so footprints of 3, 5, 23 and 29 pixels (NON_BAYER_FOOTPRINT, MARKESTEIJN_FOOTPRINT).
* **Four-colour arrays** (CMYG, RGBE, RGBW) have no three-channel bilinear answer: LibRaw
  develops them into their four camera channels, named by filter colour (no colour matrix,
  as for every layout). LibRaw has two algorithms for four colours (dcraw_process: quality 0
  is lin_interpolate, any other is vng_interpolate when colors > 3): ``linear`` is its
  bilinear, every other choice its VNG. A channel's colour: LibRaw's ``color_desc``, except
  for a DNG, where LibRaw leaves it at dcraw's default "GMCY" whatever the file says; there
  LibRaw's channel c is the DNG's CFAPlaneColor[c] (parse_tiff_ifd, tag 50710), or, without
  that tag, its guess from the CFAPattern's colours (C, M, Y for a CMY array; Y, C, M, G
  for one of green, cyan, magenta and yellow; else R, G, B, C), read here from the file.
  Measured on a smooth four-channel scene (tests/calibration/test_raw_four_colour.py): a
  saturated sample moves pixels at most 1 away through LibRaw's linear and 2 through its
  VNG, so footprints of 3 and 5 pixels.
* **No filter array**: 3 samples per pixel (linear DNG with PhotometricInterpretation
  LinearRaw, scanner NEFs, LibRaw's "stacked" raws) and monochrome sensors (one colour)
  are read as they are, sample by sample: no demosaicing, and a pixel is saturated where
  one of its own samples reached the white level.

Each result records the layout, the demosaicing used and why (DecodeInfo.layout,
.demosaic, .demosaic_reason).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

TENT = np.array([[1, 2, 1], [2, 4, 2], [1, 2, 1]], np.float32)
NON_BAYER_FOOTPRINT = {"linear": 3, "vng": 5, "ppg": 23}   # LibRaw's on non-Bayer arrays (ppg: 1-pass Markesteijn)
MARKESTEIJN_FOOTPRINT = 29  # ahd, dht, aahd on X-Trans: LibRaw's 3-pass Markesteijn
BAYER_LIBRAW_FOOTPRINT = 5  # its Bayer algorithms read up to two pixels away
DNG_PLANE_LETTERS = "RGBCMYW"   # TIFF/EP CFAPattern and DNG CFAPlaneColor codes 0-6


@dataclass
class RawRead:
    pixels: np.ndarray        # (H, W, C) float32, 1 = the white level
    saturated: np.ndarray     # (H, W) bool
    channels: list[str]
    cfa: str | None           # row-major pattern letters ("RGGB", 36 letters for X-Trans); None without a CFA
    layout: str
    demosaic: str
    reason: str
    black_level: list[float]


Develop = Callable[[str], np.ndarray]   # LibRaw's demosaicing by algorithm name, scaled like the samples


def read_layout(raw, demosaic: str, bilinear: Callable[[np.ndarray, np.ndarray], np.ndarray],
                develop: Develop, path: Path | None = None) -> RawRead:
    """The open rawpy ``raw`` (read from ``path``) as linear camera values, by its layout (see the module
    docstring)."""
    import rawpy  # deferred: start-up time

    black_all = [float(b) for b in raw.black_level_per_channel]
    white = float(raw.white_level)
    colours = int(raw.num_colors)
    if raw.raw_type != rawpy.RawType.Flat:
        return _stacked(raw.raw_image_visible, black_all, white, colours, raw.color_desc.decode())
    if colours == 1:
        return _monochrome(raw.raw_image_visible, black_all, white)
    description = raw.color_desc.decode()
    pattern = raw.raw_pattern
    visible = raw.raw_image_visible.astype(np.float32)
    cfa_index = raw.raw_colors_visible.copy()
    cfa = "".join(description[i] for i in pattern.ravel()) if pattern is not None else None
    black_here = np.asarray(black_all, np.float32)[cfa_index]
    normalised = (visible - black_here) / (np.float32(white) - black_here)
    raw_saturated = visible >= white
    rgb_letters = cfa is not None and set(cfa) <= set("RGB") and set(cfa) == {"R", "G", "B"}
    bayer = pattern is not None and pattern.shape == (2, 2) and sorted(cfa or "") == ["B", "G", "G", "R"]
    if bayer:
        layout = f"Bayer 2 x 2 ({cfa})"
        if demosaic == "linear":
            rgb = bilinear(np.clip(normalised, 0.0, None), np.where(cfa_index == 3, 1, cfa_index))
            return RawRead(rgb, _dilate(raw_saturated, 3), ["R", "G", "B"], cfa, layout, "linear",
                           "2 x 2 Bayer: bilinear in float on the raw samples (the default)", black_all)
        return RawRead(develop(demosaic), _dilate(raw_saturated, BAYER_LIBRAW_FOOTPRINT), ["R", "G", "B"], cfa, layout,
                       demosaic, f"LibRaw's {demosaic}, as asked", black_all)
    size = f"{pattern.shape[0]} x {pattern.shape[1]}" if pattern is not None else "unknown"
    if rgb_letters and colours == 3:
        layout = f"{'X-Trans' if pattern.shape == (6, 6) else 'RGB'} {size}"
        channel = np.where(cfa_index == 3, 1, cfa_index)
        if demosaic == "linear" and covers_3x3(np.where(pattern == 3, 1, pattern)):
            rgb = periodic_demosaic(np.clip(normalised, 0.0, None), channel)
            return RawRead(rgb, _dilate(raw_saturated, 3), ["R", "G", "B"], cfa, layout, "linear",
                           f"{layout} filter array: normalised convolution, 3 x 3, in float on the raw samples "
                           "(every 3 x 3 window holds all three colours)", black_all)
        why = f"LibRaw's {demosaic}, as asked" if demosaic != "linear" else \
            "LibRaw's linear: a 3 x 3 window of this pattern misses a colour"
        footprint = NON_BAYER_FOOTPRINT.get(demosaic, MARKESTEIJN_FOOTPRINT)
        return RawRead(_libraw(develop, demosaic, layout, visible.shape), _dilate(raw_saturated, footprint),
                       ["R", "G", "B"], cfa, layout, demosaic, why, black_all)
    return _four_colour(raw_saturated, pattern, channel_colours(description, colours, path), demosaic, develop,
                        black_all)


def _four_colour(raw_saturated: np.ndarray, pattern: np.ndarray | None, names: str, demosaic: str, develop: Develop,
                 black: list[float]) -> RawRead:
    """A four-colour array through LibRaw's linear (asked) or VNG (anything else), its channels named by colour."""
    cfa = "".join(names[i] for i in pattern.ravel()) if pattern is not None else None
    size = f"{pattern.shape[0]} x {pattern.shape[1]}" if pattern is not None else "unknown"
    layout = f"{len(names)}-colour {size} ({cfa})"
    used = "linear" if demosaic == "linear" else "vng"
    why = f"{len(names)}-colour filter array: LibRaw's "
    if used == "linear":
        why += "linear (bilinear), one of its two algorithms for four colours"
    elif demosaic == "vng":
        why += "VNG, as asked"
    else:
        why += f"VNG: {demosaic} was asked, and LibRaw runs VNG for four colours whatever is asked but linear"
    pixels = _libraw(develop, used, layout, raw_saturated.shape)
    return RawRead(pixels, _dilate(raw_saturated, NON_BAYER_FOOTPRINT[used]), list(names), cfa, layout, used, why,
                   black)


def channel_colours(description: str, colours: int, path: Path | None) -> str:
    """The filter colour of each of LibRaw's ``colours`` channels: for a DNG from its tags (see the module
    docstring), else LibRaw's ``description`` (its color_desc)."""
    planes = dng_plane_colours(path) if path is not None and path.suffix.lower() == ".dng" else None
    return planes if planes is not None and len(planes) == colours else description[:colours]


def dng_plane_colours(path: Path) -> str | None:
    """LibRaw's channel colours for the DNG's raw CFA image: its CFAPlaneColor, or LibRaw's guess from its
    CFAPattern (parse_tiff_ifd's cfa_pc); None when the file has no CFA image tifffile reads."""
    import tifffile  # deferred: start-up time

    try:
        with tifffile.TiffFile(path) as tif:
            for page in (p for top in tif.pages for p in (top, *(getattr(top, "pages", None) or []))):
                pattern, planes = page.tags.get(33422), page.tags.get(50710)
                if pattern is None or int(page.photometric) != 32803:
                    continue
                if planes is not None:
                    return "".join(DNG_PLANE_LETTERS[int(c)] for c in bytes(planes.value)[:4])
                present = {DNG_PLANE_LETTERS[int(c)] for c in bytes(pattern.value) if int(c) < 7}
                return {frozenset("CMY"): "CMY", frozenset("GCMY"): "YCMG"}.get(frozenset(present), "RGBC")
    except Exception:  # noqa: BLE001 - LibRaw read the file; without its tags here, LibRaw's own names stand
        return None
    return None


def _libraw(develop: Develop, demosaic: str, layout: str, shape: tuple[int, ...]) -> np.ndarray:
    """LibRaw's demosaicing of a non-Bayer array; its failure (Markesteijn's on a small image) as a user error."""
    import rawpy  # deferred: start-up time

    from workbench.core.errors import UserInputError

    try:
        return develop(demosaic)
    except rawpy.LibRawError as exc:
        raise UserInputError(f"LibRaw's {demosaic} demosaicing failed on this {shape[1]} x {shape[0]} {layout} raw "
                             f"({_message(exc)})", field="--demosaic",
                             expected="linear (ours, for any RGB filter array)") from None


def _stacked(samples: np.ndarray, black: list[float], white: float, colours: int, description: str) -> RawRead:
    from workbench.core.errors import UserInputError

    if colours != 3:
        raise UserInputError(f"a raw with {colours} samples per pixel and no colour filter array is not supported",
                             expected="3 samples per pixel (RGB) or one (monochrome)")
    values = samples[..., :3].astype(np.float32)
    level = np.asarray(black[:3], np.float32)
    pixels = np.clip((values - level) / (np.float32(white) - level), 0.0, None)
    names = list(description[:3]) if sorted(description[:3]) == ["B", "G", "R"] else ["R", "G", "B"]
    return RawRead(pixels, np.any(values >= white, axis=2), names, None, "3 samples per pixel (no filter array)",
                   "none", "no colour filter array: each pixel's own 3 samples, read as they are", black[:3])


def _monochrome(samples: np.ndarray, black: list[float], white: float) -> RawRead:
    values = samples.astype(np.float32)
    pixels = np.clip((values - np.float32(black[0])) / np.float32(white - black[0]), 0.0, None)[..., None]
    return RawRead(pixels, values >= white, ["Y"], None, "monochrome (no filter array)", "none",
                   "monochrome sensor: each pixel's own sample, read as it is", black[:1])


def covers_3x3(pattern: np.ndarray) -> bool:
    """Whether every 3 x 3 window of the periodic pattern (channel numbers 0, 1, 2) holds all three channels."""
    for c in range(3):
        mask = (pattern == c).astype(np.uint8)
        near = sum(np.roll(np.roll(mask, dy, 0), dx, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1))
        if not np.all(near > 0):
            return False
    return True


def periodic_demosaic(mosaic: np.ndarray, channel: np.ndarray) -> np.ndarray:
    """Demosaicing of any RGB filter array whose 3 x 3 windows hold every colour: per channel, normalised
    convolution ([Knutsson 1993]) of its samples with a 3 x 3 tent, the pixel's own sample kept where it has one.
    At the border (reflected, so a window may see fewer colours) a pixel with no sample of a channel within one
    pixel takes the 5 x 5 tent's value."""
    out = np.empty(mosaic.shape + (3,), np.float32)
    wide = np.outer([1, 2, 3, 2, 1], [1, 2, 3, 2, 1]).astype(np.float32)
    for c in range(3):
        mask = (channel == c).astype(np.float32)
        weight = cv2.filter2D(mask, -1, TENT, borderType=cv2.BORDER_REFLECT_101)
        value = cv2.filter2D(mosaic * mask, -1, TENT, borderType=cv2.BORDER_REFLECT_101) / np.maximum(weight, 1e-12)
        if np.any(weight == 0):
            far = cv2.filter2D(mosaic * mask, -1, wide, borderType=cv2.BORDER_REFLECT_101) / np.maximum(
                cv2.filter2D(mask, -1, wide, borderType=cv2.BORDER_REFLECT_101), 1e-12)
            value = np.where(weight == 0, far, value)
        out[..., c] = np.where(mask > 0, mosaic, value)
    return out


def _dilate(mask: np.ndarray, footprint: int) -> np.ndarray:
    return cv2.dilate(mask.astype(np.uint8), np.ones((footprint, footprint), np.uint8)).astype(bool)


def _message(exc: Exception) -> str:
    text = exc.args[0] if exc.args else exc
    return text.decode(errors="replace") if isinstance(text, bytes) else str(text)
