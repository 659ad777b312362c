"""A photo's clipped highlights filled in from darker frames of the same view (an exposure bracket).

A CD's first diffraction orders reflect the ceiling light itself: 30-60 times the walls'
level, so a photo exposed for the room clips them, and their band edges cannot be measured.
A photographer brackets. Here the photo stays as it is wherever it is not clipped (its noise,
its demosaicing, the walls the photometric alignment uses), and each clipped pixel is taken
from the longest darker frame in which it is not, scaled to the photo's exposure.

Why this merge: a raw frame is linear in irradiance (calibration.raw.decode), so frames differ by
their exposure only ([Debevec 1997, Eq. 2] with a linear response); under shot noise the
signal-to-noise ratio grows with exposure, so the longest unclipped frame is the best single
estimate of a pixel ([Hasinoff 2010, Sec. 3]). A JPEG bracket is linear too once calibration.raw.decode has
inverted the fitted response.

Each frame's exposure relative to the photo is measured from the images, not trusted from
EXIF (shutters are nominal): the median, over pixels unclipped and well above the noise in
both, of (merged so far) / (frame), frames taken from brighter to darker so each overlaps the
last; where too few pixels overlap (a frame 4 EV darker than the last), EXIF's ratio is
used, and it is recorded beside the measured one in any case. A frame must show the photo's
view to the pixel: the shift between the two images' log luminance (exposure-invariant),
found by phase correlation ([Kuglin 1975]; OpenCV's ``phaseCorrelate``), must be under
``MAX_SHIFT_PX``; a frame taken from another place (another view of a dataset) is shifted by
tens of pixels. A frame that passes but whose pixels follow no single ratio (robust spread
over ``MAX_RELATIVE_SPREAD``) is refused as well.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from reports.compare.images import Photo
from workbench.core.errors import UserInputError

MIN_LEVEL = 0.02  # of the white level: well above the read noise, where a ratio is measured
MAX_LEVEL = 0.9  # of the white level: below the shoulder where a sensor may start to bend
MIN_OVERLAP_PIXELS = 100  # pixels well exposed in both images: fewer and the ratio is a guess (EXIF's is used)
MAX_RELATIVE_SPREAD = 0.15  # median |merged - ratio x frame| / merged on the overlap; noise gives 0.01-0.05
MAX_SHIFT_PX = 1.0  # phase correlation's shift between photo and frame: a bracket's frames measured 0.0-0.5 px
# (the brightest, most clipped, 0.5), a dataset's other view (orbited 6-12 deg) 16 px
LOG_FLOOR = 1e-3  # of a frame's white level: darker pixels count as this in the view check (noise, not structure)


@dataclass(frozen=True)
class MergedFrame:
    """What one bracket frame contributed (recorded in report.json)."""

    path: str
    ratio: float  # photo units per frame unit, measured from the images
    exif_ratio: float | None  # the same from the EXIF exposure times, when both files have one
    overlap_pixels: int
    relative_spread: float
    pixels_filled: int
    shift_px: float = 0.0  # phase correlation's shift against the photo

    def to_json(self) -> dict:
        return {"path": self.path, "ratio": self.ratio, "exif_ratio": self.exif_ratio,
                "overlap_pixels": self.overlap_pixels, "relative_spread": self.relative_spread,
                "pixels_filled": self.pixels_filled, "shift_px": self.shift_px}


def merge_highlights(photo: Photo, frames: list[Photo], *, strict: bool = True
                     ) -> tuple[Photo, list[MergedFrame], dict[str, str]]:
    """``photo`` with its clipped pixels filled from ``frames`` (module docstring).

    Returns the merged photo, the frames used (darkest last) and the frames left out with the
    reason. Frames as bright as the photo or brighter add nothing to its highlights and are
    left out. A frame of another size, kind, colour pattern or view is an error when
    ``strict`` (the user named it as a bracket of this photo) and is left out otherwise (a
    folder of candidates, some of other views)."""
    merged, clipped = photo.rgb.copy(), photo.clipped.copy()
    level = photo.clip_level if photo.clip_level is not None else 1.0
    used: list[MergedFrame] = []
    skipped: dict[str, str] = {}
    for frame in sorted(frames, key=lambda f: -_brightness(f)):
        try:
            _check_compatible(photo, frame)
            exif_ratio = _exif_ratio(photo, frame)
            shift = _check_same_view(photo, frame, exif_ratio)
            record = _merge_one(merged, clipped, frame, exif_ratio)
        except UserInputError as error:
            if strict:
                raise
            skipped[frame.source] = error.reason
            continue
        if record is None:
            skipped[frame.source] = "not darker than the photo"
            continue
        used.append(replace(record, shift_px=shift))
        level = record.ratio * (frame.clip_level if frame.clip_level is not None else 1.0)
    decoding = dict(photo.decoding or {}) | {"bracket": [u.to_json() for u in used], "bracket_left_out": skipped}
    return replace(photo, rgb=merged, clipped=clipped, clip_level=level, decoding=decoding), used, skipped


def _brightness(frame: Photo) -> float:
    """A frame's exposure, for ordering: EXIF's time where known, else its median level."""
    time = (frame.decoding or {}).get("exposure_time_s")
    return float(time) if time else float(np.median(frame.rgb))


def _exif_ratio(photo: Photo, frame: Photo) -> float | None:
    a, b = (photo.decoding or {}).get("exposure_time_s"), (frame.decoding or {}).get("exposure_time_s")
    return float(a) / float(b) if a and b else None


def _merge_one(merged: np.ndarray, clipped: np.ndarray, frame: Photo, exif_ratio: float | None) -> MergedFrame | None:
    """Measure ``frame``'s ratio against ``merged`` and fill what it can of ``clipped`` (both changed in place)."""
    ratio, overlap, spread = _measured_ratio(merged, clipped, frame)
    if ratio is not None and spread > MAX_RELATIVE_SPREAD:
        raise UserInputError(f"the bracket frame does not show the photo's view: its pixels follow no single exposure "
                             f"ratio (relative spread {spread:.2f})", field="--bracket", got=frame.source,
                             expected=f"a frame of the same view, spread under {MAX_RELATIVE_SPREAD}")
    if ratio is None:
        if exif_ratio is None:
            raise UserInputError("the bracket frame overlaps the photo on too few well-exposed pixels to measure its "
                                 "exposure, and the files hold no exposure times", field="--bracket", got=frame.source,
                                 expected=f"at least {MIN_OVERLAP_PIXELS} pixels between {MIN_LEVEL} and {MAX_LEVEL} "
                                          "of the white level in both, or EXIF exposure times")
        ratio = exif_ratio
    if ratio <= 1.0:
        return None  # as bright as the photo or brighter: it cannot fill the photo's highlights
    fill = clipped & ~frame.clipped
    merged[fill] = ratio * frame.rgb[fill]
    clipped &= frame.clipped
    return MergedFrame(frame.source, float(ratio), exif_ratio, overlap, float(spread), int(fill.sum()))


