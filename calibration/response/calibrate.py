"""The camera's response curve from an exposure bracket (``workbench calibrate response``).

A pixel value is Z = f(E t): the scene irradiance E times the exposure time t through one
monotone response f per channel ([Debevec 1997, Sec. 2.1, Eq. 1]). A bracket of the
same view at several known times constrains f up to the scale of E, which is fixed here by
normalising f(0) = 0 and f(1) = 1: normalised irradiance 1 is the one that just reaches the
top value (for the synthetic camera, the raw white level).

Units: images enter as integer codes (8 or 16 bits) and are normalised to values
y = code / (2^bits - 1) in [0, 1]; irradiance is normalised as above; times in seconds.

The modules, one job each: calibration.response.bracket reads the bracket (codes, which
values are usable, exposure times from ``times_s`` (``--times``) or each file's EXIF);
calibration.response.methods holds the methods (``RESPONSE_METHODS``: debevec, robertson and
the workbench's parametric curve, each with its source) and the comparison of curves;
calibration.response.record builds and writes response.json. This module is the command.

Colour images are fitted per channel (a camera applies its curve to each channel, and the
mean of three non-linear values is no value of any curve), and once on the pooled pixels
of all channels, ``all``: the one curve ``points`` gives (truth.json's form), which the
workbench uses. Curves are compared in the log domain over the mid-range (values
0.05-0.95), after removing the unknown scale (a constant in ln E) of the OpenCV curves.

A raw bracket (DNG, NEF, CR2, ...) is checked for linearity instead: the slope of ln(raw
value) against ln(exposure time), with each pixel's ln E eliminated, should be 1.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

from tqdm import tqdm

from calibration.raw.decode import is_raw
from calibration.response.bracket import check_paths, read_bracket, read_raw_bracket
from calibration.response.methods import (
    CURVE_VALUES,
    DEFAULT_KNOTS,
    RESPONSE_METHODS,
    InverseCurves,
    SlopeResponse,
    check_method,
    fit_response,
    linearity_slope,
    log_domain_difference,
    parametric_knot_study,
    response_rms,
)
from calibration.response.record import curve_record, raw_record, write_response
from workbench.core.version import versions

# The names the command line, workbench.score and tests use, from the modules that define them.
__all__ = ["CURVE_VALUES", "RESPONSE_METHODS", "SlopeResponse", "calibrate_response", "fit_response",
           "log_domain_difference", "parametric_knot_study", "read_bracket", "response_rms"]


def calibrate_response(paths: Sequence[str | Path], out: str | Path | None = None, *,
                       times_s: Sequence[float] | None = None, knots: int = DEFAULT_KNOTS,
                       compare: Sequence[str] = ("debevec", "robertson"), progress: bool = False) -> dict:
    """``workbench calibrate response IMAGE... [--times T,...] --out response.json``.

    JPEG/PNG/TIFF brackets: the parametric curve (``points``: the pooled curve, per channel
    in ``channels``) and the ``compare`` methods in ``others``, with their log-domain
    differences to it over values 0.05-0.95. Raw brackets: the linearity check, and
    ``points`` a power law of the measured slope (the identity when linear). The result is
    returned and, when ``out`` is given, written atomically as JSON.
    """
    start = time.perf_counter()
    checked = check_paths(paths)
    if is_raw(checked[0]):
        result = _raw_result(checked, times_s)
    else:
        result = _curve_result(checked, times_s, knots, compare, progress)
    result["timings"]["total_s"] = time.perf_counter() - start
    result["versions"] = versions("numpy", "opencv", "nlopt", "rawpy", "pillow")
    if out is not None:
        write_response(out, result)
    return result


def _raw_result(paths: list[Path], times_s: Sequence[float] | None) -> dict:
    tick = time.perf_counter()
    check = linearity_slope(read_raw_bracket(paths, times_s))
    return raw_record(paths, check, {"linearity_s": time.perf_counter() - tick})


def _curve_result(paths: list[Path], times_s: Sequence[float] | None, knots: int, compare: Sequence[str],
                  progress: bool) -> dict:
    for name in compare:
        check_method(name)
    timings: dict[str, float] = {}
    tick = time.perf_counter()
    bracket = read_bracket(paths, times_s)
    timings["read_s"] = time.perf_counter() - tick
    curves: dict[str, InverseCurves] = {}
    names = ["parametric"] + [m for m in compare if m != "parametric"]
    for name in tqdm(names, desc="response curves", disable=not progress):
        tick = time.perf_counter()
        curves[name] = fit_response(bracket, name, knots=knots) if name == "parametric" else fit_response(bracket, name)
        timings[f"{name}_s"] = time.perf_counter() - tick
    return curve_record(bracket, curves, knots, timings)
