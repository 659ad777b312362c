"""A photo read for comparison with its clipped highlights filled from its bracket's darker frames.

The report and the scene fit read their photos through here (reports.compare.exposure_merge does
the merge), so the fit does not import the report.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from calibration.calibration_file import read_response
from calibration.raw.decode import is_raw
from reports.compare import images
from reports.compare.exposure_merge import merge_highlights
from workbench.core.errors import UserInputError


def read_merged_photo(photo_path: Path, calibration: Path, brackets: tuple[Path, ...], strict: bool,
                      messages: list[str]) -> tuple[images.Photo, images.Photo]:
    """The photo with its clipped highlights filled from the bracket's darker frames (reports.compare.exposure_merge), and
    the photo as taken (the same object when nothing was filled). ``strict``: a frame that does not fit
    is an error (else it is left out, with the reason)."""
    response = read_response(calibration)
    photo = images.read_photo(photo_path, response)
    if not brackets:
        return photo, photo
    frames, left_out = [], {}
    for path in brackets:
        if not strict and is_raw(path) != is_raw(photo_path):  # a RAW+JPEG folder: not decoded
            left_out[str(path)] = "raw, unlike the photo" if is_raw(path) else "not raw, unlike the photo"
            continue
        try:
            frames.append(images.read_photo(path, response, what="--bracket"))
        except UserInputError as error:
            if strict:
                raise
            left_out[str(path)] = error.reason
    merged, used, _ = merge_highlights(photo, frames, strict=strict)
    merged.decoding = (merged.decoding or {}) | {
        "bracket_left_out": ((merged.decoding or {}).get("bracket_left_out") or {}) | left_out}
    if used:
        messages.append(f"the photo's clipped pixels ({int(photo.clipped.sum())}) were filled from "
                        f"{len(used)} darker bracket frame(s); {int(merged.clipped.sum())} stay clipped. Photo and "
                        "render are compared through the photo's own saturation (fringe_offset_px) and, unclipped, "
                        "by the filled photo's half-maximum edges (fringe_offset_unclipped_px), which the prediction "
                        "and the hues use too")
        return merged, photo
    recorded = dataclasses.replace(photo, decoding=merged.decoding)  # which frames were left out, and why
    return recorded, recorded