def _measured_ratio(merged: np.ndarray, clipped: np.ndarray, frame: Photo) -> tuple[float | None, int, float]:
    """(median merged / frame, overlap pixels, robust relative spread) over pixels well exposed in both."""
    ok = ~clipped & ~frame.clipped & np.all(merged > MIN_LEVEL, axis=2)
    ok &= np.all(frame.rgb > MIN_LEVEL, axis=2) & np.all(frame.rgb < MAX_LEVEL, axis=2)
    count = int(ok.sum())
    if count < MIN_OVERLAP_PIXELS:
        return None, count, 0.0
    a, b = merged[ok].ravel(), frame.rgb[ok].ravel()
    ratio = float(np.median(a / b))
    spread = float(np.median(np.abs(a - ratio * b) / a))
    return ratio, count, spread


def _grey(photo: Photo) -> np.ndarray:
    return photo.rgb.mean(axis=2).astype(np.float64)


def _level(photo: Photo) -> float:
    return photo.clip_level if photo.clip_level is not None else float(photo.rgb.max())


def _check_same_view(photo: Photo, frame: Photo, exif_ratio: float | None) -> float:
    """Phase correlation of the two log luminances, each brought to the photo's units (EXIF's ratio, or a median
    over pixels unclipped in both) and limited to the same range (the darker clip level, the brighter noise floor),
    so a region clipped in one image and not in the other is flat in both and cannot look like a shift."""
    a, b = _grey(photo), _grey(frame)
    ratio = exif_ratio
    if ratio is None:
        both = ~photo.clipped & ~frame.clipped & (a > MIN_LEVEL) & (b > MIN_LEVEL)
        if both.sum() < MIN_OVERLAP_PIXELS:
            raise UserInputError("the bracket frame overlaps the photo on too few well-exposed pixels to compare them, "
                                 "and the files hold no exposure times", field="--bracket", got=frame.source,
                                 expected=f"at least {MIN_OVERLAP_PIXELS} pixels between {MIN_LEVEL} and "
                                          f"{MAX_LEVEL} of the white level in both, or EXIF exposure times")
        ratio = float(np.median(a[both] / b[both]))
    top = min(_level(photo), ratio * _level(frame))
    floor = max(LOG_FLOOR, ratio * LOG_FLOOR)
    log_a = np.log(np.clip(a, floor, top))
    log_b = np.log(np.clip(ratio * b, floor, top))
    window = cv2.createHanningWindow((a.shape[1], a.shape[0]), cv2.CV_64F)
    (dx, dy), _ = cv2.phaseCorrelate(log_a - log_a.mean(), log_b - log_b.mean(), window)
    shift = float(np.hypot(dx, dy))
    if shift > MAX_SHIFT_PX:
        raise UserInputError(f"the bracket frame does not show the photo's view: it is shifted by {shift:.1f} px "
                             f"({dx:+.1f}, {dy:+.1f})", field="--bracket", got=frame.source,
                             expected=f"a frame of the same view, taken from the same place (shift under "
                                      f"{MAX_SHIFT_PX} px)")
    return shift


def _check_compatible(photo: Photo, frame: Photo) -> None:
    if frame.rgb.shape != photo.rgb.shape:
        raise UserInputError("the bracket frame's size differs from the photo's", field="--bracket", got=frame.source,
                             expected=f"{photo.rgb.shape[1]} x {photo.rgb.shape[0]}")
    if frame.kind != photo.kind:
        raise UserInputError(f"the bracket frame is {frame.kind} and the photo {photo.kind}", field="--bracket",
                             got=frame.source, expected=f"{photo.kind} frames, like the photo")
    if frame.channel is None or photo.channel is None:
        same_cfa = frame.channel is None and photo.channel is None
    else:
        same_cfa = bool(np.array_equal(frame.channel, photo.channel))
    if not same_cfa:
        raise UserInputError("the bracket frame's colour filter pattern differs from the photo's", field="--bracket",
                             got=frame.source, expected="frames from the photo's camera")
