"""Photographs to linear camera RGB: ``workbench decode FILE --out OUT.exr``.

Raw files (any format LibRaw reads: DNG, NEF, CR2, ARW, ...) are read with rawpy (LibRaw)
and developed as far as demosaicing and no further: per-channel black level subtracted,
divided by (white level - black level), no white balance, no colour matrix (the camera's
own RGB), no gamma, no auto-brightening, the sensor's own orientation kept. So a value of 1
is the white level, and the result is linear in the exposure. The demosaicing is recorded.
The default, ``linear``, is bilinear interpolation done here in float32 on LibRaw's raw
samples (exact: LibRaw's own 16-bit output truncates, half a code low on average, which is
0.8 % of a value a thousandth of full scale and bent a raw bracket's slope by 0.5 %); it is
also point-symmetric, which the corner refinement relies on. The others (ahd, dht, aahd,
vng, ppg) are LibRaw's, with white balance 1, raw colour, linear gamma, no brightening and
its automatic maximum adjustment off (it would move the white level to the brightest
pixel), half a code added back for the truncation. Other layouts (X-Trans, four-colour
filters, 3-sample and monochrome raws without a filter array) are calibration.raw.layout's,
and damaged or unsupported files are refused by calibration.raw.checks (truncated image
data, all-zero blocks below the black level, a compression LibRaw lacks) with a one-line
error naming the file. The sidecar records the layout, the demosaicing and why.

A pixel is saturated where any raw sample its demosaiced channels were made from reached
the white level: the raw mask dilated by the demosaicing footprint (3 x 3 for bilinear,
5 x 5 for LibRaw's Bayer algorithms, which read up to two pixels away; see raw_layout for
the others).

Other images (8/16-bit JPEG, PNG, TIFF, grey or colour, read with OpenImageIO) are
brought to [0, 1] by their integer range and passed through an inverse response when one
is given (a callable, or response.json: ``{"points": [[irradiance, value], ...]}``, a
monotone table on [0, 1] interpolated as renderer.response does); without one they are
flagged non-linear. Float images (EXR, float TIFF) are taken as linear already. Channels are
picked by name: the EXR this command writes reads back as it was decoded (its colour
channels, ``saturated`` as the saturation mask, and from its header the colour pattern,
levels, linearity, source and EXIF); an unsupported layout is refused naming its channels.

EXIF: exposure time, ISO, make and model, from the file's own tags: tifffile for
TIFF-based files (DNG, NEF, CR2, ARW, PEF, TIFF), Pillow for JPEG and PNG, rawpy's
shutter and ISO fields for the other raw formats. A zero in the file (how some
converters write "unknown") is reported as unknown (null).

The EXR holds R, G, B (or Y) as 32-bit floats and a ``saturated`` channel (1 where
saturated), with the decode's metadata as header attributes; written atomically, with a
JSON sidecar (settings, versions, timings).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calibration.raw.layout import periodic_demosaic
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write, atomic_write_text
from workbench.core.version import versions as installed_versions

RAW_EXTENSIONS = frozenset({
    ".dng", ".nef", ".nrw", ".cr2", ".cr3", ".crw", ".arw", ".srf", ".sr2", ".raf", ".orf", ".rw2", ".pef",
    ".srw", ".raw", ".rwl", ".3fr", ".iiq", ".erf", ".kdc", ".dcr", ".mrw", ".x3f", ".mos", ".mef",
})
TIFF_BASED = frozenset({".dng", ".nef", ".nrw", ".cr2", ".arw", ".srf", ".sr2", ".pef", ".tif", ".tiff", ".iiq",
                        ".3fr", ".erf", ".kdc", ".dcr", ".mos", ".mef", ".rwl", ".srw"})
DEMOSAIC_ALGORITHMS = ("linear", "ahd", "dht", "aahd", "vng", "ppg")
ResponseLike = Callable[[np.ndarray], np.ndarray] | str | Path | dict | None
HEADER = "workbench:decode"          # the EXR header attribute write_exr records the decode in
SATURATION_CHANNEL = "saturated"     # write_exr's saturation mask (1 where saturated)
# What an EXR's decode header restores (the rest is the file's own: size, saturated share).
# Its ``linear`` is read apart (a float image of codes may still take a response).
RESTORED_FIELDS = ("black_level", "white_level", "cfa", "exposure_time_s", "iso", "make", "model", "source",
                   "demosaic", "response", "layout", "demosaic_reason")


@dataclass
class DecodeInfo:
    """What ``decode --json`` prints (and the sidecar and the EXR header record)."""

    width: int
    height: int
    black_level: list[float] | None     # per channel, in the file's units (raw counts or integer codes)
    white_level: float | None           # the same units; None for float images
    cfa: str | None                     # e.g. "RGGB" (row-major 2 x 2), None for non-raw images
    exposure_time_s: float | None
    iso: float | None
    make: str | None
    model: str | None
    saturated_fraction: float
    linear: bool
    source: str = "raw"                 # "raw" or "image"
    demosaic: str | None = None
    channels: list[str] = field(default_factory=lambda: ["R", "G", "B"])
    response: str | None = None          # where the inverse response came from
    layout: str | None = None            # raw sensor layout: "Bayer 2 x 2 (RGGB)", "X-Trans 6 x 6", "monochrome ..."
    demosaic_reason: str | None = None   # why that demosaicing (or "none": no filter array)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class DecodedImage:
    pixels: np.ndarray       # (H, W, C) float32: linear, 1 = white level (raw); [0, 1] codes or inverted (others)
    saturated: np.ndarray    # (H, W) bool
    info: DecodeInfo

    def rgb(self, path: str | Path, field: str = "photo") -> np.ndarray:
        """(H, W, 3) float32: a grey image repeated, RGB as it is. A photo of other channels (a
        four-colour raw: C, M, Y, G or R, G, B, W) is refused: the scene's camera and the
        calibration are RGB, and taking three of four planes as R, G, B would be wrong colours."""
        pixels = np.asarray(self.pixels, np.float32)
        if pixels.shape[2] == 1:
            return np.ascontiguousarray(np.repeat(pixels, 3, axis=2))
        if pixels.shape[2] == 3 and (self.info.source != "raw" or self.info.channels == ["R", "G", "B"]):
            return np.ascontiguousarray(pixels)  # an image file's three channels are its RGB, whatever their names
        layout = f" ({self.info.layout})" if self.info.layout else ""
        raise UserInputError(f"its channels are {', '.join(self.info.channels)}{layout}: only grey and RGB photos can "
                             "be compared with the RGB scene camera", field=field, got=str(path),
                             expected="a grey or RGB photo (`workbench decode` writes the four camera channels of "
                                      "this raw for other uses)")


def is_raw(path: str | Path) -> bool:
    return Path(path).suffix.lower() in RAW_EXTENSIONS


def decode(path: str | Path, *, response: ResponseLike = None, demosaic: str = "linear",
           response_for_codes_only: bool = False) -> DecodedImage:
    """A photograph as linear camera RGB (raw) or as [0, 1] values (others, inverted through ``response``).
    ``response_for_codes_only``: a linear float image ignores ``response`` instead of refusing it
    (a reader that holds one curve for whatever photo comes: the report's)."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError("no such file", file=path)
    if demosaic not in DEMOSAIC_ALGORITHMS:
        raise UserInputError("unknown demosaicing algorithm", field="--demosaic", expected=" | ".join(DEMOSAIC_ALGORITHMS),
                             got=demosaic)
    if is_raw(path):
        if response is not None:
            raise UserInputError("a raw file is linear: it takes no response curve", file=path, field="--response")
        return _decode_raw(path, demosaic)
    return _decode_image(path, response, response_for_codes_only)


def _decode_raw(path: Path, demosaic: str) -> DecodedImage:
    """A raw file through LibRaw: refused when damaged (calibration.raw.checks), then read by its sensor layout
    (calibration.raw.layout)."""
    import rawpy  # deferred: start-up time

    from calibration.raw import checks as raw_checks
    from calibration.raw import layout as raw_layout  # raw_checks defers tifffile; both need rawpy

    ifds = raw_checks.check_container(path)
    try:
        with rawpy.imread(str(path)) as raw:
            white = float(raw.white_level)
            used = raw_checks.used_black_levels(raw)
            if white <= max(used):
                raise UserInputError("the raw file's white level is not above its black level", file=path,
                                     got={"black_level": used, "white_level": white})
            raw_checks.check_samples(path, raw.raw_image_visible, min(used))
            read = raw_layout.read_layout(raw, demosaic, bilinear_demosaic, lambda name: _libraw_develop(raw, name),
                                          path)
            fallback = {"exposure_time_s": float(raw.other.shutter_speed), "iso": float(raw.other.iso_speed)}
    except rawpy.LibRawError as exc:
        raise UserInputError(raw_checks.libraw_failure(raw_checks.libraw_message(exc), ifds), file=path,
                             expected="a complete raw file LibRaw reads (DNG, NEF, CR2, ARW, ...)") from None
    except UserInputError as exc:
        raise exc.located(file=path) if exc.file is None else exc from None
    rgb, saturated = read.pixels, read.saturated
    if saturated.shape != rgb.shape[:2]:
        raise UserInputError("LibRaw's developed image and its raw samples differ in size", file=path,
                             got={"raw": saturated.shape, "developed": rgb.shape[:2]})
    exif = read_exif(path)
    if path.suffix.lower() not in TIFF_BASED:  # no tag reader for this container: LibRaw's own fields
        exif.update({key: value if value > 0 else None for key, value in fallback.items()})
    info = DecodeInfo(width=rgb.shape[1], height=rgb.shape[0], black_level=read.black_level, white_level=white,
                      cfa=read.cfa, saturated_fraction=float(saturated.mean()), linear=True, source="raw",
                      demosaic=read.demosaic, channels=read.channels, layout=read.layout,
                      demosaic_reason=read.reason, **exif)
    return DecodedImage(rgb, saturated, info)


def _libraw_develop(raw, demosaic: str) -> np.ndarray:
    """LibRaw's demosaicing, scaled to (raw - black) / (white - black), float32. LibRaw writes 16-bit integers by
    truncation, so half a code is added back (except at 0 and at full scale) to keep the values unbiased."""
    import rawpy  # deferred: start-up time

    algorithm = getattr(rawpy.DemosaicAlgorithm, demosaic.upper())
    codes = raw.postprocess(demosaic_algorithm=algorithm, use_camera_wb=False, use_auto_wb=False,
                            user_wb=[1.0, 1.0, 1.0, 1.0], output_color=rawpy.ColorSpace.raw, output_bps=16, gamma=(1, 1),
                            no_auto_bright=True, user_flip=0, adjust_maximum_thr=0.0,
                            highlight_mode=rawpy.HighlightMode.Clip).astype(np.float32)
    inside = (codes > 0) & (codes < 65535)
    return (codes + 0.5 * inside) / np.float32(65535.0)


def bilinear_demosaic(mosaic: np.ndarray, channel: np.ndarray) -> np.ndarray:
    """Bilinear demosaicing of a Bayer mosaic (float, H x W) whose pixel (y, x) holds channel ``channel[y, x]``
    (0 R, 1 G, 2 B), in float: each channel's samples kept, the missing ones the mean of the nearest samples of that
    channel (4 edge neighbours for green, 2 or 4 for red and blue): normalised convolution
    ([Knutsson 1993]) with a cross kernel for green and a tent for
    red and blue, so the image's borders need no special case. A channel map that does not repeat every 2 pixels
    (X-Trans) goes to calibration.raw.layout.periodic_demosaic, the decode's own for those arrays."""
    if min(channel.shape) > 2 and not (np.array_equal(channel[2:], channel[:-2])
                                       and np.array_equal(channel[:, 2:], channel[:, :-2])):
        return periodic_demosaic(mosaic, channel)
    cross = np.array([[0, 1, 0], [1, 4, 1], [0, 1, 0]], np.float32)
    tent = np.array([[1, 2, 1], [2, 4, 2], [1, 2, 1]], np.float32)
    out = np.empty(mosaic.shape + (3,), np.float32)
    for c, kernel in ((0, tent), (1, cross), (2, tent)):
        mask = (channel == c).astype(np.float32)
        weight = cv2.filter2D(mask, -1, kernel, borderType=cv2.BORDER_REFLECT_101)
        out[..., c] = cv2.filter2D(mosaic * mask, -1, kernel, borderType=cv2.BORDER_REFLECT_101) / weight
    return out


def cfa_channels(cfa: str | None, shape: tuple[int, int]) -> np.ndarray | None:
    """Each pixel's colour-filter channel (0 R, 1 G, 2 B) for a square row-major RGB pattern: 2 x 2 ("RGGB") or
    n x n (36 letters for X-Trans); None for anything else (no CFA, four colours)."""
    side = int(round(len(cfa) ** 0.5)) if cfa else 0
    if not cfa or side < 2 or side * side != len(cfa) or set(cfa) - set("RGB"):
        return None
    channel = np.empty(shape, np.int64)
    for k, colour in enumerate(cfa):
        dy, dx = divmod(k, side)
        channel[dy::side, dx::side] = "RGB".index(colour)
    return channel


def _decode_image(path: Path, response: ResponseLike, response_for_codes_only: bool = False) -> DecodedImage:
    """An image file through OpenImageIO: channels picked by name (_pick_channels), integer codes
    brought to [0, 1] (and through ``response``), floats taken as they are; the EXR of
    ``workbench decode`` has its recorded decode (header HEADER) restored."""
    pixels, channel_names, alpha, header_text = _read_with_openimageio(path)
    header = _decode_header(path, header_text)
    pixels, names, marked = _pick_channels(path, pixels, channel_names, alpha, header)
    if np.issubdtype(pixels.dtype, np.integer):
        values, saturated, black, white, described = _integer_values(path, pixels, response)
        linear = described is not None
    else:
        linear = bool(header.get("linear", True)) if header else True
        if response is not None and linear and not response_for_codes_only:
            raise UserInputError("a float image is taken as linear: it takes no response curve", file=path,
                                 field="--response")
        values = pixels.astype(np.float32)
        if not np.all(np.isfinite(values)):
            raise UserInputError("the image holds NaN or infinite values", file=path)
        inverse, described = load_response(None if linear else response)
        if inverse is not None:  # a decode of codes without a curve: the curve now
            values, linear = np.asarray(inverse(values), np.float32), True
        saturated = marked if marked is not None else np.zeros(values.shape[:2], bool)
        black, white = None, None
    info = DecodeInfo(width=values.shape[1], height=values.shape[0], black_level=black, white_level=white, cfa=None,
                      saturated_fraction=float(saturated.mean()), linear=linear, source="image", demosaic=None,
                      channels=names, response=described, **read_exif(path))
    for key in RESTORED_FIELDS:
        if header is not None and key in header and not (key == "response" and described is not None):
            setattr(info, key, header[key])
    return DecodedImage(values, saturated, info)


def _integer_values(path: Path, pixels: np.ndarray, response: ResponseLike):
    """8/16-bit codes as [0, 1] values, through the inverse ``response`` when given: (values,
    saturated (any channel at the top code), black levels, white level, the response's description)."""
    if pixels.dtype.itemsize > 2:
        raise UserInputError("unsupported sample type", file=path, expected="8- or 16-bit integers or floats",
                             got=str(pixels.dtype))
    top = float(np.iinfo(pixels.dtype).max)
    saturated = np.any(pixels >= top, axis=2)
    values = pixels.astype(np.float32) / top
    inverse, described = load_response(response)
    if inverse is not None:
        values = np.asarray(inverse(values), np.float32)
    return values, saturated, [0.0] * pixels.shape[2], top, described


def _decode_header(path: Path, text: Any) -> dict | None:
    """The decode record write_exr puts in the EXR header (None where there is none); a header
    of that name that is not such a record is refused."""
    if text is None:
        return None
    try:
        header = json.loads(text) if isinstance(text, str) else None
    except ValueError:
        header = None
    channels = header.get("channels") if isinstance(header, dict) else None
    if not (isinstance(header, dict) and isinstance(header.get("linear", True), bool)
            and isinstance(channels, list) and channels and all(isinstance(c, str) for c in channels)):
        raise UserInputError("the image's decode header is not the record `workbench decode` writes", file=path,
                             field=HEADER, expected="JSON with the decode's fields (channels, linear, cfa, ...)",
                             got=str(text)[:80])
    return header


def _pick_channels(path: Path, pixels: np.ndarray, names: list[str], alpha: int | None,
                   header: dict | None) -> tuple[np.ndarray, list[str], np.ndarray | None]:
    """The image's colour channels by name ([Kainz 2013]: R, G, B, Y, A and any named others), alpha
    left out, and the ``saturated`` channel (write_exr's) as the saturation mask (> 0.5; None
    without one): the channels the decode header names, in its order; else R, G, B by name;
    else one channel (grey) or three (RGB) in the file's order. Anything else is refused,
    naming the file and its channels."""
    keep = [i for i in range(len(names)) if i != alpha]
    marked = None
    if SATURATION_CHANNEL in names and names.index(SATURATION_CHANNEL) in keep:
        index = names.index(SATURATION_CHANNEL)
        marked = np.asarray(pixels[..., index]) > 0.5
        keep.remove(index)
    available = {names[i]: i for i in keep}
    wanted = header["channels"] if header else (["R", "G", "B"] if set(available) == {"R", "G", "B"} else None)
    if wanted is not None and len(wanted) == len(keep) and set(wanted) == set(available):
        return pixels[..., [available[name] for name in wanted]], list(wanted), marked
    if wanted is None and len(keep) in (1, 3):
        return pixels[..., keep], ["Y"] if len(keep) == 1 else ["R", "G", "B"], marked
    expected = (f"the channels its decode header names ({', '.join(header['channels'])})" if header else
                "grey or RGB (with or without alpha), and optionally a 'saturated' mask as `workbench decode` writes")
    raise UserInputError("unsupported channel layout", file=path, expected=expected, got=names)


IMAGE_BYTES_PER_SAMPLE = 48  # the decode's and the report's float64 working copies of each sample (about six)
IMAGE_MEMORY_FRACTION = 0.5


def check_image_size(width: int, height: int, channels: int, path: str | Path, total_bytes: int | None = None) -> None:
    """Refuse an image whose declared size would not fit in memory once decoded, before its pixels are
    read (issue 46, cause 1: a 3.5 MB PNG declaring 60000 x 60000 pixels took 24 GB before the kernel
    killed the report), with the estimate in the message."""
    if total_bytes is None:
        try:
            total_bytes = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            return
    need = int(width) * int(height) * max(int(channels), 1) * IMAGE_BYTES_PER_SAMPLE
    if need > IMAGE_MEMORY_FRACTION * total_bytes:
        raise UserInputError(f"declares {width} x {height} pixels, which would need about {need / 2**30:.0f} GiB to "
                             f"decode and compare, more than half of this machine's {total_bytes / 2**30:.0f} GiB",
                             file=path, expected="an image of at most about "
                             f"{int(IMAGE_MEMORY_FRACTION * total_bytes / (3 * IMAGE_BYTES_PER_SAMPLE) / 1e6)} megapixels")


def _read_with_openimageio(path: Path) -> tuple[np.ndarray, list[str], int | None, Any]:
    """(pixels (H, W, C) in the file's own type, channel names, the alpha channel's index or
    None, the HEADER attribute or None)."""
    import OpenImageIO as oiio  # deferred: start-up time

    image = oiio.ImageInput.open(str(path))
    if image is None:
        raise UserInputError(f"cannot be read as an image ({oiio.geterror().strip() or 'unknown format'})", file=path,
                             expected="a raw photograph, JPEG, PNG, TIFF or EXR")
    try:
        spec = image.spec()
        check_image_size(spec.width, spec.height, spec.nchannels, path)
        pixels = image.read_image(0, 0, 0, spec.nchannels, oiio.UNKNOWN)
        error = image.geterror()
        header = spec.getattribute(HEADER)
    finally:
        image.close()
    if pixels is None or error:
        raise UserInputError(f"cannot be read completely ({error.strip() or 'no pixels'})", file=path,
                             expected="an intact image file")
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.dtype == np.float16:
        pixels = pixels.astype(np.float32)
    alpha = spec.alpha_channel if spec.alpha_channel >= 0 else None
    return pixels, list(spec.channelnames), alpha, header


def load_response(response: ResponseLike) -> tuple[Callable[[np.ndarray], np.ndarray] | None, str | None]:
    """An inverse response (value -> normalised irradiance) from a callable or a response.json, and a description."""
    if response is None:
        return None, None
    if callable(response):
        return response, getattr(response, "__name__", "a callable")
    from renderer.response import ResponseCurve  # deferred: pulls in scipy, and workbench --help imports this module

    if isinstance(response, dict):
        spec, where = response, "response"
    else:
        where = str(response)
        try:
            spec = json.loads(Path(response).read_text())
        except FileNotFoundError:
            raise UserInputError("no such file", file=response, field="--response") from None
        except (OSError, ValueError) as exc:
            raise UserInputError(f"not a JSON file ({exc})", file=response, field="--response") from None
    if not isinstance(spec, dict) or "points" not in spec:
        raise UserInputError("no response table", file=None if isinstance(response, dict) else response, field="points",
                             expected='{"points": [[irradiance, value], ...]} normalised to [0, 1]', got=type(spec).__name__)
    try:
        curve = ResponseCurve.from_spec({"points": spec["points"]}, where="points")
    except UserInputError as exc:
        raise exc.located(file=None if isinstance(response, dict) else response) from None
    return curve.invert, where


def _rational(value: Any) -> float | None:
    """A TIFF RATIONAL (num, den), a Fraction or a number, as a float; 0 or a zero denominator as None."""
    if isinstance(value, tuple) and len(value) == 2:
        num, den = value
        return None if den == 0 or num == 0 else float(Fraction(int(num), int(den)))
    if isinstance(value, (tuple, list)):
        value = value[0] if value else None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if number > 0 and np.isfinite(number) else None


def _text(value: Any) -> str | None:
    if isinstance(value, bytes):
        value = value.decode(errors="replace")
    text = str(value).strip("\x00 ").strip() if value is not None else ""
    return text or None


def read_exif(path: str | Path) -> dict[str, Any]:
    """{exposure_time_s, iso, make, model} from the file's own tags; None where absent or zero."""
    path = Path(path)
    found: dict[str, Any] = {"exposure_time_s": None, "iso": None, "make": None, "model": None}
    try:
        if path.suffix.lower() in TIFF_BASED:
            found.update(_exif_tifffile(path))
        elif path.suffix.lower() in (".jpg", ".jpeg", ".png", ".webp"):
            found.update(_exif_pillow(path))
    except Exception:  # noqa: BLE001 - an unreadable tag block leaves the fields unknown; the pixels decide validity
        pass
    return found


def _exif_tifffile(path: Path) -> dict[str, Any]:
    import tifffile  # deferred: start-up time (workbench --help imports this module)

    with tifffile.TiffFile(path) as tif:
        tags = tif.pages.first.tags
        exif = tags["ExifTag"].value if "ExifTag" in tags else {}
        make = tags["Make"].value if "Make" in tags else None
        model = tags["Model"].value if "Model" in tags else None
        exposure = exif.get("ExposureTime", tags["ExposureTime"].value if "ExposureTime" in tags else None)
        iso = exif.get("ISOSpeedRatings", tags["ISOSpeedRatings"].value if "ISOSpeedRatings" in tags else None)
    return {"exposure_time_s": _rational(exposure), "iso": _rational(iso), "make": _text(make), "model": _text(model)}


def _exif_pillow(path: Path) -> dict[str, Any]:
    from PIL import Image  # deferred: start-up time (workbench --help imports this module)

    with Image.open(path) as image:
        exif = image.getexif()
        sub = exif.get_ifd(0x8769)
        exposure, iso = sub.get(0x829A), sub.get(0x8827)
        return {"exposure_time_s": _rational(exposure), "iso": _rational(iso),
                "make": _text(exif.get(0x010F)), "model": _text(exif.get(0x0110))}


def versions() -> dict[str, str]:
    """Versions of what a decode depends on (recorded in every output), with the LibRaw
    inside rawpy."""
    import rawpy  # deferred: start-up time

    return {**installed_versions("rawpy", "OpenImageIO", "numpy", "opencv"),
            "libraw": ".".join(map(str, rawpy.libraw_version))}


def write_exr(path: str | Path, decoded: DecodedImage) -> Path:
    """The decoded channels and the saturation mask as a float32 OpenEXR, metadata in its header; atomic."""
    import OpenImageIO as oiio  # deferred: start-up time

    path = Path(path)
    if path.suffix.lower() != ".exr":
        raise UserInputError("the output must be an OpenEXR file", field="--out", expected="a path ending in .exr",
                             got=str(path))
    data = np.concatenate([decoded.pixels, decoded.saturated[..., None].astype(np.float32)], axis=2)
    data = np.ascontiguousarray(data, np.float32)
    names = [*decoded.info.channels, SATURATION_CHANNEL]

    def write(tmp: Path) -> None:
        spec = oiio.ImageSpec(data.shape[1], data.shape[0], data.shape[2], oiio.FLOAT)
        spec.channelnames = tuple(names)
        spec.attribute("compression", "zip")
        spec.attribute(HEADER, json.dumps(decoded.info.to_json()))
        output = oiio.ImageOutput.create(str(tmp))
        if output is None or not output.open(str(tmp), spec):
            raise OSError(f"cannot write {tmp}: {oiio.geterror()}")
        ok = output.write_image(data)
        output.close()
        if not ok:
            raise OSError(f"cannot write {tmp}: {output.geterror()}")

    return atomic_write(path, write)


def decode_to_exr(path: str | Path, out: str | Path, *, response: ResponseLike = None,
                  demosaic: str = "linear") -> dict[str, Any]:
    """``workbench decode``: decode, write OUT.exr and its sidecar OUT.json; returns the sidecar's content."""
    out = Path(out)
    if out.suffix.lower() != ".exr":
        raise UserInputError("the output must be an OpenEXR file", field="--out", expected="a path ending in .exr",
                             got=str(out))
    start = time.perf_counter()
    decoded = decode(path, response=response, demosaic=demosaic)
    decoded_s = time.perf_counter() - start
    write_exr(out, decoded)
    written_s = time.perf_counter() - start - decoded_s
    record = {**decoded.info.to_json(), "input": str(path), "output": str(out),
              "settings": {"demosaic": decoded.info.demosaic, "white_balance": "none (1, 1, 1, 1)",
                           "colour": "camera RGB (no matrix)", "gamma": "linear", "auto_brightness": False,
                           "orientation": "sensor (EXIF orientation not applied)",
                           "response": decoded.info.response},
              "versions": versions(), "timings": {"decode_s": decoded_s, "write_s": written_s}}
    atomic_write_text(out.with_suffix(".json"), json.dumps(record, indent=2) + "\n")
    return record
