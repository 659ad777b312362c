"""What ``workbench calibrate response`` writes: response.json's content, for a fitted
curve (``curve_record``: the parametric curve's ``points``, per channel, the other methods
scaled to it, and what the bracket leaves to extrapolation) or for a raw bracket's
linearity check (``raw_record``), and the file itself, written atomically.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from calibration.response.bracket import DARK_CODES, RAW_USABLE, SATURATED, SATURATION_RADIUS_PX, Bracket
from calibration.response.methods import (
    CURVE_VALUES,
    LINEARITY_TOLERANCE,
    MID_RANGE,
    InverseCurves,
    curve_points,
    log_domain_difference,
)
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text

COVERAGE_WARNING = (0.15, 0.9)  # a bracket whose usable values do not span these is warned about


def raw_record(paths: list[Path], check: dict, timings: dict[str, float]) -> dict:
    """response.json of a raw bracket: the linearity check (calibration.response.methods.linearity_slope)
    and ``points`` a power law of the measured slope (the identity when linear). A slope that
    is not positive is no response (0 ** slope would be infinite, and JSON has no infinity):
    calibration.response.bracket refuses such brackets first, and this refuses them again."""
    x = np.linspace(0.0, 1.0, 256)
    slope = 1.0 if check["linear"] else check["slope"]
    if not (math.isfinite(slope) and slope > 0):
        raise UserInputError("the raw values do not grow with the exposure time", field="exposure times",
                             expected="a positive slope of ln(raw value) against ln(time)", got=slope)
    return {"method": "raw-linearity", "linear": check["linear"], "points": [[float(a), float(a**slope)] for a in x],
            "linearity": check, "times_s": check["times_s"], "files": [str(p) for p in paths],
            "settings": {"raw_usable": list(RAW_USABLE), "tolerance": LINEARITY_TOLERANCE},
            "timings": timings}


def curve_record(bracket: Bracket, curves: dict[str, InverseCurves], knots: int, timings: dict[str, float]) -> dict:
    """response.json of a JPEG/PNG/TIFF bracket: ``curves`` by method, the parametric one
    first (``points``: its pooled curve, per channel in ``channels``), the others in
    ``others`` with their log-domain differences to it."""
    names = list(curves)
    main = curves["parametric"]
    pooled = "all" if "all" in main.channels else main.channels[0]
    result = {
        "method": "parametric", "linear": False, "points": curve_points(main.channel(pooled)),
        "channels": {c: curve_points(main.channel(c)) for c in bracket.channels},
        "others": {name: _other(curves[name], main) for name in names[1:]},
        "times_s": bracket.times_s.tolist(), "files": list(bracket.files),
        "settings": {"bits": bracket.bits, "stride": bracket.stride, "channels": list(bracket.channels),
                     "knots": knots, "mid_range": list(MID_RANGE), "saturated": SATURATED, "dark_codes": DARK_CODES,
                     "saturation_radius_px": SATURATION_RADIUS_PX},
        "fit": main.details, "timings": timings,
    }
    low, high = main.details[pooled]["knots"][0], main.details[pooled]["knots"][-1]
    result["value_range"] = [low, high]
    result["warnings"] = _coverage_warnings(low, high)
    return result


def write_response(out: str | Path, result: dict) -> None:
    """response.json, written atomically."""
    atomic_write_text(out, json.dumps(result, indent=1) + "\n")


def _coverage_warnings(low: float, high: float) -> list[str]:
    """What the bracket leaves to extrapolation: above its brightest usable value the curve
    runs on to f(1) = 1 as a power law (so the irradiance scale rests on it), below its
    darkest as another."""
    warnings = []
    if high < COVERAGE_WARNING[1]:
        warnings.append(f"usable values reach only {high:.2f}: above that the curve is extrapolated to f(1) = 1, "
                        "which sets the irradiance scale; add a longer exposure")
    if low > COVERAGE_WARNING[0]:
        warnings.append(f"no usable value below {low:.2f}: the curve there is a power-law extrapolation; "
                        "add a shorter exposure")
    return warnings


def _other(curves: InverseCurves, main: InverseCurves) -> dict:
    """Another method's curves, scaled to the main one's irradiance (the log-domain offset
    over the mid-range removed), with their differences to it."""
    entry: dict = {"details": curves.details, "channels": {}}
    for name in curves.channels:
        difference = log_domain_difference(curves.channel(name), main.channel(name))
        shifted = curves.channel(name) - (difference["offset"] or 0.0)
        known = np.isfinite(shifted)
        entry["channels"][name] = {
            "log_difference": difference,
            "points": [[float(math.exp(v)), float(y)] for v, y in zip(shifted[known], CURVE_VALUES[known], strict=True)],
        }
    return entry

